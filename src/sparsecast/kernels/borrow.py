"""Kernels without reference counting, for hot loops (:data:`NO_REFCOUNT`).

Numba counts references to every array a compiled function copies: reading an
array out of a record, or passing it to a function, costs an atomic
increment and decrement, and every array argument of a plain call is counted on
entry and on exit. In the DVR driver's interval loop that happened several times
per interval (measured: the deep k-d tree 1.4x slower than with the arrays passed
as plain arguments, worse on two threads, where the atomics on shared counters
bounce between cores). Views with a null owner (an earlier ``borrowed``) removed
the atomics but not the calls into the runtime (``NRT_incref`` / ``NRT_decref``,
which test the null owner and return): iso_interval made 12 per interval, the k-d
tree's ``start_tile`` 4 per node visited. Measured on the tooth's isosurface at
1024^2 (perf, with a symbol map of the compiled code): the calls took 6 % of the
deep k-d tree's frame, and with them gone ``start_tile`` took 7 % instead of 13 %;
the frame went from 83.6 to 67.4 ms (naive 290 ms, unchanged).

:data:`NO_REFCOUNT` removes the calls too: the DVR driver, the plain kernels it
calls per tile, ray, interval or hit, and the surface kernels that trace a chunk
of rays or a tile of pixels compile without the runtime. Such a kernel may not
allocate (Numba refuses to compile one that does), and it takes no reference of
its own, so what it reads must be kept alive by its caller, as every argument is:
the DVR driver's scratch comes from ``render.driver.new_scratch``, called before
it; a surface driver's parallel loop allocates a chunk's stack and passes it in.
"""

from __future__ import annotations

__all__ = ["NO_REFCOUNT"]

#: Numba options of a kernel that allocates nothing: compile it without the runtime
#: (no reference counting of its arguments and locals; see the module docstring).
#: ``_nrt`` is the jit option behind Numba's ``nrt`` compiler flag (numba.core.options).
NO_REFCOUNT = {"_nrt": False}
