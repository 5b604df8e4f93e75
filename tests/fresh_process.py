"""Run a command in a process whose peak memory is its own.

On Linux a child's `ru_maxrss` starts at its parent's resident size when it is forked (exec keeps
the high-water mark), so a command started straight from a test worker that has run JAX reports
the worker's gigabytes. A small launcher process starts the command instead and reports the
command's own peak."""

from __future__ import annotations

import subprocess
import sys
import tempfile
from pathlib import Path

LAUNCHER = """import os, subprocess, sys
process = subprocess.Popen(sys.argv[2:])
_, status, usage = os.wait4(process.pid, 0)
open(sys.argv[1], "w").write(str(usage.ru_maxrss))
sys.exit(os.waitstatus_to_exitcode(status))
"""


def run_measured(argv, **kwargs) -> tuple[subprocess.CompletedProcess, float]:
    """`subprocess.run(argv, **kwargs)` through the launcher: (the result, peak resident GiB)."""
    with tempfile.TemporaryDirectory() as folder:
        peak_file = Path(folder) / "peak"
        result = subprocess.run([sys.executable, "-c", LAUNCHER, str(peak_file), *map(str, argv)], **kwargs)
        peak_kib = float(peak_file.read_text()) if peak_file.exists() else float("nan")
    return result, peak_kib * 1024 / 2**30
