"""The fault harness (tests/fault_harness.py) on the output folder: kills, signals, concurrent
writers, full disks, read-only folders. The default run: a few dozen cases of each from a fixed
seed, in one light subprocess (no JAX); the slow run: 300 of each."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

HARNESS = Path(__file__).resolve().parent / "fault_harness.py"


def _campaign(kind: str, cases: int, seed: int) -> dict:
    run = subprocess.run([sys.executable, str(HARNESS), kind, str(cases), str(seed)], capture_output=True, text=True,
                         timeout=900)
    assert run.returncode == 0, run.stderr[-2000:]
    return json.loads(run.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize("kind, cases", [("kill", 40), ("signal", 40), ("concurrent", 20), ("disk-full", 100),
                                         ("read-only", 100)])
def test_the_folder_keeps_its_promises_under_faults(kind, cases):
    result = _campaign(kind, cases, seed=0)
    assert result["cases"] == cases and result["findings"] == []


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["kill", "signal", "concurrent", "disk-full", "read-only"])
def test_fault_campaign(kind):
    result = _campaign(kind, int(os.environ.get("G2R_FAULT_CASES", "300")), seed=1)
    assert result["findings"] == [], result["findings"][:3]


def test_the_harness_sees_a_broken_folder(tmp_path):
    sys.path.insert(0, str(HARNESS.parent))
    import fault_harness as fh

    folder = tmp_path / "out"
    folder.mkdir()
    (folder / "a.dng").write_bytes(fh.payload("a.dng", 100))
    (folder / "b.dng").write_bytes(fh.payload("b.dng", 100)[:-1])
    (folder / ".c.dng.x1.tmp").write_bytes(b"")
    (folder / "manifest.jsonl").write_text(json.dumps({"output": "gone.dng"}) + "\n")
    problems = " ".join(fh.folder_problems(folder, exact=True))
    for expected in ("temporaries left", "incomplete files: ['b.dng']", "missing files: ['gone.dng']",
                     "not in the manifest"):
        assert expected in problems
