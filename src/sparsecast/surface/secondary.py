"""Secondary rays: cosine-weighted diffuse directions about surface normals."""

from __future__ import annotations

import numpy as np

__all__ = ["cosine_directions", "facing"]


def facing(normals: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """``normals`` flipped, where needed, to face against ``directions`` (the side a ray came from)."""
    n = np.asarray(normals, dtype=np.float64)
    return np.where(np.sum(n * directions, axis=-1, keepdims=True) > 0, -n, n)


def cosine_directions(normals: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """One unit direction per normal, cosine-distributed over the hemisphere around it.

    Malley's method: a uniform point on the unit disc lifted onto the hemisphere.
    """
    n = np.asarray(normals, dtype=np.float64)
    u1, u2 = rng.random(len(n)), rng.random(len(n))
    r, phi = np.sqrt(u1), 2 * np.pi * u2
    a = np.where(np.abs(n[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    t1 = np.cross(n, a)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(n, t1)
    d = (r * np.cos(phi))[:, None] * t1 + (r * np.sin(phi))[:, None] * t2 + np.sqrt(1 - u1)[:, None] * n
    return d / np.linalg.norm(d, axis=1, keepdims=True)
