"""Hostile volume files (issue 14, items 1-3 and 13): header lies, compression bombs,
files that are not regular, skips beyond the file, data files outside the header's folder."""

from __future__ import annotations

import bz2
import gzip
import os
import struct

import nibabel as nib
import numpy as np
import pytest
import tifffile

import sparsecast as sc
from sparsecast.errors import FileFormatError, ParameterError
from sparsecast.io import load_volume, save_volume
from sparsecast.io.budget import LIMIT_ENV, memory_limit


def _nrrd(path, sizes, encoding, payload, extra=b""):
    path.write_bytes(b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: " + sizes + b"\nencoding: " + encoding
                     + b"\n" + extra + b"\n" + payload)
    return path


# -- item 1: header lies and compression bombs ----------------------------------------
def test_nifti_claiming_12_gb_is_refused_before_reading(tmp_path):
    nib.save(nib.Nifti1Image(np.zeros((4, 4, 4), np.float32), np.eye(4)), str(tmp_path / "n.nii"))
    raw = bytearray((tmp_path / "n.nii").read_bytes())
    struct.pack_into("<4h", raw, 40, 3, 2000, 2000, 750)  # dim[0..3]
    (tmp_path / "lie.nii").write_bytes(raw)
    with pytest.raises(FileFormatError, match=r"lie.nii.*12000000000 bytes.*holds only"):
        load_volume(tmp_path / "lie.nii")
    (tmp_path / "lie.nii.gz").write_bytes(gzip.compress(bytes(raw)))
    with pytest.raises(FileFormatError, match=r"lie.nii.gz.*12000000000 bytes.*gzip"):
        load_volume(tmp_path / "lie.nii.gz")


def test_npy_claiming_909_tib_is_refused(tmp_path):
    header = b"{'descr': '|u1', 'fortran_order': False, 'shape': (100000, 100000, 100000), }"
    header += b" " * (118 - len(header)) + b"\n"
    (tmp_path / "lie.npy").write_bytes(b"\x93NUMPY\x01\x00" + struct.pack("<H", len(header)) + header + bytes(64))
    with pytest.raises(FileFormatError, match=r"lie.npy.*1000000000000000 bytes.*holds only 64"):
        load_volume(tmp_path / "lie.npy")


@pytest.mark.parametrize("compression", [None, "zlib"])
def test_tiff_claiming_gigabytes_is_refused(tmp_path, compression):
    path = tmp_path / "t.tif"
    tifffile.imwrite(path, np.zeros((4, 4, 4), np.uint16), photometric="minisblack", compression=compression)
    raw = bytearray(path.read_bytes())
    with tifffile.TiffFile(path) as tf:
        for page in tf.pages:
            for name in ("ImageWidth", "ImageLength"):
                tag = page.tags[name]
                struct.pack_into("<H" if tag.dtype == 3 else "<I", raw, tag.valueoffset, 60000)
    path.write_bytes(raw)
    with pytest.raises(FileFormatError, match=r"t.tif.*TIFF series.*28800000000 bytes"):
        load_volume(path)


def test_nrrd_raw_payload_smaller_than_declared(tmp_path):
    p = _nrrd(tmp_path / "r.nrrd", b"2000 2000 2000", b"raw", bytes(8))
    with pytest.raises(FileFormatError, match=r"8000000000 bytes.*holds only 8"):
        load_volume(p)


def test_nrrd_raw_payload_larger_than_declared(tmp_path):
    p = _nrrd(tmp_path / "r.nrrd", b"2 2 2", b"raw", bytes(9))
    with pytest.raises(FileFormatError, match="holds 9 bytes, the header declares 8"):
        load_volume(p)


@pytest.mark.parametrize("encoding, compress", [(b"gzip", gzip.compress), (b"bzip2", bz2.compress)])
def test_compressed_payload_stops_at_the_declared_size(tmp_path, encoding, compress):
    # 100 MB of zeros in a few kB: inflating it all is what the bomb wants
    bomb = _nrrd(tmp_path / "bomb.nrrd", b"10 10 10", encoding, compress(bytes(10**8)))
    with pytest.raises(FileFormatError, match=r"holds more than the 1000 bytes"):
        load_volume(bomb)
    short = _nrrd(tmp_path / "short.nrrd", b"10 10 10", encoding, compress(bytes(999)))
    with pytest.raises(FileFormatError, match=r"holds 999 bytes, the header declares 1000"):
        load_volume(short)
    exact = _nrrd(tmp_path / "exact.nrrd", b"10 10 10", encoding, compress(bytes(range(250)) * 4))
    assert load_volume(exact).data.ravel()[:250].tolist() == list(range(250))


def test_gzip_claim_beyond_any_deflate_ratio(tmp_path):
    p = _nrrd(tmp_path / "g.nrrd", b"100000 100000 1000", b"gzip", gzip.compress(bytes(1000)))
    with pytest.raises(FileFormatError, match="more than .* bytes of gzip can hold"):
        load_volume(p)


def test_declared_size_above_the_memory_limit(tmp_path, monkeypatch):
    monkeypatch.setenv(LIMIT_ENV, "4096")
    assert memory_limit() == 4096
    p = _nrrd(tmp_path / "b.nrrd", b"20 20 20", b"bzip2", bz2.compress(bytes(8000)))
    with pytest.raises(FileFormatError, match=r"b.nrrd.*8000 bytes.*above the limit of 4096 bytes"):
        load_volume(p)
    # Files that can be mapped are not refused: above the limit they open lazily (bricks
    # read on demand, issue 17), unless a dense volume is asked for.
    save_volume(sc.Volume(np.zeros((20, 20, 20), np.uint8)), tmp_path / "v.npy")
    (tmp_path / "r_20x20x20_uint8.raw").write_bytes(bytes(8000))
    for name in ("v.npy", "r_20x20x20_uint8.raw"):
        with pytest.raises(FileFormatError, match="above the limit"):
            load_volume(tmp_path / name, lazy=False)
        vol = load_volume(tmp_path / name)
        assert isinstance(vol, sc.BrickedVolume) and vol.lazy and vol.shape == (20, 20, 20)


def test_valid_encodings_and_skips_still_load(tmp_path):
    v = np.arange(8, dtype=np.uint8).reshape(2, 2, 2)
    p = _nrrd(tmp_path / "ls.nrrd", b"2 2 2", b"raw", b"a line\nanother\n" + v.tobytes(), b"line skip: 2\n")
    assert np.array_equal(load_volume(p).data, v)
    p = _nrrd(tmp_path / "bs.nrrd", b"2 2 2", b"raw", b"JUNK" + v.tobytes(), b"byte skip: -1\n")
    assert np.array_equal(load_volume(p).data, v)
    p = _nrrd(tmp_path / "bz.nrrd", b"2 2 2", b"gzip", gzip.compress(b"xyz" + v.tobytes()), b"byte skip: 3\n")
    assert np.array_equal(load_volume(p).data, v)
    p = _nrrd(tmp_path / "a.nrrd", b"2 2 2", b"ascii", b" ".join(str(x).encode() for x in v.ravel()))
    assert np.array_equal(load_volume(p).data, v)


# -- item 2: not regular files, unbounded headers and skips ------------------------------
@pytest.mark.parametrize("name", ["v.nrrd", "v.nhdr", "v.nii", "v.npy", "v.tif", "v_2x2x2_uint8.raw"])
def test_fifo_and_device_links_are_refused(tmp_path, name):
    os.mkfifo(tmp_path / name)
    with pytest.raises(FileFormatError, match="FIFO.*not a regular file"):
        load_volume(tmp_path / name)
    link = tmp_path / ("z" + name)
    os.symlink("/dev/zero", link)
    with pytest.raises(FileFormatError, match="character device"):
        load_volume(link)


def test_line_skip_is_bounded_by_the_file(tmp_path):
    p = _nrrd(tmp_path / "ls.nrrd", b"2 2 2", b"raw", bytes(8), b"line skip: 99999999\n")
    with pytest.raises(FileFormatError, match=r"line skip 99999999 is not in \[0, 8\]"):
        load_volume(p)
    p = _nrrd(tmp_path / "bs.nrrd", b"2 2 2", b"raw", bytes(8), b"byte skip: 99999999\n")
    with pytest.raises(FileFormatError, match="byte skip 99999999 is beyond the end"):
        load_volume(p)


def test_header_without_end_is_bounded(tmp_path):
    p = tmp_path / "h.nrrd"
    p.write_bytes(b"NRRD0004\n# " + b"x" * (2 << 20))
    with pytest.raises(FileFormatError, match="no end of the NRRD header"):
        load_volume(p)


# -- item 3: detached data files --------------------------------------------------------
def _nhdr(path, data_file):
    path.write_bytes(b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2 2 2\nencoding: raw\ndata file: "
                     + data_file.encode() + b"\n")
    return path


def test_data_file_outside_the_header_folder_is_refused(tmp_path):
    (tmp_path / "sub").mkdir()
    secret = tmp_path / "secret.raw"
    secret.write_bytes(bytes(range(8)))
    for name in (str(secret), "../secret.raw"):
        hdr = _nhdr(tmp_path / "sub" / "h.nhdr", name)
        with pytest.raises(FileFormatError, match="outside the header's folder.*allow_outside=True"):
            load_volume(hdr)
        assert load_volume(hdr, allow_outside=True).data.ravel().tolist() == list(range(8))
    os.symlink(secret, tmp_path / "sub" / "link.raw")
    with pytest.raises(FileFormatError, match="outside the header's folder"):
        load_volume(_nhdr(tmp_path / "sub" / "h.nhdr", "link.raw"))


def test_data_file_resolves_relative_to_the_header_not_the_cwd(tmp_path, monkeypatch):
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "d.raw").write_bytes(bytes(range(8)))
    (tmp_path / "d.raw").write_bytes(bytes(8))  # same name in the working directory
    monkeypatch.chdir(tmp_path)
    vol = load_volume(_nhdr(tmp_path / "sub" / "h.nhdr", "d.raw"))
    assert vol.data.ravel().tolist() == list(range(8))


# -- item 13: parameters named in errors ---------------------------------------------
def test_bad_parameters_are_named(tmp_path):
    save_volume(sc.Volume(np.zeros((2, 3, 4), np.uint8)), tmp_path / "v_4x3x2_uint8.raw")
    with pytest.raises(ParameterError, match="^path: expected a file path"):
        load_volume(b"v.nrrd")
    with pytest.raises(ParameterError, match="^header_offset: expected an integer"):
        load_volume(tmp_path / "v_4x3x2_uint8.raw", header_offset="abc")
    with pytest.raises(ParameterError, match="^spacing: expected 3 numbers"):
        load_volume(tmp_path / "v_4x3x2_uint8.raw", spacing="abc")
