"""Generated test volumes shared by several test modules."""

from __future__ import annotations

import numpy as np

import sparsecast as sc


def sparse_volume(rng: np.random.Generator, shape, n_blobs: int, dtype="float32", **kw) -> sc.Volume:
    """Gaussian blobs at random places (values in [0, 1]); the rest exactly 0."""
    nz, ny, nx = shape
    z, y, x = np.meshgrid(np.arange(nz), np.arange(ny), np.arange(nx), indexing="ij")
    field = np.zeros(shape, np.float64)
    for _ in range(n_blobs):
        c = rng.uniform(0, 1, 3) * (np.array([nx, ny, nz]) - 1)
        s = rng.uniform(0.7, 3.0)
        d2 = (x - c[0]) ** 2 + (y - c[1]) ** 2 + (z - c[2]) ** 2
        field += rng.uniform(0.3, 1.0) * np.exp(-d2 / (2 * s * s)) * (d2 < (3 * s) ** 2)
    field = np.clip(field, 0, 1)
    if np.dtype(dtype) == np.uint8:
        return sc.Volume(np.rint(field * 255).astype(np.uint8), **kw)
    return sc.Volume(field.astype(dtype), **kw)


def label_volume(rng: np.random.Generator, shape, n_labels: int, dtype="uint8", *, brick_aligned: bool = False,
                 **kw) -> sc.Volume:
    """Boxes of label ids ``1..n_labels`` (later boxes overwrite earlier ones) on background 0.

    With ``brick_aligned`` the box faces sit on, or one voxel beside, multiples of 8
    (the brick size), where an off-by-one in per-brick label sets would show.
    """
    nz, ny, nx = shape
    data = np.zeros(shape, dtype)
    for label in range(1, n_labels + 1):
        lo, hi = [], []
        for n in shape:
            if brick_aligned:
                a = 8 * int(rng.integers(0, max(n // 8, 1))) + int(rng.integers(-1, 2))
                b = a + 8 * int(rng.integers(1, 3)) + int(rng.integers(-1, 2))
            else:
                a = int(rng.integers(0, n))
                b = a + int(rng.integers(1, max(n // 2, 2)))
            lo.append(min(max(a, 0), n - 1))
            hi.append(min(max(b, lo[-1] + 1), n))
        data[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]] = label
    return sc.Volume(data, **kw)
