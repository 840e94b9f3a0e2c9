"""File input and output: volumes, meshes and point clouds, particles.

Volumes: :func:`load_volume` / :func:`save_volume` (:mod:`.volumes`) dispatch through
the suffix table of :mod:`.formats` to one module per format (:mod:`.nrrd`,
:mod:`.nifti`, :mod:`.raw`, :mod:`.npy`, :mod:`.tiff`).

Volumes larger than memory: :func:`open_source` (:mod:`.sources`) opens Zarr, OME-Zarr,
HDF5, ``.npy``, raw and raw NRRD lazily; :func:`convert_volume` (:mod:`.convert`) writes
any readable volume as chunked Zarr or an OME-Zarr pyramid.
"""

from .convert import convert_volume
from .series import load_series
from .sources import Source, open_source
from .volumes import load_volume, parse_raw_name, save_volume

__all__ = ["load_volume", "save_volume", "parse_raw_name", "load_series", "open_source", "Source", "convert_volume"]
