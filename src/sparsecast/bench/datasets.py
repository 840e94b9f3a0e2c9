"""Benchmark datasets: the generated demo and the real volumes in ``../shared/data``."""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from ..datasets import demo_volume
from ..io import load_volume
from ..transfer import TransferFunction
from ..volume import Volume

__all__ = ["BenchDataset", "DATASETS", "find_shared_data"]


def find_shared_data() -> Path | None:
    """The shared data folder, or None when this checkout has none.

    Looks at ``$SPARSECAST_DATA`` first, then ``../shared/data`` relative to the
    working directory and to the project root (where ``src/`` lives).
    """
    env = os.environ.get("SPARSECAST_DATA")
    candidates = [Path(env)] if env else []
    project_root = Path(__file__).resolve().parents[3]
    for base in (Path.cwd(), project_root):
        candidates += [base / ".." / "shared" / "data", base / "shared" / "data"]
    for c in candidates:
        if c.is_dir():
            return c.resolve()
    return None


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


DATASETS: dict[str, BenchDataset] = {
    d.name: d
    for d in (
        BenchDataset(
            "demo",
            "generated n-body-like Gaussian blobs, 256^3 float32",
            demo_volume,
            lambda v: TransferFunction.preset("viridis", v.value_range),
        ),
        BenchDataset(
            "mni152",
            "MNI152 T1 brain template, 197x233x189 uint8 (shared data)",
            _shared("mni152_t1_197x233x189_uint8.nrrd"),
            # Skin and skull transparent below ~25 %, brain tissue above.
            lambda v: TransferFunction.preset("bone", v.value_range),
            file="mni152_t1_197x233x189_uint8.nrrd",
        ),
    )
}
