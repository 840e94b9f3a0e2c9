"""Peers: the renderers users pick today, run on the same cases as ours.

Each peer module exposes ``NAME``, ``unavailable_reason() -> str | None`` (why it
cannot run here, e.g. not installed) and a ``Scene(volume, tf, dt)`` whose
``render(camera, width, height)`` returns ``(rgba, ms)``: a float32 (H, W, 4)
image, colour premultiplied over black, row 0 at the top, and the wall time of
that frame. ``render(volume, tf, camera, width, height, dt)`` does both at once.

Equivalence with our renderer (what "the same case" means): same voxels placed at
the same world positions (origin + spacing * index, x fastest), same camera,
image size and sampling step, the TF's baked table as the peer's colour and
opacity functions, opacity corrected to the step with the same unit distance.
"""

from __future__ import annotations

import importlib
from types import ModuleType

__all__ = ["PEERS", "load_peer", "PeerUnavailable"]

#: peer name -> module implementing it
PEERS: dict[str, str] = {
    "vtk": "sparsecast.bench.peers.vtk_peer",
    "yt": "sparsecast.bench.peers.yt_peer",
    "pyvista": "sparsecast.bench.peers.pyvista_peer",
}


class PeerUnavailable(RuntimeError):
    """A peer cannot run on this machine (the message says why)."""


def load_peer(name: str) -> ModuleType:
    """The module of peer ``name``; raises :class:`PeerUnavailable` with the reason
    when it is unknown, not installed or unusable here."""
    if name not in PEERS:
        raise PeerUnavailable(f"unknown peer {name!r}; expected one of {', '.join(PEERS)}")
    module = importlib.import_module(PEERS[name])
    reason = module.unavailable_reason()
    if reason:
        raise PeerUnavailable(reason)
    return module
