"""The machine a benchmark ran on, attached to every record so runs compare fairly."""

from __future__ import annotations

import os
import platform
import re
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["machine_info", "nominal_clock_ghz"]


def nominal_clock_ghz(cpuinfo: str | None = None) -> tuple[float | None, str]:
    """The CPU's nominal clock in GHz and where it was read.

    The ``@ 2.45GHz`` of the model name first (the rated clock), then the kernel's
    ``base_frequency`` / ``cpuinfo_max_freq``, then ``cpu MHz`` of ``/proc/cpuinfo``
    (the clock at the moment of reading). Cycles per sample derived from it are
    nominal: turbo, throttling and a VM's steal time are not in it.
    """
    if cpuinfo is None:
        try:
            cpuinfo = Path("/proc/cpuinfo").read_text()
        except OSError:
            cpuinfo = ""
    m = re.search(r"^model name\s*:.*@\s*([\d.]+)\s*GHz", cpuinfo, re.M)
    if m:
        return float(m.group(1)), "model name"
    for name in ("base_frequency", "cpuinfo_max_freq"):
        p = Path("/sys/devices/system/cpu/cpu0/cpufreq") / name
        try:
            return int(p.read_text()) / 1e6, name  # kHz
        except (OSError, ValueError):
            pass
    m = re.search(r"^cpu MHz\s*:\s*([\d.]+)", cpuinfo, re.M)
    if m:
        return float(m.group(1)) / 1e3, "cpu MHz"
    return None, "unknown"


def machine_info() -> dict[str, Any]:
    """Where the numbers come from (attached to every record)."""
    import numba

    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    clock, source = nominal_clock_ghz()
    return {
        "cpu": cpu,
        "cores": os.cpu_count(),
        "numba_threads": numba.get_num_threads(),
        "clock_ghz": clock,
        "clock_source": source,
        "python": platform.python_version(),
        "numpy": np.__version__,
        "numba": numba.__version__,
        "platform": platform.platform(),
    }
