"""Borrowed views: arrays (and records of arrays) without reference counting, for hot loops.

Numba counts references to every array a compiled function copies: reading an
array out of a record, or passing it to a function, costs an atomic
increment and decrement. In the DVR driver's interval loop that happened
several times per interval (measured: the deep k-d tree 1.4x slower than with
the arrays passed as plain arguments, worse on two threads, where the atomics
on shared counters bounce between cores). :func:`borrowed` returns the same
arrays with no owner (a null ``meminfo``), whose reference counting compiles to
no atomics, but each count is still a call into the runtime (``NRT_incref`` /
``NRT_decref``, which test the null owner and return).

:data:`NO_REFCOUNT` removes the calls too, in the plain (not inlined) kernels the
driver calls per tile, ray, interval or hit: every array argument was counted
on entry and on exit (iso_interval: 12 calls per interval; the k-d tree's
``start_tile``: 4 per node visited). Measured on the tooth's isosurface at
1024^2 (perf, with a symbol map of the compiled code): the calls took 6 % of the
deep k-d tree's frame, and with them gone ``start_tile`` took 7 % instead of 13 %;
the frame went from 83.6 to 67.4 ms (naive 290 ms, unchanged).
Such a kernel may not allocate (Numba refuses to compile one that does), and it
takes no reference of its own, so what it reads must be kept alive by its caller,
as every argument is. The DVR driver is such a kernel now (its scratch comes from
``render.driver.new_scratch``, called before it); borrowed views remain for loops
that allocate as they go, such as the surface kernels' per-chunk scratch inside
``prange``.

Safety: a borrowed view does not keep its data alive. Borrow only what stays
alive for as long as the view is used: a function's arguments (the caller holds
them), or a local that :func:`keep_alive` uses after the loop.
"""

from __future__ import annotations

from numba import types
from numba.core import cgutils
from numba.extending import intrinsic, overload

__all__ = ["NO_REFCOUNT", "borrowed", "keep_alive"]

#: Numba options of a kernel that allocates nothing: compile it without the runtime
#: (no reference counting of its arguments and locals; see the module docstring).
#: ``_nrt`` is the jit option behind Numba's ``nrt`` compiler flag (numba.core.options).
NO_REFCOUNT = {"_nrt": False}


def _borrow_value(context, builder, typ, value):
    """``value`` of Numba type ``typ`` with every array in it given a null owner."""
    if isinstance(typ, types.Array):
        src = context.make_array(typ)(context, builder, value=value)
        out = context.make_array(typ)(context, builder)
        for name in ("nitems", "itemsize", "data", "shape", "strides"):
            setattr(out, name, getattr(src, name))
        out.meminfo = cgutils.get_null_value(out.meminfo.type)
        out.parent = cgutils.get_null_value(out.parent.type)
        return out._getvalue()
    if isinstance(typ, types.BaseTuple):
        for i, member in enumerate(typ):
            part = builder.extract_value(value, i)
            value = builder.insert_value(value, _borrow_value(context, builder, member, part), i)
        return value
    # Anything else is returned as it is, as a new reference (what a call's result is).
    context.nrt.incref(builder, typ, value)
    return value


@intrinsic
def _borrow(typingctx, x):
    # One intrinsic for a whole record: the recursion runs in code generation, not as
    # one inlined call per member (the frame has about 35), each typed and copied by
    # Numba's inliner: that cost compile time in every driver specialisation.
    def codegen(context, builder, signature, args):
        return _borrow_value(context, builder, signature.args[0], args[0])

    return x(x), codegen


def borrowed(x):  # pragma: no cover - jitted only
    """``x`` with every array in it (recursively through tuples) borrowed."""
    raise NotImplementedError


@overload(borrowed, inline="always")  # an intrinsic's wrapper: nothing to cache on its own
def _borrowed(x):
    return lambda x: _borrow(x)


def keep_alive(x):  # pragma: no cover - jitted only
    """A use of ``x`` that the compiler keeps: its owner lives at least until here."""
    raise NotImplementedError


@intrinsic
def _use(typingctx, x):
    def codegen(context, builder, signature, args):
        return context.get_dummy_value()

    return types.none(x), codegen


@overload(keep_alive)  # any type, a foreign record too: not cached (see index.interval)
def _keep_alive(x):
    return lambda x: _use(x)
