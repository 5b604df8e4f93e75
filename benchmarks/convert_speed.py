"""Speed where datasets are made: start-up, per-frame throughput against the decode + write floor,
g2r-convert against the numpy script of the published steps, compressed DNG sizes and costs, and
g2r-diagnose on one 12-MP file, in one run.

    python benchmarks/convert_speed.py                 # 12-MP frames (3024 x 4032); long on 2 cores
    python benchmarks/convert_speed.py --quick         # 756 x 1008 frames, 8 and 16 files
    python benchmarks/convert_speed.py --sections throughput,compression

Sections:
- startup:     `g2r-convert ONE.png` (12 MP, gopro_hero6) in a fresh process with an empty
               compilation cache (cold) and with the cache it filled (warm), through
               `cli_startup.convert_walls`.
- throughput:  per input format (PNG, JPEG, EXR), in this process: the floor, i.e. decoding N files
               on `--workers` threads (the converter's own `_load`) plus writing N DNGs on as many
               threads (`write_dng_bytes` + the atomic write), then `convert_files` on the same N
               files once compiled; wall and CPU time per frame and their ratios. CPU time counts
               every thread of the process, so it stays meaningful on a shared machine.
- cli:         `g2r-convert` (fresh process, warm cache) against `published_numpy.py` writing
               the same uncompressed DNGs, on 8 and 64 PNGs (8 distinct frames, linked under
               8 names each for 64).
- compression: our outputs (s20fe_night at ISO 100-3200 and without noise, gopro_hero6 at its
               one calibrated ISO and without noise) written uncompressed and as lossless JPEG:
               size for tiles of 256 (what is written), 512, 1024 and the whole frame, encode
               CPU time, LibRaw's decode CPU time.
- diagnose:    `audit_speed.py --copies 1`: g2r-diagnose on the real 12-MP GoPro DNG, cold, warm, and
               warm with a second job spinning on one core.
Every section prints the load average before and after it: the figures are only comparable
within one run on one machine.
"""

from __future__ import annotations

import argparse
import concurrent.futures as futures
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))
FULL, QUICK = (3024, 4032), (756, 1008)
SECTIONS = ("startup", "throughput", "cli", "compression", "diagnose")


def load() -> str:
    return "load average {:.1f} / {:.1f} / {:.1f}".format(*os.getloadavg())


def clocked(function):
    """(result, wall seconds, CPU seconds of the whole process)."""
    cpu, wall = time.process_time(), time.perf_counter()
    result = function()
    return result, time.perf_counter() - wall, time.process_time() - cpu


def cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def make_frames(folder: Path, count: int, shape, formats=("png",)) -> dict:
    """`count` frames per format from `throughput.test_image` (seeded): {format: [paths]}."""
    from PIL import Image

    from throughput import test_image

    paths = {f: [] for f in formats}
    for i in range(count):
        image = test_image(*shape, seed=i)
        for fmt in formats:
            path = folder / fmt / f"frame{i:03d}.{fmt}"
            path.parent.mkdir(parents=True, exist_ok=True)
            if fmt == "exr":
                import OpenEXR

                linear = ((image.astype(np.float32) / 255) ** 2.2).astype(np.float16)
                channels = {c: np.ascontiguousarray(linear[..., k]) for k, c in enumerate("RGB")}
                OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage},
                             channels).write(str(path))
            else:
                Image.fromarray(image).save(path, **({"quality": 95} if fmt == "jpg" else {}))
            paths[fmt].append(path)
    return paths


# ----------------------------------------------------------------------------- sections

def section_startup(args, work: Path) -> None:
    from cli_startup import convert_walls, environment, write_frame

    frame = work / "startup.png"
    write_frame(frame, args.size)
    cold, warm = convert_walls(frame, work, 2, environment(), "startup")
    print(f"| g2r-convert, one {args.size[0]} x {args.size[1]} PNG, fresh process | cold cache {min(cold):.2f} s "
          f"| warm cache {min(warm):.2f} s (best of {len(warm)}) |")


def _floor(files, profile, out: Path, workers: int, compression: str):
    """Decode `files` on `workers` threads, then write as many DNGs on `workers` threads:
    (decode wall, decode CPU, write wall, write CPU)."""
    from g2r_jax.batch import conversion
    from g2r_jax.profile import dng_tags
    from g2r_jax.io.atomic import atomic_write_bytes
    from g2r_jax.io.dng_write import write_dng_bytes

    with futures.ThreadPoolExecutor(workers) as pool:
        images, decode_wall, decode_cpu = clocked(lambda: list(pool.map(lambda p: conversion._load(p, False), files)))
    height, width = images[0].shape[:2]
    del images
    rng = np.random.default_rng(0)
    mosaic = np.clip(rng.normal(0.3, 0.05, (height, width)) * profile.white_level, 0,
                     profile.white_level).astype(np.uint16)
    metadata = {"noise_shot": np.full(4, 1e-4), "noise_read": np.full(4, 1e-7),
                "neutral": np.array([0.5, 1.0, 0.6]), "iso": 100.0}
    info = dng_tags.dng_info_for(profile, metadata, height, width, noise=True)

    def write(i):
        atomic_write_bytes(out / f"floor{i}.dng", write_dng_bytes(mosaic, info, compression=compression))

    with futures.ThreadPoolExecutor(workers) as pool:
        _, write_wall, write_cpu = clocked(lambda: list(pool.map(write, range(len(files)))))
    return decode_wall, decode_cpu, write_wall, write_cpu


def section_throughput(args, work: Path) -> None:
    from g2r_jax.batch.conversion import ConvertOptions, convert_files
    from g2r_jax.profile.schema import load_profile

    profile = load_profile(args.profile)
    frames = make_frames(work / "frames", args.throughput_frames, args.size, ("png", "jpg", "exr"))
    print(f"\n{args.throughput_frames} frames of {args.size[0]} x {args.size[1]}, profile {args.profile}, "
          f"{args.workers} worker threads, batch 4; ms per frame, wall (CPU of all threads)\n")
    print("| input | DNG | decode | write | floor = decode + write | convert_files | ratio to floor, wall | ratio, CPU |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    cases = [("png", "none"), ("jpg", "none"), ("exr", "none"), ("png", "ljpeg")]
    for fmt, compression in cases:
        files = frames[fmt]
        out = work / f"out_{fmt}_{compression}"
        out.mkdir()
        decode_wall, decode_cpu, write_wall, write_cpu = _floor(files, profile, out, args.workers, compression)
        options = ConvertOptions(progress=False, workers=args.workers, compression=compression)
        convert_files(files[:4], profile, out / "warm", options=options)        # compile, outside the timing
        result, wall, cpu = clocked(lambda: convert_files(files, profile, out / "run", options=options))
        assert result.ok, result.errors
        shutil.rmtree(out)
        n = len(files)
        ms = lambda w, c: f"{1e3 * w / n:.0f} ({1e3 * c / n:.0f})"
        floor_wall, floor_cpu = decode_wall + write_wall, decode_cpu + write_cpu
        print(f"| {fmt.upper()} | {compression} | {ms(decode_wall, decode_cpu)} | {ms(write_wall, write_cpu)} | "
              f"{ms(floor_wall, floor_cpu)} | {ms(wall, cpu)} | {wall / floor_wall:.2f}x | {cpu / floor_cpu:.2f}x |",
              flush=True)


def _timed_process(argv, env=None) -> float:
    start = time.perf_counter()
    done = subprocess.run(argv, capture_output=True, text=True, env=env)
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(map(str, argv[:3]))} failed ({done.returncode}):\n{done.stderr[-2000:]}")
    return time.perf_counter() - start


def section_cli(args, work: Path) -> None:
    distinct = make_frames(work / "distinct", min(8, max(args.cli_frames)), args.size)["png"]
    env = dict(os.environ, PYTHONPATH=str(ROOT), G2R_JAX_CACHE_DIR=str(work / "cache"))
    convert = [sys.executable, "-m", "g2r_jax.cli.convert", "--profile", args.profile, "--quiet"]
    numpy_script = [sys.executable, str(HERE / "published_numpy.py"), "--profile", args.profile]
    _timed_process(convert + [str(distinct[0].parent), "-o", str(work / "cli_warmup")], env)   # fills the cache
    shutil.rmtree(work / "cli_warmup")
    print("\n| files | g2r-convert (fresh process, warm cache) | published steps, numpy | speed-up |")
    print("| --- | --- | --- | --- |")
    for count in args.cli_frames:
        folder = work / f"cli_{count}"
        folder.mkdir()
        for i in range(count):
            os.link(distinct[i % len(distinct)], folder / f"frame{i:03d}.png")
        ours = _timed_process(convert + [str(folder), "-o", str(work / f"cli_out_{count}")], env)
        shutil.rmtree(work / f"cli_out_{count}")
        theirs = _timed_process(numpy_script + [str(folder), str(work / f"numpy_out_{count}")], env)
        shutil.rmtree(work / f"numpy_out_{count}")
        print(f"| {count} | {ours:.1f} s ({ours / count:.2f} s/frame) | {theirs:.1f} s ({theirs / count:.2f} s/frame) "
              f"| **{theirs / ours:.1f}x** |", flush=True)


def section_compression(args, work: Path) -> None:
    import rawpy
    import tifffile

    from g2r_jax.batch.conversion import ConvertOptions, convert_files
    from g2r_jax.io.dng_write import write_dng_bytes
    from g2r_jax.io.lossless_jpeg import encode_tiles, precision_for
    from g2r_jax.profile.schema import load_profile

    frame = make_frames(work / "compression_in", 1, args.size)["png"][0]
    cases = [("s20fe_night", iso) for iso in ("no noise", 100, 400, 1600, 3200)] + \
            [("gopro_hero6", iso) for iso in ("no noise", 100)]
    print(f"\nOne {args.size[0]} x {args.size[1]} frame per row; sizes as a fraction of the uncompressed DNG; "
          "CPU ms (best of 2)\n")
    print("| profile | ISO | uncompressed MB | ljpeg MB (256 tiles) | fraction: tiles 256 / 512 / 1024 / whole frame "
          "| encode CPU ms: none / ljpeg | LibRaw decode CPU ms: none / ljpeg |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for name, iso in cases:
        profile = load_profile(name)
        out = work / f"compression_{name}_{iso}".replace(" ", "_")
        options = ConvertOptions(progress=False, batch_size=1, noise=iso != "no noise",
                                 iso=None if iso == "no noise" else float(iso))
        assert convert_files([frame], profile, out, options=options).ok
        dng = out / f"{frame.stem}.dng"
        from g2r_jax.io.dng_read import read_dng_info

        mosaic, info = tifffile.imread(dng), read_dng_info(dng)
        sizes, costs, reads = {}, {}, {}
        for compression in ("none", "ljpeg"):
            best = min(clocked(lambda: write_dng_bytes(mosaic, info, compression=compression))[2] for _ in range(2))
            data = write_dng_bytes(mosaic, info, compression=compression)
            path = out / f"{compression}.dng"
            path.write_bytes(data)

            def decode():
                with rawpy.imread(str(path)) as raw:
                    assert np.array_equal(raw.raw_image, mosaic)

            reads[compression] = min(clocked(decode)[2] for _ in range(2))
            sizes[compression], costs[compression] = len(data), best
        bits = precision_for(mosaic, info.white_level)
        fractions = []
        for side in (256, 512, 1024, None):
            shape = (side, side) if side else (-(-mosaic.shape[0] // 16) * 16, -(-mosaic.shape[1] // 16) * 16)
            fractions.append(sum(map(len, encode_tiles(mosaic, bits, shape))) / mosaic.nbytes)
        shutil.rmtree(out)
        print(f"| {name} | {iso} | {sizes['none'] / 1e6:.1f} | {sizes['ljpeg'] / 1e6:.1f} | "
              f"{' / '.join(f'{f:.3f}' for f in fractions)} | {1e3 * costs['none']:.0f} / {1e3 * costs['ljpeg']:.0f} | "
              f"{1e3 * reads['none']:.0f} / {1e3 * reads['ljpeg']:.0f} |", flush=True)


def section_diagnose(args, work: Path) -> None:
    done = subprocess.run([sys.executable, str(HERE / "audit_speed.py"), "--copies", "1"], capture_output=True,
                          text=True, env=dict(os.environ, PYTHONPATH=str(ROOT)))
    print("\n```\n" + (done.stdout.strip() or done.stderr.strip()[-1500:]) + "\n```")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="756 x 1008 frames, 8 and 16 files for the CLI")
    parser.add_argument("--sections", default=",".join(SECTIONS))
    parser.add_argument("--profile", default="Canon600D")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--throughput-frames", type=int, default=16)
    parser.add_argument("--cli-frames", default=None, help="comma-separated file counts (default 8,64)")
    args = parser.parse_args(argv)
    args.size = QUICK if args.quick else FULL
    args.cli_frames = [int(v) for v in (args.cli_frames or ("8,16" if args.quick else "8,64")).split(",")]

    import jax

    print(f"# convert_speed: {cpu_model()}, {os.cpu_count()} cores, JAX {jax.__version__} on "
          f"{jax.devices()[0].platform} ({jax.devices()[0].device_kind}); {load()}")
    sections = {"startup": section_startup, "throughput": section_throughput, "cli": section_cli,
                "compression": section_compression, "diagnose": section_diagnose}
    for name in args.sections.split(","):
        with tempfile.TemporaryDirectory(dir=os.environ.get("G2R_BENCH_TMP")) as work:
            print(f"\n## {name} ({load()} at start)", flush=True)
            started = time.perf_counter()
            sections[name](args, Path(work))
            print(f"\n({name}: {time.perf_counter() - started:.0f} s; {load()} at end)", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
