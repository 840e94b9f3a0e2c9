"""Any readable volume to chunked, compressed Zarr or an OME-Zarr pyramid: :func:`convert_volume`.

The output is written block by block (a block is a whole number of output chunks, so
no two tasks write the same chunk) on dask's threaded scheduler: a lazy input
(:func:`~.sources.open_source`) is never in memory whole, only the blocks in flight.
An OME-Zarr pyramid's level ``l + 1`` is computed from level ``l`` as written (read
back from the new store), each block from the 2x2x2 voxels under it: the mean
(integers rounded half to even) or, for labels, the first voxel (nearest: ids are not
averaged). Odd axes are padded by repeating the last voxel, so a level has
``ceil(n / 2)`` voxels. Voxel ``i`` of a mean level lies at the centre of the voxels
it averages, ``origin + spacing_0 * (2^l i + (2^l - 1) / 2)``, which its translation
says; a nearest level keeps the origin.

Atomic: everything goes to a temporary directory beside the output, renamed onto it
at the end; an existing output is refused unless ``force``, and never one that is (or
holds, or lies in) the input. Chunks are written even when empty
(``write_empty_chunks``), so a chunk missing later is an error, not a hole (see
:mod:`.sources`).
"""

from __future__ import annotations

import contextlib
import math
import os
import secrets
import shutil
import time
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .._util.atomic import TEMP_PREFIX
from .._util.checks import as_int, fail, vector3
from .._util.progress import ProgressArg, chunk_progress
from ..errors import FileFormatError, ParameterError
from ..volume import Volume
from .nrrd import EncodedPayloadError
from .sources import SOURCE_ATTRS, Source, is_lazy_path, is_zarr_dir, open_source

__all__ = ["convert_volume", "Converted", "pyramid_shapes", "BLOCK_BYTES"]

#: bytes of the output a block task writes (a whole number of chunks)
BLOCK_BYTES = 16 << 20
#: the path of an input that is no file (a Volume, an ndarray)
_MEMORY = Path("<in memory>")
#: an OME pyramid stops at the first level whose largest axis is at most this
PYRAMID_FLOOR = 64


@dataclass(frozen=True)
class Converted:
    """What :func:`convert_volume` wrote.

    Attributes
    ----------
    path : Path
        The store.
    shapes : tuple of (nz, ny, nx)
        The shape of every level written, finest first (one for plain Zarr).
    chunks : (cz, cy, cx)
    dtype : numpy.dtype
    bytes_in : int
        Decoded bytes of level 0.
    bytes_out : int
        Bytes of the store on disk (every level, metadata included).
    seconds : float
    """

    path: Path
    shapes: tuple[tuple[int, int, int], ...]
    chunks: tuple[int, int, int]
    dtype: np.dtype
    bytes_in: int
    bytes_out: int
    seconds: float


def pyramid_shapes(shape: tuple[int, int, int], floor: int = PYRAMID_FLOOR) -> list[tuple[int, int, int]]:
    """Level shapes, halving (``ceil``) until the largest axis is at most ``floor``."""
    shapes = [tuple(int(n) for n in shape)]
    while max(shapes[-1]) > floor:
        shapes.append(tuple(-(-n // 2) for n in shapes[-1]))
    return shapes  # type: ignore[return-value]


def _input(src, level, load_options: dict) -> Source:
    """``src`` as a Source: a Source itself, a Volume or array (in memory), a lazy path,
    or any file :func:`~.volumes.load_volume` reads (then in memory)."""
    from .volumes import load_volume

    if isinstance(src, Source):
        return src
    if isinstance(src, Volume):
        return _in_memory(src.data, src.spacing, src.origin, src.name, _MEMORY, src.orientation)
    if isinstance(src, np.ndarray):
        return _in_memory(src, np.ones(3), np.zeros(3), "array", _MEMORY, None)
    if not isinstance(src, (str, os.PathLike)):
        raise fail("src", "a file path, Source, Volume or ndarray", type(src).__name__)
    lazy_opts = {k: v for k, v in load_options.items() if k in ("dims", "dtype", "byte_order", "header_offset",
                                                                 "allow_outside") and v is not None}
    if is_lazy_path(src):
        try:
            return open_source(src, level=level, **lazy_opts)
        except EncodedPayloadError:
            pass  # a gzip/bzip2 NRRD: decoded whole below
    if level is not None:
        raise ParameterError(f"level: {os.fspath(src)!r} is not an OME-Zarr image; level= applies to those")
    vol = load_volume(src, **{k: v for k, v in load_options.items() if v is not None})
    return _in_memory(vol.data, vol.spacing, vol.origin, vol.name, Path(src), vol.orientation)


def _in_memory(data: np.ndarray, spacing, origin, name: str, path: Path, orientation) -> Source:
    from .sources import Level

    data = np.asarray(data)
    if data.ndim != 3:
        raise ParameterError(f"src: expected a 3-D array (nz, ny, nx), got shape {data.shape}")
    sp, org = np.asarray(spacing, np.float64), np.asarray(origin, np.float64)
    return Source(data, sp, org, name, path, "npy", None, (Level(name, data.shape, sp, org),), name, orientation)


def _store_size(path: Path) -> int:
    return sum(f.stat().st_size for f in path.rglob("*") if f.is_file())


def _same_or_nested(a: Path, b: Path) -> bool:
    a, b = a.resolve(), b.resolve()
    return a == b or a.is_relative_to(b) or b.is_relative_to(a)


def _blocks(shape, chunks, itemsize: int, target: int) -> tuple[int, int, int]:
    """A block of whole chunks, grown along x, then y, then z while under ``target`` bytes."""
    block = list(chunks)
    for axis in (2, 1, 0):
        while block[axis] < shape[axis]:
            grown = min(block[axis] + chunks[axis], shape[axis])
            if math.prod(block) // block[axis] * grown * itemsize > target:
                break
            block[axis] = grown
    return tuple(block)  # type: ignore[return-value]


def _regions(shape, block):
    """Every block region of an array, as tuples of slices, in C order."""
    starts = [range(0, n, b) for n, b in zip(shape, block)]
    for k in starts[0]:
        for j in starts[1]:
            for i in starts[2]:
                yield (slice(k, min(k + block[0], shape[0])), slice(j, min(j + block[1], shape[1])),
                       slice(i, min(i + block[2], shape[2])))


def _run(fn, regions: list, progress: ProgressArg, description: str, workers: int) -> None:
    """``fn(region)`` for every region on dask's threaded scheduler, with progress."""
    import dask

    with chunk_progress(progress, len(regions), description) as tick:
        def task(region):
            fn(region)
            tick.advance()

        dask.compute(*[dask.delayed(task, pure=False)(r) for r in regions],
                     scheduler="threads", num_workers=workers)


def _halve(block: np.ndarray, labels: bool) -> np.ndarray:
    """One coarser level of a block whose start is even: 2x2x2 means (or first voxels)."""
    if labels:
        return np.ascontiguousarray(block[::2, ::2, ::2])
    pad = [(0, n % 2) for n in block.shape]
    if any(p for _, p in pad):
        block = np.pad(block, pad, mode="edge")  # the last voxel stands in for the missing one
    nz, ny, nx = (n // 2 for n in block.shape)
    mean = block.reshape(nz, 2, ny, 2, nx, 2).mean(axis=(1, 3, 5), dtype=np.float64)
    if block.dtype.kind in "ui":
        info = np.iinfo(block.dtype)
        return np.clip(np.rint(mean), info.min, info.max).astype(block.dtype)
    return mean.astype(block.dtype)


def convert_volume(
    src,
    out: str | os.PathLike,
    *,
    chunks: int | tuple[int, int, int] = 64,
    ome: bool = False,
    labels: bool = False,
    force: bool = False,
    level: int | str | None = None,
    spacing=None,
    origin=None,
    clevel: int = 5,
    progress: ProgressArg = None,
    workers: int = 2,
    **load_options: Any,
) -> Converted:
    """Write a volume as chunked, zstd-compressed Zarr (v3), or an OME-Zarr (0.5) pyramid.

    Parameters
    ----------
    src : path, Source, Volume or ndarray (nz, ny, nx)
        A lazy source (Zarr, OME-Zarr, ``file.h5:/dataset``, ``.npy``, raw, raw NRRD;
        read block by block) or any file :func:`~.volumes.load_volume` reads (in memory).
    out : str or PathLike
        The store to create (a directory, ``name.zarr``).
    chunks : int or (cz, cy, cx), optional
        Chunk edge (default 64), clipped to the shape.
    ome : bool, optional
        Write an OME-Zarr multiscale image: levels ``0, 1, ...`` halving until the
        largest axis is at most 64, with scale and translation transformations.
        Default: one plain Zarr array with ``attrs["sparsecast"] = {"spacing", "origin"}``.
    labels : bool, optional
        Coarser levels take the first voxel of every 2x2x2 (ids), not the mean.
    force : bool, optional
        Replace an existing ``out`` (never the input itself).
    level : int or str, optional
        OME-Zarr input: the level to convert (default the finest).
    spacing, origin : optional
        Override the input's ``(x, y, z)`` spacing / origin.
    clevel : int, optional
        zstd level 1..9 (default 5).
    progress : bool or callable, optional
        True: a progress bar per level on stderr; a callable: ``progress(done, total)``.
    workers : int, optional
        Threads reading, compressing and writing blocks (default 2).
    **load_options
        Raw layout (``dims``, ``dtype``, ``byte_order``, ``header_offset``) and
        ``allow_outside``, ``nonfinite`` / ``orientation`` for :func:`~.volumes.load_volume`.

    Returns
    -------
    Converted

    Raises
    ------
    ParameterError
        Bad chunks / clevel, ``out`` exists (without ``force``) or is the input or
        lies inside it (or holds it), a missing output folder.
    FileFormatError
        The input cannot be read (a missing or corrupt chunk is named), or the write fails
        (nothing is left at ``out`` then).
    """
    import zarr
    from zarr.codecs import BloscCodec

    t0 = time.perf_counter()
    out = Path(out)
    if isinstance(chunks, (tuple, list)):
        if len(chunks) != 3:
            raise fail("chunks", "an integer or 3 integers (cz, cy, cx)", chunks)
        chunk3 = tuple(as_int(c, "chunks", lo=1) for c in chunks)
    else:
        chunk3 = (as_int(chunks, "chunks", lo=1),) * 3
    clevel = as_int(clevel, "clevel", lo=1, hi=9)
    workers = as_int(workers, "workers", lo=1)
    parent = out.parent if str(out.parent) else Path(".")
    if not parent.is_dir():
        raise ParameterError(f"out: {str(out)!r}: directory {str(parent)!r} does not exist")
    if out.exists() and not force:
        raise ParameterError(f"out: {str(out)!r} exists; expected a new store name (pass force=True, or --force, "
                             f"to replace it)")
    if out.exists() and not is_zarr_dir(out):
        # force replaces a store, never whatever else a typo names (a folder of one's own files)
        raise ParameterError(f"out: {str(out)!r} exists and is not a Zarr store; expected a new name or a "
                             f"Zarr store to replace")
    source = _input(src, level, load_options)
    if source.path != _MEMORY and source.path.exists() and _same_or_nested(out, source.path):
        raise ParameterError(
            f"out: {str(out)!r} is, holds or lies inside the input {str(source.path)!r}; a source is never "
            f"written to: choose another name"
        )
    shape, dtype = source.shape, source.dtype
    sp = vector3(spacing, "spacing", positive=True) if spacing is not None else np.asarray(source.spacing, float)
    org = vector3(origin, "origin") if origin is not None else np.asarray(source.origin, float)
    chunk3 = tuple(min(c, n) for c, n in zip(chunk3, shape))
    compressor = BloscCodec(cname="zstd", clevel=clevel, shuffle="bitshuffle" if dtype.itemsize == 1 else "shuffle")
    shapes = pyramid_shapes(shape) if ome else [shape]

    tmp = parent / f"{TEMP_PREFIX}{os.getpid()}-{secrets.token_hex(4)}.part.zarr"
    try:
        if ome:
            root = zarr.open_group(str(tmp), mode="w-", zarr_format=3)
            # Every chunk is written: an absent one is a loss (see io.sources, missing chunks).
            root.attrs[SOURCE_ATTRS] = {"complete": True}
            targets = [root.create_array(str(i), shape=s, chunks=tuple(min(c, n) for c, n in zip(chunk3, s)),
                                         dtype=dtype, compressors=compressor, fill_value=0,
                                         config={"write_empty_chunks": True})
                       for i, s in enumerate(shapes)]
        else:
            targets = [zarr.create_array(str(tmp), shape=shape, chunks=chunk3, dtype=dtype, compressors=compressor,
                                         fill_value=0, config={"write_empty_chunks": True},
                                         attributes={SOURCE_ATTRS: {"spacing": sp.tolist(), "origin": org.tolist(),
                                                                    "name": source.name, "complete": True}})]
        level0 = targets[0]
        block = _blocks(shape, chunk3, dtype.itemsize, BLOCK_BYTES)

        def copy(region):
            level0[region] = source.array[region]

        _run(copy, list(_regions(shape, block)), progress, f"convert {source.name}", workers)
        for i in range(1, len(shapes)):
            prev, target = targets[i - 1], targets[i]
            # Output blocks small enough that the 8x larger input stays near BLOCK_BYTES.
            oblock = _blocks(shapes[i], target.chunks, dtype.itemsize, BLOCK_BYTES // 8)

            def halve(region, prev=prev, target=target):
                inner = tuple(slice(2 * r.start, min(2 * r.stop, n)) for r, n in zip(region, prev.shape))
                target[region] = _halve(prev[inner], labels)

            _run(halve, list(_regions(shapes[i], oblock)), progress, f"level {i} {shapes[i]}", workers)
        if ome:
            _ome_metadata(root, shapes, sp, org, labels, source.name)
        _install(tmp, out, force)
    except BaseException as exc:
        shutil.rmtree(tmp, ignore_errors=True)
        if isinstance(exc, OSError):
            raise FileFormatError(f"{str(out)!r}: cannot write: {exc.strerror or exc}") from exc
        raise
    return Converted(out, tuple(shapes), chunk3, dtype, source.nbytes, _store_size(out), time.perf_counter() - t0)


def _ome_metadata(root, shapes, spacing: np.ndarray, origin: np.ndarray, labels: bool, name: str) -> None:
    """OME-Zarr 0.5 multiscales: axes z, y, x and per level a scale and a translation."""
    from ome_zarr.format import FormatV05

    with warnings.catch_warnings():
        # ome_zarr.writer builds a deprecated Scaler as a default argument on import;
        # we write our own levels and only use its metadata writer.
        warnings.simplefilter("ignore", DeprecationWarning)
        from ome_zarr.writer import write_multiscales_metadata

    datasets = []
    for i in range(len(shapes)):
        f = 2.0 ** i
        shift = origin if labels else origin + spacing * (f - 1) / 2  # a mean voxel sits mid-way
        datasets.append({"path": str(i), "coordinateTransformations": [
            {"type": "scale", "scale": (spacing * f)[::-1].tolist()},
            {"type": "translation", "translation": shift[::-1].tolist()},
        ]})
    axes = [{"name": a, "type": "space"} for a in "zyx"]
    write_multiscales_metadata(root, datasets, fmt=FormatV05(), axes=axes, name=name)


def _install(tmp: Path, out: Path, force: bool) -> None:
    """Rename the finished store onto ``out``; an old one (``force``) is moved aside first
    and removed only once the new one is in place."""
    old = None
    if out.exists():
        if not force:  # appeared while converting
            raise ParameterError(f"out: {str(out)!r} exists; pass force=True (--force) to replace it")
        old = out.parent / f"{TEMP_PREFIX}{os.getpid()}-{secrets.token_hex(4)}.old"
        os.replace(out, old)
    try:
        os.replace(tmp, out)
    except BaseException:
        if old is not None:
            with contextlib.suppress(OSError):
                os.replace(old, out)
        raise
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)
