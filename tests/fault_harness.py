"""Fault harness of the output folder: kills, signals, concurrent writers, full disks, read-only
and vanished folders, against the promises of `g2r_jax.io.output_folder` and `g2r_jax.io.atomic`.

Each case runs a small writer (the same calls g2r-convert makes: `OutputFolder`, then
`atomic_write_bytes(..., after_rename=folder.append)` per file) in a forked child of this light
interpreter (no JAX), and checks the folder afterwards:

- kill: SIGKILL at a random moment; the next opening removes the temporaries, the manifest lists
  only complete files, at most the one file renamed in the instant before its line is unlisted
  (and reported).
- signal: SIGINT or SIGTERM at a random moment under `StopOnSignal`; exit 130 (unless the writer
  had finished and left the context), no temporary, the manifest lists exactly the files, every
  file complete.
- concurrent: two writers started together on one folder; the second is refused with one line
  naming the folder, or runs after the first; the manifest lists exactly the files.
- disk-full: a write fails with ENOSPC at a random file and byte (on the data or on the manifest
  line); the error names the output in our words (no '.tmp', no 'Errno'), the folder stays exact.
- read-only / vanished folder: creating the temporary fails (EROFS, EACCES) or the folder is
  removed; the error names the file in our words.

- command-signal: g2r-convert itself, stopped after a random delay (start-up, compilation with or
  without the compilation cache, writing): exit 130 (0 only with every file written), no
  traceback, the manifest lists exactly the DNGs, each readable.

Run `python tests/fault_harness.py KIND N [SEED]` (KIND: kill, signal, concurrent, disk-full,
read-only, all of these, or command-signal: seconds per case); it prints one JSON line
{kind, cases, seed, findings}.
"""

from __future__ import annotations

import errno
import hashlib
import json
import os
import random
import shutil
import signal
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from g2r_jax.io import atomic  # noqa: E402
from g2r_jax.io.output_folder import MANIFEST_NAME, OutputFolder  # noqa: E402

KINDS = ("kill", "signal", "concurrent", "disk-full", "read-only")
NAMES = [f"img{i:03d}.dng" for i in range(12)]
REFUSED_STATUS = 3


def payload(name: str, size: int) -> bytes:
    """Self-checking file content: a 32-byte digest of the rest, then `size` bytes."""
    body = (hashlib.sha256(name.encode()).digest() * (size // 32 + 1))[:size]
    return hashlib.sha256(body).digest() + body


def complete(path: Path) -> bool:
    data = path.read_bytes()
    return len(data) >= 32 and hashlib.sha256(data[32:]).digest() == data[:32]


def write_files(folder: Path, names, rng: random.Random, pause: float = 0.0, fail_at=None) -> None:
    """What g2r-convert does per output: temporary, rename, manifest line."""
    with OutputFolder(folder) as opened:
        for index, name in enumerate(names):
            output = opened.path / name
            data = payload(name, rng.randrange(1, 50_000))
            record = {"input": name.replace(".dng", ".png"), "output": str(output)}
            if fail_at is not None and fail_at[0] == index:
                data = _failing_writer(data, fail_at[1])
            atomic.atomic_write_bytes(output, data, after_rename=lambda o=output, r=record: opened.append(r, o))
            if pause:
                time.sleep(rng.uniform(0, pause))
        opened.compact()


def _failing_writer(data: bytes, at: int):
    def write(handle):
        handle.write(data[:at])
        raise OSError(errno.ENOSPC, "No space left on device")
    return write


def folder_problems(folder: Path, *, exact: bool, allow_unlisted: int = 0, killed: bool = False) -> list:
    """Broken promises of a folder at rest: temporaries, incomplete files, manifest mismatch
    (after a kill, temporaries and an older record of a file being replaced are expected)."""
    problems = []
    names = sorted(p.name for p in folder.iterdir()) if folder.is_dir() else []
    temporaries = [n for n in names if atomic.is_temporary_name(n)]
    if temporaries and not killed:
        problems.append(f"temporaries left: {temporaries}")
    dngs = [n for n in names if n.endswith(".dng")]
    broken = [n for n in dngs if not complete(folder / n)]
    if broken:
        problems.append(f"incomplete files: {broken}")
    listed = []
    if MANIFEST_NAME in names:
        try:
            listed = [Path(json.loads(line)["output"]).name for line in (folder / MANIFEST_NAME).read_text().splitlines()]
        except (ValueError, KeyError) as error:
            problems.append(f"manifest unreadable: {error}")
    if len(listed) != len(set(listed)) and not killed:
        problems.append("manifest lists a file twice")
    if set(listed) - set(dngs):
        problems.append(f"manifest lists missing files: {sorted(set(listed) - set(dngs))}")
    unlisted = set(dngs) - set(listed)
    if exact and unlisted or len(unlisted) > allow_unlisted:
        problems.append(f"files not in the manifest: {sorted(unlisted)}")
    return problems


def _fork(target) -> int:
    pid = os.fork()
    if pid == 0:
        status = 1
        try:
            status = target() or 0
        except atomic.OutputError as error:
            os.write(2, f"fault: error: {error}\n".encode())
            status = REFUSED_STATUS
        except BaseException as error:  # noqa: BLE001 - the child reports and ends
            os.write(2, f"fault: unexpected {type(error).__name__}: {error}\n".encode())
            status = 99
        finally:
            os._exit(status)
    return pid


def _status(pid: int) -> int:
    _, status = os.waitpid(pid, 0)
    return os.waitstatus_to_exitcode(status)


def kill_case(rng: random.Random, folder: Path) -> list:
    names = rng.sample(NAMES, rng.randrange(1, len(NAMES)))
    pid = _fork(lambda: write_files(folder, names, rng, pause=0.002))
    time.sleep(rng.uniform(0, 0.05))
    os.kill(pid, signal.SIGKILL)
    _status(pid)
    if not folder.is_dir():
        return []
    problems = folder_problems(folder, exact=False, allow_unlisted=1, killed=True)
    with OutputFolder(folder) as reopened:              # the next run opens the folder
        if len(reopened.unlisted) > 1:
            problems.append(f"unlisted after reopening: {reopened.unlisted}")
    return problems + folder_problems(folder, exact=False, allow_unlisted=1)


def signal_case(rng: random.Random, folder: Path) -> list:
    from g2r_jax.cli.interruption import StopOnSignal

    names = rng.sample(NAMES, rng.randrange(1, len(NAMES)))
    number = rng.choice([signal.SIGINT, signal.SIGTERM])
    read, write = os.pipe()

    def child():
        os.close(read)
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, 2)
        with StopOnSignal("fault"):
            os.write(write, b"r")
            write_files(folder, names, rng, pause=0.002)
        return 0

    pid = _fork(child)
    os.close(write)
    os.read(read, 1)                        # the handlers are installed
    os.close(read)
    time.sleep(rng.uniform(0, 0.05))
    os.kill(pid, number)
    status = _status(pid)
    finished = folder.is_dir() and {p.name for p in folder.glob("*.dng")} == set(names)
    problems = [] if status in (0, 130) or finished else [f"exit status {status} (expected 130)"]
    return problems + folder_problems(folder, exact=True)


def concurrent_case(rng: random.Random, folder: Path) -> list:
    names = rng.sample(NAMES, rng.randrange(1, len(NAMES)))
    pids = [_fork(lambda: write_files(folder, names, random.Random(rng.random()), pause=0.001)) for _ in range(2)]
    statuses = sorted(_status(pid) for pid in pids)
    problems = []
    if statuses not in ([0, 0], [0, REFUSED_STATUS]):
        problems.append(f"exit statuses {statuses} (expected both 0, or one refused)")
    return problems + folder_problems(folder, exact=True)


def disk_full_case(rng: random.Random, folder: Path) -> list:
    names = rng.sample(NAMES, rng.randrange(1, len(NAMES)))
    index = rng.randrange(len(names))
    on_manifest = rng.random() < 0.5
    message = ""
    original_write = os.write
    calls = {"n": 0}

    def failing_write(descriptor, data):      # the manifest line is the only os.write of a run
        calls["n"] += 1
        if calls["n"] == index + 1:
            raise OSError(errno.ENOSPC, "No space left on device")
        return original_write(descriptor, data)

    try:
        if on_manifest:
            os.write = failing_write
            write_files(folder, names, rng)
        else:
            write_files(folder, names, rng, fail_at=(index, rng.randrange(0, 1000)))
    except atomic.OutputError as error:
        message = str(error)
    finally:
        os.write = original_write
    problems = folder_problems(folder, exact=True)
    expected = folder / (MANIFEST_NAME if on_manifest else names[index])
    if not message:
        problems.append("no error for a full disk")
    elif not message.startswith(f"{expected}: cannot write: no space left on the disk"):
        problems.append(f"message {message!r} does not name {expected.name} in our words")
    if ".tmp" in message or "Errno" in message:
        problems.append(f"message shows internals: {message!r}")
    return problems


def read_only_case(rng: random.Random, folder: Path) -> list:
    names = rng.sample(NAMES, rng.randrange(1, len(NAMES)))
    code = rng.choice([errno.EROFS, errno.EACCES, errno.ENOENT])
    original = tempfile.mkstemp
    message = ""

    def refused(*args, **kwargs):
        raise OSError(code, os.strerror(code))

    folder.mkdir(parents=True, exist_ok=True)
    try:
        tempfile.mkstemp = refused
        write_files(folder, names, rng)
    except atomic.OutputError as error:
        message = str(error)
    finally:
        tempfile.mkstemp = original
    problems = folder_problems(folder, exact=True)
    if not message.startswith(f"{folder / names[0]}: cannot write: "):
        problems.append(f"message {message!r} does not name {names[0]}")
    if ".tmp" in message or "Errno" in message or os.strerror(code) in message:
        problems.append(f"message shows internals: {message!r}")
    return problems


def command_signal_case(rng: random.Random, folder: Path) -> list:
    """g2r-convert itself (a subprocess, JAX included) stopped by SIGINT or SIGTERM after a random
    delay: during start-up, compilation (half the cases without the compilation cache) or writing."""
    import subprocess

    images = folder.parent / "frames"
    if not images.is_dir():
        import numpy as np
        from PIL import Image

        images.mkdir(parents=True)
        pixels = np.random.default_rng(0)
        for index in range(16):
            Image.fromarray(pixels.integers(0, 255, (96, 128, 3), dtype=np.uint8)).save(images / f"f{index:02d}.png")
    number = rng.choice([signal.SIGINT, signal.SIGTERM])
    argv = [sys.executable, "-m", "g2r_jax.cli.convert", str(images), "--profile", "NikonD40", "-o", str(folder),
            "--batch-size", "2"] + (["--no-compile-cache"] if rng.random() < 0.5 else [])
    process = subprocess.Popen(argv, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    time.sleep(rng.uniform(0.2, 12.0))
    process.send_signal(number)
    _, stderr = process.communicate(timeout=600)
    problems = []
    if process.returncode not in (0, 130):
        problems.append(f"exit status {process.returncode}: {stderr.strip()[-200:]}")
    if "Traceback" in stderr or "KeyboardInterrupt" in stderr or "Exception ignored" in stderr:
        problems.append(f"foreign text: {stderr.strip()[-200:]}")
    if process.returncode == 0 and len(list(folder.glob("*.dng"))) != 16:
        problems.append("exit 0 without every file: the signal was swallowed")
    folder.mkdir(parents=True, exist_ok=True)
    return problems + [p for p in folder_problems_dng(folder) if p]


def folder_problems_dng(folder: Path) -> list:
    """`folder_problems` for real DNGs (complete = readable by our reader, not the test payload)."""
    from g2r_jax.io.dng_read import read_dng_info

    problems = []
    names = sorted(p.name for p in folder.iterdir())
    if [n for n in names if atomic.is_temporary_name(n)]:
        problems.append("temporaries left")
    dngs = [n for n in names if n.endswith(".dng")]
    listed = [Path(json.loads(line)["output"]).name for line in (folder / MANIFEST_NAME).read_text().splitlines()] \
        if MANIFEST_NAME in names else []
    if sorted(listed) != dngs:
        problems.append(f"manifest lists {len(listed)} files for {len(dngs)} DNGs")
    for name in dngs:
        try:
            read_dng_info(folder / name)
        except Exception as error:  # noqa: BLE001 - an unreadable output is the finding
            problems.append(f"{name} unreadable: {error}")
    return problems


CASES = {"kill": kill_case, "signal": signal_case, "concurrent": concurrent_case,
         "disk-full": disk_full_case, "read-only": read_only_case, "command-signal": command_signal_case}


def campaign(kind: str, n: int, seed: int = 0) -> dict:
    """`n` cases of `kind` from `seed`: {kind, cases, seed, findings: [(case, problems)]}."""
    findings = []
    for case in range(n):
        rng = random.Random(f"{kind}:{seed}:{case}")
        scratch = Path(tempfile.mkdtemp(prefix="g2r_fault_"))
        try:
            problems = CASES[kind](rng, scratch / "out")
        finally:
            shutil.rmtree(scratch, ignore_errors=True)
        if problems:
            findings.append((case, problems))
    return {"kind": kind, "cases": n, "seed": seed, "findings": findings}


if __name__ == "__main__":
    kinds = KINDS if sys.argv[1] == "all" else (sys.argv[1],)
    count, first_seed = int(sys.argv[2]), int(sys.argv[3]) if len(sys.argv) > 3 else 0
    for name in kinds:
        print(json.dumps(campaign(name, count, first_seed)), flush=True)
