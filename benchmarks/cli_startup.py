"""Start-up of the commands: argument errors, --help, imports, and the first converted frame.

    python benchmarks/cli_startup.py             # one 12-MP frame (3024 x 4032)
    python benchmarks/cli_startup.py --quick     # one 756 x 1008 frame
    python benchmarks/cli_startup.py --repeat 7  # more runs per figure (the median is printed)
    python benchmarks/cli_startup.py --baseline /path/to/older/checkout   # side by side with it

Every figure is the wall time of a fresh process, as a user meets it (with `--baseline`, the same
command of an older checkout, run as `python -m` with that checkout first on PYTHONPATH, beside it):
- arguments: each command's `--help`, its usage on no arguments, and argument errors found while
  parsing (a bad value, a bad output path); and whether such a run imported JAX (it must not).
- imports:   `python -X importtime -c "import g2r_jax.batch.conversion"` (what `g2r-convert`
  imports before its first frame): the total and the largest packages.
- first frame: `g2r-convert ONE.png` end to end with an empty compilation cache (cold) and with
  the cache the cold run filled (warm), also without the traced programs kept on disk
  (`G2R_JAX_NO_PROGRAM_STORE=1`), split into its phases in one process (imports, profile,
  first DNG written, then a second DNG of the same size: what a frame costs once the program is
  traced); beside it the floor: Python + `import jax` + one trivial jitted call.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

FULL = (3024, 4032)
QUICK = (756, 1008)
COMMANDS = ("g2r-convert", "g2r-fit-profile", "g2r-diagnose")
MODULES = {"g2r-convert": "g2r_jax.cli.convert", "g2r-fit-profile": "g2r_jax.cli.fit_profile",
           "g2r-diagnose": "g2r_jax.cli.diagnose"}
# Packages whose cumulative import time is listed (colour/matplotlib should be absent).
WATCHED = ("jax", "numpy", "equinox", "optimistix", "lineax", "jaxtyping", "colour", "matplotlib",
           "scipy", "imagecodecs", "tifffile", "PIL", "g2r_jax.batch.conversion", "g2r_jax.pipeline",
           "g2r_jax.audit")


def command_line(command: str) -> list[str]:
    """`python -m` of the command's module (what its console script runs)."""
    return [sys.executable, "-m", MODULES[command]]


def environment(checkout: str | None = None, **extra) -> dict:
    """This environment, with `checkout` first on PYTHONPATH when given."""
    env = dict(os.environ, **extra)
    if checkout:
        env["PYTHONPATH"] = os.pathsep.join([str(Path(checkout).resolve())] + [p for p in [env.get("PYTHONPATH")] if p])
    return env


def wall(argv, env=None, cwd=None) -> tuple[float, subprocess.CompletedProcess]:
    start = time.perf_counter()
    done = subprocess.run(argv, capture_output=True, text=True, env=env, cwd=cwd)
    return time.perf_counter() - start, done


def median_wall(argv, repeat: int, cwd=None, env=None) -> tuple[float, int]:
    runs = [wall(argv, cwd=cwd, env=env) for _ in range(repeat)]
    return statistics.median(t for t, _ in runs), runs[-1][1].returncode


def imports_jax(argv, cwd=None, env=None) -> bool:
    """Whether the process imported jax: `-X importtime` lists every module it imported."""
    done = subprocess.run([argv[0], "-X", "importtime"] + argv[1:], capture_output=True, text=True, cwd=cwd, env=env)
    return any(line.split("|")[-1].strip() == "jax" for line in done.stderr.splitlines())


def argument_cases(folder: Path) -> list[tuple[str, list[str]]]:
    """(label, arguments) of each command: help, no arguments, errors caught while parsing."""
    (folder / "a_file").write_text("x")
    return [
        ("g2r-convert", ["--help"]), ("g2r-convert", []),
        ("g2r-convert", ["in.png", "--profile", "gopro_hero6", "-o", "out", "--seed", "x"]),
        ("g2r-convert", ["in.png", "--profile", "gopro_hero6"]),
        ("g2r-convert", ["in.png", "--profile", "gopro_hero6", "-o", "a_file"]),
        ("g2r-convert", ["in.png", "--profile", "no_such_camera", "-o", "out"]),
        ("g2r-fit-profile", ["--help"]), ("g2r-fit-profile", []),
        ("g2r-fit-profile", ["dngs", "-o", "missing/dir/p.json"]),
        ("g2r-fit-profile", ["dngs", "-o", "."]),
        ("g2r-diagnose", ["--help"]), ("g2r-diagnose", []),
        ("g2r-diagnose", ["--profile", "gopro_hero6", "--measured", "dngs", "--report", "r.json", "--alpha", "2"]),
        ("g2r-diagnose", ["--profile", "gopro_hero6", "--report", "r.json"]),
    ]


def section_arguments(repeat: int, baseline: str | None) -> None:
    sides = [("this checkout", environment())] + ([(baseline, environment(baseline))] if baseline else [])
    print(f"\n== arguments: wall time of a fresh process (median of {repeat}), exit status, whether it "
          f"imported jax; columns: {' | '.join(name for name, _ in sides)}" + (" | ratio" if baseline else ""))
    with tempfile.TemporaryDirectory() as folder:
        for command, arguments in argument_cases(Path(folder)):
            argv = command_line(command) + arguments
            cells, seconds = [], []
            for _, env in sides:
                median, code = median_wall(argv, repeat, cwd=folder, env=env)
                jax_loaded = imports_jax(argv, cwd=folder, env=env)
                seconds.append(median)
                cells.append(f"{median:6.3f} s  exit {code}  jax: {'yes' if jax_loaded else 'no '}")
            if baseline:
                cells.append(f"{seconds[1] / seconds[0]:5.1f}x")
            print(f"  {' | '.join(cells)} | {command} {' '.join(arguments) or '(no arguments)'}")


def import_table(module: str, env=None) -> dict[str, float]:
    """Cumulative import time (s) of each module `python -X importtime -c 'import module'` lists."""
    done = subprocess.run([sys.executable, "-X", "importtime", "-c", f"import {module}"], capture_output=True,
                          text=True, check=True, env=env, cwd=tempfile.gettempdir())   # not this checkout's cwd
    table = {}
    for line in done.stderr.splitlines():
        if not line.startswith("import time:") or "cumulative" in line:
            continue
        _, cumulative, name = (part.strip() for part in line.split(":", 1)[1].split("|"))
        table.setdefault(name, int(cumulative) / 1e6)
    return table


def section_imports(repeat: int, baseline: str | None) -> None:
    module = "g2r_jax.batch.conversion"
    tables = [import_table(module) for _ in range(repeat)]
    total = statistics.median(t[module] for t in tables)
    print(f"\n== imports: python -X importtime -c 'import {module}' (median of {repeat})")
    print(f"  total {total:.3f} s")
    for name in WATCHED:
        values = [t[name] for t in tables if name in t]
        print(f"  {name:28s} " + (f"{statistics.median(values):6.3f} s" if values else "  not imported"))
    if baseline:   # the conversion module of an older layout
        old = "g2r_jax.batch.conversion" if (Path(baseline) / "g2r_jax" / "batch").is_dir() else "g2r_jax.convert"
        old_tables = [import_table(old, environment(baseline)) for _ in range(repeat)]
        old_total = statistics.median(t[old] for t in old_tables)
        print(f"  {baseline}: import {old} {old_total:.3f} s ({old_total / total:.1f}x); colour-science "
              f"{'imported' if 'colour' in old_tables[0] else 'not imported'}, matplotlib "
              f"{'imported' if 'matplotlib' in old_tables[0] else 'not imported'}")


PHASES = r"""
import sys, time
T0 = float(sys.argv[1])
def mark(label):
    print(f"{label} {time.time() - T0:.4f}", flush=True)
mark("python")
import g2r_jax.cli.convert as cli
from g2r_jax.batch import conversion
mark("imports")
from g2r_jax.runtime.deterministic import request_deterministic_gpu_ops
from g2r_jax.runtime.compile_cache import enable
request_deterministic_gpu_ops()   # as the command does: XLA flags are part of the cache key
enable(program="g2r-convert")
from g2r_jax.profile.schema import load_profile
profile = load_profile("gopro_hero6")
mark("profile")
result = conversion.convert_files([sys.argv[2]], profile, sys.argv[3],
                                  options=conversion.ConvertOptions(progress=False))
assert len(result.records) == 1, result.errors
mark("first-dng")
result = conversion.convert_files([sys.argv[2]], profile, sys.argv[3] + "_again",
                                  options=conversion.ConvertOptions(progress=False))
mark("second-dng")
"""

FLOOR_JAX = "import jax, jax.numpy as jnp; jax.jit(lambda x: x + 1)(jnp.zeros(4)).block_until_ready()"


def write_frame(path: Path, shape) -> None:
    import numpy as np
    from PIL import Image

    rows, cols = np.mgrid[0:shape[0], 0:shape[1]]
    noise = np.random.default_rng(0).integers(0, 24, shape + (3,))
    image = np.stack([cols * 230 // shape[1], rows * 230 // shape[0], (rows + cols) * 230 // sum(shape)], -1)
    Image.fromarray((image + noise).astype(np.uint8)).save(path)


def convert_walls(frame: Path, folder: Path, repeat: int, env: dict, label: str) -> tuple[list, list]:
    """Wall times of `g2r-convert frame`: cold (each with an empty cache) and warm (the cache the
    last cold run filled)."""
    convert = command_line("g2r-convert") + [str(frame), "--profile", "gopro_hero6", "--no-progress"]
    cold, warm = [], []
    for k in range(max(1, repeat // 2)):
        cache = {"G2R_JAX_CACHE_DIR": str(folder / f"cache_{label}_{k}")}
        seconds, done = wall(convert + ["-o", str(folder / f"out_{label}_cold{k}")], env=dict(env, **cache), cwd=folder)
        assert done.returncode == 0, done.stderr[-2000:]
        cold.append(seconds)
    for k in range(repeat):
        seconds, done = wall(convert + ["-o", str(folder / f"out_{label}_warm{k}")], env=dict(env, **cache), cwd=folder)
        assert done.returncode == 0, done.stderr[-2000:]
        warm.append(seconds)
    return cold, warm


def section_first_frame(shape, repeat: int, baseline: str | None) -> None:
    print(f"\n== first frame: g2r-convert ONE.png ({shape[0]} x {shape[1]}), fresh process, median of {repeat}")
    with tempfile.TemporaryDirectory() as folder:
        folder = Path(folder)
        frame = folder / "frame.png"
        write_frame(frame, shape)
        sides = [("this checkout", environment()),
                 ("this checkout, no program store", environment(G2R_JAX_NO_PROGRAM_STORE="1"))]
        sides += [(baseline, environment(baseline))] if baseline else []
        results = []
        for k, (name, env) in enumerate(sides):
            cold, warm = convert_walls(frame, folder, repeat, env, f"side{k}")
            results.append((statistics.median(cold), statistics.median(warm)))
            print(f"  {name}: cold cache {results[-1][0]:6.3f} s   warm cache {results[-1][1]:6.3f} s"
                  f"   (warm runs: {', '.join(f'{s:.2f}' for s in warm)})")
        for (name, _), (cold, warm) in list(zip(sides, results))[1:]:
            print(f"  ratio ({name} / this checkout): cold {cold / results[0][0]:.2f}x, warm {warm / results[0][1]:.2f}x")
        env = environment(G2R_JAX_CACHE_DIR=str(folder / "cache_side0_0"))
        phases = []
        for k in range(repeat):
            done = subprocess.run([sys.executable, "-c", PHASES, repr(time.time()), str(frame),
                                   str(folder / f"out_phase{k}")], capture_output=True, text=True, env=env)
            assert done.returncode == 0, done.stderr[-2000:]
            phases.append(dict((label, float(t)) for label, t in (line.split() for line in done.stdout.splitlines())))
        previous = 0.0
        print("  this checkout, warm cache, phases in one process (seconds since it was started; median):")
        for label in phases[0]:
            at = statistics.median(p[label] for p in phases)
            print(f"    {label:10s} at {at:6.3f} s  (+{at - previous:.3f} s)")
            previous = at
        jax_floor = statistics.median(wall([sys.executable, "-c", FLOOR_JAX])[0] for _ in range(repeat))
        print(f"  floor: python + import jax + one jitted call  {jax_floor:6.3f} s")


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="a 756 x 1008 frame instead of 12 MP")
    parser.add_argument("--repeat", type=int, default=5, help="runs per figure (median printed)")
    parser.add_argument("--only", choices=["arguments", "imports", "first-frame"], help="one section")
    parser.add_argument("--baseline", help="an older checkout of g2r_jax to time beside this one")
    args = parser.parse_args(argv)
    print(f"python {sys.version.split()[0]}, {os.cpu_count()} cores, load average "
          f"{', '.join(f'{v:.1f}' for v in os.getloadavg())}")
    if args.only in (None, "arguments"):
        section_arguments(args.repeat, args.baseline)
    if args.only in (None, "imports"):
        section_imports(args.repeat, args.baseline)
    if args.only in (None, "first-frame"):
        section_first_frame(QUICK if args.quick else FULL, args.repeat, args.baseline)


if __name__ == "__main__":
    main()
