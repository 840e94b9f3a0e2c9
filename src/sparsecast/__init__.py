"""sparsecast: fast ray casting of sparse data.

>>> import sparsecast as sc
>>> vol = sc.datasets.nbody_blobs(64)
>>> tf = sc.TransferFunction.preset("viridis", value_range=vol.value_range)
>>> cam = sc.Camera.orbit(vol, azimuth=30, elevation=20)
>>> img = sc.render(vol, tf, cam, width=64, height=64)
>>> img.rgba.shape
(64, 64, 4)
"""

from . import kernel_cache

kernel_cache.configure()  # before any kernel module is imported (see kernel_cache)

from .kernels.parallel import configure_wait_policy  # noqa: E402

configure_wait_policy()  # before the OpenMP runtime loads (see kernels.parallel)

from . import datasets  # noqa: E402
from .camera import Camera
from .elements import ParticleSet
from .errors import (
    DistributedError,
    FileFormatError,
    ParameterError,
    SparsecastError,
    TransferFunctionError,
    VolumeDataError,
)
from .index import SpatialIndex, available_indices, build_index
from .io import load_series, load_volume, save_volume
from .series import VolumeSeries
from .storage import BrickedVolume, MemoryBudgetError
from .distributed import ClusterVolume
from .image import Image
from .render import render
from .io.particles import load_particles
from .render.particles import render_particles
from .transfer import PRESETS, LabelTransferFunction, TransferFunction
from .threshold import auto_threshold
from .volume import BrickStats, Volume
from .warmup import compile_kernels

__version__ = "0.1.0"


def show(volume, tf=None, **kwargs):
    """Interactive viewer for Jupyter (see :func:`sparsecast.viewer.show`); needs
    ``pip install "sparsecast[view]"``. Imported lazily: ``import sparsecast`` does not
    load the web stack."""
    from .viewer import show as _show

    return _show(volume, tf, **kwargs)


__all__ = [
    "BrickStats",
    "BrickedVolume",
    "MemoryBudgetError",
    "Camera",
    "ClusterVolume",
    "DistributedError",
    "FileFormatError",
    "Image",
    "PRESETS",
    "ParticleSet",
    "ParameterError",
    "SparsecastError",
    "SpatialIndex",
    "TransferFunction",
    "LabelTransferFunction",
    "TransferFunctionError",
    "Volume",
    "VolumeDataError",
    "auto_threshold",
    "available_indices",
    "build_index",
    "compile_kernels",
    "datasets",
    "load_particles",
    "load_volume",
    "load_series",
    "VolumeSeries",
    "render",
    "render_particles",
    "save_volume",
    "show",
    "__version__",
]
