"""Fuzz campaign of the DNG reader's tag/pixel consistency (issue 34), through the reader and
through the in-process entry points of g2r-fit-profile and g2r-diagnose.

    python benchmarks/fuzz_reader.py --cases 2000 --commands 300 --audits 4 --seed 0 \
        --log /tmp/fuzz_reader.log --json /tmp/fuzz_reader.json

Seeds (made in a temporary folder, never in the repository): three `g2r-convert --example`
outputs (Canon600D, 640 x 480, uncompressed, seeds 0-2), the same three rewritten as lossless
JPEG tiles (`write_dng(..., compression='ljpeg')`), and the real GoPro HERO6 DNG of
`../shared/data/dng` when present (drawn for 1 case in 10: it is 24 MB).

Each case mutates the tags that place and pack the raw pixels (tests/fuzz_tags.py:
BitsPerSample, ImageWidth, ImageLength, Strip/TileOffsets, Strip/TileByteCounts, RowsPerStrip and
tile sides, WhiteLevel, Compression, SamplesPerPixel; one or two tags, listed or random values)
and counts, per mutation class:
- reader (`--cases`): the outcome of `read_dng_info` + `read_dng_pixels` (tests/fuzz_tags.py
  OUTCOMES; 'silently corrupt' = accepted with pixels other than the seed's, must be 0), and
  whether the mutated file changed on disk;
- g2r-diagnose's loader (every case): `audit.loading.load_measured([good, good, mutated],
  on_error=...)`, the call the audit reads its DNGs with: the mutated file kept with pixels other
  than the seed's is a silent acceptance; a file left out must be named in the line;
- g2r-fit-profile (`--commands`, the first N cases): `cli.fit_profile.main([folder, -o, p.json])`
  in-process on two good copies of the seed's camera and the mutated file, through
  tests/fuzz_harness.py's runner (exit status, stderr lines, tracebacks, inputs unchanged); a
  silent acceptance is a file whose tags the reader refuses and the command does not name, or
  any acceptance of a 'silently corrupt' file. The command fits tags only: a file whose tags are
  sound but whose pixels cannot be decoded ('pixels refused') is used for its tags, and counted
  apart when the command does not mention it;
- g2r-diagnose (`--audits`, the first N cases whose file the reader refuses): the whole command,
  `cli.diagnose.main(--profile Canon600D --measured folder ...)`, which must exit 1 naming the
  mutated file and still write the report (minutes per case on 2 shared cores, hence few).
"""

from __future__ import annotations

import argparse
import collections
import contextlib
import hashlib
import io
import json
import random
import shutil
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT))

import fuzz_harness as fh  # noqa: E402
import fuzz_tags as ft  # noqa: E402

GOPRO = ROOT / ".." / "shared" / "data" / "dng" / "gopro_hero6_GOPR0024.dng"
REFUSED = ("refused", "pixels refused")


def make_seeds(folder: Path) -> list:
    """[{'path', 'partners', 'truth', 'entries', 'weight'}] of the seed DNGs."""
    from g2r_jax.cli.convert import main as convert_main
    from g2r_jax.io.dng_read import read_dng_info, read_dng_pixels
    from g2r_jax.io.dng_write import write_dng

    plain, tiled = [], []
    for seed in range(3):
        out = folder / f"example{seed}"
        with contextlib.redirect_stderr(io.StringIO()), contextlib.redirect_stdout(io.StringIO()):
            status = convert_main(["--example", "-o", str(out), "--no-progress", "--seed", str(seed)])
        if status != 0:
            raise SystemExit(f"g2r-convert --example failed (exit {status})")
        plain.append(out / "colour_checker_scene.dng")
        info = read_dng_info(plain[-1])
        tiled.append(folder / f"example{seed}_ljpeg.dng")
        write_dng(tiled[-1], read_dng_pixels(plain[-1], info), info, compression="ljpeg")
    seeds = [(group[0], group[1:], 3.0) for group in (plain, tiled)]
    if GOPRO.is_file():   # two good partners: hard links under other names (the command reads each once)
        partners = []
        for k in range(2):
            partners.append(folder / f"gopro_{k}.dng")
            try:
                partners[-1].hardlink_to(GOPRO)
            except OSError:
                shutil.copyfile(GOPRO, partners[-1])
        seeds.append((GOPRO, partners, 0.7))
    out = []
    for path, partners, weight in seeds:
        data = path.read_bytes()
        out.append({"path": path, "partners": partners, "truth": ft.truth(path), "weight": weight,
                    "entries": ft.raw_entries(data), "data": data})
    return out


def generate(seeds: list, n: int, seed: int):
    """The campaign's cases, deterministic in `seed`: (case, seed dict, class, label, bytes)."""
    rng = random.Random(seed)
    weights = [s["weight"] for s in seeds]
    for case in range(n):
        chosen = rng.choices(seeds, weights)[0]
        name, label, data = ft.random_mutation(chosen["data"], chosen["entries"], rng)
        yield case, chosen, name, label, data


def digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def loader_outcome(folder: Path, bad: Path, truth) -> str:
    """What g2r-diagnose's loader does with the mutated file among two good ones."""
    import numpy as np

    from g2r_jax.audit.loading import load_measured

    lines = []
    try:
        loaded = load_measured(sorted(folder.glob("*.dng")), on_error=lines.append)
    except Exception as error:  # noqa: BLE001 - every good file refused, or an escaping error
        return f"loader raised {type(error).__name__}: {error}"
    kept = [m for m, info in loaded if Path(info.path).name == bad.name]
    if kept:
        mosaic = kept[0]   # the loader crops odd sizes to even: compare what both hold, as ft.outcome
        rows, columns = min(mosaic.shape[0], truth.shape[0]), min(mosaic.shape[1], truth.shape[1])
        same = np.array_equal(mosaic[:rows, :columns], truth[:rows, :columns])
        return "kept, same pixels" if same else "kept, other pixels"
    named = any(bad.name in line for line in lines)
    return "left out, named" if named else "left out, not named"


def command_outcome(work: Path, chosen: dict, data: bytes, reader: str, audit: bool) -> dict:
    """g2r-fit-profile (or, with `audit`, g2r-diagnose) on two good files and the mutated one."""
    from g2r_jax.cli.diagnose import main as diagnose_main
    from g2r_jax.cli.fit_profile import main as fit_main

    folder = work / "in"
    folder.mkdir(parents=True)
    for k, partner in enumerate(chosen["partners"]):
        target = folder / f"good{k}.dng"
        try:
            target.hardlink_to(partner)
        except OSError:
            shutil.copyfile(partner, target)
    bad = folder / "mutated.dng"
    bad.write_bytes(data)
    before = {p.name: digest(p) for p in folder.iterdir()}
    (work / "out").mkdir()
    if audit:
        name, output = "g2r-diagnose", work / "new" / "REPORT.json"
        argv = ["--profile", "Canon600D", "--measured", str(folder), "--report", str(output), "--quiet",
                "--folds", "2"]
        status, out, err = fh.run_main(diagnose_main, argv)
    else:
        name, output = "g2r-fit-profile", work / "out" / "p.json"
        status, out, err = fh.run_main(fit_main, [str(folder), "-o", str(output)])
    problems = fh._line_problems(name, err)
    if not isinstance(status, int):
        problems.append(str(status)[:300])
    elif status not in (0, 1):
        problems.append(f"exit {status} although two good files were there: {err.strip()[-300:]}")
    named = "mutated.dng" in err
    silent = (reader == "silently corrupt" and status == 0) or (reader == "refused" and not named)
    if {p.name: digest(p) for p in folder.iterdir()} != before:
        problems.append("inputs modified")
    return {"command": name, "status": status if isinstance(status, int) else "exception", "named": named,
            "silent": silent, "problems": problems, "written": output.exists()}


def run(args) -> dict:
    import numpy as np  # noqa: F401 - loaded before the clock starts

    base = Path(tempfile.mkdtemp(prefix="g2r_fuzz_reader_"))
    log = open(args.log, "a") if args.log else sys.stdout
    began = time.time()
    counts = {"reader": collections.Counter(), "loader": collections.Counter(), "classes": {},
              "commands": collections.Counter(), "audits": collections.Counter()}
    findings, audits_run = [], 0
    try:
        seeds = make_seeds(base / "seeds")
        for case, chosen, name, label, data in generate(seeds, args.cases, args.seed):
            work = base / f"case{case}"
            work.mkdir()
            single = work / "mutated.dng"
            single.write_bytes(data)
            reader, message = ft.outcome(single, chosen["truth"])
            modified = digest(single) != hashlib.sha256(data).hexdigest()
            counts["reader"][reader] += 1
            counts["reader"]["inputs modified"] += modified
            counts["classes"].setdefault(name, collections.Counter())[reader] += 1
            loader_folder = work / "loader"
            loader_folder.mkdir()
            for k, partner in enumerate(chosen["partners"]):
                (loader_folder / f"good{k}.dng").hardlink_to(partner)
            shutil.copyfile(single, loader_folder / "mutated.dng")
            loaded = loader_outcome(loader_folder, loader_folder / "mutated.dng", chosen["truth"])
            counts["loader"][loaded] += 1
            bad = reader in ("silently corrupt", "unnamed error", "traceback") or modified or \
                loaded in ("kept, other pixels", "left out, not named") or loaded.startswith("loader raised")
            result = None
            if case < args.commands:
                result = command_outcome(work / "fit", chosen, data, reader, audit=False)
                counts["commands"][f"exit {result['status']}"] += 1
                counts["commands"]["named"] += result["named"]
                counts["commands"]["silently accepted"] += result["silent"]
                counts["commands"]["tags used, pixels refused, file not mentioned"] += (
                    reader == "pixels refused" and not result["named"])
                counts["commands"]["with problems"] += bool(result["problems"])
                bad = bad or result["silent"] or bool(result["problems"])
            if audits_run < args.audits and reader in REFUSED:
                audits_run += 1
                result = command_outcome(work / "audit", chosen, data, reader, audit=True)
                counts["audits"][f"exit {result['status']}"] += 1
                counts["audits"]["named"] += result["named"]
                counts["audits"]["report written"] += result["written"]
                counts["audits"]["silently accepted"] += result["silent"]
                counts["audits"]["with problems"] += bool(result["problems"])
                bad = bad or result["silent"] or bool(result["problems"])
            if bad:
                findings.append({"case": case, "seed": chosen["path"].name, "class": name, "mutation": label,
                                 "reader": reader, "message": message[:300], "loader": loaded,
                                 "command": result})
                print(f"finding in case {case}: {findings[-1]}", file=log, flush=True)
            shutil.rmtree(work, ignore_errors=True)
            if (case + 1) % 100 == 0:
                print(f"{case + 1} cases, {time.time() - began:.0f} s, reader {dict(counts['reader'])}, "
                      f"commands {dict(counts['commands'])}", file=log, flush=True)
    finally:
        shutil.rmtree(base, ignore_errors=True)
    return {"cases": args.cases, "seed": args.seed, "commands": args.commands, "audits": audits_run,
            "seconds": round(time.time() - began), "reader": dict(counts["reader"]),
            "loader": dict(counts["loader"]), "fit_profile": dict(counts["commands"]),
            "diagnose": dict(counts["audits"]),
            "classes": {k: dict(v) for k, v in sorted(counts["classes"].items())}, "findings": findings}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cases", type=int, default=2000)
    parser.add_argument("--commands", type=int, default=300, help="cases also run through g2r-fit-profile")
    parser.add_argument("--audits", type=int, default=4, help="refused cases also run through g2r-diagnose")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--log", help="progress lines go here (default: stdout)")
    parser.add_argument("--json", help="write the counts here")
    args = parser.parse_args(argv)
    result = run(args)
    text = json.dumps(result, indent=1)
    if args.json:
        Path(args.json).write_text(text)
    print(json.dumps({k: v for k, v in result.items() if k not in ("classes", "findings")}))
    print(f"findings: {len(result['findings'])}")
    return 0 if not result["findings"] else 1


if __name__ == "__main__":
    sys.exit(main())
