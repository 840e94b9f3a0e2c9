"""Bad loader options fail as one ParameterError naming the option, before any file is read."""

from __future__ import annotations

import numpy as np
import pytest

import sparsecast as sc
from sparsecast.errors import ParameterError
from sparsecast.io.meshes import load_points


def test_bad_options_name_themselves(tmp_path):
    raw = tmp_path / "v_4x3x2_uint8.raw"
    raw.write_bytes(bytes(24))
    with pytest.raises(ParameterError, match="^header_offset: expected an integer >= 0, got 'x'$"):
        sc.load_volume(raw, header_offset="x")
    with pytest.raises(ParameterError, match="^radius: expected a positive number, got -1$"):
        load_points(tmp_path / "missing.npy", radius=-1)
    with pytest.raises(ParameterError, match="^radius: expected a positive number, got 0$"):
        sc.load_particles(tmp_path / "missing.csv", radius=0)


def test_volume_rejects_an_unknown_nonfinite_policy_even_for_finite_data():
    with pytest.raises(ParameterError, match="nonfinite: expected 'raise' or 'replace', got 'ignore'"):
        sc.Volume(np.zeros((2, 2, 2), np.uint8), nonfinite="ignore")
