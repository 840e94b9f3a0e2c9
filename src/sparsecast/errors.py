"""One exception family for bad input.

Every error raised at the library's boundary is a subclass of :class:`ValueError`
so callers can catch the whole family with ``except ValueError`` or, more
precisely, ``except SparsecastError``. Messages name the file or parameter, what
was found and what was expected; the CLI prints them as a single line.
"""

from __future__ import annotations

__all__ = [
    "SparsecastError",
    "ParameterError",
    "VolumeDataError",
    "FileFormatError",
    "TransferFunctionError",
    "DistributedError",
]


class SparsecastError(ValueError):
    """Base class of every input error sparsecast raises on purpose."""


class ParameterError(SparsecastError):
    """A function or CLI parameter is out of range or of the wrong kind."""


class VolumeDataError(SparsecastError):
    """Voxel data is unusable: wrong shape, unsupported dtype, empty, NaN/Inf."""


class FileFormatError(SparsecastError):
    """A file is missing, truncated, corrupt or not what its name says."""


class TransferFunctionError(SparsecastError):
    """A transfer function definition or preset is invalid."""


class DistributedError(SparsecastError):
    """A cluster render failed: no scheduler, no workers, a frame past its timeout."""
