"""Lazy sources (:mod:`sparsecast.io.sources`): round trips of every kind, slicing, and bad input."""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

import h5py
import nrrd
import numpy as np
import pytest
import zarr

import sparsecast as sc
from sparsecast.errors import FileFormatError, ParameterError
from sparsecast.io import convert_volume, open_source
from sparsecast.storage import scan

SHAPE = (37, 50, 23)  # (nz, ny, nx): no axis a multiple of another, none a chunk multiple
SPACING = (0.5, 1.25, 2.0)
ORIGIN = (-3.0, 4.5, 10.0)
DTYPES = ("uint8", "uint16", "float32")


def _volume(dtype: str, shape=SHAPE, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    a = rng.random(shape) * 200
    a[rng.random(shape) < 0.7] = 0  # mostly background, as the sparse volumes are
    return a.astype(dtype)


def _write(kind: str, a: np.ndarray, folder: Path) -> Path | str:
    """``a`` stored as ``kind`` (with SPACING / ORIGIN where the kind can hold them)."""
    vol = sc.Volume(a, SPACING, ORIGIN)
    nz, ny, nx = a.shape
    if kind in ("zarr", "ome-zarr"):
        return convert_volume(vol, folder / "v.zarr", chunks=(16, 21, 9), ome=kind == "ome-zarr").path
    if kind == "hdf5":
        with h5py.File(folder / "v.h5", "w") as fh:
            fh.create_dataset("/scans/v", data=a, chunks=(8, 16, 10), compression="gzip")
        return f"{folder / 'v.h5'}:/scans/v"
    if kind == "npy":
        np.save(folder / "v.npy", a)
        return folder / "v.npy"
    if kind == "raw":
        path = folder / f"v_{nx}x{ny}x{nz}_{a.dtype}.raw"
        a.tofile(path)
        return path
    if kind == "nrrd":
        return sc.save_volume(vol, folder / "v.nrrd", compress=False)
    raise AssertionError(kind)


GEOMETRY = {"zarr", "ome-zarr", "nrrd"}  # the kinds that store spacing and origin


@pytest.mark.parametrize("kind", ["zarr", "ome-zarr", "hdf5", "npy", "raw", "nrrd"])
@pytest.mark.parametrize("dtype", DTYPES)
def test_round_trip_every_kind(tmp_path, kind, dtype):
    a = _volume(dtype)
    src = open_source(_write(kind, a, tmp_path))
    assert src.kind == kind
    assert src.shape == SHAPE and src.dtype == a.dtype and src.nbytes == a.nbytes
    np.testing.assert_array_equal(src.array[...], a)
    np.testing.assert_array_equal(src.array[5:30:4, 7, -3:], a[5:30:4, 7, -3:])
    np.testing.assert_array_equal(src.array[-1], a[-1])
    assert isinstance(src.array[1:3], np.ndarray)
    if kind in GEOMETRY:
        np.testing.assert_allclose(src.spacing, SPACING)
        np.testing.assert_allclose(src.origin, ORIGIN)
    assert src.levels[0].shape == SHAPE
    expect_chunks = {"zarr": (16, 21, 9), "ome-zarr": (16, 21, 9), "hdf5": (8, 16, 10)}.get(kind)
    assert src.chunks == expect_chunks


def test_big_endian_sources_read_native(tmp_path):
    a = _volume("uint16")
    np.save(tmp_path / "be.npy", a.astype(">u2"))
    nz, ny, nx = a.shape
    a.astype(">u2").tofile(tmp_path / "be.raw")
    for src in (open_source(tmp_path / "be.npy"),
                open_source(tmp_path / "be.raw", dims=(nx, ny, nz), dtype="uint16", byte_order="big")):
        block = src.array[2:9]
        assert block.dtype == np.dtype("uint16") and block.dtype.isnative
        np.testing.assert_array_equal(block, a[2:9])


def test_source_reads_regions_not_the_whole(tmp_path, monkeypatch):
    """A region read of a memory map touches that region: the whole array is never copied."""
    a = _volume("uint8")
    src = open_source(_write("npy", a, tmp_path))
    assert isinstance(src.array._array, np.memmap)  # mapped, not loaded
    assert src.array[3:4].nbytes == a[3:4].nbytes


def test_zarr_group_with_one_array_and_with_several(tmp_path):
    a = _volume("uint8")
    g = zarr.open_group(str(tmp_path / "g.zarr"), mode="w")
    g.create_array("vol", data=a, chunks=(10, 10, 10))
    g.create_array("mask2d", data=np.zeros((4, 4), np.uint8))
    np.testing.assert_array_equal(open_source(tmp_path / "g.zarr").array[...], a)
    g.create_array("other", data=a[:5], chunks=(5, 5, 5))
    with pytest.raises(FileFormatError, match=r"2 3-D arrays.*other \(5, 50, 23\).*vol \(37, 50, 23\)") as exc:
        open_source(tmp_path / "g.zarr")
    assert "g.zarr" in str(exc.value)
    np.testing.assert_array_equal(open_source(tmp_path / "g.zarr" / "other").array[...], a[:5])


def test_zarr_v2_store(tmp_path):
    a = _volume("float32")
    z = zarr.create_array(str(tmp_path / "v2.zarr"), shape=a.shape, chunks=(7, 9, 11), dtype=">f4", zarr_format=2)
    z[...] = a
    src = open_source(tmp_path / "v2.zarr")
    assert src.kind == "zarr" and src.chunks == (7, 9, 11)
    np.testing.assert_array_equal(src.array[...], a)


def test_missing_chunk_is_named_with_the_store(tmp_path):
    a = _volume("uint16")
    store = convert_volume(a, tmp_path / "m.zarr", chunks=16).path
    os.remove(store / "c" / "1" / "2" / "0")  # chunk (1, 2, 0): z 16..31, y 32..47, x 0..15
    src = open_source(store)
    np.testing.assert_array_equal(src.array[:16], a[:16])  # other chunks read fine
    with pytest.raises(FileFormatError, match=r"chunk 'c/1/2/0' \(chunk index \(1, 2, 0\)\) is missing") as exc:
        src.array[20, 40, 3]
    assert str(store) in str(exc.value)
    filled = open_source(store, missing_chunks="fill").array[...]
    assert (filled[16:32, 32:48, :16] == 0).all()
    np.testing.assert_array_equal(filled[:16], a[:16])


def test_corrupt_chunk_is_named(tmp_path):
    a = _volume("uint8")
    store = convert_volume(a, tmp_path / "c.zarr", chunks=16).path
    (store / "c" / "0" / "1" / "1").write_bytes(b"not a blosc frame")
    with pytest.raises(FileFormatError, match=r"chunk 'c/0/1/1' \(chunk index \(0, 1, 1\)\) cannot be read"):
        open_source(store).array[...]


def test_ome_levels_missing_level_and_names(tmp_path):
    a = _volume("uint8", (150, 90, 70))
    store = convert_volume(sc.Volume(a, SPACING, ORIGIN), tmp_path / "o.zarr", ome=True, chunks=32).path
    src = open_source(store)
    assert src.kind == "ome-zarr" and src.level == "0"
    assert [lv.shape for lv in src.levels] == [(150, 90, 70), (75, 45, 35), (38, 23, 18)]  # to <= 64
    coarse = open_source(store, level=1)
    assert coarse.shape == (75, 45, 35) and coarse.level == "1"
    np.testing.assert_allclose(coarse.spacing, np.array(SPACING) * 2)
    np.testing.assert_allclose(coarse.origin, np.array(ORIGIN) + np.array(SPACING) / 2)  # mean voxel centres
    assert open_source(store, level="1").shape == coarse.shape
    listed = r"0: '0' \(150, 90, 70\), 1: '1' \(75, 45, 35\), 2: '2' \(38, 23, 18\)"
    with pytest.raises(ParameterError, match=r"no level 5; expected one of the levels.*" + listed):
        open_source(store, level=5)
    with pytest.raises(ParameterError, match="single resolution"):
        open_source(_write("npy", a, tmp_path), level=1)


def _ome_5d(path: Path, a: np.ndarray, channels: int = 1) -> Path:
    from ome_zarr.format import FormatV04
    from ome_zarr.writer import write_multiscales_metadata

    g = zarr.open_group(str(path), mode="w", zarr_format=2)
    g.create_array("s0", data=np.stack([a] * channels)[None], chunks=(1, 1, 16, 16, 16))
    axes = [{"name": "t", "type": "time"}, {"name": "c", "type": "channel"}] + \
        [{"name": n, "type": "space"} for n in "zyx"]
    write_multiscales_metadata(g, [{"path": "s0", "coordinateTransformations": [
        {"type": "scale", "scale": [1.0, 1.0, 3.0, 2.0, 0.5]},
        {"type": "translation", "translation": [0.0, 0.0, 7.0, 8.0, 9.0]}]}], fmt=FormatV04(), axes=axes)
    return path


def test_ome_v04_t_c_squeezed_and_spacing_in_xyz(tmp_path):
    a = _volume("uint16")
    src = open_source(_ome_5d(tmp_path / "five.zarr", a))
    assert src.shape == SHAPE and src.level == "s0"
    np.testing.assert_array_equal(src.spacing, [0.5, 2.0, 3.0])
    np.testing.assert_array_equal(src.origin, [9.0, 8.0, 7.0])
    np.testing.assert_array_equal(src.array[...], a)
    with pytest.raises(ParameterError, match="c of size 3"):
        open_source(_ome_5d(tmp_path / "rgb.zarr", a, channels=3))


def test_hdf5_paths(tmp_path):
    a = _volume("float32")
    path = tmp_path / "f.h5"
    with h5py.File(path, "w") as fh:
        fh["only"] = a
        fh["meta/table"] = np.arange(5)
    assert open_source(path).name == "f"  # a single 3-D dataset: the path may be left out
    with h5py.File(path, "a") as fh:
        fh["second"] = a[:3]
    with pytest.raises(FileFormatError, match=r"2 3-D datasets.*f\.h5:/path.*/only \(37, 50, 23\)"):
        open_source(path)
    with pytest.raises(FileFormatError, match=r"'/meta' is a group; expected a dataset"):
        open_source(f"{path}:/meta")
    with pytest.raises(FileFormatError, match=r"'/nope' is not found.*/second \(3, 50, 23\)"):
        open_source(f"{path}:/nope")
    with pytest.raises(FileFormatError, match=r"shape \(5,\); expected a 3-D volume"):
        open_source(f"{path}:/meta/table")
    np.testing.assert_array_equal(open_source(f"{path}:/second").array[...], a[:3])


def test_gzip_nrrd_is_not_lazy(tmp_path):
    path = sc.save_volume(sc.Volume(_volume("uint8")), tmp_path / "g.nrrd", compress=True)
    with pytest.raises(FileFormatError, match="gzip-encoded NRRD payload cannot be read lazily"):
        open_source(path)


@pytest.mark.parametrize("make, match", [
    (lambda d: (d / "bad.zarr").mkdir() or (d / "bad.zarr" / "zarr.json").write_text("{not json"), "cannot open"),
    (lambda d: (d / "bad.zarr").mkdir(), "not a Zarr store"),
    (lambda d: (d / "bad.npy").write_bytes(b"\x93NUMPY garbage"), "cannot open"),
    (lambda d: np.save(d / "bad.npy", np.zeros((4, 4))), r"shape \(4, 4\); expected a 3-D"),
    (lambda d: (d / "bad.h5").write_bytes(b"HDF garbage"), "cannot open"),
    (lambda d: (d / "bad_4x4x4_uint8.raw").write_bytes(b"\0" * 63), "file size is 63 bytes, expected 64"),
    (lambda d: (d / "bad.tif").write_bytes(b"II*\0"), "not a lazily readable volume"),
])
def test_corrupt_inputs_raise_one_error(tmp_path, make, match):
    make(tmp_path)
    (path,) = [p for p in tmp_path.iterdir()]
    with pytest.raises(FileFormatError, match=match) as exc:
        open_source(path)
    assert path.name in str(exc.value)


def test_npy_truncated_payload(tmp_path):
    path = tmp_path / "t.npy"
    np.save(path, np.zeros((8, 8, 8), np.float32))
    path.write_bytes(path.read_bytes()[:-100])
    with pytest.raises(FileFormatError, match="t.npy"):
        open_source(path).array[...]


def test_sources_are_read_only(tmp_path):
    a = _volume("uint8")
    for kind in ("zarr", "hdf5", "npy", "raw"):
        sub = tmp_path / kind
        sub.mkdir()
        src_path = _write(kind, a, sub)
        before = _digest(sub)
        src = open_source(src_path)
        with pytest.raises(TypeError):
            src.array[0, 0, 0] = 1  # no __setitem__
        scan(src)
        convert_volume(src, tmp_path / f"{kind}-copy.zarr")
        assert _digest(sub) == before, kind


def _digest(folder: Path) -> dict[str, str]:
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def test_basic_indexing_only(tmp_path):
    src = open_source(_write("npy", _volume("uint8"), tmp_path))
    with pytest.raises(ParameterError, match="basic indexing"):
        src.array[[1, 2]]
    with pytest.raises(ParameterError, match="out of bounds"):
        src.array[37]


@pytest.mark.parametrize("suffix", [".npy", "_20x18x16_int16.raw"])
def test_a_dense_npy_or_raw_volume_maps_the_file(tmp_path, suffix):
    """Within the memory budget, .npy and raw load as a dense Volume over a read-only memory
    map of the file (no copy), equal to what was written."""
    import mmap

    data = np.random.default_rng(3).integers(-500, 500, (16, 18, 20)).astype(np.int16)
    path = tmp_path / f"v{suffix}"
    sc.save_volume(sc.Volume(data), path)
    vol = sc.load_volume(path)
    assert type(vol) is sc.Volume
    np.testing.assert_array_equal(vol.data, data)
    assert not vol.data.flags.writeable
    base = vol.data
    while getattr(base, "base", None) is not None and not isinstance(base, mmap.mmap):
        base = base.base
    assert isinstance(base, mmap.mmap)
    assert vol.value_range == (float(data.min()), float(data.max()))
