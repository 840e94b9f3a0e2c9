"""Volumes larger than memory: statistics of chunked sources (:func:`scan`)."""

from .scan import Scan, scan

__all__ = ["Scan", "scan"]
