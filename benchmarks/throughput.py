"""Throughput of g2r_jax against a numpy statement of the published steps, in one run.

    python benchmarks/throughput.py            # 12-MP frames (3024 x 4032), a few minutes on 2 cores
    python benchmarks/throughput.py --quick    # 756 x 1008 frames, well under a minute
    python benchmarks/throughput.py --json results.json

Sections (each in a fresh subprocess, so that its peak memory is its own):
- bandwidth: the machine's memory bandwidth, measured here (large numpy and JAX copies).
- numpy:     the published per-image steps in numpy (`published_numpy.unprocess_published`).
- jax:       `g2r_jax.unprocess` under jit + vmap for a batch, noise off and on, and
             `unprocess_batch` (what g2r-convert runs); frames/s, speed-up over numpy, peak
             memory, and the share of the measured bandwidth reached by the minimal traffic
             (uint8 RGB in, uint16 mosaic out: 5 bytes a pixel).
- sampling:  illuminant + CST sampling for 10^5 illuminants in JAX (vmap of sample, neutral ->
             xy, matrix) against a per-sample Python loop over colour_hdri's functions (timed on
             a subset and extrapolated).
- convert:   `g2r-convert` end to end on a folder of PNGs (decode, convert, encode) against
             `published_numpy.py` writing the same DNGs, both as fresh processes.
- noise, startup, mixed, training: noise on/off for uint8, float16 and float32 input; start-up
             with and without the compilation cache; mixed sizes; synthesis inside a training step.
- stages:    the per-image conditions (in fixed vmapped chunks as unprocess_batch runs them, and
             image by image as it did before) against the pixels, timed apart.
- capacity:  on an accelerator, the largest batch of frames `unprocess_batch` (noise on) runs in
             one call, and frames/s at batch sizes up to it (skipped on a CPU).
Timings are the best of a few repetitions (the median for the end-to-end runs is the single run).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
FULL = (3024, 4032)
QUICK = (756, 1008)
MIXED_BASE = (1512, 2016)          # the mixed-size section's largest frame (3 MP)
BYTES_PER_PIXEL = 3 + 2            # uint8 RGB read, uint16 mosaic written
MAX_CAPACITY_BATCH = 1024          # 12-MP frames: 36 GiB of uint8 input, 24 GiB of uint16 output


def peak_rss_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def best_of(function, repeats: int):
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return min(times)


def test_image(height: int, width: int, seed: int = 0) -> np.ndarray:
    """A smooth synthetic scene (gradients, discs, a few saturated patches), uint8 RGB."""
    rng = np.random.default_rng(seed)
    y, x = np.ogrid[0:height, 0:width]
    y, x = y.astype(np.float32), x.astype(np.float32)
    image = np.empty((height, width, 3), np.float32)
    image[..., 0] = x / width
    image[..., 1] = y / height
    image[..., 2] = 0.5 + 0.5 * np.sin(x / 97.0 + y / 61.0 + seed)
    for _ in range(12):
        cy, cx, radius = rng.uniform(0, height), rng.uniform(0, width), rng.uniform(0.03, 0.15) * height
        image[(y - cy) ** 2 + (x - cx) ** 2 < radius**2] = rng.uniform(0, 1, 3)
    image[: height // 16, : width // 16] = 1.0
    image += rng.standard_normal(image.shape, np.float32) * np.float32(0.01)
    return np.clip(image * 255 + 0.5, 0, 255).astype(np.uint8)


# ----------------------------------------------------------------------------- sections

def section_bandwidth(args) -> dict:
    """Memory bandwidth: the best of large copies (read + write counted), numpy and JAX."""
    import jax
    import jax.numpy as jnp

    size = (256 if args.quick else 1024) << 20
    source = np.ones(size, np.uint8)
    target = np.empty_like(source)
    np.copyto(target, source)
    numpy_copy = 2 * size / best_of(lambda: np.copyto(target, source), 5) / 1e9
    device = jax.devices()[0]
    words = jnp.ones(size // 4, jnp.uint32)
    add_one = jax.jit(lambda a: a + jnp.uint32(1))
    add_one(words).block_until_ready()
    jax_copy = 2 * size / best_of(lambda: add_one(words).block_until_ready(), 5) / 1e9
    return {"numpy_copy_GBps": numpy_copy, "jax_copy_GBps": jax_copy,
            "bandwidth_GBps": max(numpy_copy, jax_copy), "device": str(device.device_kind)}


def section_numpy(args) -> dict:
    """The published steps in numpy, one frame at a time; peak Python-heap memory by tracemalloc."""
    import tracemalloc

    sys.path.insert(0, str(HERE))
    from published_numpy import published_matrices, unprocess_published

    from g2r_jax.profile.schema import load_profile

    height, width = args.size
    profile = load_profile("Canon600D")
    image = test_image(height, width)
    neutral = np.array([0.55, 1.0, 0.72])
    srgb_to_xyz, xyz_to_camera = published_matrices(profile, neutral)
    cfa, black, white = list(np.asarray(profile.cfa_pattern)), np.asarray(profile.black_level), float(profile.white_level)
    run = lambda: unprocess_published(image, srgb_to_xyz, xyz_to_camera, neutral, cfa, black, white)
    run()
    tracemalloc.start()
    seconds = best_of(run, args.numpy_repeats)
    _, traced_peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return {"seconds_per_frame": seconds, "frames_per_s": 1.0 / seconds,
            "peak_traced_MiB": traced_peak / 2**20, "peak_rss_MiB": peak_rss_mib()}


def section_jax(args) -> dict:
    import jax
    import jax.numpy as jnp

    from g2r_jax.profile.schema import load_profile
    from g2r_jax.pipeline import unprocess, unprocess_batch

    height, width = args.size
    batch = args.batch
    profile = load_profile(args.profile)
    images = jnp.asarray(np.stack([test_image(height, width, seed) for seed in range(batch)]))
    keys = jax.random.split(jax.random.PRNGKey(0), batch)
    results = {"batch": batch, "profile": args.profile, "device": str(jax.devices()[0].device_kind),
               "platform": jax.devices()[0].platform}
    variants = {
        "vmap_noise_off": jax.jit(jax.vmap(lambda k, im: unprocess(k, im, profile, noise=False)[0])),
        "vmap_noise_on": jax.jit(jax.vmap(lambda k, im: unprocess(k, im, profile, noise=True)[0])),
        "batch_noise_off": jax.jit(lambda k, im: unprocess_batch(k, im, profile, noise=False)[0]),
        "batch_noise_on": jax.jit(lambda k, im: unprocess_batch(k, im, profile, noise=True)[0]),
    }
    for name, function in variants.items():
        start = time.perf_counter()
        function(keys, images).block_until_ready()
        compile_seconds = time.perf_counter() - start
        seconds = best_of(lambda: function(keys, images).block_until_ready(), args.repeats)
        results[name] = {"seconds_per_batch": seconds, "frames_per_s": batch / seconds,
                         "first_call_seconds": compile_seconds}
    stats = jax.devices()[0].memory_stats() or {}
    results["peak_rss_MiB"] = peak_rss_mib()
    if "peak_bytes_in_use" in stats:
        results["device_peak_MiB"] = stats["peak_bytes_in_use"] / 2**20
    return results


def section_sampling(args) -> dict:
    """10^5 illuminants + CSTs in JAX against a per-sample loop over colour_hdri, per profile."""
    return {name: _sampling(name, args.samples, args.loop_samples) for name in args.sampling_profiles.split(",")}


def _sampling(profile_name: str, count: int, subset: int) -> dict:
    import colour
    import jax
    from colour_hdri.models import dng as reference

    from g2r_jax.colour import dng_model as dng
    from g2r_jax.illuminants import distributions as illuminants
    from g2r_jax.profile.schema import load_profile

    profile = load_profile(profile_name)
    model = profile.colour

    def one(key):
        neutral = illuminants.chromaticity_to_neutral(illuminants.sample_chromaticity(key, profile.illuminants))
        xy, _ = dng.camera_neutral_to_xy(neutral, model, throw=False)
        return neutral, xy, dng.matrix_XYZ_D65_to_camera(xy, model)

    sample = jax.jit(jax.vmap(one))
    keys = jax.random.split(jax.random.PRNGKey(1), count)
    start = time.perf_counter()
    jax.block_until_ready(sample(keys))
    first = time.perf_counter() - start
    jax_seconds = best_of(lambda: jax.block_until_ready(sample(keys)), 3)

    # The loop: numpy draws with rejection to the hull, colour_hdri's neutral -> xy and matrices.
    cct1, cct2 = (float(v) for v in np.asarray(model.calibration_cct))
    cm1, cm2 = np.asarray(model.color_matrix, np.float64)
    cc1, cc2 = np.asarray(model.camera_calibration, np.float64)
    fm1, fm2 = np.asarray(model.forward_matrix, np.float64)    # identity = no ForwardMatrix, for both
    balance = np.asarray(model.analog_balance, np.float64)
    means = np.asarray(profile.illuminants.means, np.float64)
    cholesky = np.asarray(profile.illuminants.cholesky, np.float64)
    weights = np.asarray(profile.illuminants.weights, np.float64)
    hull = np.asarray(profile.illuminants.hull, np.float64)
    rng = np.random.default_rng(0)
    whites = colour.CCS_ILLUMINANTS["CIE 1931 2 Degree Standard Observer"]
    bradford = colour.adaptation.matrix_chromatic_adaptation_VonKries(
        colour.xy_to_XYZ(whites["D50"]), colour.xy_to_XYZ(whites["D65"]), transform="Bradford")

    def loop_one():
        while True:
            k = rng.choice(len(weights), p=weights)
            point = means[k] + cholesky[k] @ rng.standard_normal(2)
            if not profile.illuminants.use_hull or np.all(point @ hull[:, :2].T + hull[:, 2] <= 1e-9):
                break
        neutral = np.array([point[0], 1.0, point[1]])
        xy = reference.camera_neutral_to_xy(neutral, cct1, cct2, cm1, cm2, cc1, cc2, balance)
        camera_to_xyz = reference.matrix_camera_space_to_XYZ(xy, cct1, cct2, cm1, cm2, cc1, cc2, balance, fm1, fm2)
        return np.linalg.inv(bradford @ camera_to_xyz)

    start = time.perf_counter()
    for _ in range(subset):
        loop_one()
    loop_seconds_subset = time.perf_counter() - start
    loop_seconds = loop_seconds_subset / subset * count
    return {"samples": count, "illuminant_model": f"{profile.illuminants.kind}, {len(weights)} component(s)"
            + (", hull rejection" if profile.illuminants.use_hull else ""),
            "jax_seconds": jax_seconds, "jax_first_call_seconds": first,
            "loop_subset": subset, "loop_subset_seconds": loop_seconds_subset,
            "loop_seconds_extrapolated": loop_seconds, "speedup": loop_seconds / jax_seconds}


def section_convert(args) -> dict:
    """g2r-convert against published_numpy.py on the same folder of PNGs, as fresh processes.

    g2r-convert also runs on the first 4 PNGs alone: the difference gives its per-frame cost
    once started and compiled (numpy's per-frame cost is its total over the frame count)."""
    from PIL import Image

    height, width = args.size
    work = Path(args.workdir)
    folder, small = work / "pngs", work / "pngs_first4"
    folder.mkdir(parents=True, exist_ok=True)
    existing = sorted(folder.glob("*.png"))
    if len(existing) != args.frames or Image.open(existing[0]).size != (width, height):
        for path in existing:
            path.unlink()
        for index in range(args.frames):
            Image.fromarray(test_image(height, width, 100 + index)).save(folder / f"frame_{index:03d}.png",
                                                                         compress_level=1)
    small.mkdir(exist_ok=True)
    for path in small.glob("*.png"):
        path.unlink()
    for path in sorted(folder.glob("*.png"))[:4]:
        os.link(path, small / path.name)
    bin_dir = Path(sys.executable).parent

    def g2r(source, target):
        return [str(bin_dir / "g2r-convert"), str(source), "--profile", args.profile, "-o", str(work / target),
                "--no-progress", "--batch-size", str(args.convert_batch)]

    numpy_script = [sys.executable, str(HERE / "published_numpy.py"), str(folder), str(work / "numpy"),
                    "--profile", args.profile]

    def timed(command):
        start = time.perf_counter()
        completed = subprocess.run(command, capture_output=True, text=True)
        if completed.returncode != 0:
            raise RuntimeError(f"{command[0]} failed:\n{completed.stdout}\n{completed.stderr}")
        return time.perf_counter() - start

    # g2r-convert before and after the numpy run (the best of the two): load on a shared
    # machine changes over minutes.
    g2r_runs = [timed(g2r(folder, "g2r"))]
    numpy_seconds = timed(numpy_script)
    g2r_runs.append(timed(g2r(folder, "g2r")))
    g2r_small = min(timed(g2r(small, "g2r_first4")) for _ in range(2))
    g2r_seconds = min(g2r_runs)
    marginal = (g2r_seconds - g2r_small) / (args.frames - 4)
    numpy_per_frame = numpy_seconds / args.frames
    return {"frames": args.frames, "command": " ".join(g2r(folder, "g2r")),
            "g2r_convert": {"seconds": g2r_seconds, "runs": g2r_runs, "frames_per_s": args.frames / g2r_seconds,
                            "first4_seconds": g2r_small, "marginal_seconds_per_frame": marginal},
            "published_numpy": {"seconds": numpy_seconds, "frames_per_s": 1 / numpy_per_frame},
            "speedup": numpy_seconds / g2r_seconds, "steady_speedup": numpy_per_frame / marginal,
            "peak_rss_children_MiB": resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024.0}


def _cpu_and_wall(function, repeats: int):
    """(best wall seconds, mean process CPU seconds) over `repeats` calls: CPU time is what
    compares on a shared machine (wall time there includes waiting for the other jobs)."""
    wall, cpu = [], []
    for _ in range(repeats):
        w, c = time.perf_counter(), time.process_time()
        function()
        wall.append(time.perf_counter() - w)
        cpu.append(time.process_time() - c)
    return min(wall), float(np.mean(cpu))


def section_noise(args) -> dict:
    """Noise on vs off and uint8 vs float16 vs float32 input, one profile and option set, side by side:
    `unprocess_batch` under jit (what g2r-convert runs), inputs already on the device."""
    import jax
    import jax.numpy as jnp

    from g2r_jax.profile.schema import load_profile
    from g2r_jax.pipeline import unprocess_batch

    height, width = args.size
    profile = load_profile(args.profile)
    codes = np.stack([test_image(height, width, seed) for seed in range(args.batch)])
    inputs = {"uint8": jnp.asarray(codes), "float16": jnp.asarray(codes.astype(np.float16) / np.float16(255)),
              "float32": jnp.asarray(codes.astype(np.float32) / np.float32(255))}
    keys = jax.random.split(jax.random.PRNGKey(0), args.batch)
    results = {"batch": args.batch, "profile": args.profile, "device": str(jax.devices()[0].device_kind)}
    for _ in range(2):          # two passes, interleaved: the best of each is kept
        for dtype, images in inputs.items():
            for noise in (False, True):
                function = jax.jit(lambda k, im, noise=noise: unprocess_batch(k, im, profile, noise=noise)[0])
                function(keys, images).block_until_ready()
                wall, cpu = _cpu_and_wall(lambda: function(keys, images).block_until_ready(), args.repeats)
                name = f"{dtype}_noise_{'on' if noise else 'off'}"
                old = results.get(name, {"wall_ms_per_frame": np.inf, "cpu_ms_per_frame": np.inf})
                results[name] = {"wall_ms_per_frame": min(old["wall_ms_per_frame"], 1e3 * wall / args.batch),
                                 "cpu_ms_per_frame": min(old["cpu_ms_per_frame"], 1e3 * cpu / args.batch)}
    return results


def _write_pngs(folder: Path, sizes, seed0: int):
    from PIL import Image

    folder.mkdir(parents=True, exist_ok=True)
    for path in folder.glob("*"):
        path.unlink()
    for index, (height, width) in enumerate(sizes):
        Image.fromarray(test_image(height, width, seed0 + index)).save(folder / f"frame_{index:03d}.png", compress_level=1)


def _timed(command, env=None):
    start = time.perf_counter()
    completed = subprocess.run(command, capture_output=True, text=True, env=env)
    if completed.returncode != 0:
        raise RuntimeError(f"{command[0]} failed:\n{completed.stdout}\n{completed.stderr}")
    return time.perf_counter() - start


def section_startup(args) -> dict:
    """g2r-convert on 8 PNGs with a cold and a warm persistent compilation cache, and without the
    cache, against published_numpy.py on the same PNGs; `--help` time."""
    import shutil

    height, width = args.size
    work = Path(args.workdir)
    folder = work / "pngs8"
    _write_pngs(folder, [(height, width)] * 8, 200)
    bin_dir = Path(sys.executable).parent
    cache = work / "jax_cache"
    shutil.rmtree(cache, ignore_errors=True)
    env = dict(os.environ, G2R_JAX_CACHE_DIR=str(cache))
    g2r = lambda *extra: [str(bin_dir / "g2r-convert"), str(folder), "--profile", args.profile, "-o",
                          str(work / "g2r8"), "--no-progress", *extra]
    cold = _timed(g2r(), env)
    warm = min(_timed(g2r(), env) for _ in range(2))
    uncached = _timed(g2r("--no-compile-cache"), env)
    numpy_seconds = _timed([sys.executable, str(HERE / "published_numpy.py"), str(folder), str(work / "numpy8"),
                            "--profile", args.profile])
    help_seconds = min(_timed([str(bin_dir / "g2r-convert"), "--help"]) for _ in range(3))
    return {"frames": 8, "cold_cache_seconds": cold, "warm_cache_seconds": warm, "no_cache_seconds": uncached,
            "published_numpy_seconds": numpy_seconds, "help_seconds": help_seconds,
            "speedup_warm": numpy_seconds / warm, "speedup_cold": numpy_seconds / cold}


def section_mixed(args) -> dict:
    """g2r-convert on 11 PNGs of 11 different sizes against 12 PNGs of one size (no persistent
    cache: every shape's compilation is paid, as on a first run)."""
    height, width = MIXED_BASE
    work = Path(args.workdir)
    uniform, mixed = work / "uniform12", work / "mixed11"
    _write_pngs(uniform, [(height, width)] * 12, 300)
    sizes = [(height - 2 * (37 * i % 200), width - 2 * (53 * i % 300)) for i in range(11)]
    _write_pngs(mixed, sizes, 400)
    bin_dir = Path(sys.executable).parent
    g2r = lambda source: [str(bin_dir / "g2r-convert"), str(source), "--profile", args.profile, "-o",
                          str(work / f"out_{source.name}"), "--no-progress", "--no-compile-cache"]
    return {"size": [height, width], "mixed_sizes": sizes, "uniform12_seconds": min(_timed(g2r(uniform)) for _ in range(2)),
            "mixed11_seconds": min(_timed(g2r(mixed)) for _ in range(2))}


def _out_of_memory(error: Exception) -> bool:
    text = str(error)
    return "RESOURCE_EXHAUSTED" in text or "out of memory" in text.lower()


def section_capacity(args) -> dict:
    """On an accelerator: batches of uint8 frames through `unprocess_batch` (noise on, inputs on the
    device), doubled from 4 until the device runs out of memory or MAX_CAPACITY_BATCH is
    reached; frames/s at each, and the device's peak memory. Skipped on a CPU (host memory, not
    the program, is the limit there)."""
    import jax
    import jax.numpy as jnp

    from g2r_jax.profile.schema import load_profile
    from g2r_jax.pipeline import unprocess_batch

    device = jax.devices()[0]
    if device.platform == "cpu":
        return {"skipped": "cpu"}
    height, width = args.size
    profile = load_profile(args.profile)
    frame = jnp.asarray(test_image(height, width))
    function = jax.jit(lambda k, im: unprocess_batch(k, im, profile, noise=True)[0])
    results = {"device": str(device.device_kind), "profile": args.profile, "batches": {}}
    batch = 4
    while batch <= MAX_CAPACITY_BATCH:
        try:
            images = jnp.broadcast_to(frame, (batch,) + frame.shape).copy()
            keys = jax.random.split(jax.random.PRNGKey(batch), batch)
            function(keys, images).block_until_ready()
            seconds = best_of(lambda: function(keys, images).block_until_ready(), args.repeats)
        except Exception as error:   # noqa: BLE001 - the device's out-of-memory error ends the search
            if not _out_of_memory(error):
                raise
            results["out_of_memory_at"] = batch
            break
        finally:
            images = None
        results["batches"][batch] = {"seconds_per_batch": seconds, "frames_per_s": batch / seconds}
        results["largest_batch"] = batch
        batch *= 2
    stats = device.memory_stats() or {}
    results["device_memory_MiB"] = stats.get("bytes_limit", 0) / 2**20
    results["device_peak_MiB"] = stats.get("peak_bytes_in_use", 0) / 2**20
    return results


def section_stages(args) -> dict:
    """Where `unprocess_batch`'s time goes: the per-image conditions (`sample_conditions`: no pixels)
    as it runs them (`batch_conditions`: vmapped in fixed chunks), as it ran them before (`lax.map`,
    one image at a time), and the pixels (`render_mosaic` vmapped, noise on) from precomputed
    conditions; at the batch size and, on an accelerator, at 64."""
    import jax
    import jax.numpy as jnp

    from g2r_jax.profile.schema import load_profile
    from g2r_jax.pipeline import batch_conditions, render_mosaic, sample_conditions

    device = jax.devices()[0]
    height, width = args.size
    profile = load_profile(args.profile)
    frame = jnp.asarray(test_image(height, width))
    condition = lambda key: sample_conditions(key, profile)
    looped = jax.jit(lambda keys: jax.lax.map(condition, keys))
    chunked = jax.jit(lambda keys: batch_conditions(keys, profile))
    pixels = jax.jit(jax.vmap(lambda image, c: render_mosaic(image, c, profile, noise=True)))
    results = {"device": str(device.device_kind), "profile": args.profile, "batches": {}}
    for batch in sorted({args.batch} | ({64} if device.platform != "cpu" else set())):
        keys = jax.random.split(jax.random.PRNGKey(1), batch)
        images = jnp.broadcast_to(frame, (batch,) + frame.shape).copy()
        conditions = looped(keys)
        entry = {}
        for name, function, argument in (("conditions_lax_map", looped, (keys,)), ("conditions_chunked", chunked, (keys,)),
                                         ("pixels_vmap", pixels, (images, conditions))):
            jax.block_until_ready(function(*argument))
            seconds = best_of(lambda: jax.block_until_ready(function(*argument)), args.repeats)
            entry[name] = {"ms_per_frame": 1e3 * seconds / batch}
        results["batches"][batch] = entry
    return results


def section_training(args) -> dict:
    """benchmarks/train_denoiser_example.py: share of a training step spent synthesising."""
    output = Path(args.workdir) / "training.json"
    Path(args.workdir).mkdir(parents=True, exist_ok=True)
    _timed([sys.executable, str(HERE / "train_denoiser_example.py"), "--json", str(output), "--profile", args.profile])
    return json.loads(output.read_text())


SECTIONS = {"bandwidth": section_bandwidth, "numpy": section_numpy, "jax": section_jax,
            "sampling": section_sampling, "convert": section_convert, "noise": section_noise,
            "startup": section_startup, "mixed": section_mixed, "training": section_training,
            "capacity": section_capacity, "stages": section_stages}


# ----------------------------------------------------------------------------- driver

def parse(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="756 x 1008 frames and fewer repetitions")
    parser.add_argument("--sections", default=",".join(SECTIONS), help="comma-separated subset of " + ",".join(SECTIONS))
    parser.add_argument("--profile", default="Canon600D")
    parser.add_argument("--batch", type=int, help="frames per jit+vmap batch (default 4, quick 8)")
    parser.add_argument("--frames", type=int, help="PNGs in the end-to-end folder (default 12, quick 8)")
    parser.add_argument("--samples", type=int, default=100_000, help="illuminants in the sampling benchmark")
    parser.add_argument("--loop-samples", type=int, default=200, help="colour_hdri loop iterations timed")
    parser.add_argument("--sampling-profiles", default="Canon600D,s20fe_night",
                        help="profiles whose illuminant models are sampled (comma-separated)")
    parser.add_argument("--workdir", default=None, help="folder for the end-to-end PNGs and DNGs")
    parser.add_argument("--json", type=Path, help="also write the results as JSON")
    parser.add_argument("--section", help=argparse.SUPPRESS)       # internal: run one section, print JSON
    args = parser.parse_args(argv)
    args.size = QUICK if args.quick else FULL
    args.batch = args.batch or (8 if args.quick else 4)
    args.frames = args.frames or (8 if args.quick else 12)
    args.repeats = 3
    args.numpy_repeats = 3 if args.quick else 2
    args.convert_batch = 4
    args.workdir = args.workdir or str(Path(os.environ.get("TMPDIR", "/tmp")) / f"g2r_bench_{args.size[0]}")
    return args


def run_section(name, argv) -> dict:
    """One section in a fresh interpreter (own peak memory, own JAX state)."""
    completed = subprocess.run([sys.executable, __file__, "--section", name] + argv, capture_output=True, text=True)
    if completed.returncode != 0:
        raise RuntimeError(f"section {name} failed:\n{completed.stderr[-4000:]}")
    return json.loads(completed.stdout.strip().splitlines()[-1])


def _cpu_vector_width() -> str:
    """The XLA CPU vector width the sections ran with (each section imports g2r_jax, which
    chooses it: `g2r_jax.cpu_vectors.chosen_width`)."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from g2r_jax.runtime.cpu_vectors import chosen_width

    return f"XLA CPU vectors {chosen_width() or '256 (XLA default)'} bits"


def report(results: dict, args) -> str:
    height, width = args.size
    lines = [f"g2r_jax throughput, {height}x{width} frames ({height * width / 1e6:.1f} MP), "
             f"{platform.processor() or platform.machine()}, {os.cpu_count()} CPU(s), {_cpu_vector_width()}"]
    bandwidth = results.get("bandwidth")
    if bandwidth:
        lines.append(f"memory bandwidth (copy, read+write): numpy {bandwidth['numpy_copy_GBps']:.1f} GB/s, "
                     f"JAX {bandwidth['jax_copy_GBps']:.1f} GB/s on {bandwidth['device']}")
    numpy_result, jax_result = results.get("numpy"), results.get("jax")
    if numpy_result:
        lines.append(f"numpy published steps: {numpy_result['seconds_per_frame']:.2f} s/frame "
                     f"({numpy_result['frames_per_s']:.3f} frames/s), peak traced {numpy_result['peak_traced_MiB']:.0f} MiB, "
                     f"peak RSS {numpy_result['peak_rss_MiB']:.0f} MiB")
    if jax_result:
        lines.append(f"JAX on {jax_result['platform']} ({jax_result['device']}), batch {jax_result['batch']}, "
                     f"profile {jax_result['profile']}, peak RSS {jax_result['peak_rss_MiB']:.0f} MiB"
                     + (f", device peak {jax_result['device_peak_MiB']:.0f} MiB" if "device_peak_MiB" in jax_result else ""))
        for name in ("vmap_noise_off", "vmap_noise_on", "batch_noise_off", "batch_noise_on"):
            entry = jax_result[name]
            text = f"  {name:16s} {entry['frames_per_s']:8.2f} frames/s ({1e3 / entry['frames_per_s']:.0f} ms/frame)"
            if numpy_result:
                text += f", {entry['frames_per_s'] / numpy_result['frames_per_s']:.0f}x numpy"
            if bandwidth:
                traffic = entry["frames_per_s"] * height * width * BYTES_PER_PIXEL / 1e9
                text += f", {traffic:.2f} GB/s = {100 * traffic / bandwidth['bandwidth_GBps']:.1f}% of bandwidth"
            lines.append(text)
        for kind in ("vmap", "batch"):
            ratio = jax_result[f"{kind}_noise_off"]["frames_per_s"] / jax_result[f"{kind}_noise_on"]["frames_per_s"]
            lines.append(f"  noise costs {ratio:.2f}x the noise-off time ({kind})")
    for name, sampling in (results.get("sampling") or {}).items():
        lines.append(f"sampling {sampling['samples']:,} illuminants + CSTs, {name} ({sampling['illuminant_model']}): "
                     f"JAX {sampling['jax_seconds']:.3f} s (first call {sampling['jax_first_call_seconds']:.1f} s); "
                     f"colour_hdri loop {sampling['loop_subset_seconds']:.2f} s for {sampling['loop_subset']} samples, "
                     f"extrapolated {sampling['loop_seconds_extrapolated']:.0f} s; speed-up {sampling['speedup']:.0f}x")
    convert = results.get("convert")
    if convert:
        ours, theirs = convert["g2r_convert"], convert["published_numpy"]
        lines.append(f"end to end, {convert['frames']} PNGs: g2r-convert {ours['seconds']:.1f} s "
                     f"({ours['frames_per_s']:.2f} frames/s), published numpy {theirs['seconds']:.1f} s "
                     f"({theirs['frames_per_s']:.3f} frames/s); speed-up {convert['speedup']:.1f}x with process "
                     f"start and JIT compile; per frame once running {ours['marginal_seconds_per_frame']:.2f} s vs "
                     f"{1 / theirs['frames_per_s']:.2f} s: {convert['steady_speedup']:.1f}x")
    noise = results.get("noise")
    if noise:
        lines.append(f"noise on vs off, unprocess_batch under jit, batch {noise['batch']}, profile {noise['profile']} "
                     f"(ms/frame wall best-of, CPU ms/frame):")
        for dtype in ("uint8", "float16", "float32"):
            if f"{dtype}_noise_off" not in noise:
                continue
            off, on = noise[f"{dtype}_noise_off"], noise[f"{dtype}_noise_on"]
            lines.append(f"  {dtype:7s} off {off['wall_ms_per_frame']:6.1f} wall {off['cpu_ms_per_frame']:6.1f} CPU | "
                         f"on {on['wall_ms_per_frame']:6.1f} wall {on['cpu_ms_per_frame']:6.1f} CPU | noise costs "
                         f"{on['wall_ms_per_frame'] / off['wall_ms_per_frame']:.2f}x wall, "
                         f"{on['cpu_ms_per_frame'] / off['cpu_ms_per_frame']:.2f}x CPU")
        lines.append(f"  float32 input costs {noise['float32_noise_off']['cpu_ms_per_frame'] / noise['uint8_noise_off']['cpu_ms_per_frame']:.2f}x "
                     f"uint8 (noise off, CPU): the sRGB curve computed (exp and log) instead of a 256-entry table, 12 bytes/pixel read instead of 3")
    startup = results.get("startup")
    if startup:
        lines.append(f"g2r-convert, 8 PNGs: cold cache {startup['cold_cache_seconds']:.1f} s, warm cache "
                     f"{startup['warm_cache_seconds']:.1f} s, no cache {startup['no_cache_seconds']:.1f} s; published numpy "
                     f"{startup['published_numpy_seconds']:.1f} s: {startup['speedup_warm']:.1f}x warm, "
                     f"{startup['speedup_cold']:.1f}x cold; --help {startup['help_seconds']:.2f} s")
    mixed = results.get("mixed")
    if mixed:
        lines.append(f"mixed sizes (up to {mixed['size'][0]}x{mixed['size'][1]}, no compile cache): 11 PNGs of 11 sizes "
                     f"{mixed['mixed11_seconds']:.1f} s vs 12 PNGs of one size {mixed['uniform12_seconds']:.1f} s "
                     f"({mixed['mixed11_seconds'] / mixed['uniform12_seconds']:.2f}x)")
    capacity = results.get("capacity")
    if capacity and "skipped" not in capacity:
        lines.append(f"capacity on {capacity['device']} ({capacity['device_memory_MiB'] / 1024:.0f} GiB usable), "
                     f"unprocess_batch noise on, uint8: largest batch {capacity.get('largest_batch')} "
                     + (f"(out of memory at {capacity['out_of_memory_at']})" if "out_of_memory_at" in capacity
                        else f"(search stopped at {MAX_CAPACITY_BATCH})")
                     + f", device peak {capacity['device_peak_MiB'] / 1024:.1f} GiB")
        for batch, entry in capacity["batches"].items():
            text = f"  batch {int(batch):5d}: {entry['frames_per_s']:8.1f} frames/s"
            if bandwidth:
                traffic = entry["frames_per_s"] * height * width * BYTES_PER_PIXEL / 1e9
                text += f", {traffic:.0f} GB/s = {100 * traffic / bandwidth['bandwidth_GBps']:.1f}% of bandwidth"
            lines.append(text)
    stages = results.get("stages")
    if stages:
        lines.append(f"stages of unprocess_batch on {stages['device']} (ms/frame): conditions image by image (lax.map) | "
                     f"in vmapped chunks (batch_conditions) | pixels (vmap, noise on)")
        for batch, entry in stages["batches"].items():
            pixel_ms = entry["pixels_vmap"]["ms_per_frame"]
            text = (f"  batch {int(batch):4d}: {entry['conditions_lax_map']['ms_per_frame']:7.2f} | "
                    f"{entry['conditions_chunked']['ms_per_frame']:7.2f} | {pixel_ms:7.2f}")
            if bandwidth:
                traffic = height * width * BYTES_PER_PIXEL / (pixel_ms * 1e-3) / 1e9
                text += f"  (pixels alone: {traffic:.0f} GB/s = {100 * traffic / bandwidth['bandwidth_GBps']:.1f}% of bandwidth)"
            lines.append(text)
    training = results.get("training")
    if training:
        lines.append(f"training step ({training['batch']} crops {training['crop']}x{training['crop']}, {training['device']}): "
                     f"{1e3 * training['step_seconds_median']:.1f} ms, synthesis {1e3 * training['synthesis_seconds_median']:.1f} ms "
                     f"= {100 * training['synthesis_share']:.0f}% of the step")
    return "\n".join(lines)


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    args = parse(argv)
    if args.section:
        print(json.dumps(SECTIONS[args.section](args)))
        return 0
    passthrough = (["--quick"] if args.quick else []) + [
        "--profile", args.profile, "--batch", str(args.batch), "--frames", str(args.frames),
        "--samples", str(args.samples), "--loop-samples", str(args.loop_samples), "--workdir", args.workdir,
        "--sampling-profiles", args.sampling_profiles]
    results = {"size": list(args.size), "cpus": os.cpu_count(), "load_average_start": os.getloadavg()}
    for name in args.sections.split(","):
        start = time.perf_counter()
        results[name] = run_section(name, passthrough)
        print(f"[{name}: {time.perf_counter() - start:.0f} s]", file=sys.stderr, flush=True)
    results["load_average_end"] = os.getloadavg()
    print(report(results, args))
    if args.json:
        args.json.write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
