"""auto_threshold: the colour-map presets' default transparency threshold, 0.1 unless the
histogram's background peak reaches above it (a CT whose air is not at the bottom of its
range), then just above that peak; bricked volumes agree with dense ones."""

from __future__ import annotations

import numpy as np
import pytest

import sparsecast as sc
from sparsecast.threshold import DEFAULT_THRESHOLD, auto_threshold


def _noisy_scan(rng, background=0.3, shape=(40, 36, 32)):
    """Background noise around ``background`` of the range 0..1, a bright ball at 0.8."""
    a = rng.normal(background, 0.02, shape)
    z, y, x = np.indices(shape)
    ball = (x - 16) ** 2 + (y - 18) ** 2 + (z - 20) ** 2 < 8 ** 2
    a[ball] = rng.normal(0.8, 0.02, int(ball.sum()))
    a[0, 0, 0], a[-1, -1, -1] = 0.0, 1.0
    return np.clip(a, 0.0, 1.0).astype(np.float32), ball


def test_a_background_peak_above_the_default_moves_the_threshold_over_it(rng):
    a, ball = _noisy_scan(rng)
    t = auto_threshold(sc.Volume(a))
    assert np.quantile(a[~ball], 0.98) < t < 0.8 - 0.1  # over the noise, under the ball
    tf = sc.TransferFunction.preset("viridis", (0.0, 1.0), threshold=t)
    assert float(tf(np.quantile(a[~ball], 0.98))[3]) == 0.0
    assert float(tf(0.8)[3]) > 0.0


def test_background_at_the_bottom_keeps_the_default(rng):
    a, _ = _noisy_scan(rng, background=0.02)
    assert auto_threshold(sc.Volume(a)) == DEFAULT_THRESHOLD
    assert auto_threshold(sc.Volume(np.zeros((8, 8, 8), np.uint8))) == DEFAULT_THRESHOLD  # constant


def test_no_background_peak_keeps_the_default(rng):
    flat = rng.random((32, 32, 32)).astype(np.float32)  # a flat histogram: no peak to stand on
    assert auto_threshold(sc.Volume(flat)) == DEFAULT_THRESHOLD
    bright = np.full((16, 16, 16), 250, np.uint8)  # background at the top of the range
    bright[4:8, 4:8, 4:8] = 10
    assert auto_threshold(sc.Volume(bright)) == DEFAULT_THRESHOLD


def test_the_threshold_is_a_fraction_of_the_tf_range(rng):
    a, _ = _noisy_scan(rng)
    vol = sc.Volume(a)
    t_full = auto_threshold(vol)
    t_wide = auto_threshold(vol, (0.0, 2.0))  # the same value, half the fraction
    assert t_wide == pytest.approx(max(DEFAULT_THRESHOLD, t_full / 2), abs=1e-9)


def test_bricked_volumes_agree_with_dense(rng):
    a, _ = _noisy_scan(rng)
    assert auto_threshold(sc.BrickedVolume(a)) == pytest.approx(auto_threshold(sc.Volume(a)), abs=1e-6)


def test_the_shared_tooth_ct_renders_the_tooth_not_its_box(shared_file):
    vol = sc.load_volume(shared_file("tooth_103x94x161_uint8.nrrd"))
    t = auto_threshold(vol)
    lo, hi = vol.value_range
    shown = np.asarray(vol.data) > lo + t * (hi - lo)
    assert 0.3 < t < 0.6 and 0.1 < shown.mean() < 0.5  # 0.1 shows every voxel (the background at 30 %)
    aneurism = sc.load_volume(shared_file("aneurism_256x256x256_uint8.nrrd"))
    assert auto_threshold(aneurism) == DEFAULT_THRESHOLD  # air at the bottom: the default stays


def test_a_volume_without_a_histogram_gets_the_default():
    class Bare:
        value_range = (0.0, 1.0)

    assert auto_threshold(Bare()) == DEFAULT_THRESHOLD
