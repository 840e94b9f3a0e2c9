"""Fuzz every loader (issue 14): mutated and truncated valid files of each format must load
or raise the project's error family (:class:`~sparsecast.errors.SparsecastError`), nothing
else. Bounded: a fixed number of derandomized examples per format, a few seconds in all."""

from __future__ import annotations

import gzip
import io
import json
import os
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import sparsecast as sc
from sparsecast.bench.progress import ResultStore
from sparsecast.errors import SparsecastError
from sparsecast.io.meshes import load_mesh, load_points
from sparsecast.io.particles import load_particles
from sparsecast.transfer import TransferFunction

#: examples per format (19 formats: ~1900 inputs in a few seconds); raise it for a longer campaign
EXAMPLES = int(os.environ.get("SPARSECAST_FUZZ_EXAMPLES", "100"))


def _volume_seeds(folder: Path) -> dict[str, bytes]:
    vol = sc.Volume(np.arange(4 * 5 * 6, dtype=np.uint16).reshape(4, 5, 6))
    out = {}
    for name, kw in (("v.nrrd", {}), ("r.nrrd", {"compress": False}), ("v.nii", {}), ("v.nii.gz", {}),
                     ("v.npy", {}), ("v.tif", {}), ("v_6x5x4_uint16.raw", {})):
        sc.save_volume(vol, folder / name, **kw)
        out[name] = (folder / name).read_bytes()
    out["b.nrrd"] = (b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2 2 2\nencoding: bzip2\nline skip: 0\n"
                     b"byte skip: 0\n\n" + __import__("bz2").compress(bytes(8)))
    out["d.nhdr"] = b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2 2 2\nencoding: raw\ndata file: d.raw\n"
    return out


def _mesh_seeds() -> dict[str, bytes]:
    import trimesh

    box = trimesh.creation.box()
    out = {}
    for suffix in ("ply", "obj", "stl", "off"):
        kw = {"encoding": "ascii"} if suffix == "ply" else {}
        out["m." + suffix] = box.export(file_type=suffix, **kw)
        if isinstance(out["m." + suffix], str):
            out["m." + suffix] = out["m." + suffix].encode()
    buf = io.BytesIO()
    np.save(buf, np.random.default_rng(0).random((5, 6)))
    out["p.npy"] = buf.getvalue()
    return out


def _particle_seeds() -> dict[str, bytes]:
    buf = io.BytesIO()
    np.save(buf, np.random.default_rng(1).random((4, 7)))
    return {
        "q.csv": b"x,y,z,radius,red,green,blue\n0,0,0,1,255,0,0\n1,2,3,0.5,0,1,0\n",
        "q.ply": (b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
                  b"property float z\nproperty float radius\nend_header\n0 0 0 1\n1 1 1 2\n"),
        "q.npy": buf.getvalue(),
    }


def _tf_seed() -> bytes:
    tf = TransferFunction([(0, 0, 0, 0, 0), (0.5, 1, 0, 0, 0.5), (1, 1, 1, 1, 1)], table_size=256)
    return json.dumps(tf.to_dict()).encode()


def _journal_seed() -> bytes:
    recs = [{"dataset": "d", "tf": "default", "method": "naive", "phase": "load", "ms": 1.0},
            {"dataset": "mesh", "method": "rbvh", "phase": "render", "section": "s", "ms": 2.0},
            {"method": "s", "phase": "section_done"}]
    return b"".join(json.dumps(r).encode() + b"\n" for r in recs)


def _load_volume(p: Path):
    return sc.load_volume(p)


def _load_store(p: Path):
    return ResultStore(p)


def _cases():
    import tempfile

    folder = Path(tempfile.mkdtemp(prefix="sc-fuzz-seeds-"))
    cases = [(name, data, _load_volume) for name, data in _volume_seeds(folder).items()]
    cases += [(name, data, load_points if name.endswith(".npy") else load_mesh) for name, data in _mesh_seeds().items()]
    cases += [(name, data, load_particles) for name, data in _particle_seeds().items()]
    cases += [("tf.json", _tf_seed(), TransferFunction.load), ("j.jsonl", _journal_seed(), _load_store)]
    return cases


CASES = _cases()
STATS = {"inputs": 0, "loaded": 0, "clean_errors": 0}


@st.composite
def mutations(draw, seed: bytes) -> bytes:
    data = bytearray(seed)
    kind = draw(st.sampled_from(["edit", "truncate", "splice", "random"]))
    if kind == "random":
        return draw(st.binary(max_size=512))
    if kind == "truncate":
        return bytes(data[: draw(st.integers(0, len(data)))])
    for _ in range(draw(st.integers(1, 8))):
        pos = draw(st.integers(0, max(len(data) - 1, 0)))
        if kind == "edit" and data:
            data[pos] = draw(st.integers(0, 255))
        else:  # splice interesting text into the header area
            token = draw(st.sampled_from([b"999999999", b"-1", b"\n", b"\n\n", b"nan", b"1e400", b"[",
                                          b"{", b"\x00", b"\xff", b"Infinity", b"../", b"/dev/zero"]))
            data[pos:pos] = token
    return bytes(data)


@pytest.mark.parametrize("name, seed, loader", CASES, ids=[c[0] for c in CASES])
def test_loader_fuzz(tmp_path_factory, name, seed, loader):
    folder = tmp_path_factory.mktemp("fuzz")
    (folder / "d.raw").write_bytes(bytes(8))  # for the detached header

    @settings(max_examples=EXAMPLES, deadline=None, derandomize=True, database=None,
              suppress_health_check=list(HealthCheck))
    @given(data=mutations(seed))
    def run(data: bytes) -> None:
        path = folder / name
        path.write_bytes(data)
        STATS["inputs"] += 1
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                loader(path)
                STATS["loaded"] += 1
            except SparsecastError:
                STATS["clean_errors"] += 1
        # anything else propagates and fails the test with the input that caused it

    run()


def test_fuzz_report(capsys):
    # last in the file: prints the totals (with -s) for the closing note
    with capsys.disabled():
        print(f"\nfuzz: {STATS['inputs']} inputs, {STATS['loaded']} loaded, "
              f"{STATS['clean_errors']} clean errors, 0 other exceptions")
