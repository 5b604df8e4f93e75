"""Fuzz campaign of g2r-downstream (issue 34): mutated DNGs, CG images, burst frames and arguments
through the command's in-process entry point (`g2r_jax.cli.downstream.main`).

Seeds (written once per run, no data files needed): 14 DNGs of a NikonD40 (dead-leaves scenes under
drawn lights, 128 x 160), 3 CG PNGs and a JPEG, a synthetic burst of 4 frames. Each case builds its
inputs in an empty folder from the seeds and one attack:

- `dng`: a mutated copy of a measured DNG added to 13 good ones (`tests/fuzz_harness.mutate_dng`);
- `cg`: a mutated CG image beside the good ones (`mutate_image`);
- `burst`: a mutated frame added to the 4 good frames, with `--burst` alone;
- `duplicate`: a copy of a measured DNG under another name, or the folder given twice;
- `calibration`: one DNG whose calibration illuminants or camera model differ from the others';
- `constant`: one DNG whose pixels all read one value;
- `args`: one or two arguments replaced by hostile values (numbers, paths, report folders, names).

Most cases run with `--dry-run` (everything read, vetted and the report folder probed, nothing
trained); one in `FULL_EVERY` runs the whole check with the cheapest settings (moments estimator,
1 seed, 50 views, 2 folds, 2 denoiser steps). Counted, all of which must be 0:
- `silently_accepted_corrupt`: a mutated DNG or frame that the command used without naming it
  although the reader gives pixels that differ from the original's in more than 1 % of places
  (or no pixels at all);
- `duplicate_leaks`: a copy used without the note that keeps it in one fold;
- `whole_run_aborts`: exit 2 although one bad file was among enough good ones;
- `unnamed_refusals`: a file left out without its name, or an exit 2 whose message names no
  option and no input;
- `tracebacks`: an escaping exception, or a line on stderr that is not the command's own (a
  traceback, a library's text);
- `hangs`: no answer within `CASE_SECONDS`;
- `inputs_modified`: an input file whose size, first MiB or mtime changed;
- `report_problems`: a report folder left by a refused or dry run, a missing report after a full
  run, or a temporary file left.

Run: `nice -n 5 python benchmarks/fuzz_downstream.py N [SEED] [--log FILE] [--first K]`; prints one
JSON line of counts (docs/pages/validation/reliability.md).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import random
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]

import fuzz_harness  # noqa: E402  (sets TF_CPP_MIN_LOG_LEVEL before JAX loads)
from fuzz_harness import _digest, _line_problems, _tag_fields, mutate_dng, mutate_image, run_main  # noqa: E402

COMMAND = "g2r-downstream"
KINDS = {"dng": 20, "cg": 14, "burst": 20, "duplicate": 6, "calibration": 6, "constant": 4, "args": 30}
FULL_EVERY = 250
CASE_SECONDS = 120               # a dry run; a full one (tiny training) takes minutes on a loaded machine
FULL_SECONDS = 1200
GOOD_MEASURED = 13
COUNTS = ("silently_accepted_corrupt", "duplicate_leaks", "whole_run_aborts", "unnamed_refusals", "tracebacks",
          "hangs", "inputs_modified", "report_problems")
CHEAP = ["--estimators", "moments", "--seeds", "1", "--n", "50", "--folds", "2", "--denoiser-steps", "2"]


def make_seeds(folder: Path) -> dict:
    """The seed files in `folder` (made once, reused when `folder` holds them): measured DNGs, CG
    images, burst frames, and what the checks compare with (the original pixels)."""
    from PIL import Image

    import g2r_jax
    from g2r_jax.audit import scenes, simulate
    from g2r_jax.downstream.denoising.bursts import write_synthetic_burst
    from g2r_jax.io.dng_read import read_dng_info, read_dng_pixels
    from g2r_jax.io.dng_write import write_dng

    measured, cg, burst = folder / "measured", folder / "cg", folder / "burst"
    if not (folder / "done").exists():
        profile = g2r_jax.load_profile("NikonD40")
        for sub in (measured, cg, burst):
            sub.mkdir(parents=True, exist_ok=True)
        files = simulate.simulate(profile, scenes.scene_set(GOOD_MEASURED + 1, 3, 128, 160), 1)
        for i, (mosaic, info) in enumerate(files):
            write_dng(measured / f"real_{i:02d}.dng", mosaic, info)
        for i, scene in enumerate(scenes.scene_set(4, 9, 136, 176)):
            pixels = (np.clip(scene, 0, 1) * 255).round().astype(np.uint8) if scene.dtype != np.uint8 else scene
            Image.fromarray(pixels).save(cg / (f"render_{i}.png" if i < 3 else f"render_{i}.jpg"))
        write_synthetic_burst(burst, profile, n_frames=4, height=128, width=160)
        (folder / "done").write_text("")
    dngs, frames = sorted(measured.glob("*.dng")), sorted(burst.glob("*.dng"))
    infos = [read_dng_info(p) for p in dngs]
    return {"measured": dngs, "infos": infos, "mosaics": [read_dng_pixels(p, i) for p, i in zip(dngs, infos)],
            "burst_mosaics": {p: read_dng_pixels(p, read_dng_info(p)) for p in frames},
            "cg": sorted(cg.iterdir()), "burst": frames,
            "fields": {p: _tag_fields(p.read_bytes()) for p in dngs + frames}}


@dataclasses.dataclass
class Case:
    """One case's inputs as written, the command line, and what the checks need."""

    label: str
    argv: list
    inputs: list                  # every input file (checked unchanged)
    bad: str = ""                 # the file name that must be named if left out
    original: object = None       # the pixels a mutated DNG had (for the corrupt check)
    copy_of: tuple = ()           # (copy name, original name)
    one_bad_among_good: bool = False
    dry_run: bool = True


def _copy(paths, folder: Path, skip=None) -> list:
    folder.mkdir(exist_ok=True)
    out = []
    for path in paths[:GOOD_MEASURED] if skip is None else [p for p in paths if p != skip][:GOOD_MEASURED]:
        shutil.copyfile(path, folder / path.name)
        out.append(folder / path.name)
    return out


def _base(work: Path, seeds: dict, measured=True, cg=True, burst=False) -> tuple[list, list]:
    argv, inputs = [], []
    if measured:
        inputs += _copy(seeds["measured"], work / "measured")
        argv += ["--measured", str(work / "measured")]
    if cg:
        inputs += _copy(seeds["cg"], work / "cg")
        argv += ["--cg", str(work / "cg")]
    if burst:
        inputs += _copy(seeds["burst"], work / "burst")
        argv += ["--burst", str(work / "burst")]
    return argv, inputs


def _dng_case(rng, work, seeds) -> Case:
    argv, inputs = _base(work, seeds)
    index = rng.randrange(len(seeds["measured"]))
    source = seeds["measured"][index]
    data, how = mutate_dng(source.read_bytes(), rng, seeds["fields"][source], deep=rng.random() < 0.3)
    target = work / "measured" / "zz_mutated.dng"
    target.write_bytes(data)
    return Case(f"dng {source.name}: {how}", argv, inputs + [target], bad=target.name, original=seeds["mosaics"][index],
                one_bad_among_good=True)


def _cg_case(rng, work, seeds) -> Case:
    colour = rng.random() < 0.4   # else the CG content of the burst's denoising check (fewer files to read)
    argv, inputs = _base(work, seeds, measured=colour, burst=not colour)
    source = rng.choice(seeds["cg"])
    data, how = mutate_image(source.read_bytes(), source.suffix.lower(), rng)
    target = work / "cg" / f"zz_mutated{source.suffix}"
    target.write_bytes(data)
    return Case(f"cg {source.name}: {how}", argv, inputs + [target], bad=target.name, one_bad_among_good=True)


def _burst_case(rng, work, seeds) -> Case:
    folder = work / "burst"
    inputs = _copy(seeds["burst"], folder)
    source = rng.choice(seeds["burst"])
    data, how = mutate_dng(source.read_bytes(), rng, seeds["fields"][source], deep=rng.random() < 0.5)
    target = folder / "zz_mutated.dng"
    target.write_bytes(data)
    original = seeds["burst_mosaics"][source]
    return Case(f"burst {source.name}: {how}", ["--burst", str(folder)], inputs + [target], bad=target.name,
                original=original, one_bad_among_good=True)


def _duplicate_case(rng, work, seeds) -> Case:
    argv, inputs = _base(work, seeds)
    if rng.random() < 0.3:
        return Case("measured folder given twice", argv[:2] + [argv[1]] + argv[2:], inputs)
    source = seeds["measured"][rng.randrange(GOOD_MEASURED)]
    name = rng.choice(("copy.dng", "zz_same.DNG", f"{source.stem}_2.dng", "a.dng"))
    shutil.copyfile(source, work / "measured" / name)
    return Case(f"copy of {source.name} as {name}", argv, inputs + [work / "measured" / name], copy_of=(name, source.name))


def _odd_file_case(rng, work, seeds, kind) -> Case:
    from g2r_jax.io.dng_write import write_dng

    argv, inputs = _base(work, seeds)
    index = GOOD_MEASURED   # the 14th seed scene: not among the good copies
    mosaic, info = seeds["mosaics"][index], seeds["infos"][index]
    if kind == "constant":
        mosaic = np.full_like(mosaic, rng.choice((0, 1, 600, int(info.white_level), 65535)))
        how = f"every pixel {mosaic.flat[0]}"
    elif rng.random() < 0.5:
        other = tuple(info.calibration_illuminants)
        while sorted(other) == sorted(info.calibration_illuminants):
            other = tuple(rng.sample((17, 19, 20, 21, 23, 10, 11), 2))
        info = dataclasses.replace(info, calibration_illuminants=other)
        how = f"calibration illuminants {other}"
    else:
        info = dataclasses.replace(info, unique_camera_model="Other Camera", model="Other")
        how = "another camera model"
    target = work / "measured" / "zz_odd.dng"
    write_dng(target, mosaic, info)
    return Case(f"{kind}: {how}", argv, inputs + [target], bad=target.name, one_bad_among_good=True)


ARGUMENT_VALUES = {
    "--seeds": ("0", "-1", "abc", "", "1e3", str(10 ** 30), "99999999999999999999", "2", "101"),
    "--n": ("0", "49", "-5", "nan", str(2 ** 63), "100000000", "64"),
    "--folds": ("0", "1", "51", "-2", "x", "3"),
    "--denoiser-steps": ("0", "-1", "1e9", "5"),
    "--estimators": ("", "cnn,,", "oracle", "moments,moments", "CNN", "histogram"),
    "--profile": ("nonexistent_camera", "NikonD40", "{garbage}", "/dev/null", "../x.json"),
    "--max-megapixels": ("-1", "nan", "inf", "0", "1e-9", "abc"),
}


def _args_case(rng, work, seeds) -> Case:
    colour = rng.random() < 0.5
    argv, inputs = _base(work, seeds, measured=colour, cg=colour or rng.random() < 0.5, burst=not colour)
    (work / "a_file.txt").write_text("not a folder")
    report = rng.choice(("", " ", "/proc/g2r/x", "/proc/self/status", str(work / "measured"),
                         str(work / "cg" / "sub"), str(work / "a_file.txt"), str(work / "a_file.txt" / "r"),
                         str(work / ("n" * 300)), str(work / "r" / "deep"), "/dev/null/x", str(work / "report")))
    argv += ["--report", report]
    how = [f"--report {report[:40]!r}"]
    for _ in range(rng.randint(0, 2)):
        choice = rng.random()
        if choice < 0.6:
            option = rng.choice(list(ARGUMENT_VALUES))
            value = rng.choice(ARGUMENT_VALUES[option])
            if option == "--profile" and value == "{garbage}":
                (work / "garbage.json").write_text("{garbage")
                value = str(work / "garbage.json")
            argv += [option, value]
        elif choice < 0.8:
            option = rng.choice(("--measured", "--cg", "--burst"))
            value = rng.choice((str(work / "missing"), str(work / "a_file.txt"), str(work / "cg"), str(work / "measured"),
                                str(work / "empty")))
            (work / "empty").mkdir(exist_ok=True)
            argv = [a for a in argv] + [option, value]
        else:
            option, value = rng.choice((("--bogus", "1"), ("--measured", ""), ("--seeds", "--quiet"), ("-q", "")))
            argv += [option] + ([value] if value else [])
        how.append(f"{option} {value[:40]!r}")
    return Case("args: " + ", ".join(how), argv, inputs)


def make_case(kind: str, rng: random.Random, work: Path, seeds: dict) -> Case:
    if kind in ("calibration", "constant"):
        return _odd_file_case(rng, work, seeds, kind)
    return {"dng": _dng_case, "cg": _cg_case, "burst": _burst_case, "duplicate": _duplicate_case,
            "args": _args_case}[kind](rng, work, seeds)


def _pixels_differ(path: Path, original) -> bool:
    """True when the reader's pixels of `path` differ from `original` in more than 1 % of places."""
    from g2r_jax.io.dng_read import read_dng_info, read_dng_pixels

    try:
        pixels = read_dng_pixels(path, read_dng_info(path))
    except Exception:  # noqa: BLE001 - used by the command although the reader refuses it
        return True
    return pixels.shape != np.shape(original) or float(np.mean(pixels != original)) > 0.01


def _refusal_named(err: str, argv: list) -> bool:
    lines = [line for line in err.splitlines() if line.startswith(f"{COMMAND}: error")]
    if not lines:
        return False
    last = lines[-1]
    paths = [a for a in argv if "/" in a]
    return "--" in last or "argument" in last or any(p and p in last for p in paths)


def check(case: Case, status, err: str, work: Path, before: dict) -> dict:
    """The broken promises of one case, as {count name: [details]}."""
    found = {name: [] for name in COUNTS}
    if not isinstance(status, int):
        found["hangs" if str(status).startswith("hang") else "tracebacks"].append(str(status)[:300])
        return found
    own = err if "usage:" not in err else "\n".join(l for l in err.splitlines() if l.startswith(f"{COMMAND}:"))
    found["tracebacks"] += _line_problems(COMMAND, own)
    if status == 2 and not _refusal_named(err, case.argv):
        found["unnamed_refusals"].append(err.strip()[-300:])
    if status == 2 and case.one_bad_among_good:
        found["whole_run_aborts"].append(err.strip()[-300:])
    named = bool(case.bad) and case.bad in err
    if status == 1 and case.bad and not named:
        found["unnamed_refusals"].append(f"exit 1 without {case.bad}: {err.strip()[-300:]}")
    if status in (0, 1) and case.bad and not named and case.original is not None:
        if _pixels_differ(work / ("burst" if case.label.startswith("burst") else "measured") / case.bad, case.original):
            found["silently_accepted_corrupt"].append(case.label)
    if status in (0, 1) and case.copy_of and not all(name in err for name in case.copy_of):
        found["duplicate_leaks"].append(case.label)
    if {str(p): _digest(p) for p in case.inputs if p.exists()} != before:
        found["inputs_modified"].append(case.label)
    report = work / "report"
    if case.dry_run or status == 2:
        if report.exists() and any(report.iterdir()):
            found["report_problems"].append("report written by a dry or refused run")
    elif not (report / "report.json").exists():
        found["report_problems"].append("no report.json after a full run")
    if case.dry_run and (work / "r").exists():
        found["report_problems"].append("the report folder's probe left a folder")
    leftovers = [p.name for p in work.rglob("*") if p.name.endswith(".tmp") or p.name.startswith(".g2r-probe")]
    if leftovers:
        found["report_problems"].append(f"left: {leftovers[:3]}")
    return found


def campaign(n: int, seed: int = 0, log=print, full_every: int = FULL_EVERY, seeds_dir: Path | None = None,
             first: int = 0, stop_after: float = float("inf")) -> dict:
    """Run cases `first`..`n`-1 drawn from `seed` (the earlier ones are drawn, not run: a campaign
    runs in pieces), starting none after `stop_after` seconds; returns the counts, outcomes and
    findings (`cases`: how many ran)."""
    from g2r_jax.cli.downstream import main

    base = Path(tempfile.mkdtemp(prefix="g2r_fuzz_downstream_"))
    totals = {name: 0 for name in COUNTS}
    outcomes, findings, started, ran = {}, [], time.time(), 0
    try:
        seeds = make_seeds(seeds_dir or base / "seeds")
        rng = random.Random(seed)
        kinds = [k for k, w in KINDS.items() for _ in range(w)]
        for index in range(n):
            kind = rng.choice(kinds)
            work = base / f"case{index}"
            work.mkdir()
            case = make_case(kind, rng, work, seeds)
            if index < first or time.time() - started > stop_after:
                shutil.rmtree(work, ignore_errors=True)
                if index < first:
                    continue
                break
            ran += 1
            full = full_every > 0 and (index - first) % full_every == 0 and kind != "args"
            fuzz_harness.CASE_SECONDS = FULL_SECONDS if full else CASE_SECONDS
            case.dry_run = not full
            argv = list(case.argv)
            if "--report" not in argv:
                argv += ["--report", str(work / "report")]
            argv += (["--dry-run"] if case.dry_run else CHEAP) + ["--quiet"]
            if "--profile" not in argv:   # a shipped profile: no fit per case (the fit is tested elsewhere)
                argv += ["--profile", "NikonD40"]
            case.argv = argv
            before = {str(p): _digest(p) for p in case.inputs if p.exists()}
            began = time.time()
            status, _, err = run_main(main, argv)
            seconds = time.time() - began
            found = check(case, status, err, work, before)
            outcomes[f"{kind} exit {status if isinstance(status, int) else 'none'}"] = \
                outcomes.get(f"{kind} exit {status if isinstance(status, int) else 'none'}", 0) + 1
            for name, details in found.items():
                if details:
                    totals[name] += 1
                    findings.append({"case": index, "kind": kind, "count": name, "input": case.label,
                                     "detail": details[0][:300]})
                    log(f"finding in case {index} ({kind}: {case.label}): {name}: {details[0][:300]}")
            shutil.rmtree(work, ignore_errors=True)
            log(f"case {index} {kind} exit {status if isinstance(status, int) else 'none'} {seconds:.1f} s"
                f"{' full' if full else ''}: {case.label[:80]}")
            if (index + 1) % 50 == 0:
                log(f"progress: {index + 1} cases, {time.time() - started:.0f} s, findings {sum(totals.values())}")
    finally:
        shutil.rmtree(base, ignore_errors=True)
    return {"cases": ran, "first": first, "last": first + ran - 1, "seed": seed, "seconds": round(time.time() - started), "counts": totals,
            "outcomes": dict(sorted(outcomes.items())), "findings": findings}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("n", type=int)
    parser.add_argument("seed", type=int, nargs="?", default=0)
    parser.add_argument("--log", type=Path, help="progress and findings go here (default: stderr)")
    parser.add_argument("--full-every", type=int, default=FULL_EVERY,
                        help="one case in this many runs the whole check (tiny training) instead of --dry-run, "
                             "the first of a piece among them (0: none)")
    parser.add_argument("--seeds-dir", type=Path, help="keep (or reuse) the seed files here")
    parser.add_argument("--first", type=int, default=0, help="run cases FIRST..N-1 only")
    parser.add_argument("--stop-after", type=float, default=float("inf"), metavar="SECONDS",
                        help="start no case after this many seconds (the count run is reported)")
    args = parser.parse_args(argv)
    handle = open(args.log, "a") if args.log else sys.stderr
    try:
        result = campaign(args.n, args.seed, log=lambda line: print(line, file=handle, flush=True),
                          full_every=args.full_every, seeds_dir=args.seeds_dir, first=args.first,
                          stop_after=args.stop_after)
    finally:
        if args.log:
            handle.close()
    print(json.dumps({k: v for k, v in result.items() if k != "findings"}), flush=True)
    if result["findings"]:
        print(json.dumps(result["findings"][:50], indent=1))
    return 0 if not any(result["counts"].values()) else 1


if __name__ == "__main__":
    sys.exit(main())
