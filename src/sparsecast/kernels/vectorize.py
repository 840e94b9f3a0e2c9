"""What a Numba kernel needs for LLVM's loop vectorizer to turn a lane loop into SIMD code.

A loop over the lanes of a packet (``for l in range(8): ... buf[l] = ...``) that
gathers from one array and stores into another is only vectorised if LLVM can
tell that the stores never change what the loop reads. The gathers' addresses
are data (voxel addresses computed from positions), so LLVM cannot bound them
and will not emit run-time overlap checks either (its remark: "cannot identify
array bounds"): the loop stays scalar. Numba can declare a function's pointer
arguments ``noalias`` (its ``noalias`` compiler flag), but no ``jit`` option
sets that flag; :class:`LaneLoopCompiler` is Numba's documented extension point
for it (``njit(pipeline_class=...)``), the default pipeline with the flag on (and
wider vectors preferred, see there). ``cache=True`` keeps working.

A kernel compiled so promises that no two of its array arguments overlap in
memory where one of them is written: give it distinct arrays (distinct rows of
one array are distinct). :func:`lane_buffer` gives a caller a small scratch
array on its own stack, so that a kernel which runs without the runtime
(:data:`.borrow.NO_REFCOUNT`) has somewhere to put a packet's lanes without
allocating. :func:`load_run` reads a run of neighbouring voxels with one load, where
a loop would issue one load per voxel: in a vectorised lane loop whose reads are
not gathers, every load is a scalar load and an insert per lane.
"""

from __future__ import annotations

from llvmlite import ir
from numba import types
from numba.core import cgutils, lowering
from numba.core.compiler import Compiler
from numba.core.compiler_machinery import register_pass
from numba.core.typed_passes import NativeLowering
from numba.extending import intrinsic

__all__ = ["LaneLoopCompiler", "PREFER_VECTOR_WIDTH", "lane_buffer", "load_run", "load_window", "run_loadable"]


#: the vector width (bits) the lane loops ask LLVM's x86 back end for (function attribute
#: ``prefer-vector-width``)
PREFER_VECTOR_WIDTH = 512


class _WideLower(lowering.Lower):
    """Numba's lowering, marking the function with ``prefer-vector-width``."""

    def post_lower(self):
        super().post_lower()
        # llvmlite's attribute set takes enum attributes by name only; a string
        # attribute goes into the definition as written, after the enum ones.
        set.add(self.function.attributes, f'"prefer-vector-width"="{PREFER_VECTOR_WIDTH}"')


@register_pass(mutates_CFG=True, analysis_only=False)
class _WideNativeLowering(NativeLowering):
    _name = "sparsecast_wide_native_lowering"

    @property
    def lowering_class(self):
        return _WideLower


class LaneLoopCompiler(Compiler):
    """Numba's default pipeline for lane loops: pointer arguments ``noalias``, and
    :data:`PREFER_VECTOR_WIDTH`-bit vectors preferred.

    ``noalias`` is what lets LLVM vectorise the loop at all (see the module
    docstring). The width: LLVM's x86 back end prefers 256-bit vectors on Intel
    CPUs with AVX-512 (a tuning from Skylake-X, whose 512-bit instructions lowered
    the clock), so a loop of eight float64 lanes became two ymm halves; the
    function attribute ``prefer-vector-width=512`` makes it one zmm loop on CPUs
    with AVX-512 and changes nothing elsewhere (the width is capped by the target's
    registers). Same operations per lane, so the same floats. Measured (naive
    marcher, unshaded, 512², Intel Xeon Emerald Rapids, 2 threads, 2026-12-06):
    frames 15-25 % less CPU.

    On CPUs that LLVM does not tune as having fast gathers (AMD Zen 3 and older, AVX2)
    the lane loops of :mod:`.packet` stay mostly scalar (fully unrolled, each lane's
    reads scalar loads): LLVM prices a gather there as the scalar loads it replaces.
    Forcing gathers (the x86 tuning flag ``fast-gather`` in the lane loops'
    ``target-features``) was measured on such a CPU (AMD EPYC Zen 3, one thread, 512²,
    alternating processes, 2026-12-07) and made frames slower: naive dense-TF 0.70-0.96x,
    deep k-d tree sparse 0.69-1.10x (0.81-0.84x by minima), images identical. So
    LLVM's choice stands.
    """

    def define_pipelines(self):
        self.state.flags.noalias = True
        pms = super().define_pipelines()
        for pm in pms:
            pm.passes = [(_WideNativeLowering, d) if p is NativeLowering else (p, d) for p, d in pm.passes]
        return pms


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


def run_loadable(flat, n: int) -> bool:
    """Whether :func:`load_run` takes runs of ``n`` items from arrays of Numba type
    ``flat``: a C-contiguous array of integers or float32 whose ``n`` items fit one
    64-bit word. (Typing-time: callers pick their code by it.)"""
    if not (isinstance(flat, types.Array) and flat.ndim >= 1 and flat.layout == "C"):
        return False
    dt = flat.dtype
    if isinstance(dt, types.Integer):
        return n * dt.bitwidth <= 64
    return dt == types.float32 and n * 32 <= 64


@intrinsic
def load_run(typingctx, flat, i, n):
    """``(float(flat[i]), ..., float(flat[i + n - 1]))`` from one load.

    ``i`` is the item's position in C order (for a 2-D ``(m, 4)`` array, item ``(r, c)``
    is ``4 r + c``). Reads the ``n`` adjacent items as one little-endian integer (x86 and ARM in
    their usual modes are little-endian), then takes each item out by a shift and a
    truncation and converts it as Numba's ``float()`` does (integers to float64;
    float32 stays float32), so values and types are exactly the element-wise reads'. ``n`` is a literal;
    the items must lie inside ``flat`` (no bounds check, as in the kernels that use
    it). Types: :func:`run_loadable`.
    """
    if not isinstance(n, types.IntegerLiteral) or not isinstance(i, types.Integer):
        return None
    count = n.literal_value
    if not run_loadable(flat, count):
        return None
    dt = flat.dtype
    ret = types.UniTuple(types.float32 if dt == types.float32 else types.float64, count)

    def codegen(context, builder, signature, args):
        word = _load_word(context, builder, signature, args, count)
        return context.make_tuple(builder, ret, _word_items(builder, word, dt, count))

    return ret(flat, i, n), codegen


@intrinsic
def load_window(typingctx, flat, i, n, skip, m):
    """``(float(flat[i + skip]), ..., float(flat[i + skip + m - 1]))`` from the one load of
    :func:`load_run` ``(flat, i, n)``.

    ``skip`` is a run-time integer in ``[0, n - m]`` (not checked: a larger one shifts
    the word by its width or more, which LLVM leaves undefined); ``n`` and ``m`` are
    literals. The items are taken out by a shift of ``skip`` items, which in a vectorised
    lane loop is one variable shift per vector: a caller that must keep a wide read inside
    a row (:func:`.sample.trilinear_pairs` on 8-bit voxels) moves the word's start and
    picks its items by ``skip``. Values and types as for :func:`load_run`.
    """
    if not all(isinstance(v, types.IntegerLiteral) for v in (n, m)):
        return None
    if not (isinstance(i, types.Integer) and isinstance(skip, types.Integer)):
        return None
    count, take = n.literal_value, m.literal_value
    if not (run_loadable(flat, count) and 0 < take <= count):
        return None
    dt = flat.dtype
    bits = dt.bitwidth
    ret = types.UniTuple(types.float32 if dt == types.float32 else types.float64, take)

    def codegen(context, builder, signature, args):
        word = _load_word(context, builder, signature, args, count)
        skip_v = context.cast(builder, args[3], signature.args[3], types.intp)
        skip_w = builder.trunc(skip_v, word.type) if word.type.width < 64 else skip_v
        word = builder.lshr(word, builder.mul(skip_w, ir.Constant(word.type, bits)))
        return context.make_tuple(builder, ret, _word_items(builder, word, dt, take))

    return ret(flat, i, n, skip, m), codegen


def _load_word(context, builder, signature, args, count):
    """The ``count`` items of ``args[0]`` from item ``args[1]`` on, loaded as one integer."""
    ary = context.make_array(signature.args[0])(context, builder, args[0])
    index = context.cast(builder, args[1], signature.args[1], types.intp)
    item = cgutils.gep_inbounds(builder, ary.data, index)
    word_t = ir.IntType(signature.args[0].dtype.bitwidth * count)
    return builder.load(builder.bitcast(item, word_t.as_pointer()), align=1, typ=word_t)


def _word_items(builder, word, dt, count):
    """The first ``count`` items of a loaded word, each as :func:`_item_float` gives it."""
    bits = dt.bitwidth
    item_t = ir.IntType(bits)
    return [_item_float(builder, builder.trunc(builder.lshr(word, ir.Constant(word.type, j * bits)) if j else word,
                                               item_t), dt)
            for j in range(count)]


def _item_float(builder, part, dt):
    """An item's bits as Numba's ``float()`` of it: float32 stays float32, integers become float64."""
    if dt == types.float32:
        return builder.bitcast(part, ir.FloatType())
    if dt.signed:
        return builder.sitofp(part, ir.DoubleType())
    return builder.uitofp(part, ir.DoubleType())
