"""Idle OpenMP threads sleep: sparsecast sets a passive wait policy unless the user chose one."""

from __future__ import annotations

import os
import subprocess
import sys


def _policy_after_import(env_policy: str | None) -> str:
    env = {k: v for k, v in os.environ.items() if k != "OMP_WAIT_POLICY"}
    if env_policy is not None:
        env["OMP_WAIT_POLICY"] = env_policy
    code = "import os, sparsecast; print(os.environ.get('OMP_WAIT_POLICY'))"
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    return out.stdout.strip()


def test_import_makes_idle_threads_passive():
    assert _policy_after_import(None) == "PASSIVE"


def test_a_policy_the_user_set_is_kept():
    assert _policy_after_import("ACTIVE") == "ACTIVE"
