"""The benchmark's catalogue of named volumes (:data:`DATASETS`), each with the TF it is
measured with (and :func:`dense_tf`, the TF with no empty space that every dataset is
also measured with): generated fields from :mod:`sparsecast.datasets` (the demo at three
sizes, the synthetic cluster sweeps of Fig. 5) and real files from the shared data
folder (:func:`~.shared_data.find_shared_data`), which are skipped where it is absent.

:mod:`sparsecast.datasets` makes volumes; this module only names them for
``sparsecast bench -d NAME`` and says how each is loaded and classified.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from ..datasets import demo_volume, nbody_blobs, random_clusters
from ..io import load_volume
from ..transfer import TransferFunction
from ..volume import Volume
from .shared_data import find_shared_data

__all__ = ["BenchDataset", "DATASETS", "dense_tf"]


@dataclass(frozen=True)
class BenchDataset:
    """A named volume with the transfer function it is benchmarked with."""

    name: str
    description: str
    load: Callable[[], Volume]
    make_tf: Callable[[Volume], TransferFunction]
    file: str | None = None  # file name under the shared data folder, if any
    default: bool = True  # run by a plain `sparsecast bench`; False: only when named

    def available(self) -> bool:
        if self.file is None:
            return True
        root = find_shared_data()
        return root is not None and (root / self.file).is_file()


def _shared(file: str) -> Callable[[], Volume]:
    def load() -> Volume:
        root = find_shared_data()
        if root is None:
            raise FileNotFoundError("no shared data folder (set SPARSECAST_DATA)")
        return load_volume(root / file)

    return load


# The other volumes of the shared data folder (its MANIFEST.md): name, file, what, and
# the colour-map threshold (fraction of the range below which the TF is transparent)
# that leaves air, noise and background empty. Opt-in for a plain `sparsecast bench`
# (the quick suite stays short); the paper suite takes every shared file.
_SHARED_VOLUMES = (
    ("bonsai", "bonsai_256x256x256_uint8.nrrd", "CT of a bonsai tree, 256^3 uint8", 0.2),
    ("aneurism", "aneurism_256x256x256_uint8.nrrd", "rotational angiography of an aneurism, 256^3 uint8", 0.2),
    ("tooth", "tooth_103x94x161_uint8.nrrd", "CT of a tooth, 103x94x161 uint8 (noisy background)", 0.4),
    ("neghip", "neghip_64x64x64_uint8.nrrd", "negative-potential field of a protein, 64^3 uint8", 0.2),
    ("avm-cta", "avm_cta_337x319x154_uint8.nrrd", "CT angiography, 337x319x154 uint8, anisotropic", 0.3),
    ("chest-ct", "lidc2_chest_ct_256x256x133_uint8.nrrd", "chest CT (LIDC), 256x256x133 uint8", 0.3),
    ("headsq", "headsq_ct_64x64x93_uint16.nrrd", "12-bit head CT in uint16, 64x64x93", 0.3),
    ("density-1jzv", "density_1jzv_76x96x70_float32.nrrd", "electron density map, 76x96x70 float32", 0.3),
)


def _shared_volume(name: str, file: str, what: str, threshold: float) -> BenchDataset:
    return BenchDataset(
        name, f"{what} (shared data)", _shared(file),
        lambda v, t=threshold: TransferFunction.preset("viridis", v.value_range, threshold=t),
        file=file, default=False,
    )


DATASETS: dict[str, BenchDataset] = {
    d.name: d
    for d in (
        BenchDataset(
            "demo",
            "generated n-body-like Gaussian blobs, 256^3 float32",
            demo_volume,
            lambda v: TransferFunction.preset("viridis", v.value_range),
        ),
        # Scale study (issue 5, the LBVH paper's Fig. 4): the demo field at other
        # sizes, same TF; opt-in (`sparsecast bench -d demo-128 -d demo-512`).
        BenchDataset(
            "demo-128",
            "the demo's n-body-like Gaussian blobs at 128^3 float32 (scale study)",
            lambda: nbody_blobs(128),
            lambda v: TransferFunction.preset("viridis", v.value_range),
            default=False,
        ),
        BenchDataset(
            "demo-512",
            "the demo's n-body-like Gaussian blobs at 512^3 float32 (scale study, 512 MiB)",
            lambda: nbody_blobs(512),
            lambda v: TransferFunction.preset("viridis", v.value_range),
            default=False,
        ),
        BenchDataset(
            "mni152",
            "MNI152 T1 brain template, 197x233x189 uint8 (shared data)",
            _shared("mni152_t1_197x233x189_uint8.nrrd"),
            # Skin and skull transparent below ~25 %, brain tissue above.
            lambda v: TransferFunction.preset("bone", v.value_range),
            file="mni152_t1_197x233x189_uint8.nrrd",
        ),
        *(_shared_volume(*row) for row in _SHARED_VOLUMES),
    )
}


# -- issue 4: the synthetic sweeps of Zellmann et al. 2018, Fig. 5 (opt-in) -----------
def _cluster_tf(v: Volume) -> TransferFunction:
    return TransferFunction.preset("viridis", (0.0, 1.0), threshold=0.1)


def _fig5_datasets() -> list[BenchDataset]:
    out = []
    for n in (256, 512):
        for frac in (0.03, 0.06, 0.12, 0.2, 0.3):  # (a) three clusters growing in size
            r = frac * n
            out.append(BenchDataset(
                f"fig5a-{n}-r{int(round(frac * 100)):02d}",
                f"three random-voxel balls of radius {r:.0f} in {n}^3 (Fig. 5a sweep)",
                lambda n=n, r=r: random_clusters(n, 3, r),
                _cluster_tf, default=False,
            ))
        for k in (1, 8, 64, 512, 4096):  # (b) more and more fixed-size clusters
            out.append(BenchDataset(
                f"fig5b-{n}-k{k:04d}",
                f"{k} random-voxel balls of radius {n / 32:.0f} in {n}^3 (Fig. 5b sweep)",
                lambda n=n, k=k: random_clusters(n, k, n / 32),
                _cluster_tf, default=False,
            ))
    return out


DATASETS.update({d.name: d for d in _fig5_datasets()})


def dense_tf(vol: Volume) -> TransferFunction:
    """A TF with non-zero opacity for every value: no empty space at all."""
    lo, hi = vol.value_range
    if hi <= lo:
        hi = lo + 1.0
    return TransferFunction([(lo, 0.2, 0.3, 0.8, 0.004), (hi, 1.0, 0.9, 0.6, 0.2)], (lo, hi), name="dense")
