"""Time series stored with a time axis: 4-D Zarr arrays, OME-Zarr images with ``t``, 4-D NIfTI."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
import zarr

import sparsecast as sc
from sparsecast.errors import FileFormatError, ParameterError
from sparsecast.io.sources import open_source, time_steps

STEPS, SHAPE = 4, (10, 12, 14)


def _series_data(dtype="float32") -> np.ndarray:
    rng = np.random.default_rng(4)
    base = rng.random(SHAPE).astype(np.float32)
    # every step differs: a blob moving along x
    z, y, x = np.meshgrid(*[np.arange(n) for n in SHAPE], indexing="ij")
    out = np.stack([base * 0.2 + np.exp(-((x - 3 - 2 * t) ** 2 + (y - 6) ** 2 + (z - 5) ** 2) / 6.0)
                    for t in range(STEPS)])
    return (out * 200).astype(np.uint8) if dtype == "uint8" else out.astype(dtype)


def _ome_t(path: Path, a: np.ndarray) -> Path:
    from ome_zarr.format import FormatV04

    with warnings.catch_warnings():
        # ome_zarr.writer builds a deprecated Scaler as a default argument on import
        # (as in sparsecast.io.convert); whichever imports it first sees the warning.
        warnings.simplefilter("ignore", DeprecationWarning)
        from ome_zarr.writer import write_multiscales_metadata

    g = zarr.open_group(str(path), mode="w", zarr_format=2)
    g.create_array("0", data=a[:, None], chunks=(1, 1, 8, 8, 8))
    axes = [{"name": "t", "type": "time"}, {"name": "c", "type": "channel"}] + \
        [{"name": n, "type": "space"} for n in "zyx"]
    write_multiscales_metadata(g, [{"path": "0", "coordinateTransformations": [
        {"type": "scale", "scale": [1.0, 1.0, 2.0, 1.5, 0.5]}]}], fmt=FormatV04(), axes=axes)
    return path


def _check_steps(series, a, spacing=None):
    assert len(series) == STEPS
    for t in (0, 2, STEPS - 1):
        vol = series[t]
        np.testing.assert_array_equal(np.asarray(vol.data if not hasattr(vol, "to_dense") else vol.to_dense()), a[t])
        if spacing is not None:
            np.testing.assert_allclose(vol.spacing, spacing, rtol=1e-6)  # NIfTI zooms are float32


def test_a_4d_zarr_array_is_a_series_read_a_step_at_a_time(tmp_path):
    a = _series_data()
    z = zarr.create_array(str(tmp_path / "run.zarr"), data=a, chunks=(1, 8, 8, 8))
    z.attrs["spacing"] = [0.5, 1.0, 2.0]
    assert time_steps(tmp_path / "run.zarr") == STEPS
    series = sc.load_series(tmp_path / "run.zarr")
    _check_steps(series, a)
    src = open_source(tmp_path / "run.zarr", time=3)
    assert src.steps == STEPS and src.shape == SHAPE
    np.testing.assert_array_equal(src.array[2:5, :, 1:3], a[3, 2:5, :, 1:3])
    with pytest.raises(ParameterError, match=r"has 4 time steps \(0\.\.3\); got 4"):
        open_source(tmp_path / "run.zarr", time=4)
    with pytest.raises(FileFormatError, match="expected a 3-D volume"):
        open_source(tmp_path / "run.zarr")  # a 4-D store is not one volume


def test_an_ome_zarr_image_with_a_t_axis_is_a_series_with_its_spacing(tmp_path):
    a = _series_data("uint8")
    store = _ome_t(tmp_path / "cells.zarr", a)
    series = sc.load_series(store)
    _check_steps(series, a, spacing=[0.5, 1.5, 2.0])
    with pytest.raises(ParameterError, match="t of size 4.*load_series"):
        sc.load_volume(store)
    img = sc.render(series[2], sc.TransferFunction.preset("viridis", (0, 255)), sc.Camera.orbit(series[2]), 16, 16)
    ref = sc.render(sc.Volume(a[2], spacing=(0.5, 1.5, 2.0)), sc.TransferFunction.preset("viridis", (0, 255)),
                    sc.Camera.orbit(series[2]), 16, 16)
    assert np.abs(img.rgba - ref.rgba).max() <= 1e-5


def test_a_3d_store_is_not_a_series(tmp_path):
    zarr.create_array(str(tmp_path / "one.zarr"), data=_series_data()[0])
    with pytest.raises(FileFormatError, match=r"expected a 4-D time series"):
        sc.load_series(tmp_path / "one.zarr")


def test_a_4d_nifti_is_a_series_read_a_volume_per_step(tmp_path):
    nib = pytest.importorskip("nibabel")
    a = _series_data("int16")
    affine = np.diag([0.8, 0.9, 1.7, 1.0])
    affine[:3, 3] = (5.0, -2.0, 1.0)
    for name in ("bold.nii", "bold.nii.gz"):
        path = tmp_path / name
        nib.save(nib.Nifti1Image(a.transpose(3, 2, 1, 0).copy(), affine), str(path))  # (x, y, z, t) on disk
        series = sc.load_series(path)
        _check_steps(series, a, spacing=[0.8, 0.9, 1.7])
        np.testing.assert_array_equal(series[1].origin, [5.0, -2.0, 1.0])
        assert series[1].dtype == np.int16
    with pytest.raises(FileFormatError, match="4-D NIfTI"):
        sc.load_volume(tmp_path / "bold.nii")  # one volume only from a 3-D image


def test_cli_renders_a_step_of_a_zarr_series(tmp_path, monkeypatch, capsys):
    from cli_runner import run_cli

    a = _series_data()
    zarr.create_array(str(tmp_path / "run.zarr"), data=a, chunks=(1, 8, 8, 8))
    code, out, err = run_cli(monkeypatch, capsys, "render", str(tmp_path / "run.zarr"), "--time", "2",
                             "--size", "16x16", "--threshold", "0.1",
                             "-o", str(tmp_path / "t2.png"), "--array", str(tmp_path / "t2.npy"))
    assert code == 0, err
    ref = sc.render(sc.Volume(a[2]), sc.TransferFunction.preset("viridis", (float(a.min()), float(a.max())),
                                                                threshold=0.1),
                    sc.Camera.orbit(sc.Volume(a[2]), 30, 20), 16, 16, background="black")
    got = np.load(tmp_path / "t2.npy")
    assert got.shape == (16, 16, 4) and (tmp_path / "t2.png").is_file()
    assert np.abs(got - ref.rgba).max() < 0.05  # the series' TF spans every step: close, not equal
