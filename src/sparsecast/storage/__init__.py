"""Storage other than one dense in-memory array: bricked volumes resident on demand, and
the chunk-parallel scan that computes their statistics from a lazy source."""

from .bricked import BrickedVolume, MemoryBudgetError, parse_memory
from .scan import Scan, scan

__all__ = ["BrickedVolume", "MemoryBudgetError", "Scan", "parse_memory", "scan"]
