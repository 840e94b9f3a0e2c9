"""Bad particle and mesh files (issue 14, items 2 and 11): the project's error family only."""

from __future__ import annotations

import os

import numpy as np
import pytest

from sparsecast.errors import FileFormatError, SparsecastError
from sparsecast.io.meshes import load_mesh, load_points
from sparsecast.io.particles import load_particles

_PLY = b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n"


@pytest.mark.parametrize("name, content, message", [
    ("h.csv", b"x,y,z\n", "no particle rows"),
    ("e.csv", b"", "no particle rows"),
    ("n.ply", _PLY + b"0 0 0\n", "cannot read"),                      # no end_header
    ("t.ply", _PLY.replace(b"float z", b"quux z") + b"end_header\n0 0 0\n", "cannot read"),
    ("e.npy", b"", "cannot read"),
    ("c.csv", b"x,y,z,radius,red,green,blue\n0,0,0,1,nan,0,0\n", "NaN or infinite colour"),
])
def test_bad_particle_files(tmp_path, name, content, message):
    (tmp_path / name).write_bytes(content)
    with pytest.raises(FileFormatError, match=message):
        load_particles(tmp_path / name)


def test_structured_and_nan_npy(tmp_path):
    np.save(tmp_path / "s.npy", np.zeros(3, dtype=[("x", "f4"), ("y", "f4"), ("z", "f4")]))
    with pytest.raises(FileFormatError, match="not structured"):
        load_particles(tmp_path / "s.npy")
    a = np.zeros((2, 7))
    a[1, 5] = np.nan
    np.save(tmp_path / "n.npy", a)
    with pytest.raises(FileFormatError, match="particle 1 has a NaN"):
        load_particles(tmp_path / "n.npy")
    np.save(tmp_path / "o.npy", np.array([1, "a"], dtype=object), allow_pickle=True)
    with pytest.raises(FileFormatError, match="Python objects"):
        load_particles(tmp_path / "o.npy")


@pytest.mark.parametrize("loader, name", [(load_particles, "p.ply"), (load_particles, "p.csv"),
                                          (load_mesh, "m.ply"), (load_points, "q.npy")])
def test_not_regular_files(tmp_path, loader, name):
    os.mkfifo(tmp_path / name)
    with pytest.raises(SparsecastError, match="FIFO"):
        loader(tmp_path / name)


def test_good_csv_still_loads(tmp_path):
    (tmp_path / "g.csv").write_text("x,y,z,radius,red,green,blue\n0,0,0,1,255,0,0\n1,1,1,2,0,128,0\n")
    ps = load_particles(tmp_path / "g.csv")
    assert ps.radii.tolist() == [1.0, 2.0] and ps.colors[0].tolist() == [1.0, 0.0, 0.0]


def test_particle_set_refuses_nan_colours():
    from sparsecast.elements import ParticleSet

    with pytest.raises(SparsecastError, match="colors: expected finite"):
        ParticleSet(np.zeros((1, 3)), 1.0, [[np.nan, 0, 0]])
