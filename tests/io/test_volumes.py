"""Tests for sparsecast.io.volumes: every format round-trips, axis order, bad input."""

from __future__ import annotations

import gzip
import os

import nibabel as nib
import nrrd
import numpy as np
import pytest
import tifffile

from sparsecast.errors import FileFormatError, ParameterError, VolumeDataError
from sparsecast.io import load_volume, save_volume
from sparsecast.io import volumes as volumes_mod
from sparsecast.io.volumes import parse_raw_name
from sparsecast.volume import Volume

DTYPES = ["uint8", "uint16", "int16", "float32", "float64"]
SHAPE = (3, 4, 5)  # (nz, ny, nx): non-cubic so axis mix-ups show
SPACING = (0.5, 1.25, 2.0)
ORIGIN = (-3.0, 4.5, 10.0)

def make_data(dtype: str, shape=SHAPE) -> np.ndarray:
    """Distinct values per voxel: value = i + 10*j + 100*k (scaled into range)."""
    k, j, i = np.indices(shape)
    vals = i + 10 * j + 100 * k
    dt = np.dtype(dtype)
    if dt == np.uint8:
        vals = vals % 251
    elif dt.kind == "i":
        vals = vals - 150  # negatives too
    elif dt.kind == "f":
        vals = vals * 0.25 - 7.5
    return vals.astype(dt)


def make_volume(dtype: str, **kw) -> Volume:
    return Volume(make_data(dtype), SPACING, ORIGIN, name="v", **kw)


def assert_same(vol: Volume, ref: Volume, *, geometry: bool = True) -> None:
    assert vol.shape == ref.shape
    assert vol.dtype == ref.dtype
    np.testing.assert_array_equal(vol.data, ref.data)
    if geometry:
        np.testing.assert_allclose(vol.spacing, ref.spacing, rtol=1e-6)
        np.testing.assert_allclose(vol.origin, ref.origin, rtol=1e-6, atol=1e-9)


# ----------------------------------------------------------------------------- round trips
@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("compress", [True, False], ids=["gzip", "raw"])
def test_nrrd_round_trip(tmp_path, dtype, compress):
    ref = make_volume(dtype)
    out = save_volume(ref, tmp_path / "vol.nrrd", compress=compress)
    assert out == tmp_path / "vol.nrrd"
    header = nrrd.read_header(str(out))
    assert header["encoding"] == ("gzip" if compress else "raw")
    assert list(header["sizes"]) == [5, 4, 3]  # x y z in the file
    vol = load_volume(out)
    assert vol.name == "vol"
    assert_same(vol, ref)


@pytest.mark.parametrize("encoding", ["raw", "gzip"])
def test_nhdr_detached_round_trip(tmp_path, encoding):
    ref = make_volume("int16")
    header = {
        "space dimension": 3,
        "space directions": np.diag(SPACING),
        "space origin": np.array(ORIGIN),
        "encoding": encoding,
    }
    nrrd.write(str(tmp_path / "det.nhdr"), ref.data, header, index_order="C")
    data_files = [f for f in os.listdir(tmp_path) if f != "det.nhdr"]
    assert len(data_files) == 1  # really detached
    vol = load_volume(tmp_path / "det.nhdr")
    assert vol.name == "det"
    assert_same(vol, ref)


@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("suffix", [".nii", ".nii.gz"])
def test_nifti_round_trip(tmp_path, dtype, suffix):
    ref = make_volume(dtype)
    out = save_volume(ref, tmp_path / f"brain{suffix}")
    img = nib.load(str(out))
    assert img.shape == (5, 4, 3)  # (x, y, z) on disk
    assert img.get_data_dtype() == np.dtype(dtype)
    vol = load_volume(out)
    assert vol.name == "brain"
    assert_same(vol, ref)


def test_nifti_scaling_applied(tmp_path):
    raw = np.arange(60, dtype=np.int16).reshape(5, 4, 3)  # (x, y, z)
    nib.save(nib.Nifti1Image(raw, np.eye(4)), str(tmp_path / "scaled.nii"))
    # nibabel recomputes scaling on save, so patch scl_slope / scl_inter (bytes 112..119).
    blob = bytearray((tmp_path / "scaled.nii").read_bytes())
    blob[112:120] = np.array([0.5, 10.0], "<f4").tobytes()
    (tmp_path / "scaled.nii").write_bytes(bytes(blob))
    proxy = nib.load(str(tmp_path / "scaled.nii")).dataobj
    assert (proxy.slope, proxy.inter) == (0.5, 10.0)
    vol = load_volume(tmp_path / "scaled.nii")
    assert vol.dtype.kind == "f"
    np.testing.assert_allclose(vol.data, raw.transpose(2, 1, 0) * 0.5 + 10.0)


def test_nifti_unscaled_keeps_dtype_and_trailing_singleton(tmp_path):
    raw = np.arange(60, dtype=np.uint16).reshape(5, 4, 3, 1)
    nib.save(nib.Nifti1Image(raw, np.diag([2.0, 3.0, 4.0, 1.0])), str(tmp_path / "t.nii.gz"))
    vol = load_volume(tmp_path / "t.nii.gz")
    assert vol.dtype == np.uint16
    assert vol.dims == (5, 4, 3)
    np.testing.assert_array_equal(vol.data, raw[..., 0].transpose(2, 1, 0))
    np.testing.assert_allclose(vol.spacing, (2.0, 3.0, 4.0))


@pytest.mark.parametrize("dtype", DTYPES)
def test_raw_round_trip_name_convention(tmp_path, dtype):
    ref = make_volume(dtype)
    path = tmp_path / f"blob_5x4x3_{dtype}.raw"
    save_volume(ref, path)
    assert path.stat().st_size == ref.nbytes
    vol = load_volume(path)
    assert vol.name == f"blob_5x4x3_{dtype}"
    assert_same(vol, ref, geometry=False)
    np.testing.assert_allclose(vol.spacing, 1.0)
    vol2 = load_volume(path, spacing=SPACING, origin=ORIGIN)
    assert_same(vol2, ref)


@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("suffix", [".raw", ".bin", ".dat"])
def test_raw_explicit_dims(tmp_path, dtype, suffix):
    ref = make_volume(dtype)
    path = tmp_path / f"plain{suffix}"
    path.write_bytes(ref.data.astype(ref.dtype.newbyteorder("<")).tobytes())
    vol = load_volume(path, dims=(5, 4, 3), dtype=dtype)
    assert_same(vol, ref, geometry=False)


def test_raw_big_endian_and_header_offset(tmp_path):
    ref = make_volume("uint16")
    path = tmp_path / "be.raw"
    path.write_bytes(b"HEADER!!" + ref.data.astype(">u2").tobytes())
    vol = load_volume(path, dims=(5, 4, 3), dtype="uint16", byte_order="big", header_offset=8)
    assert vol.dtype == np.uint16  # native byte order after loading
    np.testing.assert_array_equal(vol.data, ref.data)


@pytest.mark.parametrize(
    "spelling,expected",
    [("float", "float32"), ("double", "float64"), ("int8", "int8"), ("uint8", "uint8"), ("short", "int16")],
)
def test_parse_raw_name_spellings(spelling, expected):
    dims, dt = parse_raw_name(f"bonsai_256x128x64_{spelling}.raw")
    assert dims == (256, 128, 64)
    assert dt == np.dtype(expected)


def test_parse_raw_name_none():
    assert parse_raw_name("volume.raw") is None
    assert parse_raw_name("scan_2x3x4.raw") is None  # no dtype part


def test_raw_int8_is_converted_losslessly(tmp_path):
    data = (np.arange(60).reshape(3, 4, 5) - 30).astype(np.int8)
    path = tmp_path / "s_5x4x3_int8.raw"
    path.write_bytes(data.tobytes())
    vol = load_volume(path)
    assert vol.dtype == np.int16
    np.testing.assert_array_equal(vol.data, data)


@pytest.mark.parametrize("dtype", DTYPES)
def test_npy_round_trip(tmp_path, dtype):
    ref = make_volume(dtype)
    save_volume(ref, tmp_path / "a.npy")
    vol = load_volume(tmp_path / "a.npy")
    assert vol.name == "a"
    assert_same(vol, ref, geometry=False)


@pytest.mark.parametrize("dtype", DTYPES)
def test_tiff_stack_round_trip(tmp_path, dtype):
    ref = make_volume(dtype)
    save_volume(ref, tmp_path / "stack.tif")
    with tifffile.TiffFile(str(tmp_path / "stack.tif")) as tf:
        assert len(tf.pages) == 3  # one page per z slice
    vol = load_volume(tmp_path / "stack.tif")
    assert_same(vol, ref, geometry=False)


def test_tiff_written_by_tifffile_directly(tmp_path):
    data = make_data("uint16", shape=(6, 4, 5))  # nz not 3/4: tifffile's default is unambiguous
    tifffile.imwrite(str(tmp_path / "direct.tiff"), data)
    vol = load_volume(tmp_path / "direct.tiff")
    np.testing.assert_array_equal(vol.data, data)


def test_tiff_directory_of_slices(tmp_path):
    data = make_data("uint8", shape=(12, 4, 5))
    d = tmp_path / "slices"
    d.mkdir()
    for k in range(data.shape[0]):
        tifffile.imwrite(str(d / f"slice_{k}.tif"), data[k])  # natural order: 2 < 10
    vol = load_volume(d)
    assert vol.name == "slices"
    np.testing.assert_array_equal(vol.data, data)


def test_overrides_beat_file_geometry(tmp_path):
    save_volume(make_volume("float32"), tmp_path / "g.nrrd")
    vol = load_volume(tmp_path / "g.nrrd", spacing=3.0, origin=(1, 2, 3))
    np.testing.assert_allclose(vol.spacing, (3.0, 3.0, 3.0))
    np.testing.assert_allclose(vol.origin, (1.0, 2.0, 3.0))


# ----------------------------------------------------------------------------- axis order
def test_nrrd_axis_order_fortran_file(tmp_path):
    nx, ny, nz = 5, 4, 3
    x, y, z = np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij")
    f_data = (x + 10 * y + 100 * z).astype(np.uint16)  # indexed [x, y, z]
    header = {"space directions": np.diag([1.0, 2.0, 3.0]), "space dimension": 3}
    nrrd.write(str(tmp_path / "f.nrrd"), f_data, header, index_order="F")
    assert list(nrrd.read_header(str(tmp_path / "f.nrrd"))["sizes"]) == [nx, ny, nz]
    vol = load_volume(tmp_path / "f.nrrd")
    assert vol.dims == (nx, ny, nz)
    assert vol.shape == (nz, ny, nx)
    for k in range(nz):
        for j in range(ny):
            for i in range(nx):
                assert vol.data[k, j, i] == i + 10 * j + 100 * k
    np.testing.assert_allclose(vol.spacing, (1.0, 2.0, 3.0))


def test_nifti_axis_order(tmp_path):
    x, y, z = np.meshgrid(np.arange(5), np.arange(4), np.arange(3), indexing="ij")
    nib.save(nib.Nifti1Image((x + 10 * y + 100 * z).astype(np.int16), np.eye(4)), str(tmp_path / "o.nii"))
    vol = load_volume(tmp_path / "o.nii")
    k, j, i = np.indices(vol.shape)
    np.testing.assert_array_equal(vol.data, i + 10 * j + 100 * k)


# ----------------------------------------------------------------------------- bad input
def test_raw_size_mismatch_names_file_and_sizes(tmp_path):
    path = tmp_path / "bad_5x4x3_uint16.raw"
    path.write_bytes(b"\0" * 100)
    with pytest.raises(FileFormatError) as info:
        load_volume(path)
    msg = str(info.value)
    assert "bad_5x4x3_uint16.raw" in msg
    assert "100" in msg and "120" in msg


def test_raw_size_mismatch_with_header_offset(tmp_path):
    path = tmp_path / "h.raw"
    path.write_bytes(b"\0" * 60)
    with pytest.raises(FileFormatError, match="76"):
        load_volume(path, dims=(5, 4, 3), dtype="uint8", header_offset=16)


def test_raw_without_dims_or_dtype(tmp_path):
    path = tmp_path / "mystery.raw"
    path.write_bytes(b"\0" * 60)
    with pytest.raises(ParameterError, match="dims"):
        load_volume(path)
    with pytest.raises(ParameterError, match="dtype"):
        load_volume(path, dims=(5, 4, 3))


def test_raw_unsupported_dtype_in_name(tmp_path):
    path = tmp_path / "c_5x4x3_complex64.raw"
    path.write_bytes(b"\0" * 480)
    with pytest.raises(FileFormatError, match="complex64"):
        load_volume(path)
    with pytest.raises(FileFormatError, match="complex64"):
        parse_raw_name(path)
    with pytest.raises(FileFormatError, match="unsupported dtype"):
        load_volume(tmp_path / "c_5x4x3_complex64.raw", dims=(5, 4, 3), dtype=np.complex64)


def test_raw_bad_byte_order(tmp_path):
    path = tmp_path / "b_5x4x3_uint8.raw"
    path.write_bytes(b"\0" * 60)
    with pytest.raises(ParameterError, match="byte_order"):
        load_volume(path, byte_order="middle")


def test_truncated_gzip_nrrd(tmp_path):
    rng = np.random.default_rng(0)
    save_volume(Volume(rng.random((8, 9, 10)).astype(np.float32)), tmp_path / "t.nrrd")
    blob = (tmp_path / "t.nrrd").read_bytes()
    (tmp_path / "cut.nrrd").write_bytes(blob[: len(blob) // 2])
    with pytest.raises(FileFormatError, match="cut.nrrd"):
        load_volume(tmp_path / "cut.nrrd")


def test_corrupt_gzip_payload_nrrd(tmp_path):
    save_volume(make_volume("uint8"), tmp_path / "z.nrrd")
    blob = bytearray((tmp_path / "z.nrrd").read_bytes())
    head_end = blob.index(b"\n\n") + 2
    blob[head_end:] = b"\xff" * (len(blob) - head_end)
    (tmp_path / "z.nrrd").write_bytes(bytes(blob))
    with pytest.raises(FileFormatError, match="z.nrrd"):
        load_volume(tmp_path / "z.nrrd")


@pytest.mark.parametrize(
    "text",
    [
        b"NOT A NRRD\n\n\x00\x00",
        b"NRRD0004\ntype: uint8\ndimension: three\nsizes: 2 2 2\nencoding: raw\n\n" + b"\0" * 8,
        b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2 2\nencoding: raw\n\n" + b"\0" * 8,
        b"NRRD0004\ntype: quaternion\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n\n" + b"\0" * 8,
    ],
    ids=["magic", "dimension", "sizes", "type"],
)
def test_corrupt_nrrd_header(tmp_path, text):
    path = tmp_path / "corrupt.nrrd"
    path.write_bytes(text)
    with pytest.raises(FileFormatError, match="corrupt.nrrd"):
        load_volume(path)


def test_nrrd_4d_and_vector_rejected(tmp_path):
    nrrd.write(str(tmp_path / "four.nrrd"), np.zeros((2, 3, 4, 5), np.float32), index_order="C")
    with pytest.raises(FileFormatError, match="4-D"):
        load_volume(tmp_path / "four.nrrd")
    nrrd.write(
        str(tmp_path / "vec.nrrd"),
        np.zeros((4, 5, 3), np.float32),
        {"kinds": ["vector", "domain", "domain"]},
        index_order="F",
    )
    with pytest.raises(FileFormatError, match="non-scalar"):
        load_volume(tmp_path / "vec.nrrd")


def test_nhdr_missing_data_file(tmp_path):
    nrrd.write(str(tmp_path / "d.nhdr"), make_data("uint8"), {"encoding": "raw"}, index_order="C")
    (tmp_path / "d.raw").unlink()
    with pytest.raises(FileFormatError, match="d.nhdr"):
        load_volume(tmp_path / "d.nhdr")


def test_truncated_nifti_gz(tmp_path):
    save_volume(make_volume("float32"), tmp_path / "n.nii.gz")
    blob = (tmp_path / "n.nii.gz").read_bytes()
    (tmp_path / "cut.nii.gz").write_bytes(blob[: len(blob) // 2])
    with pytest.raises(FileFormatError, match="cut.nii.gz"):
        load_volume(tmp_path / "cut.nii.gz")


def test_garbage_nifti(tmp_path):
    (tmp_path / "g.nii").write_bytes(b"hello, not nifti" * 3)
    with pytest.raises(FileFormatError, match="g.nii"):
        load_volume(tmp_path / "g.nii")


def test_missing_file(tmp_path):
    with pytest.raises(FileFormatError, match="nope.nrrd"):
        load_volume(tmp_path / "nope.nrrd")


def test_unknown_suffix(tmp_path):
    (tmp_path / "v.xyz").write_bytes(b"\0" * 8)
    with pytest.raises(FileFormatError) as info:
        load_volume(tmp_path / "v.xyz")
    msg = str(info.value)
    assert "v.xyz" in msg and ".nrrd" in msg and ".nii.gz" in msg and ".npy" in msg
    with pytest.raises(FileFormatError, match="supported"):
        save_volume(make_volume("uint8"), tmp_path / "out.xyz")


def test_raw_options_rejected_for_other_formats(tmp_path):
    save_volume(make_volume("uint8"), tmp_path / "a.npy")
    with pytest.raises(ParameterError, match="raw"):
        load_volume(tmp_path / "a.npy", dims=(5, 4, 3))


def test_2d_tiff_rejected(tmp_path):
    tifffile.imwrite(str(tmp_path / "flat.tif"), np.zeros((4, 5), np.uint8))
    with pytest.raises(FileFormatError, match="3-D stack"):
        load_volume(tmp_path / "flat.tif")


def test_rgb_tiff_rejected(tmp_path):
    tifffile.imwrite(str(tmp_path / "rgb.tif"), np.zeros((4, 5, 3), np.uint8), photometric="rgb")
    with pytest.raises(FileFormatError, match="rgb.tif"):
        load_volume(tmp_path / "rgb.tif")


def test_corrupt_tiff(tmp_path):
    (tmp_path / "x.tif").write_bytes(b"II*\x00garbage")
    with pytest.raises(FileFormatError, match="x.tif"):
        load_volume(tmp_path / "x.tif")


def test_empty_tiff_dir(tmp_path):
    (tmp_path / "empty").mkdir()
    with pytest.raises(FileFormatError, match="no .tif"):
        load_volume(tmp_path / "empty")


def test_nan_in_npy(tmp_path):
    data = make_data("float32")
    data[1, 2, 3] = np.nan
    data[0, 0, 0] = np.inf
    np.save(tmp_path / "nan.npy", data)
    with pytest.raises(VolumeDataError, match="nan.npy"):
        load_volume(tmp_path / "nan.npy")
    vol = load_volume(tmp_path / "nan.npy", nonfinite="replace")
    assert np.all(np.isfinite(vol.data))
    finite = data[np.isfinite(data)]
    assert vol.data[1, 2, 3] == finite.min()
    assert vol.data[0, 0, 0] == finite.max()
    assert vol.name == "nan"


def test_zero_size_npy(tmp_path):
    np.save(tmp_path / "empty.npy", np.zeros((0, 4, 5), np.float32))
    with pytest.raises(VolumeDataError, match="empty.npy"):
        load_volume(tmp_path / "empty.npy")


def test_4d_npy(tmp_path):
    np.save(tmp_path / "four.npy", np.zeros((2, 3, 4, 5), np.uint8))
    with pytest.raises(VolumeDataError, match="4-D"):
        load_volume(tmp_path / "four.npy")


def test_pickled_npy_rejected(tmp_path):
    np.save(tmp_path / "obj.npy", np.array([{"a": 1}], dtype=object), allow_pickle=True)
    with pytest.raises(FileFormatError, match="obj.npy"):
        load_volume(tmp_path / "obj.npy")


def test_truncated_npy(tmp_path):
    np.save(tmp_path / "t.npy", make_data("float64"))
    blob = (tmp_path / "t.npy").read_bytes()
    (tmp_path / "t.npy").write_bytes(blob[:-40])
    with pytest.raises(FileFormatError, match="t.npy"):
        load_volume(tmp_path / "t.npy")


def test_save_to_missing_directory(tmp_path):
    with pytest.raises(ParameterError, match="does not exist"):
        save_volume(make_volume("uint8"), tmp_path / "no" / "such" / "dir" / "v.nrrd")


def test_save_raw_name_must_match_volume(tmp_path):
    with pytest.raises(FileFormatError, match="5x4x3"):
        save_volume(make_volume("uint8"), tmp_path / "v_4x4x4_uint8.raw")
    with pytest.raises(FileFormatError, match="uint16"):
        save_volume(make_volume("uint16"), tmp_path / "v_5x4x3_uint8.raw")
    assert os.listdir(tmp_path) == []


def test_failed_write_leaves_nothing(tmp_path, monkeypatch):
    def half_writer(file, data, header=None, **kw):
        with open(file, "wb") as fh:
            fh.write(b"NRRD0005\npartial")
        raise OSError("disk full (simulated)")

    monkeypatch.setattr(nrrd, "write", half_writer)
    with pytest.raises(FileFormatError, match="disk full"):
        save_volume(make_volume("uint8"), tmp_path / "out.nrrd")
    assert os.listdir(tmp_path) == []


def test_failed_write_keeps_old_file(tmp_path, monkeypatch):
    target = tmp_path / "keep.npy"
    save_volume(make_volume("uint8"), target)
    before = target.read_bytes()

    def boom(fh, arr, **kw):
        fh.write(b"\x93NUMPY garbage")
        raise RuntimeError("interrupted")

    monkeypatch.setattr(volumes_mod.np, "save", boom)
    with pytest.raises(RuntimeError):
        save_volume(make_volume("float64"), target)
    monkeypatch.undo()
    assert sorted(os.listdir(tmp_path)) == ["keep.npy"]
    assert target.read_bytes() == before


def test_save_overwrites_existing(tmp_path):
    save_volume(make_volume("uint8"), tmp_path / "w.nii.gz")
    ref = make_volume("float32")
    save_volume(ref, tmp_path / "w.nii.gz")
    assert_same(load_volume(tmp_path / "w.nii.gz"), ref)
    assert os.listdir(tmp_path) == ["w.nii.gz"]


# ----------------------------------------------------------------------------- real data
def test_real_mni152_nrrd(shared_file):
    path = shared_file("mni152_t1_197x233x189_uint8.nrrd")
    vol = load_volume(path)
    assert vol.dims == (197, 233, 189)
    assert vol.shape == (189, 233, 197)
    assert vol.dtype == np.uint8
    np.testing.assert_allclose(vol.spacing, 1.0)
    np.testing.assert_allclose(vol.origin, 0.0)
    assert vol.name == "mni152_t1_197x233x189_uint8"
    lo, hi = vol.value_range
    assert lo == 0 and hi > 200
    # Sanity check against pynrrd read directly (its default Fortran order).
    f_data, _ = nrrd.read(str(path))
    assert vol.data[100, 120, 90] == f_data[90, 120, 100]


def test_gzip_module_is_what_nrrd_uses(tmp_path):
    # A gzip NRRD payload decompresses with the stdlib: our writer really wrote gzip.
    save_volume(make_volume("uint16"), tmp_path / "g.nrrd")
    blob = (tmp_path / "g.nrrd").read_bytes()
    payload = blob[blob.index(b"\n\n") + 2 :]
    raw = gzip.decompress(payload)
    np.testing.assert_array_equal(np.frombuffer(raw, "<u2").reshape(SHAPE), make_data("uint16"))
