"""Primary-ray generation from :meth:`sparsecast.Camera.ray_params`."""

from __future__ import annotations

import math

from numba import njit

from .borrow import NO_REFCOUNT


@njit(cache=True, **NO_REFCOUNT)
def primary_ray(params, px, py, width, height):
    """World-space ray through the centre of pixel ``(px, py)`` (row 0 at the top).

    Returns ``(ox, oy, oz, dx, dy, dz)`` with a unit direction.
    """
    u = (px + 0.5) / width * 2.0 - 1.0
    v = 1.0 - (py + 0.5) / height * 2.0
    sx = u * params[6] + v * params[9]
    sy = u * params[7] + v * params[10]
    sz = u * params[8] + v * params[11]
    if params[12] != 0.0:  # perspective
        dx = params[3] + sx
        dy = params[4] + sy
        dz = params[5] + sz
        inv = 1.0 / math.sqrt(dx * dx + dy * dy + dz * dz)
        return params[0], params[1], params[2], dx * inv, dy * inv, dz * inv
    return params[0] + sx, params[1] + sy, params[2] + sz, params[3], params[4], params[5]


@njit(cache=True, **NO_REFCOUNT)
def index_space_ray(params, px, py, width, height, origin, inv_spacing):
    """Primary ray of pixel ``(px, py)`` mapped into the volume's index space.

    Returns ``(ox, oy, oz, dx, dy, dz, wdx, wdy, wdz)``: the index-space origin and
    direction (``d_index = d_world / spacing``, *not* renormalised, so the ray
    parameter ``t`` stays a world-space distance) and the unit world direction.
    """
    wox, woy, woz, wdx, wdy, wdz = primary_ray(params, px, py, width, height)
    ox = (wox - origin[0]) * inv_spacing[0]
    oy = (woy - origin[1]) * inv_spacing[1]
    oz = (woz - origin[2]) * inv_spacing[2]
    return ox, oy, oz, wdx * inv_spacing[0], wdy * inv_spacing[1], wdz * inv_spacing[2], wdx, wdy, wdz


@njit(cache=True, error_model="numpy", **NO_REFCOUNT)  # once per ray or tile, a plain call: see index.interval, "Inlining"
def tile_corner_rays(params, x0, x1, y0, y1, width, height, origin, inv_spacing):
    """Index-space rays ``(ox, oy, oz, dx, dy, dz)`` of a pixel rectangle's four corners.

    The corners are the pixels ``(x0, y0), (x1 - 1, y0), (x1 - 1, y1 - 1), (x0, y1 - 1)``
    (``x1``, ``y1`` exclusive), in that winding order. Ray generation is affine in the
    pixel, so every ray of the rectangle lies in the convex hull of these four: what
    :func:`sparsecast.index.interval.start_tile` culls against.

    Returns
    -------
    tuple of 4 tuples of 6 floats
    """
    a = index_space_ray(params, x0, y0, width, height, origin, inv_spacing)
    b = index_space_ray(params, x1 - 1, y0, width, height, origin, inv_spacing)
    c = index_space_ray(params, x1 - 1, y1 - 1, width, height, origin, inv_spacing)
    e = index_space_ray(params, x0, y1 - 1, width, height, origin, inv_spacing)
    return ((a[0], a[1], a[2], a[3], a[4], a[5]), (b[0], b[1], b[2], b[3], b[4], b[5]),
            (c[0], c[1], c[2], c[3], c[4], c[5]), (e[0], e[1], e[2], e[3], e[4], e[5]))
