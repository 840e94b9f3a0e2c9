"""Time series: :func:`sparsecast.load_series` and :class:`sparsecast.VolumeSeries`."""

from __future__ import annotations

import numpy as np
import pytest

import sparsecast as sc
from sparsecast.errors import FileFormatError, ParameterError, VolumeDataError


def _steps(n=4, shape=(10, 11, 12)):
    rng = np.random.default_rng(2)
    return (rng.random((n, *shape)) * np.arange(1, n + 1)[:, None, None, None]).astype(np.float32)


def test_from_array_steps_and_the_range_over_all_steps():
    data = _steps()
    s = sc.load_series(data, spacing=(1, 2, 3))
    assert len(s) == 4 and s.names[1] == "t=1"
    np.testing.assert_array_equal(s[2].data, data[2])
    assert tuple(s[-1].spacing) == (1, 2, 3)
    assert s.value_range == (float(data.min()), float(data.max()))
    assert [v.shape for v in s[1:3]] == [data.shape[1:]] * 2


def test_a_folder_is_read_in_natural_order_and_a_glob_too(tmp_path):
    data = _steps(3)
    for t, name in enumerate(["s2.npy", "s10.npy", "s100.npy"]):
        np.save(tmp_path / name, data[t])
    (tmp_path / "notes.txt").write_text("not a volume")
    s = sc.load_series(tmp_path)
    assert s.names == ("s2.npy", "s10.npy", "s100.npy")
    np.testing.assert_array_equal(s[1].data, data[1])
    g = sc.load_series(str(tmp_path / "s1*.npy"))
    assert g.names == ("s10.npy", "s100.npy")
    lst = sc.load_series([tmp_path / "s100.npy", tmp_path / "s2.npy"])
    np.testing.assert_array_equal(lst[0].data, data[2])


def test_a_4d_npy_is_memory_mapped_and_read_per_step(tmp_path):
    data = _steps(5)
    np.save(tmp_path / "run.npy", data)
    s = sc.load_series(tmp_path / "run.npy")
    assert len(s) == 5
    np.testing.assert_array_equal(s[3].data, data[3])
    np.save(tmp_path / "flat.npy", data[0])
    with pytest.raises(FileFormatError, match="3-D array.*expected a 4-D"):
        sc.load_series(tmp_path / "flat.npy")


def test_steps_are_loaded_lazily_and_evicted_by_bytes():
    calls = []
    data = _steps(6)

    def loader(t):
        def load():
            calls.append(t)
            return sc.Volume(data[t])
        return load

    s = sc.VolumeSeries([loader(t) for t in range(6)], [str(t) for t in range(6)], cache_bytes=2 * data[0].nbytes)
    assert calls == []
    s[0], s[1], s[0], s[2]
    assert calls == [0, 1, 2]           # step 0 came from the cache the second time
    s[1]
    assert calls == [0, 1, 2, 1]        # two steps fit: 1 was evicted when 2 loaded
    assert s[2] is s[2]                 # cached volumes keep their brick statistics


def test_a_step_on_another_grid_is_an_error_naming_it(tmp_path):
    np.save(tmp_path / "a0.npy", np.zeros((4, 4, 4), np.float32))
    np.save(tmp_path / "a1.npy", np.zeros((4, 4, 5), np.float32))
    s = sc.load_series(tmp_path)
    s[0]
    with pytest.raises(VolumeDataError, match=r"a1\.npy: shape \(4, 4, 5\) differs"):
        s[1]


@pytest.mark.parametrize("t", [4, -5, 1.5, "x"])
def test_bad_steps(t):
    s = sc.load_series(_steps(4))
    with pytest.raises(ParameterError, match="time: expected"):
        s[t]


def test_sources_without_steps(tmp_path):
    with pytest.raises(FileFormatError, match="no volume files"):
        sc.load_series(tmp_path)
    with pytest.raises(FileFormatError, match="matches no files"):
        sc.load_series(str(tmp_path / "*.nrrd"))
    with pytest.raises(FileFormatError, match="expected a directory, a glob"):
        sc.load_series(tmp_path / "missing.nrrd")
    with pytest.raises(VolumeDataError, match="4-D"):
        sc.load_series(np.zeros((3, 3, 3)))
