"""The worker's side: a piece of a volume, loaded once and rendered every frame.

A piece is a :class:`~sparsecast.storage.BrickedVolume` over the **whole** volume's
shape whose stored bricks are only the piece's: the bricks outside it are absent (their
statistics say background), so nothing outside is ever read, and every sample, page
table lookup and gradient is computed in the global index space with the same floats
as one process. Each stored brick carries its one-voxel apron (the ghost voxels a
trilinear sample and a central-difference gradient at the cut faces read), taken from
the real data. The frame's clip box (the piece's box, half open at shared faces)
keeps every sample on the global lattice in exactly one piece.

The voxels come from the source itself where the volume was opened from a file
(:class:`~sparsecast.io.sources.SourceRecipe`: the worker opens it and reads only its
bricks), else from the piece's window of the client's array, shipped once.
"""

from __future__ import annotations

import hashlib
import pickle
import time
from collections import OrderedDict
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import ParameterError
from ..index import build_index
from ..render.local import render_local
from ..render.schedule import limit_threads
from ..storage import BrickedVolume
from ..volume import BrickStats
from .composite import Layer

#: TFs (with their indices) a piece keeps
TF_CACHE = 4

__all__ = ["PieceSpec", "Window", "Piece", "load_piece", "render_piece", "render_piece_after", "tf_key"]


class Window:
    """An array-like of the volume's full shape that holds voxels only inside a window:
    the piece's part of an in-memory volume. Reads outside the window are refused (the
    piece's bricks never make one)."""

    def __init__(self, block: np.ndarray, offset: tuple[int, int, int], shape: tuple[int, int, int]) -> None:
        self.block = block
        self.offset = tuple(int(o) for o in offset)  # (z, y, x) of block[0, 0, 0]
        self.shape = tuple(int(n) for n in shape)
        self.dtype = block.dtype
        self.ndim = 3

    def __getitem__(self, key) -> np.ndarray:
        if not (isinstance(key, tuple) and len(key) == 3 and all(isinstance(k, slice) for k in key)):
            raise TypeError("Window reads (z0:z1, y0:y1, x0:x1) blocks only")
        out = []
        for k, o, n, m in zip(key, self.offset, self.shape, self.block.shape):
            a, b, step = k.indices(n)
            if step != 1 or a < o or b > o + m:
                raise IndexError(f"voxels {a}:{b} are outside this piece's window {o}:{o + m}")
            out.append(slice(a - o, b - o))
        return self.block[tuple(out)]


@dataclass(frozen=True)
class PieceSpec:
    """Everything a worker needs to load piece ``number`` (small but for ``window``).

    ``box`` is the piece's brick box ``((bx0, by0, bz0), (bx1, by1, bz1))``, half open;
    ``vmin``/``vmax`` the brick statistics of that box (``(bz, by, bx)`` order); the
    voxels come from ``recipe`` (a :class:`SourceRecipe`, the worker opens the file) or
    ``window`` (a :class:`Window`).
    """

    number: int
    box: tuple
    shape: tuple[int, int, int]
    spacing: tuple[float, float, float]
    origin: tuple[float, float, float]
    name: str
    brick_size: int
    background: float
    nonfinite: str
    value_range: tuple[float, float]
    vmin: np.ndarray
    vmax: np.ndarray
    recipe: Any = None
    window: Window | None = None


class Piece:
    """A loaded piece: its bricked volume and the index of the last TF it rendered."""

    def __init__(self, spec: PieceSpec, volume: BrickedVolume, load_ms: float, bytes_read: int) -> None:
        self.spec = spec
        self.volume = volume
        self.load_ms = load_ms
        self.bytes_read = bytes_read
        # The TFs of the last few frames with their indices: a viewer toggling between a
        # few TFs (or a label shown and hidden) rebuilds nothing.
        self._tfs: OrderedDict[str, tuple] = OrderedDict()

    def __sizeof__(self) -> int:
        # What Dask's scheduler weighs a transfer by: a piece is its bricks, so the
        # render tasks go where it is instead of moving it.
        return int(self.volume.nbytes) + 1024

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        state["_tfs"] = OrderedDict()  # indices are rebuilt where a moved piece lands
        return state

    def tf_for(self, key: str, tf):
        """The TF object to render with: the one kept from an earlier frame when ``key``
        matches (its indices stay valid), else ``tf``, kept from now on."""
        if key not in self._tfs:
            self._tfs[key] = (tf, {})
            while len(self._tfs) > TF_CACHE:
                self._tfs.popitem(last=False)
        self._tfs.move_to_end(key)
        return self._tfs[key][0]

    def index_for(self, key: str, name: str, options: dict):
        """Index ``name`` for the TF of ``key`` (built once per TF: a new TF builds here)."""
        tf, indices = self._tfs[key]
        k = (name, tuple(sorted(options.items())))
        if k not in indices:
            indices[k] = build_index(self.volume, tf, name, **options)
            return indices[k], True
        return indices[k], False


def tf_key(tf) -> str:
    """A fingerprint of a TF that survives pickling: equal for equal TFs."""
    return hashlib.sha1(pickle.dumps(tf, protocol=4)).hexdigest()


def load_piece(spec: PieceSpec) -> Piece:
    """Open (or take) the piece's voxels and load every stored brick of it."""
    t0 = time.perf_counter()
    B = spec.brick_size
    grid = tuple(max(1, -(-(n - 1) // B)) for n in spec.shape)
    vmin = np.full(grid, spec.background, np.float64)
    vmax = np.full(grid, spec.background, np.float64)
    (x0, y0, z0), (x1, y1, z1) = spec.box
    vmin[z0:z1, y0:y1, x0:x1] = spec.vmin
    vmax[z0:z1, y0:y1, x0:x1] = spec.vmax
    if spec.recipe is not None:
        array = spec.recipe.open().array
    elif spec.window is not None:
        array = spec.window
    else:
        raise ParameterError(f"piece {spec.number}: neither a source recipe nor a window of voxels")
    vol = BrickedVolume(array, spec.spacing, spec.origin, name=f"{spec.name} [piece {spec.number}]",
                        brick_size=B, background=spec.background, stats=BrickStats(B, vmin, vmax, 0.0),
                        nonfinite=spec.nonfinite, eager=True, value_range=spec.value_range)
    return Piece(spec, vol, (time.perf_counter() - t0) * 1e3, int(vol.loads["bytes_read"]))


def _threads() -> str:
    """Render with as many threads as the worker runs tasks; the worker's address."""
    try:
        from distributed import get_worker

        worker = get_worker()
    except (ImportError, ValueError, AttributeError):
        return "here"  # not on a worker (a test calling the function directly)
    limit_threads(worker.state.nthreads)
    return worker.address


def render_piece(piece: Piece, job: dict, crop: bool = True) -> Layer:
    """Render the piece's screen rectangle for one frame (``job``: see
    :meth:`~.cluster.ClusterVolume.render`); a :class:`Layer` over transparent black."""
    t0 = time.perf_counter()
    worker = _threads()
    tf = piece.tf_for(job["tf_key"], job["tf"])
    index, built = piece.index_for(job["tf_key"], job["index"], job["index_options"])
    x0, y0, w, h = job["rect"]
    img = render_local(piece.volume, tf, job["camera"], job["width"], job["height"], index=index,
                       background="transparent", rect=(x0, y0, w, h), initial=job.get("initial"),
                       clip_box=job["clip_box"], clip_open=job["clip_open"], **job["frame"])
    stats = dict(piece=piece.spec.number, ms=img.stats["ms"], jit_ms=img.stats["jit_ms"],
                 build_ms=index.build_ms if built else 0.0, index=index.name, samples=img.stats["samples"],
                 samples_nonempty=img.stats["samples_nonempty"], rays=w * h, worker=worker,
                 wall_ms=(time.perf_counter() - t0) * 1e3)
    rgba, samples, dx, dy = img.rgba, img.samples, 0, 0
    if crop and job.get("initial") is None:
        # Pixels that took no sample are transparent black: send only the box of the others.
        rows = np.flatnonzero(samples.any(axis=1))
        cols = np.flatnonzero(samples.any(axis=0))
        if rows.size == 0:
            rgba, samples = rgba[:0, :0], samples[:0, :0]
        else:
            dy, dx = int(rows[0]), int(cols[0])
            rgba = rgba[dy:rows[-1] + 1, dx:cols[-1] + 1]
            samples = samples[dy:rows[-1] + 1, dx:cols[-1] + 1]
    return Layer(x0 - job["frame_x0"] + dx, y0 - job["frame_y0"] + dy, np.ascontiguousarray(rgba),
                 np.ascontiguousarray(samples), [stats])


def render_piece_after(piece: Piece, job: dict, front: Layer) -> Layer:
    """Cross-piece termination: continue the rays of ``front`` (everything in front of
    this piece, over the whole frame) through this piece; the whole frame again."""
    fx, fy = job["rect"][0] - job["frame_x0"], job["rect"][1] - job["frame_y0"]
    w, h = job["rect"][2], job["rect"][3]
    mine = render_piece(piece, {**job, "initial": front.rgba[fy:fy + h, fx:fx + w]}, crop=False)
    rgba = front.rgba.copy()
    samples = front.samples.copy()
    rgba[fy:fy + h, fx:fx + w] = mine.rgba
    samples[fy:fy + h, fx:fx + w] += mine.samples
    return Layer(front.x0, front.y0, rgba, samples, front.stats + mine.stats, front.composite_ms,
                 front.moved + front.nbytes)
