"""Borrowed views: arrays (and records of arrays) without reference counting, for hot loops.

Numba counts references to every array a compiled function copies: reading an
array out of a record, or passing it to a function, costs an atomic
increment and decrement. In the DVR driver's interval loop that happened
several times per interval (measured: the deep k-d tree 1.4x slower than with
the arrays passed as plain arguments, worse on two threads, where the atomics
on shared counters bounce between cores). :func:`borrowed` returns the same
arrays with no owner (a null ``meminfo``), whose reference counting compiles to
nothing.

Safety: a borrowed view does not keep its data alive. Borrow only what stays
alive for as long as the view is used: a function's arguments (the caller holds
them), or a local that :func:`keep_alive` uses after the loop.
"""

from __future__ import annotations

from numba import types
from numba.core import cgutils
from numba.extending import intrinsic, overload

__all__ = ["borrowed", "keep_alive"]


@intrinsic
def _borrow_array(typingctx, arr):
    if not isinstance(arr, types.Array):
        return None

    def codegen(context, builder, signature, args):
        src = context.make_array(arr)(context, builder, value=args[0])
        out = context.make_array(arr)(context, builder)
        for name in ("nitems", "itemsize", "data", "shape", "strides"):
            setattr(out, name, getattr(src, name))
        out.meminfo = cgutils.get_null_value(out.meminfo.type)
        out.parent = cgutils.get_null_value(out.parent.type)
        return out._getvalue()

    return arr(arr), codegen


def borrowed(x):  # pragma: no cover - jitted only
    """``x`` with every array in it (recursively through tuples) borrowed."""
    raise NotImplementedError


@overload(borrowed, inline="always")  # impls made by exec: nothing to cache on their own
def _borrowed(x):
    if isinstance(x, types.Array):
        return lambda x: _borrow_array(x)
    if isinstance(x, types.BaseTuple):
        n = len(x)
        parts = ", ".join(f"borrowed(x[{i}])" for i in range(n))
        if isinstance(x, types.BaseNamedTuple):
            body = f"return cls({parts})"
            scope = {"cls": x.instance_class, "borrowed": borrowed}
        else:
            body = f"return ({parts}{',' if n == 1 else ''})" if n else "return ()"
            scope = {"borrowed": borrowed}
        exec(f"def impl(x):\n    {body}\n", scope)
        return scope["impl"]
    return lambda x: x


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
