"""``sparsecast convert``: any readable volume to chunked Zarr or an OME-Zarr pyramid."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Optional

import typer

from .app import AllowOutsideOpt, DimsOpt, DtypeOpt, SpacingOpt, app, out
from .parse import parse_dims, parse_spacing

__all__ = ["convert"]


@app.command()
def convert(
    src: Annotated[Path, typer.Argument(
        help="Input: a Zarr / OME-Zarr store, file.h5:/dataset, .npy, raw, .nrrd (read chunk by chunk), or any "
             "other volume file (.nii .tif, gzip NRRD: read into memory).")],
    dst: Annotated[Path, typer.Argument(help="Output Zarr store to create (e.g. out.zarr).")],
    chunks: Annotated[int, typer.Option(help="Chunk edge in voxels.")] = 64,
    ome: Annotated[bool, typer.Option("--ome", help="Write an OME-Zarr image with a multiscale pyramid "
                                                     "(levels halving down to about 64^3).")] = False,
    labels: Annotated[bool, typer.Option("--labels", help="Pyramid levels take the nearest voxel (label ids), "
                                                           "not the 2x2x2 mean.")] = False,
    level: Annotated[Optional[str], typer.Option(help="OME-Zarr input: the level to convert, by index or "
                                                      "path (default the finest).")] = None,
    force: Annotated[bool, typer.Option("--force", help="Replace an existing output store.")] = False,
    clevel: Annotated[int, typer.Option(help="zstd compression level 1..9.")] = 5,
    dims: DimsOpt = None,
    dtype: DtypeOpt = None,
    spacing: SpacingOpt = None,
    allow_outside_data: AllowOutsideOpt = False,
) -> None:
    """Convert a volume to chunked, zstd-compressed Zarr, or OME-Zarr with --ome (atomic: a temporary store
    beside the output is renamed onto it at the end)."""
    from ..io import convert_volume

    lvl = int(level) if level is not None and level.strip().isdigit() else level
    done = convert_volume(
        str(src), dst, chunks=chunks, ome=ome, labels=labels, force=force, level=lvl, clevel=clevel,
        spacing=parse_spacing(spacing) if spacing else None, progress=True,
        dims=parse_dims(dims) if dims else None, dtype=dtype, allow_outside=allow_outside_data or None,
    )
    shape = " x ".join(map(str, done.shapes[0][::-1]))
    kind = f"OME-Zarr, {len(done.shapes)} levels" if ome else "Zarr"
    out.print(f"{done.path}: {kind}, {shape} {done.dtype}, chunks {'x'.join(map(str, done.chunks))}, "
              f"{done.bytes_in / 2**20:.1f} MiB -> {done.bytes_out / 2**20:.1f} MiB on disk, {done.seconds:.2f} s")
    if ome:
        for i, s in enumerate(done.shapes):
            out.print(f"  level {i}  {' x '.join(map(str, s[::-1]))}")
