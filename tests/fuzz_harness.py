"""Mutation fuzzing of the three commands, in-process, against the promises of issue 12.

Seeds: DNGs written by g2r-convert from shipped profiles (two images per profile, so every mutated
file has two good files of its camera beside it), the DNGs in ../shared/data/dng when present,
small PNG/JPEG/TIFF/EXR images, and the shipped profiles' JSON.

Mutations (`mutate_dng`): bit flips, truncation, overwritten bytes at random places and in tag
fields (entry counts, types, offsets, values) within the first 8 KB, or anywhere in the file
(campaign 'fit-deep'). Chart CSVs (tests/input_attacks.py's mutations) through `g2r-diagnose --charts`
(campaign 'diagnose-charts'). Side inputs, charts, hostile names and lying image headers are also
attacked at their readers by tests/input_attacks.py; faults of the output folder by
tests/fault_harness.py. Images (`mutate_image`): the
same, plus headers claiming enormous sizes. Profiles (`mutate_profile`): a numeric leaf replaced by
an extreme, non-finite or wrongly typed value, a key deleted, or a byte-level flip of the JSON.

Promises checked for every case (`check_*`): the command returns (no exception escapes; a
per-case alarm catches hangs), the exit status is the documented one (0 all good, 1 some inputs
failed, 2 could not run at all), every line on stderr is the command's own, short and without a
traceback or a JAX/equinox text, a failing input is named, the batch goes on (the good files are
converted or fitted), no partial or temporary outputs, inputs unchanged, bounded memory.
Run with `python tests/fuzz_harness.py fit|fit-deep|convert|diagnose|diagnose-charts N [SEED [FIRST]]`
(cases FIRST..N-1 of the campaign of SEED; docs/pages/validation/reliability.md) or through
tests/test_fuzz.py. Run `convert` in pieces of at most 4,000 cases per process: each case's new
profile structure or image size keeps a compiled program in the process (7 memory mappings each),
and about 9,000 reach the kernel's mapping limit, where XLA aborts.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import os
import random
import resource
import shutil
import signal
import struct
import sys
import tempfile
import traceback
from pathlib import Path

import numpy as np

# as the commands' entry point (g2r_jax.cli.common.run_command) does before JAX loads: XLA's C++ log
# lines are not the commands' (effective only when this module is imported before JAX)
os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "3")

ROOT = Path(__file__).resolve().parents[1]
SHARED_DNG = ROOT / ".." / "shared" / "data" / "dng"
CORPUS = Path(__file__).resolve().parent / "fuzz_corpus"
SEED_PROFILES = ("gopro_hero6", "s20fe_night", "NikonD40")
HEAD = 8192
CASE_SECONDS = int(os.environ.get("G2R_FUZZ_CASE_SECONDS", "300"))   # generous: first compilations on a loaded machine
MAX_RSS_GIB = 8.0
FORBIDDEN = ("Traceback", "equinox", "Equinox", "XlaRuntimeError", "jaxlib", "CpuCallback", "TiffTag",
             "tifffile.", "UserWarning", "RuntimeWarning", "DeprecationWarning", "ColourWarning")
INTERESTING_32 = (0, 1, 2, 0x7F, 0x80, 0xFF, 0x100, 0x7FFF, 0x8000, 0xFFFF, 0x10000, 0x7FFFFFFF,
                  0x80000000, 0xFFFFFFFE, 0xFFFFFFFF)
INTERESTING_FLOATS = (float("nan"), float("inf"), -float("inf"), 0.0, -0.0, 1e308, -1e308, 9.2e18, -1.0,
                      1e-308, 65535.0, 65536.0, -65536.0)


class Hang(BaseException):
    """Raised by the per-case alarm; a BaseException so that the command's own catch-all does not
    turn it into an ordinary error line."""


# ----------------------------------------------------------------------------- seeds

def make_seeds(folder: Path, profiles=SEED_PROFILES) -> dict:
    """Seed files in `folder`: {'dng': [(path, [good partner paths])], 'image': [...], 'profile': [...]}."""
    from PIL import Image

    from g2r_jax.cli.convert import main as convert_main

    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(0)
    images = folder / "images"
    images.mkdir(exist_ok=True)
    pixels = rng.integers(40, 220, (48, 64, 3), dtype=np.uint8)
    Image.fromarray(pixels).save(images / "seed.png")
    Image.fromarray(pixels).save(images / "seed.jpg", quality=90)
    Image.fromarray(pixels).save(images / "seed.tif")
    _write_exr(images / "seed.exr", (pixels / 255.0) ** 2.2)
    seeds = {"dng": [], "image": sorted(images.iterdir()), "profile": []}
    scenes = folder / "scenes"
    scenes.mkdir(exist_ok=True)
    for k in range(4):
        Image.fromarray(np.roll(pixels, 7 * k, axis=1)).save(scenes / f"scene{k}.png")
    for name in profiles:
        out = folder / f"dng_{name}"
        if not (out / "scene3.dng").exists():
            with contextlib.redirect_stderr(io.StringIO()), contextlib.redirect_stdout(io.StringIO()):
                status = convert_main([str(scenes), "--profile", name, "-o", str(out), "--no-progress", "--seed", "1"])
            assert status == 0, f"seed conversion with {name} failed"
        pair = [out / "scene0.dng", out / "scene1.dng"]
        seeds["dng"].append((pair[0], pair))
        seeds.setdefault("measured", []).append((pair[0], [out / f"scene{k}.dng" for k in range(1, 4)]))
        profile = folder / f"{name}.json"
        shutil.copyfile(ROOT / "profiles" / f"{name}.json", profile)
        seeds["profile"].append(profile)
    if SHARED_DNG.is_dir():   # real files; a LinearRaw one gets good partners of another camera
        from g2r_jax.io.dng_read import read_dng_info

        for path in sorted(SHARED_DNG.glob("*.dng")):
            try:
                bayer = read_dng_info(path).is_cfa
            except Exception:  # noqa: BLE001 - a seed that is itself refused still gets partners
                bayer = False
            partners = seeds["dng"][-1][1]
            if bayer:   # two distinct good files of its camera: the command counts a file once, however linked
                partners = []
                for k in range(2):
                    copy = folder / "shared_copies" / f"{path.stem}_{k}.dng"
                    if not copy.exists():
                        copy.parent.mkdir(exist_ok=True)
                        shutil.copyfile(path, copy)
                    partners.append(copy)
            seeds["dng"].append((path, partners))
    return seeds


def _write_exr(path, array):
    import OpenEXR

    channels = {name: np.ascontiguousarray(array[..., i].astype(np.float32)) for i, name in enumerate("RGB")}
    OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}, channels).write(str(path))


# ----------------------------------------------------------------------------- mutators

def _tag_fields(data: bytes) -> list:
    """(offset, size) of the tag entries and their values inside the first HEAD bytes."""
    import tifffile

    fields = []
    try:
        with tifffile.TiffFile(io.BytesIO(data[: max(HEAD * 4, 65536)] if len(data) > 4 * 2 ** 20 else data)) as tif:
            pages = [tif.pages.first] + list(getattr(tif.pages.first, "pages", None) or [])
            for page in pages:
                for tag in page.tags.values():
                    if tag.offset < HEAD:
                        fields.append((tag.offset, 12))
                    if tag.valueoffset < HEAD:
                        fields.append((tag.valueoffset, max(1, min(tag.valuebytecount, 64))))
    except Exception:  # noqa: BLE001 - a seed we cannot parse is mutated blindly
        pass
    return fields


def mutate_dng(data: bytes, rng: random.Random, fields=None, deep: bool = False) -> tuple[bytes, str]:
    """One mutation of a DNG (bytes, description); `deep`: anywhere in the file (image data,
    tiles, later IFDs), not only in its first `HEAD` bytes."""
    data = bytearray(data)
    head = len(data) if deep else min(HEAD, len(data))
    kind = rng.choice(("flip", "flip", "truncate", "overwrite", "field", "field", "field"))
    if kind == "flip":
        for _ in range(rng.randint(1, 8)):
            position = rng.randrange(head)
            data[position] ^= 1 << rng.randrange(8)
        return bytes(data), kind
    if kind == "truncate":
        return bytes(data[: rng.randrange(len(data))]), kind
    if kind == "overwrite" or not fields:
        position = rng.randrange(max(1, head - 4))
        data[position:position + 4] = struct.pack("<I", rng.choice(INTERESTING_32))
        return bytes(data), "overwrite"
    offset, size = rng.choice(fields)
    choice = rng.random()
    if choice < 0.4 and size >= 8:      # a (S)RATIONAL or DOUBLE value
        at = offset + 4 * rng.randrange(size // 4 - 1)
        if rng.random() < 0.5:
            data[at:at + 8] = struct.pack("<d", rng.choice(INTERESTING_FLOATS))
        else:
            data[at:at + 8] = struct.pack("<iI", rng.choice((0, 1, -1, 2 ** 31 - 1, -2 ** 31)),
                                          rng.choice((0, 1, 2 ** 32 - 1)))
    else:
        at = offset + rng.randrange(max(1, size - 3))
        width = rng.choice((1, 2, 4))
        value = rng.choice(INTERESTING_32) & ((1 << (8 * width)) - 1)
        data[at:at + width] = value.to_bytes(width, "little")
    return bytes(data[: len(data)]), "field"


def mutate_image(data: bytes, suffix: str, rng: random.Random) -> tuple[bytes, str]:
    """One mutation of an image file; a fifth of them claim an enormous size in the header."""
    data = bytearray(data)
    if rng.random() < 0.2:
        if suffix == ".png" and len(data) > 24:      # IHDR width, height
            data[16:24] = struct.pack(">II", 100000, 100000)
            return bytes(data), "huge-header"
        if suffix in (".tif", ".tiff"):
            import tifffile

            with tifffile.TiffFile(io.BytesIO(bytes(data))) as tif:
                for code in (256, 257):
                    tag = tif.pages.first.tags[code]
                    if tag.dtype == 3:   # SHORT: change the type to LONG so it can be large
                        data[tag.offset + 2:tag.offset + 4] = struct.pack("<H", 4)
                    data[tag.valueoffset:tag.valueoffset + 4] = struct.pack("<I", 100000)
            return bytes(data), "huge-header"
        if suffix in (".jpg", ".jpeg"):
            marker = data.find(b"\xff\xc0")
            if marker > 0:
                data[marker + 5:marker + 9] = struct.pack(">HH", 65000, 65000)
                return bytes(data), "huge-header"
    mutated, kind = mutate_dng(bytes(data), rng)
    return mutated, kind


EXTREMES = (float("nan"), float("inf"), -float("inf"), 0, -1, 1, 1e308, -1e308, 9.2e18, -9.2e18, 1e-320, 2 ** 63,
            "text", None, [], {}, [1, 2], True)


def _leaves(node, path=()):
    if isinstance(node, dict):
        for key, value in node.items():
            yield from _leaves(value, path + (key,))
    elif isinstance(node, list) and node:
        for index, value in enumerate(node):
            yield from _leaves(value, path + (index,))
    else:
        yield path


def mutate_profile(text: str, rng: random.Random) -> tuple[str, str]:
    """One mutation of a profile's JSON text."""
    if rng.random() < 0.15:
        data = bytearray(text.encode())
        for _ in range(rng.randint(1, 4)):
            data[rng.randrange(len(data))] ^= 1 << rng.randrange(7)
        return data.decode("latin-1"), "flip"
    document = json.loads(text)
    leaves = list(_leaves(document))
    path = rng.choice(leaves)
    parent = document
    for key in path[:-1]:
        parent = parent[key]
    if rng.random() < 0.1:
        if isinstance(parent, dict):
            del parent[path[-1]]
        else:
            parent.pop(path[-1])
        return json.dumps(document), "delete " + ".".join(map(str, path))
    value = rng.choice(EXTREMES)
    if isinstance(value, float) and not np.isfinite(value):
        value_text = {"nan": "NaN", "inf": "Infinity", "-inf": "-Infinity"}[str(value)]
    else:
        value_text = None
    parent[path[-1]] = value if value_text is None else "__NONFINITE__"
    text = json.dumps(document)
    if value_text is not None:
        text = text.replace('"__NONFINITE__"', value_text)
    return text, "set " + ".".join(map(str, path)) + f" = {value!r}"


# ----------------------------------------------------------------------------- running one case

def _digest(path: Path) -> tuple:
    stat = path.stat()
    with open(path, "rb") as handle:
        head = handle.read(1 << 20)
    return stat.st_size, hashlib.sha256(head).hexdigest(), stat.st_mtime_ns


@contextlib.contextmanager
def _alarm(seconds: int):
    def ring(signum, frame):
        raise Hang(f"no answer within {seconds} s")

    previous = signal.signal(signal.SIGALRM, ring)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


def run_main(main, argv) -> tuple[int, str, str]:
    """main(argv) in-process with its output captured; exceptions become part of the result."""
    out, err = io.StringIO(), io.StringIO()
    saved = os.dup(2)
    with tempfile.TemporaryFile() as native:   # what C libraries write to descriptor 2 counts too
        os.dup2(native.fileno(), 2)
        try:
            with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
                try:
                    with _alarm(CASE_SECONDS):
                        status = main(argv)
                except Hang as hang:
                    status = f"hang: {hang}"
                except BaseException:  # noqa: BLE001 - an escaping exception breaks a promise
                    status = "exception: " + traceback.format_exc(limit=3)
        finally:
            os.dup2(saved, 2)
            os.close(saved)
        native.seek(0)
        native_text = native.read().decode("utf-8", "replace")
    return status, out.getvalue(), err.getvalue() + native_text


def _line_problems(command: str, err: str) -> list:
    problems = []
    for line in err.splitlines():
        if not line.startswith(f"{command}:"):
            problems.append(f"foreign line: {line[:200]!r}")
        elif len(line) > 600:
            problems.append(f"line of {len(line)} characters")
        for word in FORBIDDEN:
            if word in line:
                problems.append(f"library text {word!r}: {line[:200]!r}")
    return problems


def _leftovers(folder: Path) -> list:
    return [p.name for p in folder.rglob(".*.tmp")] if folder.exists() else []


def _memory_problem() -> list:
    peak_gib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2 ** 20
    return [f"peak memory {peak_gib:.1f} GiB"] if peak_gib > MAX_RSS_GIB else []


def fit_case(work: Path, seed_path: Path, partners, data: bytes) -> list:
    """Two good DNGs and one mutated copy through g2r-fit-profile; the broken promises."""
    from g2r_jax.cli.fit_profile import main
    from g2r_jax.profile.schema import load_profile

    folder = work / "in"
    folder.mkdir()
    for k, partner in enumerate(partners):
        target = folder / f"good{k}.dng"
        if partner.stat().st_size > 4 * 2 ** 20:
            try:   # a hard link: a distinct path to the command (a symbolic link would be the same file)
                os.link(partner, target)
            except OSError:
                shutil.copyfile(partner, target)
        else:
            shutil.copyfile(partner, target)
    bad = folder / "mutated.dng"
    bad.write_bytes(data)
    before = {p.name: _digest(p) for p in folder.iterdir()}
    output = work / "out" / "p.json"
    output.parent.mkdir()
    status, out, err = run_main(main, [str(folder), "-o", str(output)])
    problems = _line_problems("g2r-fit-profile", err) + _memory_problem()
    if not isinstance(status, int):
        return problems + [str(status)]
    if status not in (0, 1):
        problems.append(f"exit {status} although two good files were there: {err.strip()[:300]!r}")
    if status == 1 and "mutated.dng" not in err:
        problems.append(f"exit 1 without naming the mutated file: {err.strip()[:300]!r}")
    if status in (0, 1):
        try:
            load_profile(output)
        except Exception as error:  # noqa: BLE001
            problems.append(f"written profile refused by the loader: {error}")
    if status == 2 and output.exists():
        problems.append("profile written although the command failed")
    problems += [f"temporary file left: {name}" for name in _leftovers(output.parent)]
    if {p.name: _digest(p) for p in folder.iterdir()} != before:
        problems.append("inputs modified")
    return problems


def convert_case(work: Path, good_image: Path, mutated_name: str, image_data: bytes, profile: Path,
                 profile_text: str | None) -> list:
    """One good and one mutated image (and possibly a mutated profile) through g2r-convert."""
    from g2r_jax.cli.convert import main
    from g2r_jax.io.dng_read import read_dng_info, read_dng_pixels

    folder = work / "in"
    folder.mkdir()
    shutil.copyfile(good_image, folder / f"good{good_image.suffix}")
    (folder / mutated_name).write_bytes(image_data)
    profile_path = work / "profile.json"
    if profile_text is None:
        shutil.copyfile(profile, profile_path)
    else:
        profile_path.write_bytes(profile_text.encode("utf-8", "surrogateescape"))
    before = {p.name: _digest(p) for p in list(folder.iterdir()) + [profile_path]}
    output = work / "out"
    status, out, err = run_main(main, [str(folder), "--profile", str(profile_path), "-o", str(output),
                                       "--no-progress", "--batch-size", "2"])
    problems = _line_problems("g2r-convert", err) + _memory_problem()
    if not isinstance(status, int):
        return problems + [str(status)]
    if status == 2:
        lines = err.strip().splitlines()
        if profile_text is None:
            problems.append(f"exit 2 with a good profile: {err.strip()[:300]!r}")
        elif len(lines) != 1 or "profile.json" not in lines[0]:
            problems.append(f"refused profile not named in one line: {err.strip()[:300]!r}")
        if output.exists() and any(p.name != ".g2r.lock" for p in output.iterdir()):
            problems.append("output left although the profile was refused")
    elif status in (0, 1):
        good = output / "good.dng"
        if not good.exists():
            problems.append(f"the good image was not converted (exit {status}): {err.strip()[:300]!r}")
        else:
            try:
                info = read_dng_info(good)
                mosaic = read_dng_pixels(good, info).astype(np.float64)
                problems += _mosaic_problems(mosaic, info)
            except Exception as error:  # noqa: BLE001
                problems.append(f"written DNG unreadable: {error}")
        if status == 1 and mutated_name not in err:
            problems.append(f"exit 1 without naming the mutated input: {err.strip()[:300]!r}")
        manifest = output / "manifest.jsonl"
        written = sorted(p.name for p in output.glob("*.dng")) if output.exists() else []
        if written:
            records = [json.loads(line) for line in manifest.read_text().splitlines()]
            if sorted(Path(r["output"]).name for r in records) != written:
                problems.append("manifest does not list exactly the written DNGs")
        elif manifest.exists():
            problems.append("manifest left although nothing was written")
    else:
        problems.append(f"exit status {status}")
    problems += [f"temporary file left: {name}" for name in _leftovers(output)]
    if {p.name: _digest(p) for p in list(folder.iterdir()) + [profile_path]} != before:
        problems.append("inputs modified")
    return problems


def _mosaic_problems(mosaic, info) -> list:
    """A converted mid-grey scene must not give a CFA position stuck at 0 or at white."""
    problems = []
    black, white = np.asarray(info.black_level), float(info.white_level)
    for position in range(4):
        plane = mosaic[position // 2::2, position % 2::2]
        if np.mean(plane <= 0) > 0.5 and black[position] > 0:
            problems.append(f"CFA position {position} mostly 0, below the black level {black[position]:g}")
        if np.mean(plane >= white) > 0.9:
            problems.append(f"CFA position {position} stuck at the white level")
    return problems


def diagnose_case(work: Path, partners, data: bytes) -> list:
    """Good measured DNGs and one mutated copy through g2r-diagnose: the audit goes on."""
    from g2r_jax.cli.diagnose import main

    folder = work / "measured"
    folder.mkdir()
    for k, partner in enumerate(partners):
        shutil.copyfile(partner, folder / f"good{k}.dng")
    (folder / "mutated.dng").write_bytes(data)
    before = {p.name: _digest(p) for p in folder.iterdir()}
    report = work / "new" / "REPORT.json"
    status, out, err = run_main(main, ["--profile", "NikonD40", "--measured", str(folder), "--report", str(report),
                                       "--quiet", "--folds", "2"])
    problems = _line_problems("g2r-diagnose", err) + _memory_problem()
    if not isinstance(status, int):
        return problems + [str(status)]
    if status not in (0, 1):
        problems.append(f"exit {status}: the audit stopped: {err.strip()[:300]!r}")
    elif not report.exists():
        problems.append("no report although the good files were audited")
    if status == 1 and "mutated.dng" not in err:
        problems.append(f"exit 1 without naming the mutated file: {err.strip()[:300]!r}")
    if {p.name: _digest(p) for p in folder.iterdir()} != before:
        problems.append("inputs modified")
    return problems


def charts_case(work: Path, text: str) -> list:
    """A (mutated) chart CSV through `g2r-diagnose --charts`: a report, or one line naming the file."""
    from g2r_jax.cli.diagnose import main

    charts = work / "charts.csv"
    charts.write_bytes(text.encode("utf-8", "surrogateescape"))
    before = _digest(charts)
    report = work / "new" / "REPORT.json"
    status, out, err = run_main(main, ["--profile", "NikonD40", "--charts", str(charts), "--report", str(report),
                                       "--quiet", "--folds", "2"])
    problems = _line_problems("g2r-diagnose", err) + _memory_problem()
    if not isinstance(status, int):
        return problems + [str(status)]
    lines = err.strip().splitlines()
    if status == 0:
        try:
            json.loads(report.read_text())
        except (OSError, ValueError) as error:
            problems.append(f"exit 0 without a readable report: {error}")
    elif status == 2:
        if len(lines) != 1 or "charts.csv" not in lines[0]:
            problems.append(f"refused charts not named in one line: {err.strip()[:300]!r}")
        if report.exists():
            problems.append("report written although the command failed")
    else:
        problems.append(f"exit status {status}: {err.strip()[:300]!r}")
    problems += [f"temporary file left: {name}" for name in _leftovers(work / "new")]
    if _digest(charts) != before:
        problems.append("inputs modified")
    return problems


# ----------------------------------------------------------------------------- campaigns

def generate_cases(kind: str, n: int, seed: int, seeds: dict):
    """The cases of a campaign, deterministic in `seed`: dicts with the mutated payload and what
    the case runner needs (no command is run here, so a finding can be regenerated)."""
    rng = random.Random(seed)
    fields, contents = {}, {}
    for case in range(n):
        if kind in ("fit", "fit-deep", "diagnose"):
            choices = seeds["dng"] if kind == "fit" else seeds["measured"]   # the audit needs 3+ good files
            seed_path, partners = rng.choice(choices)
            if seed_path not in contents:   # each seed read once (the cases before FIRST are generated too)
                contents[seed_path] = seed_path.read_bytes()
                fields[seed_path] = _tag_fields(contents[seed_path])
            original = contents[seed_path]
            data, how = mutate_dng(original, rng, fields[seed_path], deep=kind == "fit-deep")
            yield {"case": case, "kind": kind, "partners": partners, "data": data, "suffix": ".dng",
                   "label": f"{seed_path.name}: {how}", "payload": data}
        elif kind == "diagnose-charts":   # the chart CSVs of tests/input_attacks.py, through the command
            from input_attacks import chart_seed, mutate_csv

            text, how = mutate_csv(chart_seed(rng), rng)
            if rng.random() < 0.15:   # what the documented format allows: every patch nan
                lines = text.splitlines()
                text = "\n".join([lines[0]] + [",".join(line.split(",")[:2] + ["nan"] * 3)
                                               if ",illuminant," not in line else line for line in lines[1:]]) + "\n"
                how += ", every patch nan"
            yield {"case": case, "kind": kind, "text": text, "label": f"charts: {how}",
                   "payload": text.encode("utf-8", "surrogateescape"), "suffix": ".csv"}
        else:
            image = rng.choice(seeds["image"])
            profile = rng.choice(seeds["profile"])
            if image not in contents:
                contents[image] = image.read_bytes()
            if profile not in contents:
                contents[profile] = profile.read_text()
            data, how = mutate_image(contents[image], image.suffix.lower(), rng)
            profile_text, profile_how = None, "good profile"
            if rng.random() < 0.5:
                profile_text, profile_how = mutate_profile(contents[profile], rng)
                data, how = contents[image], "good image"
            yield {"case": case, "kind": kind, "image": image, "data": data, "profile": profile,
                   "profile_text": profile_text,
                   "payload": data if profile_text is None else profile_text.encode("utf-8", "surrogateescape"),
                   "suffix": image.suffix if profile_text is None else ".json",
                   "label": f"{image.name} ({how}), {profile.name} ({profile_how})"}


def run_case(spec: dict, work: Path) -> list:
    """Run one generated (or corpus) case in the empty folder `work`; the broken promises."""
    if spec["kind"] in ("fit", "fit-deep"):
        return fit_case(work, None, spec["partners"], spec["data"])
    if spec["kind"] == "diagnose":
        return diagnose_case(work, spec["partners"], spec["data"])
    if spec["kind"] == "diagnose-charts":
        return charts_case(work, spec["text"])
    return convert_case(work, spec["image"], f"mutated{spec['image'].suffix}", spec["data"], spec["profile"],
                        spec["profile_text"])


def campaign(kind: str, n: int, seed: int = 0, *, seeds_dir: Path | None = None, save_findings: bool = False,
             profiles=SEED_PROFILES, log=print, first: int = 0) -> dict:
    """Run cases `first`..`n`-1 of `kind` ('fit', 'fit-deep', 'convert', 'diagnose' or 'diagnose-charts')
    from `seed`; returns counts and findings. The cases before `first` are generated, not run, so
    that one campaign can be run in pieces (one process each) with the same cases as in one."""
    base = Path(tempfile.mkdtemp(prefix="g2r_fuzz_"))
    seeds = make_seeds(seeds_dir or base / "seeds", profiles)
    findings = []
    try:
        for spec in generate_cases(kind, n, seed, seeds):
            if spec["case"] < first:
                continue
            work = base / f"case{spec['case']}"
            work.mkdir()
            problems = run_case(spec, work)
            if problems:
                finding = {"case": spec["case"], "kind": kind, "input": spec["label"], "problems": problems}
                findings.append(finding)
                log(f"finding {len(findings)} in case {spec['case']}: {spec['label']}: {problems[0][:300]}")
                if save_findings and kind != "diagnose":
                    save_reproducer(spec)
            shutil.rmtree(work, ignore_errors=True)
            if (spec["case"] + 1) % 100 == 0:
                log(f"progress: {kind} {spec['case'] + 1} cases done, {len(findings)} findings")
    finally:
        shutil.rmtree(base, ignore_errors=True)
    return {"kind": kind, "cases": n - first, "first": first, "findings": findings}


def save_reproducer(spec: dict) -> Path:
    """Keep a case's mutated file in tests/fuzz_corpus/ as '<kind>_<image kind or dng>_<hash>.<ext>'."""
    CORPUS.mkdir(exist_ok=True)
    what = spec["kind"] if spec["kind"] != "convert" else ("profile" if spec["profile_text"] is not None
                                                           else "image")
    path = CORPUS / f"{what}_{hashlib.sha256(spec['payload']).hexdigest()[:10]}{spec['suffix']}"
    path.write_bytes(spec["payload"])
    return path


def corpus_case(path: Path, seeds: dict) -> dict:
    """The case that replays one corpus file against good seeds."""
    data = path.read_bytes()
    what = path.name.split("_", 1)[0]
    if what == "diagnose-charts":
        return {"kind": what, "text": data.decode("utf-8", "surrogateescape"), "label": path.name}
    if what in ("fit", "fit-deep", "diagnose"):
        return {"kind": what, "partners": seeds["dng"][0][1], "data": data, "label": path.name}
    if what == "profile":
        return {"kind": "convert", "image": seeds["image"][0], "data": seeds["image"][0].read_bytes(),
                "profile": seeds["profile"][0], "profile_text": data.decode("utf-8", "surrogateescape"),
                "label": path.name}
    image = next(p for p in seeds["image"] if p.suffix == path.suffix)
    return {"kind": "convert", "image": image, "data": data, "profile": seeds["profile"][0], "profile_text": None,
            "label": path.name}


if __name__ == "__main__":
    sys.path.insert(0, str(ROOT))
    what, count = sys.argv[1], int(sys.argv[2])
    start = int(sys.argv[3]) if len(sys.argv) > 3 else 0
    first = int(sys.argv[4]) if len(sys.argv) > 4 else 0   # run cases first..count-1 of the campaign
    import time

    began = time.time()
    import jax

    jax.config.update("jax_compilation_cache_dir", os.environ.get("G2R_FUZZ_JAX_CACHE", "/tmp/g2r_fuzz_jax_cache"))
    reuse = os.environ.get("G2R_FUZZ_SEEDS")
    result = campaign(what, count, start, save_findings=True, seeds_dir=Path(reuse) if reuse else None,
                      log=lambda line: print(line, flush=True), first=first)
    print(json.dumps({"kind": what, "cases": result["cases"], "first": first, "seed": start,
                      "findings": len(result["findings"]),
                      "seconds": round(time.time() - began)}), flush=True)
