"""Four-lane float32 SIMD in Numba kernels: LLVM vector IR emitted by intrinsics.

Why intrinsics: Numba runs LLVM without the SLP vectorizer (``NUMBA_SLP_VECTORIZE``
is off by default, and it is a process-wide switch), and its loop vectorizer
skips loops of four iterations, so a wide BVH's "four slab tests in one loop"
compiles to scalar code (checked with ``inspect_asm``: only ``*sd`` instructions).
The intrinsics here build the ``<4 x float>`` operations themselves, so the test
of a node's four child boxes is a handful of SSE/AVX instructions on every
target, whatever Numba's pass pipeline does.

:func:`slab4` is the one operation the traversal needs; :func:`slab4_reference`
is its scalar specification (the tests compare the two).
"""

from __future__ import annotations

from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic

__all__ = ["slab4", "slab4_reference"]

_F4 = ir.VectorType(ir.FloatType(), 4)


def _splat(builder, x):
    """``<x, x, x, x>`` from a float32 scalar."""
    v = builder.insert_element(ir.Constant(_F4, ir.Undefined), x, ir.Constant(ir.IntType(32), 0))
    return builder.shuffle_vector(v, ir.Constant(_F4, ir.Undefined), ir.Constant(ir.VectorType(ir.IntType(32), 4),
                                                                                  [0, 0, 0, 0]))


def _min(builder, a, b):
    # a < b ? a : b is exactly x86's minps (the second operand on NaN): one instruction.
    return builder.select(builder.fcmp_ordered("<", a, b), a, b)


def _max(builder, a, b):
    return builder.select(builder.fcmp_ordered(">", a, b), a, b)


@intrinsic
def slab4(typingctx, nodes, node, rows, org, inv, t_lo, t_hi, out):
    """Slab test of a ray against the four boxes of one node, as ``<4 x float>`` operations.

    Parameters (Numba types)
    ------------------------
    nodes : (n, k) float32 C array
        Row ``node`` holds the boxes in SoA: ``nodes[node, r + c]`` is coordinate
        row ``r`` (a multiple of 4) of box ``c``.
    node : int
    rows : 6-tuple of int
        Offsets of the near x, y, z and far x, y, z rows (picked per ray from the
        direction's signs).
    org : 6-tuple of float32
        Origin coordinate for the near x, y, z and far x, y, z planes.
    inv : 6-tuple of float32
        Scale of the near x, y, z and far x, y, z planes: ``1 / d`` (the far ones
        may be widened so that rounding never drops a box, see
        :mod:`sparsecast.surface._wide_kernels`).
    t_lo, t_hi : float32
        The ray's interval; ``t_hi`` also bounds the (scaled) exit distance.
    out : (>= 4,) float32 C array
        Receives the four entry distances.

    Returns
    -------
    int64
        Bit ``c`` set iff box ``c`` is entered: ``max(near distances, t_lo) <=
        min(far distances, t_hi)`` (see :func:`slab4_reference`).
    """
    sig = types.int64(nodes, node, rows, org, inv, t_lo, t_hi, out)

    def codegen(context, builder, signature, args):
        nodes_v, node_v, rows_v, org_v, inv_v, lo_v, hi_v, out_v = args
        arr = context.make_array(signature.args[0])(context, builder, nodes_v)
        i64 = ir.IntType(64)
        node64 = context.cast(builder, node_v, signature.args[1], types.int64)
        stride0 = builder.extract_value(arr.strides, 0)
        row_base = builder.gep(builder.bitcast(arr.data, ir.IntType(8).as_pointer()),
                               [builder.mul(node64, stride0)])
        row_base = builder.bitcast(row_base, ir.FloatType().as_pointer())

        def load_row(k):
            r = context.cast(builder, builder.extract_value(rows_v, k), signature.args[2][k], types.int64)
            p = builder.bitcast(builder.gep(row_base, [r]), _F4.as_pointer())
            return builder.load(p, align=4)

        def plane(k):
            o = _splat(builder, builder.extract_value(org_v, k))
            s = _splat(builder, builder.extract_value(inv_v, k))
            return builder.fmul(builder.fsub(load_row(k), o), s)

        tn = _max(builder, _max(builder, plane(0), plane(1)), _max(builder, plane(2), _splat(builder, lo_v)))
        tf = _min(builder, _min(builder, plane(3), plane(4)), _min(builder, plane(5), _splat(builder, hi_v)))
        hit = builder.fcmp_ordered("<=", tn, tf)
        out_arr = context.make_array(signature.args[7])(context, builder, out_v)
        builder.store(tn, builder.bitcast(out_arr.data, _F4.as_pointer()), align=4)
        return builder.zext(builder.bitcast(hit, ir.IntType(4)), i64)

    return sig, codegen


@njit(cache=True)
def slab4_reference(nodes, node, rows, org, inv, t_lo, t_hi, out):
    """Scalar :func:`slab4` (same float32 operations in the same order)."""
    mask = 0
    for c in range(4):
        tx0 = (nodes[node, rows[0] + c] - org[0]) * inv[0]
        ty0 = (nodes[node, rows[1] + c] - org[1]) * inv[1]
        tz0 = (nodes[node, rows[2] + c] - org[2]) * inv[2]
        tx1 = (nodes[node, rows[3] + c] - org[3]) * inv[3]
        ty1 = (nodes[node, rows[4] + c] - org[4]) * inv[4]
        tz1 = (nodes[node, rows[5] + c] - org[5]) * inv[5]
        a = tx0 if tx0 > ty0 else ty0
        b = tz0 if tz0 > t_lo else t_lo
        tn = a if a > b else b
        a = tx1 if tx1 < ty1 else ty1
        b = tz1 if tz1 < t_hi else t_hi
        tf = a if a < b else b
        out[c] = tn
        if tn <= tf:
            mask |= 1 << c
    return mask
