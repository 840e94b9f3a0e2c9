"""The one suffix table: what load_volume reads and save_volume writes, in the order messages list them."""

from __future__ import annotations

import pytest

from sparsecast.io import formats, volumes
from sparsecast.io.names import stem_of, suffix_of


def test_suffix_lists_come_from_the_table():
    assert volumes.READ_SUFFIXES == (".nrrd", ".nhdr", ".nii", ".nii.gz", ".raw", ".bin", ".dat", ".npy",
                                     ".tif", ".tiff")
    assert volumes.WRITE_SUFFIXES == (".nrrd", ".nii", ".nii.gz", ".raw", ".npy", ".tif", ".tiff")
    assert set(formats.FORMATS) == set(volumes.READ_SUFFIXES)
    assert {s for s, f in formats.FORMATS.items() if f.raw_layout} == {".raw", ".bin", ".dat"}


@pytest.mark.parametrize("name, suffix, stem", [
    ("brain.nii.gz", ".nii.gz", "brain"), ("CT.NRRD", ".nrrd", "CT"), ("a.b.raw", ".raw", "a.b"), ("noext", "", "noext"),
])
def test_suffix_and_stem(tmp_path, name, suffix, stem):
    assert suffix_of(tmp_path / name) == suffix and stem_of(tmp_path / name) == stem
