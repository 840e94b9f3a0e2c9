"""Storage other than one dense in-memory array: bricked volumes resident on demand."""

from .bricked import BrickedVolume, MemoryBudgetError, parse_memory

__all__ = ["BrickedVolume", "MemoryBudgetError", "parse_memory"]
