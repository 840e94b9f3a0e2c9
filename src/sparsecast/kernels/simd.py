"""Four-lane SIMD in Numba kernels: LLVM vector IR emitted by intrinsics.

Why intrinsics: Numba runs LLVM without the SLP vectorizer (``NUMBA_SLP_VECTORIZE``
is off by default, and it is a process-wide switch), and its loop vectorizer
skips loops of four iterations, so a wide BVH's "four slab tests in one loop"
compiles to scalar code (checked with ``inspect_asm``: only ``*sd`` instructions).
The intrinsics here build the vector operations themselves, so the test
of a node's four child boxes is a handful of SSE/AVX instructions on every
target, whatever Numba's pass pipeline does.

:func:`slab4` tests a ray against four boxes (``<4 x float>``), :func:`woop4`
against a packet of four triangles (``<4 x double>``, the watertight test);
:func:`slab4_reference` and :func:`woop4_reference` are their scalar
specifications (the tests compare them bit for bit). No FMA is formed: the
watertight test needs the products rounded as the scalar code rounds them.
"""

from __future__ import annotations

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic

__all__ = ["slab4", "slab4_reference", "woop4", "woop4_reference"]

_F4 = ir.VectorType(ir.FloatType(), 4)
_D4 = ir.VectorType(ir.DoubleType(), 4)


def _splat(builder, x, vec=_F4):
    """``<x, x, x, x>`` from a scalar of ``vec``'s element type."""
    v = builder.insert_element(ir.Constant(vec, ir.Undefined), x, ir.Constant(ir.IntType(32), 0))
    return builder.shuffle_vector(v, ir.Constant(vec, ir.Undefined), ir.Constant(ir.VectorType(ir.IntType(32), 4),
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


def _row_pointer(context, builder, arr_type, arr_value, index_type, index, row):
    """Pointer to ``arr[index, row, 0]`` of a C array (n, rows, 4) as a ``<4 x float>*``."""
    arr = context.make_array(arr_type)(context, builder, arr_value)
    i8p = ir.IntType(8).as_pointer()
    idx = context.cast(builder, index, index_type, types.int64)
    s0 = builder.extract_value(arr.strides, 0)
    s1 = builder.extract_value(arr.strides, 1)
    off = builder.add(builder.mul(idx, s0), builder.mul(row, s1))
    return builder.bitcast(builder.gep(builder.bitcast(arr.data, i8p), [off]), _F4.as_pointer())


@intrinsic
def woop4(typingctx, tri4, p, axes, org, shear, t_lo, t_hi, out):
    """Watertight ray-triangle test (Woop, Benthin & Wald 2013) of one packet of four triangles, in float64 lanes.

    Parameters (Numba types)
    ------------------------
    tri4 : (n, 9, 4) float32 C array
        ``tri4[p, 3 v + a, lane]``: coordinate ``a`` of vertex ``v`` of each lane.
    p : int
        The packet.
    axes : 3-tuple of int
        ``kx, ky, kz``: the ray's dominant axis last.
    org : 3-tuple of float64
        The origin's coordinates along ``kx, ky, kz``.
    shear : 3-tuple of float64
        ``d_kx / d_kz, d_ky / d_kz, 1 / d_kz``.
    t_lo, t_hi : float64
        Hits count in ``[t_lo, t_hi]``.
    out : (>= 8,) float64 C array
        ``out[:4]`` the hit distance per lane (inf where it misses), ``out[4:8]``
        the determinants (the barycentrics of a hit are its edge functions over it).

    Returns
    -------
    int64
        Bit ``lane`` set iff that lane's triangle is hit (see :func:`woop4_reference`,
        the same operations in the same order: the shared edge of two triangles gets
        edge functions of opposite sign, bit for bit, so no ray slips between them).
    """
    sig = types.int64(tri4, p, axes, org, shear, t_lo, t_hi, out)

    def codegen(context, builder, signature, args):
        tri_v, p_v, axes_v, org_v, shear_v, lo_v, hi_v, out_v = args
        i64 = ir.IntType(64)
        axis = [context.cast(builder, builder.extract_value(axes_v, k), signature.args[2][k], types.int64)
                for k in range(3)]
        o = [_splat(builder, builder.extract_value(org_v, k), _D4) for k in range(3)]
        sx, sy, sz = (_splat(builder, builder.extract_value(shear_v, k), _D4) for k in range(3))

        def vertex(v):
            out = []
            for k in range(3):
                row = builder.add(ir.Constant(i64, 3 * v), axis[k])
                ptr = _row_pointer(context, builder, signature.args[0], tri_v, signature.args[1], p_v, row)
                out.append(builder.fsub(builder.fpext(builder.load(ptr, align=4), _D4), o[k]))
            return out

        (ax, ay, az), (bx, by, bz), (cx, cy, cz) = vertex(0), vertex(1), vertex(2)
        f = builder
        a_x, a_y = f.fsub(ax, f.fmul(sx, az)), f.fsub(ay, f.fmul(sy, az))
        b_x, b_y = f.fsub(bx, f.fmul(sx, bz)), f.fsub(by, f.fmul(sy, bz))
        c_x, c_y = f.fsub(cx, f.fmul(sx, cz)), f.fsub(cy, f.fmul(sy, cz))
        u = f.fsub(f.fmul(c_x, b_y), f.fmul(c_y, b_x))
        v = f.fsub(f.fmul(a_x, c_y), f.fmul(a_y, c_x))
        w = f.fsub(f.fmul(b_x, a_y), f.fmul(b_y, a_x))
        det = f.fadd(f.fadd(u, v), w)
        zero = ir.Constant(_D4, [0.0] * 4)
        pos = f.and_(f.and_(f.fcmp_ordered(">=", u, zero), f.fcmp_ordered(">=", v, zero)), f.fcmp_ordered(">=", w, zero))
        neg = f.and_(f.and_(f.fcmp_ordered("<=", u, zero), f.fcmp_ordered("<=", v, zero)), f.fcmp_ordered("<=", w, zero))
        t = f.fdiv(f.fmul(sz, f.fadd(f.fadd(f.fmul(u, az), f.fmul(v, bz)), f.fmul(w, cz))), det)
        ok = f.and_(f.or_(pos, neg), f.fcmp_unordered("!=", det, zero))
        ok = f.and_(ok, f.and_(f.fcmp_ordered(">=", t, _splat(builder, lo_v, _D4)),
                               f.fcmp_ordered("<=", t, _splat(builder, hi_v, _D4))))
        t = f.select(ok, t, ir.Constant(_D4, [float("inf")] * 4))
        out_arr = context.make_array(signature.args[7])(context, builder, out_v)
        base = f.bitcast(out_arr.data, _D4.as_pointer())
        f.store(t, base, align=8)
        f.store(det, f.gep(base, [ir.Constant(ir.IntType(32), 1)]), align=8)
        return f.zext(f.bitcast(ok, ir.IntType(4)), i64)

    return sig, codegen


@njit(cache=True)
def woop4_reference(tri4, p, axes, org, shear, t_lo, t_hi, out):
    """Scalar :func:`woop4` (same float64 operations in the same order)."""
    kx, ky, kz = axes
    okx, oky, okz = org
    sx, sy, sz = shear
    mask = 0
    for lane in range(4):
        vax = np.float64(tri4[p, kx, lane]) - okx
        vay = np.float64(tri4[p, ky, lane]) - oky
        vaz = np.float64(tri4[p, kz, lane]) - okz
        vbx = np.float64(tri4[p, 3 + kx, lane]) - okx
        vby = np.float64(tri4[p, 3 + ky, lane]) - oky
        vbz = np.float64(tri4[p, 3 + kz, lane]) - okz
        vcx = np.float64(tri4[p, 6 + kx, lane]) - okx
        vcy = np.float64(tri4[p, 6 + ky, lane]) - oky
        vcz = np.float64(tri4[p, 6 + kz, lane]) - okz
        a_x, a_y = vax - sx * vaz, vay - sy * vaz
        b_x, b_y = vbx - sx * vbz, vby - sy * vbz
        c_x, c_y = vcx - sx * vcz, vcy - sy * vcz
        u = c_x * b_y - c_y * b_x
        v = a_x * c_y - a_y * c_x
        w = b_x * a_y - b_y * a_x
        det = u + v + w
        inside = ((u >= 0.0) & (v >= 0.0) & (w >= 0.0)) | ((u <= 0.0) & (v <= 0.0) & (w <= 0.0))
        t = sz * (u * vaz + v * vbz + w * vcz) / det if det != 0.0 else np.inf
        ok = inside & (det != 0.0) & (t >= t_lo) & (t <= t_hi)
        out[lane] = t if ok else np.inf
        out[4 + lane] = det
        if ok:
            mask |= 1 << lane
    return mask


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
