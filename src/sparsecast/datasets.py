"""Generated data: the built-in demo volume, synthetic test and benchmark fields, particles.

This is the public ``sparsecast.datasets`` (``sc.datasets.nbody_blobs(64)``). Nothing
here downloads or reads anything; every generator is deterministic given its seed.
Which of these volumes the benchmark runs, under which names and TFs, is
:mod:`sparsecast.bench.catalog`'s business.
"""

from __future__ import annotations

import numpy as np

from .errors import ParameterError
from .volume import Volume

__all__ = ["nbody_blobs", "sphere_shell", "random_clusters", "demo_volume", "nbody_particles"]


def nbody_blobs(
    size: int | tuple[int, int, int] = 256,
    *,
    n_clusters: int = 8,
    blobs_per_cluster: int = 30,
    seed: int = 0,
    dtype=np.float32,
) -> Volume:
    """A sparse field of Gaussian blobs clustered like an n-body snapshot.

    Clusters are placed uniformly; blobs scatter around their cluster centre with a
    Gaussian spread, and blob widths and masses follow a power law (few big halos,
    many small ones). Values are normalised to ``[0, 1]``. At the defaults and
    256^3, 1.4 % of the voxels exceed 0.1 and 5.5 % of the 8^3 bricks are non-empty
    for the ``viridis`` preset (threshold 0.1).

    Parameters
    ----------
    size : int or (nx, ny, nz)
        Grid size.
    n_clusters, blobs_per_cluster : int
        How many clusters and blobs per cluster.
    seed : int
        Random seed (the field is deterministic given the arguments).
    dtype : numpy dtype
        ``float32`` (default) or ``uint8`` (values scaled to 0..255).
    """
    nx, ny, nz = (size, size, size) if np.isscalar(size) else tuple(int(s) for s in size)
    if min(nx, ny, nz) < 2:
        raise ParameterError(f"size: expected at least 2 voxels per axis, got {(nx, ny, nz)}")
    rng = np.random.default_rng(seed)
    field = np.zeros((nz, ny, nx), np.float32)
    dims = np.array([nx, ny, nz], np.float64)
    scale = dims.min() / 256.0
    centres = rng.uniform(0.15, 0.85, size=(n_clusters, 3)) * (dims - 1)
    for c in centres:
        spread = rng.uniform(6.0, 16.0) * scale
        pos = c + rng.normal(0.0, spread, size=(blobs_per_cluster, 3))
        # Pareto-distributed widths: many small blobs, a few large ones.
        sigma = np.clip((rng.pareto(2.5, blobs_per_cluster) + 1.0) * 1.2 * scale, 0.8, 8.0 * scale)
        mass = rng.uniform(0.5, 1.0, blobs_per_cluster)
        for p, s, m in zip(pos, sigma, mass):
            _splat_gaussian(field, p, s, m)
    peak = float(field.max())
    if peak > 0:
        field /= peak
    # Gentle compression so faint halos stay visible next to the densest cores.
    np.sqrt(field, out=field)
    if np.dtype(dtype) == np.uint8:
        return Volume(np.rint(field * 255).astype(np.uint8), name="nbody-blobs")
    return Volume(field.astype(dtype, copy=False), name="nbody-blobs")


def _splat_gaussian(field: np.ndarray, centre: np.ndarray, sigma: float, mass: float) -> None:
    """Add ``mass * exp(-r^2 / 2 sigma^2)`` within 3 sigma of ``centre`` (x, y, z)."""
    nz, ny, nx = field.shape
    r = 3.0 * sigma
    lo = np.maximum(np.floor(centre - r).astype(int), 0)
    hi = np.minimum(np.ceil(centre + r).astype(int) + 1, [nx, ny, nz])
    if np.any(hi <= lo):
        return
    xs = (np.arange(lo[0], hi[0]) - centre[0]) ** 2
    ys = (np.arange(lo[1], hi[1]) - centre[1]) ** 2
    zs = (np.arange(lo[2], hi[2]) - centre[2]) ** 2
    d2 = zs[:, None, None] + ys[None, :, None] + xs[None, None, :]
    g = (mass * np.exp(-d2 / (2.0 * sigma * sigma))).astype(np.float32)
    g[d2 > r * r] = 0.0  # spherical support: keeps bricks outside the ball empty
    field[lo[2]:hi[2], lo[1]:hi[1], lo[0]:hi[0]] += g


def sphere_shell(size: int = 64, *, radius: float = 0.35, thickness: float = 0.05) -> Volume:
    """A hollow sphere: 1 inside a shell of the given relative radius/thickness, 0 elsewhere,
    with a smooth (linear) edge one voxel wide."""
    if size < 2:
        raise ParameterError(f"size: expected at least 2, got {size}")
    c = (size - 1) / 2.0
    g = np.arange(size) - c
    r = np.sqrt(g[:, None, None] ** 2 + g[None, :, None] ** 2 + g[None, None, :] ** 2) / (size - 1)
    d = np.abs(r - radius) - thickness / 2.0
    vals = np.clip(0.5 - d * (size - 1), 0.0, 1.0).astype(np.float32)
    return Volume(vals, name="sphere-shell")


def random_clusters(n: int, n_clusters: int, radius: float, seed: int = 7) -> Volume:
    """Balls of random voxel values: the synthetic sweeps of the hybrid-grids paper (Fig. 5).

    Parameters
    ----------
    n : int
        Grid size: the volume is ``n``^3 float32.
    n_clusters : int
        How many balls, at random centres (they may overlap or leave the grid).
    radius : float
        Ball radius in voxels (at least half a voxel).
    seed : int
        Random seed.

    Returns
    -------
    Volume
        Voxels inside a ball hold uniform random values in ``[0.2, 1]``, the rest 0.
    """
    rng = np.random.default_rng(seed)
    data = np.zeros((n, n, n), np.float32)
    r = max(float(radius), 0.5)
    ri = int(np.ceil(r))
    off = np.arange(-ri, ri + 1)
    dz, dy, dx = np.meshgrid(off, off, off, indexing="ij")
    ball = dz * dz + dy * dy + dx * dx <= r * r
    pz, py, px = (a[ball] for a in (dz, dy, dx))
    for _ in range(n_clusters):
        c = rng.integers(0, n, 3)
        z, y, x = pz + c[0], py + c[1], px + c[2]
        keep = (z >= 0) & (z < n) & (y >= 0) & (y < n) & (x >= 0) & (x < n)
        data[z[keep], y[keep], x[keep]] = rng.uniform(0.2, 1.0, int(keep.sum())).astype(np.float32)
    return Volume(data)


def demo_volume() -> Volume:
    """The built-in demo: a 256^3 float32 n-body-like field (see :func:`nbody_blobs`)."""
    return nbody_blobs(256)


def nbody_particles(n: int = 100_000, *, n_clusters: int = 12, seed: int = 0):
    """An n-body-like particle set (:class:`~sparsecast.elements.ParticleSet`) in the
    unit cube: Plummer-like clusters (heavy-tailed radial profile) plus a sparse
    uniform background, radii shrinking in dense cores, colours by cluster."""
    from .elements import ParticleSet

    if int(n) != n or n < 0:
        raise ParameterError(f"n: expected a non-negative integer, got {n!r}")
    n = int(n)
    rng = np.random.default_rng(seed)
    n_bg = n // 10
    centres = rng.uniform(0.2, 0.8, size=(n_clusters, 3))
    scale = rng.uniform(0.01, 0.05, n_clusters)
    which = rng.integers(0, n_clusters, n - n_bg)
    # Plummer radial profile: r = a / sqrt(u^(-2/3) - 1), capped at 10 a.
    u = rng.uniform(1e-3, 1.0, n - n_bg)
    rad = np.minimum(1.0 / np.sqrt(u ** (-2.0 / 3.0) - 1.0 + 1e-12), 10.0) * scale[which]
    dirs = rng.normal(size=(n - n_bg, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True) + 1e-300
    pos = np.concatenate([centres[which] + dirs * rad[:, None], rng.uniform(0, 1, (n_bg, 3))])
    radii = np.concatenate([0.002 + 0.004 * np.minimum(rad / scale[which], 3.0) / 3.0,
                            np.full(n_bg, 0.004)])
    palette = np.array([[0.99, 0.75, 0.35], [0.45, 0.7, 1.0], [0.95, 0.4, 0.45], [0.6, 0.95, 0.6]])
    colors = np.concatenate([palette[which % len(palette)], np.full((n_bg, 3), 0.6)])
    return ParticleSet(pos, radii, colors, name="nbody-particles")
