"""The one table from file suffix to volume reader and writer: :data:`FORMATS`.

Supported suffixes
------------------
============== ====== ====== ==========================================================
suffix         read   write  notes
============== ====== ====== ==========================================================
``.nrrd``      yes    yes    raw / gzip / bzip2 encodings; spacing from ``space
                             directions`` (vector norms) or ``spacings``
``.nhdr``      yes    no     detached header, data file resolved relative to it (and
                             refused outside its folder unless ``allow_outside``)
``.nii``       yes    yes    on-disk dtype kept; ``scl_slope``/``scl_inter`` applied
``.nii.gz``    yes    yes    when set and non-trivial
``.raw``       yes    yes    dims/dtype explicit or from ``name_XxYxZ_dtype.raw``
``.bin``       yes    no     same as ``.raw``
``.dat``       yes    no     same as ``.raw``
``.npy``       yes    yes    ``allow_pickle=False``
``.tif(f)``    yes    yes    multi-page stack or 3-D array; a directory of 2-D slices
                             (sorted by name) is read as a stack too
============== ====== ====== ==========================================================

A directory is read as a stack of 2-D TIFF slices (:func:`~.tiff.read_tiff_dir`); it
has no suffix, so it is not in the table.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from ..volume import Volume
from . import nifti, npy, nrrd, raw, tiff

__all__ = ["VolumeFormat", "FORMATS", "READ_SUFFIXES", "WRITE_SUFFIXES"]


@dataclass(frozen=True)
class VolumeFormat:
    """How one file suffix is read and written.

    Attributes
    ----------
    read : callable
        ``read(path) -> (array, spacing or None, origin or None)``; with ``raw_layout``,
        ``read(path, dims, dtype, byte_order, header_offset)``.
    write : callable or None
        ``write(volume, tmp_path, compress)``, or None where the suffix is read only.
    raw_layout : bool
        The file has no header: the reader takes the layout options of
        :func:`~.volumes.load_volume` (every other reader refuses them).
    check_target : callable or None
        ``check_target(volume, path)`` before anything is written (a raw name that
        contradicts the volume).
    data_file : bool
        The header may name a separate data file: the reader takes ``allow_outside=``
        (see :func:`~.nrrd.read_nrrd`).
    """

    read: Callable
    write: Callable[[Volume, Path, bool], None] | None = None
    raw_layout: bool = False
    check_target: Callable[[Volume, Path], None] | None = None
    data_file: bool = False


_NRRD = VolumeFormat(nrrd.read_nrrd, nrrd.write_nrrd, data_file=True)
_NIFTI = VolumeFormat(nifti.read_nifti, nifti.write_nifti)
_TIFF = VolumeFormat(tiff.read_tiff, tiff.write_tiff)

#: suffix (lower case, ``.nii.gz`` as one) -> format, in the order messages list them
FORMATS: dict[str, VolumeFormat] = {
    ".nrrd": _NRRD,
    ".nhdr": VolumeFormat(nrrd.read_nrrd, data_file=True),  # detached header: the data file is beside it
    ".nii": _NIFTI,
    ".nii.gz": _NIFTI,
    ".raw": VolumeFormat(raw.read_raw, raw.write_raw, raw_layout=True, check_target=raw.check_raw_name),
    ".bin": VolumeFormat(raw.read_raw, raw_layout=True),
    ".dat": VolumeFormat(raw.read_raw, raw_layout=True),
    ".npy": VolumeFormat(npy.read_npy, npy.write_npy),
    ".tif": _TIFF,
    ".tiff": _TIFF,
}

#: Suffixes :func:`~.volumes.load_volume` understands (besides a directory of TIFF slices).
READ_SUFFIXES: tuple[str, ...] = tuple(FORMATS)
#: Suffixes :func:`~.volumes.save_volume` can write.
WRITE_SUFFIXES: tuple[str, ...] = tuple(s for s, f in FORMATS.items() if f.write is not None)
