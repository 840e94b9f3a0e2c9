"""Benchmark harness behind ``sparsecast bench``: suites, the dataset catalogue, timing, peers, reports.

Benchmarks are not tests: they time things and write JSON records (one per
measurement) so runs can be compared; they never assert a time. A run follows a
suite (:data:`SUITES`: ``quick``, ``paper``, ``sweep``, ``bih``, ``surface``),
journals every record as it is taken (an interrupted run resumes), and writes a
Markdown report and figures in the papers' style.
"""

from .catalog import DATASETS, BenchDataset
from .config import BenchConfig
from .harness import run_benchmarks
from .report import format_table, write_json
from .shared_data import find_shared_data
from .suites import SUITES, Suite

__all__ = [
    "DATASETS", "BenchDataset", "find_shared_data", "BenchConfig", "run_benchmarks",
    "format_table", "write_json", "SUITES", "Suite",
]
