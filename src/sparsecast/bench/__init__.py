"""Benchmark harness behind ``sparsecast bench``: datasets, timing, reports.

Benchmarks are not tests: they time things and write JSON records (one per
measurement) so runs can be compared; they never assert a time.
"""

from .datasets import DATASETS, BenchDataset, find_shared_data
from .harness import BenchConfig, run_benchmarks
from .report import format_table, write_json

__all__ = [
    "DATASETS", "BenchDataset", "find_shared_data", "BenchConfig", "run_benchmarks",
    "format_table", "write_json",
]
