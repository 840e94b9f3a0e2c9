"""Every parser of command-line values, in one place: image sizes, number lists, raw
dims, spacing, backgrounds, index specs ``NAME:KEY=VALUE[,KEY=VALUE]`` and
repeatable lists with ``none``.

Each returns plain Python values or raises :class:`~sparsecast.errors.ParameterError`
naming the option, what it found and what it expected (``sparsecast`` prints that as
one line). Index specs are parsed by :func:`sparsecast.index.parse_index_spec`
(re-exported here), which the benchmark harness uses too.
"""

from __future__ import annotations

import math
import re
from typing import Optional

from .._util.checks import fail
from ..index.registry import parse_index_spec

__all__ = [
    "parse_size", "parse_pair", "parse_numbers", "parse_dims", "parse_spacing", "parse_background",
    "parse_index_spec", "none_list", "parse_clip_box", "parse_clip_plane",
]


#: an ASCII decimal integer: Python's int() also takes full-width and other Unicode
#: digits ("３２"), which a command line should not silently accept
_ASCII_INT = re.compile(r"[0-9]+", re.ASCII)


def _ascii_int(text: str) -> int:
    text = text.strip()
    if not _ASCII_INT.fullmatch(text):
        raise ValueError(text)
    return int(text)


def parse_size(size: str) -> tuple[int, int]:
    """``"640x480"`` -> ``(640, 480)``; one number means a square (``"512"``). ASCII digits only."""
    parts = size.lower().split("x")
    try:
        if len(parts) == 1:
            w = h = _ascii_int(parts[0])
        elif len(parts) == 2:
            w, h = _ascii_int(parts[0]), _ascii_int(parts[1])
        else:
            raise ValueError
    except ValueError:
        raise fail("--size", "WIDTHxHEIGHT like 512x512 (ASCII digits)", size) from None
    return w, h


def parse_pair(text: str, name: str) -> tuple[float, float]:
    """``"lo,hi"`` -> ``(lo, hi)`` as floats (``name`` is the option, for the message)."""
    try:
        lo, hi = (float(x) for x in text.split(","))
    except ValueError:
        raise fail(name, "two numbers 'lo,hi'", text) from None
    return lo, hi


def parse_numbers(text: str, name: str) -> tuple[float, ...]:
    """``"1,0.5,0"`` -> ``(1.0, 0.5, 0.0)``: any count of comma-separated numbers."""
    try:
        return tuple(float(x) for x in text.split(","))
    except ValueError:
        raise fail(name, "comma-separated numbers", text) from None


def parse_dims(dims: str) -> tuple[int, ...]:
    """``--dims`` ``"256x256x128"`` -> ``(256, 256, 128)`` (the loader checks there are three)."""
    try:
        return tuple(_ascii_int(x) for x in dims.lower().split("x"))
    except ValueError:
        raise fail("--dims", "NXxNYxNZ like 256x256x128 (ASCII digits)", dims) from None


def parse_spacing(spacing: str) -> float | list[float]:
    """``--spacing`` ``"sx,sy,sz"`` -> a list, or one number -> that number (isotropic)."""
    try:
        vals = [float(x) for x in spacing.split(",")]
    except ValueError:
        raise fail("--spacing", "'sx,sy,sz' or one number", spacing) from None
    return vals[0] if len(vals) == 1 else vals


def parse_background(background: str) -> str | list[float]:
    """``--background``: a colour name is passed on as it is, ``"r,g,b[,a]"`` as numbers
    (the renderer checks both)."""
    if "," in background:
        return list(parse_numbers(background, "--background"))
    return background


def none_list(values: Optional[list[str]]) -> Optional[list[str]]:
    """Repeatable option values, with 'none' meaning an explicit empty list."""
    if values is None:
        return None
    return [] if [v.lower() for v in values] == ["none"] else values


def parse_clip_box(text: Optional[str]):
    """``--clip-box x0,y0,z0,x1,y1,z1`` (world units) -> ``((x0, y0, z0), (x1, y1, z1))`` or None."""
    if text is None:
        return None
    v = parse_numbers(text, "--clip-box")
    if len(v) != 6:
        raise fail("--clip-box", "6 numbers x0,y0,z0,x1,y1,z1 (world units)", text)
    if not all(math.isfinite(x) for x in v) or any(v[i] > v[i + 3] for i in range(3)):
        # (the renderer checks this too, but names its own parameter and not the text typed)
        raise fail("--clip-box", "finite corners x0,y0,z0,x1,y1,z1 with x0 <= x1, y0 <= y1, z0 <= z1", text)
    return tuple(v[:3]), tuple(v[3:])


def parse_clip_plane(text: str):
    """``--clip-plane px,py,pz,nx,ny,nz`` -> ``((px, py, pz), (nx, ny, nz))``: the plane
    through ``p`` keeping the side ``n`` points to."""
    v = parse_numbers(text, "--clip-plane")
    if len(v) != 6:
        raise fail("--clip-plane", "6 numbers px,py,pz,nx,ny,nz (a point, and the normal of the kept side)", text)
    if not any(v[3:]):
        raise fail("--clip-plane", "a non-zero normal nx,ny,nz after the point", text)
    return tuple(v[:3]), tuple(v[3:])
