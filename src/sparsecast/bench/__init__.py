"""Benchmark harness behind ``sparsecast bench``: suites, datasets, timing, peers, reports.

Benchmarks are not tests: they time things and write JSON records (one per
measurement) so runs can be compared; they never assert a time. A run follows a
suite (:data:`SUITES`: ``quick``, ``paper``, ``sweep``, ``bih``, ``surface``),
journals every record as it is taken (an interrupted run resumes), and writes a
Markdown report and figures in the papers' style.
"""

from .datasets import DATASETS, BenchDataset, find_shared_data
from .harness import BenchConfig, run_benchmarks
from .report import format_table, write_json
from .suites import SUITES, Suite

__all__ = [
    "DATASETS", "BenchDataset", "find_shared_data", "BenchConfig", "run_benchmarks",
    "format_table", "write_json", "SUITES", "Suite",
]
