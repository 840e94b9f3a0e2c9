"""Brute-force oracles for the surface tests: every ray against every triangle (NumPy, float64)."""

from __future__ import annotations

import numpy as np


def brute_force_hits(tris: np.ndarray, origins: np.ndarray, dirs: np.ndarray, chunk: int = 64):
    """Closest ``t`` (inf on a miss) and face of each ray, two-sided Möller–Trumbore."""
    tris = np.asarray(tris, np.float64)
    a, e1, e2 = tris[:, 0], tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]
    t_out = np.full(len(origins), np.inf)
    f_out = np.full(len(origins), -1)
    for s in range(0, len(origins), chunk):
        o = origins[s:s + chunk, None, :]
        d = dirs[s:s + chunk, None, :]
        p = np.cross(d, e2[None])
        det = np.sum(e1[None] * p, -1)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / det
            tv = o - a[None]
            u = np.sum(tv * p, -1) * inv
            q = np.cross(tv, e1[None])
            v = np.sum(d * q, -1) * inv
            t = np.sum(e2[None] * q, -1) * inv
        ok = (det != 0) & (u >= 0) & (u <= 1) & (v >= 0) & (u + v <= 1) & (t >= 0)
        t = np.where(ok, t, np.inf)
        t_out[s:s + chunk] = t.min(1)
        f_out[s:s + chunk] = np.where(np.isfinite(t.min(1)), t.argmin(1), -1)
    return t_out, f_out


def rays_at(points: np.ndarray, rng: np.random.Generator, distance: float, jitter: float = 0.0):
    """Rays from random directions ``distance`` away aimed at ``points`` (plus jitter)."""
    d = rng.normal(size=points.shape)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    target = points + jitter * rng.normal(size=points.shape)
    return target - distance * d, d


def brute_force_disc_hits(centers: np.ndarray, normals: np.ndarray, radii: np.ndarray,
                          origins: np.ndarray, dirs: np.ndarray, chunk: int = 64):
    """Closest ``t`` (inf on a miss) and disc of each ray against every disc (two-sided)."""
    c, n, r = (np.asarray(a, np.float64) for a in (centers, normals, radii))
    t_out = np.full(len(origins), np.inf)
    k_out = np.full(len(origins), -1)
    for s in range(0, len(origins), chunk):
        o = origins[s:s + chunk, None, :]
        d = dirs[s:s + chunk, None, :]
        den = np.sum(d * n[None], -1)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.sum((c[None] - o) * n[None], -1) / den
        p = o + t[..., None] * d - c[None]
        ok = (den != 0) & (t >= 0) & (np.sum(p * p, -1) <= r[None] ** 2)
        t = np.where(ok, t, np.inf)
        t_out[s:s + chunk] = t.min(1)
        k_out[s:s + chunk] = np.where(np.isfinite(t.min(1)), t.argmin(1), -1)
    return t_out, k_out
