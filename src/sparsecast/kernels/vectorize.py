"""What a Numba kernel needs for LLVM's loop vectorizer to turn a lane loop into SIMD code.

A loop over the lanes of a packet (``for l in range(8): ... buf[l] = ...``) that
gathers from one array and stores into another is only vectorised if LLVM can
tell that the stores never change what the loop reads. The gathers' addresses
are data (voxel addresses computed from positions), so LLVM cannot bound them
and will not emit run-time overlap checks either (its remark: "cannot identify
array bounds"): the loop stays scalar. Numba can declare a function's pointer
arguments ``noalias`` (its ``noalias`` compiler flag), but no ``jit`` option
sets that flag; :class:`NoAliasCompiler` is Numba's documented extension point
for it (``njit(pipeline_class=...)``), the default pipeline with the flag on.
``cache=True`` keeps working.

A kernel compiled so promises that no two of its array arguments overlap in
memory where one of them is written: give it distinct arrays (distinct rows of
one array are distinct). :func:`lane_buffer` gives a caller a small scratch
array on its own stack, so that a kernel which runs without the runtime
(:data:`.borrow.NO_REFCOUNT`) has somewhere to put a packet's lanes without
allocating.
"""

from __future__ import annotations

from numba import types
from numba.core import cgutils
from numba.core.compiler import Compiler
from numba.extending import intrinsic

__all__ = ["NoAliasCompiler", "lane_buffer"]


class NoAliasCompiler(Compiler):
    """Numba's default pipeline, with the pointer arguments of the function ``noalias``."""

    def define_pipelines(self):
        self.state.flags.noalias = True
        return super().define_pipelines()


@intrinsic
def lane_buffer(typingctx, n):
    """A ``(n,)`` float64 C array on the calling function's stack (``n`` a literal int).

    It lives as long as the function that called this (after inlining: the kernel
    it was inlined into) and has no owner, so it costs nothing in a kernel without
    the runtime. Its contents start undefined. It is one ``alloca`` in the
    function's entry block, however often the call site runs.
    """
    if not isinstance(n, types.IntegerLiteral):
        return None
    size = n.literal_value
    arrty = types.Array(types.float64, 1, "C")

    def codegen(context, builder, signature, args):
        elem = context.get_data_type(types.float64)
        data = cgutils.alloca_once(builder, elem, size=size)
        itemsize = context.get_abi_sizeof(elem)
        ary = context.make_array(arrty)(context, builder)
        context.populate_array(
            ary, data=data,
            shape=[context.get_constant(types.intp, size)],
            strides=[context.get_constant(types.intp, itemsize)],
            itemsize=context.get_constant(types.intp, itemsize),
            meminfo=None,
        )
        return ary._getvalue()

    return arrty(n), codegen

