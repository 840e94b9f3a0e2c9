"""The client's side: a volume cut into pieces that live on a Dask cluster.

:class:`ClusterVolume` decomposes the volume (:mod:`.decompose`), asks each worker to
load its pieces once (:func:`.piece.load_piece`; the futures are held, so the pieces
stay resident across frames), and renders a frame as a task graph: one
:func:`.piece.render_piece` per piece a pixel can see, then a tree of
:func:`.composite.over` tasks in the visibility order of the camera, whose two top
layers are gathered and composited here (one hop fewer than a root task). A TF change
sends only the TF; the pieces rebuild their own indices.

Faults are Dask's to handle: a worker lost mid-frame takes its pieces' data with it,
and the scheduler recomputes the load tasks (their arguments, a source recipe or the
piece's window, are in the graph) and the frame's tasks elsewhere. A frame that does
not complete in ``timeout`` is an error; its tasks are cancelled and the pieces stay.
"""

from __future__ import annotations

import pickle
import time
import uuid
import warnings
import weakref
from typing import Any

import numpy as np

from ..camera import Camera
from ..errors import DistributedError, ParameterError
from ..image import Image
from ..render.options import background_array, check_size, initial_rgba, rect_bounds, world_clip
from ..storage import BrickedVolume
from ..transfer import TransferFunction
from ..volume import Volume
from .composite import Layer, over
from .decompose import PieceTree, decompose
from .piece import PieceSpec, Window, load_piece, render_piece, render_piece_after, tf_key
from .screen import screen_rect

__all__ = ["ClusterVolume", "render_on_cluster", "connect", "DEFAULT_TIMEOUT"]

#: seconds a frame may take unless ``timeout=`` says otherwise
DEFAULT_TIMEOUT = 300.0

#: parameters of render() that each piece takes as they are
_FRAME_KEYS = ("dt", "ert", "shading", "clip_planes", "max_samples")

_CACHE: "weakref.WeakKeyDictionary[Volume, dict]" = weakref.WeakKeyDictionary()


def connect(address: str, timeout: float = 10.0):
    """A :class:`dask.distributed.Client` for the scheduler at ``address``
    (``tcp://host:8786``); one :class:`DistributedError` naming it when it cannot be reached."""
    from distributed import Client

    if not isinstance(address, str) or not address.strip():
        raise ParameterError(f"scheduler: expected an address such as tcp://host:8786, got {address!r}")
    try:
        return Client(address, timeout=timeout)
    except (OSError, TimeoutError, ValueError) as exc:
        raise DistributedError(
            f"scheduler: cannot reach the Dask scheduler at {address!r} within {timeout:g} s: "
            f"{type(exc).__name__}: {exc}"
        ) from None


def _check_client(client):
    try:
        from distributed import Client
    except ImportError as exc:  # a dependency; say so rather than fail obscurely
        raise DistributedError(f"client: dask.distributed is not installed ({exc})") from None
    if not isinstance(client, Client):
        raise ParameterError(f"client: expected a dask.distributed.Client, got {type(client).__name__}")
    if client.status not in ("running", "connecting"):
        raise DistributedError(f"client: this Dask client is {client.status}; connect a new one")
    return client


class ClusterVolume:
    """A volume whose pieces are resident on the workers of a Dask cluster.

    Parameters
    ----------
    volume : Volume
        Dense or bricked. A volume opened from a file (``source_recipe`` set by
        :func:`~sparsecast.io.load_volume`: Zarr, OME-Zarr, HDF5, ``.npy``, raw) is
        read by each worker from the file itself, which must be readable there;
        any other volume ships each piece's voxels (with their ghost voxels) once.
    client : dask.distributed.Client
    pieces : int, optional
        Pieces to cut (default: one per worker thread of the cluster).

    Attributes
    ----------
    tree : PieceTree
        The decomposition (brick boxes, non-empty bricks per piece, the k-d tree).
    futures : list of Future
        One per piece: the loaded piece on its worker.
    """

    def __init__(self, volume: Volume, client, pieces: int | None = None) -> None:
        if not isinstance(volume, Volume):
            raise ParameterError(f"volume: expected a sparsecast.Volume, got {type(volume).__name__}")
        volume.require_renderable()
        self.client = _check_client(client)
        # The geometry only: the cache in render_on_cluster is keyed weakly on the volume,
        # which a reference from here would keep alive for ever.
        self.shape = tuple(volume.shape)
        self.spacing = np.array(volume.spacing, np.float64)
        self.origin = np.array(volume.origin, np.float64)
        threads = self.client.nthreads()
        if not threads:
            raise DistributedError(f"client: the cluster at {self.client.scheduler.address} has no workers")
        n = sum(threads.values()) if pieces is None else pieces
        bricked = isinstance(volume, BrickedVolume)
        B = volume.brick_size if bricked else 8
        background = float(volume.background) if bricked else 0.0
        stats = volume.brick_stats(B)
        occupied = ~((stats.vmin == background) & (stats.vmax == background))
        self.tree: PieceTree = decompose(occupied, n, B)
        recipe = volume.source_recipe
        # Voxels to ship when the workers cannot open the file themselves: windows of the
        # dense array, or read from a bricked volume one window at a time.
        read = None
        if recipe is None:
            read = volume.read_window if bricked else (
                lambda z0, z1, y0, y1, x0, x1: volume.data[z0:z1, y0:y1, x0:x1])
        nz, ny, nx = volume.shape
        self._token = uuid.uuid4().hex[:12]
        workers = _assign(self.tree.weights, threads)
        self.futures = []
        self.piece_workers = workers
        for p in range(self.tree.count):
            (bx0, by0, bz0), (bx1, by1, bz1) = (tuple(int(v) for v in r) for r in self.tree.boxes[p])
            window = None
            if read is not None:
                # the piece's cells and the one-voxel apron of its bricks: its ghost voxels
                lo = [max(b * B - 1, 0) for b in (bz0, by0, bx0)]
                hi = [min(b * B + 1, m - 1) + 1 for b, m in ((bz1, nz), (by1, ny), (bx1, nx))]
                block = np.ascontiguousarray(read(lo[0], hi[0], lo[1], hi[1], lo[2], hi[2]))
                window = Window(block, tuple(lo), volume.shape)
            spec = PieceSpec(
                number=p, box=((bx0, by0, bz0), (bx1, by1, bz1)), shape=volume.shape,
                spacing=tuple(float(s) for s in volume.spacing), origin=tuple(float(o) for o in volume.origin),
                name=volume.name, brick_size=B, background=background,
                # shipped voxels were checked (or replaced) here already
                nonfinite="replace" if read is not None else getattr(volume, "nonfinite", "raise"),
                value_range=tuple(float(v) for v in volume.value_range),
                vmin=np.ascontiguousarray(stats.vmin[bz0:bz1, by0:by1, bx0:bx1]),
                vmax=np.ascontiguousarray(stats.vmax[bz0:bz1, by0:by1, bx0:bx1]),
                recipe=recipe, window=window,
            )
            with warnings.catch_warnings():
                # The window rides in the graph on purpose: a lost worker's piece is
                # reloaded from it elsewhere (scattered data would be lost with it).
                warnings.filterwarnings("ignore", message=".*[Ll]arge object.*")
                self.futures.append(self.client.submit(
                    load_piece, spec, key=f"sparsecast-piece-{self._token}-{p}", workers=[workers[p]],
                    allow_other_workers=True, pure=False))

    def close(self) -> None:
        """Release the pieces on the workers."""
        self.client.cancel(self.futures)
        self.futures = []

    # -- one frame ---------------------------------------------------------
    def render(self, tf: TransferFunction, camera: Camera, width: int = 512, height: int = 512, *,
               index: str = "auto", background="transparent", clip_box=None, clip_open=None,
               clip_cap: bool = False, initial=None, rect=None, mode: str = "dvr", iso=None, iso_colors=None,
               cross_termination: bool = False, timeout: float | None = None, **frame: Any) -> Image:
        """Render one frame on the cluster; the arguments are :func:`~sparsecast.render`'s."""
        t_start = time.perf_counter()
        if not self.futures:
            raise DistributedError("this ClusterVolume is closed")
        if not isinstance(tf, TransferFunction):
            raise ParameterError(f"tf: expected a sparsecast.TransferFunction, got {type(tf).__name__}")
        if not isinstance(camera, Camera):
            raise ParameterError(f"camera: expected a sparsecast.Camera, got {type(camera).__name__}")
        if mode != "dvr" or iso is not None or iso_colors is not None:
            raise ParameterError(
                f"mode: {mode!r} with client= is not supported: an isosurface crossing between the last "
                "sample of one piece and the first of the next belongs to neither; render iso modes in one process")
        if clip_cap:
            raise ParameterError("clip_cap: not supported with client= (the pieces' own faces are not cut faces)")
        if not isinstance(index, str):
            raise ParameterError(
                f"index: with client= pass an index name (each piece builds its own), got {type(index).__name__}")
        width, height = check_size(width, height)
        fx0, fy0, fw, fh = rect_bounds(rect, width, height)
        init = initial_rgba(initial, fw, fh)
        bg = background_array(background)
        if timeout is None:
            timeout = DEFAULT_TIMEOUT
        if isinstance(timeout, bool) or not isinstance(timeout, (int, float)) or not timeout > 0:
            raise ParameterError(f"timeout: expected seconds > 0, got {timeout!r}")
        known = {k: frame.pop(k) for k in list(frame) if k in _FRAME_KEYS}
        if known.get("dt") is None:
            known["dt"] = 0.5 * float(self.spacing.min())  # every piece on the same lattice
        user = _user_clip(clip_box, clip_open)
        key = tf_key(tf)
        base = dict(tf=tf, tf_key=key, camera=camera, width=width, height=height, index=index,
                    index_options=frame, frame=known, frame_x0=fx0, frame_y0=fy0)
        job_bytes = len(pickle.dumps(base, protocol=5))
        jobs: dict[int, dict] = {}
        for p in range(self.tree.count):
            box = self._clip_of(p, user)
            if box is None:
                continue
            (wlo, whi), (open_lo, open_hi), (slo, shi) = box
            r = screen_rect(camera, width, height, slo, shi)
            if r is None:
                continue
            x0, y0 = max(r[0], fx0), max(r[1], fy0)
            x1, y1 = min(r[0] + r[2], fx0 + fw), min(r[1] + r[3], fy0 + fh)
            if x0 >= x1 or y0 >= y1:
                continue
            jobs[p] = dict(base, rect=(x0, y0, x1 - x0, y1 - y0), clip_box=(tuple(wlo), tuple(whi)),
                           clip_open=(tuple(open_lo), tuple(open_hi)))
        near_low = self._near_low(camera)
        frame_futures: list = []
        t_submit = time.perf_counter()
        if cross_termination:
            front = Layer(0, 0, init.copy() if init.shape[0] else np.zeros((fh, fw, 4), np.float32),
                          np.zeros((fh, fw), np.int32))
            result = front
            for p in self.tree.order(near_low):
                if p in jobs:
                    result = self.client.submit(render_piece_after, self.futures[p], jobs[p], result,
                                                workers=[self.piece_workers[p]], allow_other_workers=True,
                                                pure=False)
                    frame_futures.append(result)
            final = result
        else:
            # Pinned softly to the piece's worker: it goes elsewhere only if that one is lost.
            leaves = {p: self.client.submit(render_piece, self.futures[p], jobs[p], workers=[self.piece_workers[p]],
                                            allow_other_workers=True, pure=False) for p in jobs}
            frame_futures.extend(leaves.values())

            def reduce(node):
                if isinstance(node, (int, np.integer)):
                    return leaves.get(int(node))
                a, b = reduce(node[0]), reduce(node[1])
                if a is None or b is None:
                    return a if b is None else b
                f = self.client.submit(over, a, b, pure=False)
                frame_futures.append(f)
                return f

            root = self.tree.reduction(near_low)
            # The subtrees reduce on the cluster; the root's two layers come here and are
            # composited by the client, which saves a worker-to-worker hop per frame.
            final = [reduce(root[0]), reduce(root[1])] if isinstance(root, tuple) else [reduce(root)]
            final = [f for f in final if f is not None]
        submit_ms = (time.perf_counter() - t_submit) * 1e3
        t_wait = time.perf_counter()
        from distributed import wait

        pending = [final] if cross_termination else final
        pending = [f for f in pending if hasattr(f, "result")]  # no piece visible: the front layer itself
        try:
            wait(pending, timeout=timeout)
            parts = self.client.gather(pending) if pending else ([final] if cross_termination else [])
            # what reached the client: the root's layers (or the chain's last)
            moved_here = sum(part.nbytes for part in parts if part is not None)
            layer = None
            for part in parts:  # near, then far
                layer = part if layer is None else over(layer, part)
        except TimeoutError:
            done = sum(f.done() for f in frame_futures)
            self.client.cancel(frame_futures)
            raise DistributedError(
                f"frame: did not complete within timeout={timeout:g} s ({done} of {len(frame_futures)} tasks "
                "done); no image is returned, the pieces stay loaded for the next frame"
            ) from None
        except Exception as exc:
            from distributed import KilledWorker

            if isinstance(exc, KilledWorker):
                raise DistributedError(f"frame: a task killed its workers repeatedly: {exc}") from None
            raise
        wait_ms = (time.perf_counter() - t_wait) * 1e3
        moved = job_bytes * len(jobs)
        stats_list: list = []
        comp_ms = 0.0
        if layer is not None and layer.samples.shape == (fh, fw) and layer.rgba.flags.writeable:
            rgba, samples = layer.rgba, layer.samples  # the layer is the whole frame already
        else:
            rgba = np.zeros((fh, fw, 4), np.float32)
            samples = np.zeros((fh, fw), np.int32)
            if layer is not None and layer.samples.size:
                h, w = layer.samples.shape
                rgba[layer.y0:layer.y0 + h, layer.x0:layer.x0 + w] = layer.rgba
                samples[layer.y0:layer.y0 + h, layer.x0:layer.x0 + w] = layer.samples
        if layer is not None:
            moved += sum(part.moved for part in parts if part is not None) + moved_here
            stats_list = layer.stats
            comp_ms = layer.composite_ms
        if init.shape[0] and not cross_termination:
            rgba = init + (1.0 - init[..., 3:4]) * rgba
        if bg[3] > 0:  # over the background, as the driver writes a pixel
            rest = (1.0 - rgba[..., 3:4]) * np.float32(bg[3])
            rgba[..., :3] += rest * bg[:3].astype(np.float32)
            rgba[..., 3:4] += rest
        piece_ms = [s["ms"] for s in stats_list]
        n_samples = int(samples.sum(dtype=np.int64))
        ms = (time.perf_counter() - t_start) * 1e3
        stats = {
            "ms": ms,
            "samples": n_samples,
            "samples_nonempty": int(sum(s["samples_nonempty"] for s in stats_list)),
            "rays": fw * fh,
            "msamples_per_s": n_samples / ms / 1e3 if ms > 0 else float("nan"),
            "index": sorted({s["index"] for s in stats_list}) or [index],
            "pieces": len(stats_list),
            "pieces_total": self.tree.count,
            "workers": len({st["worker"] for st in stats_list}),
            "bytes_moved": int(moved),
            "submit_ms": submit_ms,
            "wait_ms": wait_ms,
            "piece_ms": piece_ms,
            "piece_ms_max": max(piece_ms, default=0.0),
            "composite_ms": comp_ms,
            "build_ms": max((s["build_ms"] for s in stats_list), default=0.0),
            "jit_ms": max((s["jit_ms"] for s in stats_list), default=0.0),
            "cross_termination": bool(cross_termination),
            "width": fw,
            "height": fh,
            "dt": known["dt"],
            "mode": mode,
        }
        return Image(rgba, stats, samples)

    def _clip_of(self, p: int, user):
        """Piece ``p``'s clip box for the frame in world units (faces on the volume's own
        faces pushed one voxel out, so they clamp to it exactly; shared faces open above),
        its open faces, and the box that the screen rectangle is computed from; None
        when the user's clip box leaves nothing of it."""
        nz, ny, nx = self.shape
        top = np.array([nx - 1, ny - 1, nz - 1], np.float64)
        lo_i, hi_i = self.tree.voxel_box(p, self.shape)
        org, sp = self.origin, self.spacing
        lo = np.where(lo_i > 0, org + sp * lo_i, org - sp)
        hi = np.where(hi_i < top, org + sp * hi_i, org + sp * (top + 1.0))
        open_lo = np.zeros(3, bool)
        open_hi = hi_i < top  # a shared face belongs to the piece above it
        if user is not None:
            (ulo, uhi), (uolo, uohi) = user
            open_lo = np.where(ulo > lo, uolo, np.where(ulo < lo, open_lo, open_lo | uolo))
            open_hi = np.where(uhi < hi, uohi, np.where(uhi > hi, open_hi, open_hi | uohi))
            lo, hi = np.maximum(lo, ulo), np.minimum(hi, uhi)
            if np.any(lo > hi):
                return None
        seen_lo = np.maximum(lo, org + sp * lo_i)
        seen_hi = np.minimum(hi, org + sp * hi_i)
        if np.any(seen_lo > seen_hi):
            return None
        return (lo, hi), (open_lo, open_hi), (seen_lo, seen_hi)

    def _near_low(self, camera: Camera):
        """``near_low(axis, plane)`` for the tree: whether the side below a cut is in front."""
        B = self.tree.brick_size
        if camera.projection == "perspective":
            eye = (np.asarray(camera.eye, np.float64) - self.origin) / self.spacing
            return lambda axis, plane: bool(eye[axis] < plane * B)
        forward = camera.basis()[0]
        return lambda axis, plane: bool(forward[axis] >= 0.0)


def _user_clip(clip_box, clip_open):
    checked = world_clip(clip_box, clip_open)
    if checked is None:
        return None
    box, flags = checked
    return (box[0], box[1]), (flags[0], flags[1])


def _assign(weights: np.ndarray, threads: dict) -> list[str]:
    """A worker per piece: heaviest pieces first, each to the worker with the least
    non-empty bricks per thread so far."""
    addrs = sorted(threads)
    load = {a: 0.0 for a in addrs}
    out = [addrs[0]] * len(weights)
    for p in np.argsort(-np.asarray(weights), kind="stable"):
        # a piece with no non-empty brick still costs a little (its rays are traversed)
        a = min(addrs, key=lambda a: (load[a] / threads[a], a))
        out[int(p)] = a
        load[a] += float(weights[p]) + 1.0
    return out


def render_on_cluster(client, volume: Volume, tf: TransferFunction, camera: Camera, width: int = 512,
                      height: int = 512, *, pieces: int | None = None, **frame: Any) -> Image:
    """:func:`~sparsecast.render` with ``client``: the volume's pieces are loaded once per
    (client, piece count) and kept (until the volume is collected) for later frames."""
    if isinstance(volume, np.ndarray):
        volume = Volume(volume)
    if not isinstance(volume, Volume):
        raise ParameterError(f"volume: expected a sparsecast.Volume, got {type(volume).__name__}")
    client = _check_client(client)
    per = _CACHE.setdefault(volume, {})
    k = (client.id, pieces)
    cv = per.get(k)
    if cv is None or cv.client.status != "running":
        cv = per[k] = ClusterVolume(volume, client, pieces)
    return cv.render(tf, camera, width, height, **frame)
