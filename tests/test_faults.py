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


@pytest.mark.slow
def test_convert_stopped_at_random_moments():
    result = _campaign("command-signal", int(os.environ.get("G2R_FAULT_COMMAND_CASES", "10")), seed=2)
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


def _mount_small_tmpfs(folder: Path) -> bool:
    """A 2 MB tmpfs at `folder` when this process may mount one (root in a container), else False."""
    if not hasattr(os, "geteuid") or os.geteuid() != 0:
        return False
    folder.mkdir()
    return subprocess.run(["mount", "-t", "tmpfs", "-o", "size=2m", "tmpfs", str(folder)], capture_output=True).returncode == 0


@pytest.mark.slow
def test_convert_on_a_full_disk_names_the_file_and_keeps_the_manifest_exact(tmp_path, monkeypatch, capsys):
    import numpy as np
    from PIL import Image

    from g2r_jax.cli.convert import main as convert_main
    from g2r_jax.io import atomic

    images = tmp_path / "in"
    images.mkdir()
    rng = np.random.default_rng(0)
    for index in range(24):
        Image.fromarray(rng.integers(0, 255, (256, 384, 3), dtype=np.uint8)).save(images / f"img{index:03d}.png")
    disk = tmp_path / "disk"
    mounted = _mount_small_tmpfs(disk)
    if not mounted:          # a write failing with ENOSPC after a few files instead
        calls, fsync = {"n": 0}, os.fsync

        def full(descriptor):
            calls["n"] += 1
            if calls["n"] > 6:
                raise OSError(28, "No space left on device")
            return fsync(descriptor)

        monkeypatch.setattr(atomic.os, "fsync", full)
    try:
        status = convert_main([str(images), "--profile", "NikonD40", "-o", str(disk / "out"), "-q"])
        err = capsys.readouterr().err
        out = disk / "out"
        dngs = sorted(p.name for p in out.glob("*.dng"))
        listed = sorted(Path(json.loads(line)["output"]).name
                        for line in (out / "manifest.jsonl").read_text().splitlines()) if dngs else []
        leftovers = [p.name for p in out.iterdir() if p.name.endswith(".tmp")]
    finally:
        if mounted:
            subprocess.run(["umount", str(disk)], capture_output=True)
    assert status == 2
    assert "cannot write: no space left on the disk" in err and ".tmp" not in err and "Errno" not in err
    assert 0 < len(dngs) < 24 and listed == dngs and leftovers == []
