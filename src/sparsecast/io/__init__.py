"""File input and output: volumes, meshes and point clouds, particles.

Volumes: :func:`load_volume` / :func:`save_volume` (:mod:`.volumes`) dispatch through
the suffix table of :mod:`.formats` to one module per format (:mod:`.nrrd`,
:mod:`.nifti`, :mod:`.raw`, :mod:`.npy`, :mod:`.tiff`).
"""

from .series import load_series
from .volumes import load_volume, parse_raw_name, save_volume

__all__ = ["load_volume", "save_volume", "parse_raw_name", "load_series"]
