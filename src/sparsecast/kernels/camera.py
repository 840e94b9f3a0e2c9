"""Primary-ray generation from :meth:`sparsecast.Camera.ray_params`."""

from __future__ import annotations

import math

from numba import njit


@njit(cache=True)
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


@njit(cache=True)
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
