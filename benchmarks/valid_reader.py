"""Valid-file campaign of the DNG reader (issue 44): every file here is a sound DNG, none may be
refused.

    python benchmarks/valid_reader.py --per-kind 11 --seeds 1 2 --json /tmp/valid_reader.json

The fuzz campaign (`benchmarks/fuzz_reader.py`) counts corrupt files the reader lets through;
this one counts valid files it refuses. The reader's checks of a decoded raster
(`g2r_jax.io.pixel_layout.decoded_finding`) guess at corruption from the pixels; a guess that
holds for smooth photographs can fail on content a CG user converts (white noise refused 3 times
in 120 conversions before issue 44). Made in a temporary folder, nothing kept:

- CG inputs of ten kinds (`KINDS`), sRGB PNGs of small sizes (`SHAPES`): white noise in colour and
  in grey at several contrasts, textures (blurred noise, dead leaves), line patterns of period 2,
  3 and 4 px (1-2 px wide) in columns, rows, diagonals and checkerboards, colour charts,
  gradients, night frames (converted at the profile's highest ISO), flat fields, dark and black
  frames, and saturated frames (the converted mosaic scaled up and clipped at WhiteLevel);
- converted by `g2r_jax.batch.conversion.convert_files` (what `g2r-convert` runs) with each
  profile of `--profiles` and each seed of `--seeds`: the profiles cover the four Bayer phases
  (RGGB, GRBG, GBRG, BGGR);
- each converted DNG is also rewritten in the three other phases (`write_dng_bytes`): the mosaic
  cropped by one row and/or column (the same scene seen from another corner, so the new
  CFAPattern is the true one; relabelling without the crop would be a corrupt file) with the
  CFAPattern and BlackLevel moved with it;
- every real DNG under `../shared/data` (skipped when the folder is absent).

Each file is read as the commands read it, `read_dng_info` then `read_dng_pixels`; a warning is
a line the reader adds to `info.warnings` (and issues as a `UserWarning`, silenced here). With
`--shifted` the same rasters are also shifted by one column and by one row in memory and given to
`decoded_finding` with the file's tags: how many such corrupt rasters are refused or warned about,
per kind (what the check can and cannot see). Prints counts: files, refused (with names and
reasons), warned, per kind and per phase. Exit status 1 when a valid file is refused.
"""

from __future__ import annotations

import argparse
import collections
import dataclasses
import json
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

DATA = ROOT / ".." / "shared" / "data"
PROFILES = ("Canon600D", "NikonD40", "PanasonicGX1", "gopro_hero6", "s20fe_night", "rpi_hq_imx477")
SHAPES = ((64, 96), (96, 128), (128, 128), (128, 192), (192, 256), (256, 256))
PHASE_NAMES = {(0, 1, 1, 2): "RGGB", (1, 0, 2, 1): "GRBG", (1, 2, 0, 1): "GBRG", (2, 1, 1, 0): "BGGR"}


# ----------------------------------------------------------------------------- CG content (uint8 sRGB)

def _colour(rng, grey=False) -> np.ndarray:
    value = rng.integers(0, 256, 3)
    return np.full(3, value[0]) if grey else value


def white_noise(rng, shape, grey=False) -> np.ndarray:
    """Independent uniform values per pixel (and channel), contrast 4..255 codes about a random mean."""
    contrast = float(rng.choice([4, 16, 48, 128, 255]))
    mean = rng.uniform(contrast / 2, 255 - contrast / 2, 1 if grey else 3)
    values = rng.uniform(-0.5, 0.5, shape + ((1,) if grey else (3,))) * contrast + mean
    return np.broadcast_to(values, shape + (3,))


def _blur(field: np.ndarray, radius: int) -> np.ndarray:
    """A box blur of (H, W, C) by cumulative sums along both axes (edges wrapped)."""
    for axis in (0, 1):
        padded = np.concatenate([field.take(range(-radius, 0), axis), field, field.take(range(radius), axis)], axis)
        total = np.cumsum(padded, axis, dtype=np.float64)
        total = np.concatenate([np.zeros_like(total.take([0], axis)), total], axis)
        size = field.shape[axis]
        field = (total.take(range(2 * radius + 1, 2 * radius + 1 + size), axis) - total.take(range(size), axis)) / (
            2 * radius + 1)
    return field


def texture(rng, shape) -> np.ndarray:
    """Blurred colour noise (radius 1..8 px) or dead leaves (discs of random colours and sizes)."""
    if rng.random() < 0.5:
        field = _blur(rng.uniform(0, 1, shape + (3,)), int(rng.integers(1, 9)))
        low, high = field.min(), field.max()
        return (field - low) / max(high - low, 1e-9) * rng.uniform(60, 255)
    image = np.empty(shape + (3,))
    image[:] = _colour(rng)
    rows, columns = np.mgrid[0:shape[0], 0:shape[1]]
    for _ in range(int(rng.integers(30, 120))):
        radius = max(shape) * rng.uniform(0.01, 0.25) ** 1.5
        centre = rng.uniform(0, shape[0]), rng.uniform(0, shape[1])
        image[(rows - centre[0]) ** 2 + (columns - centre[1]) ** 2 < radius ** 2] = _colour(rng)
    return image


def lines(rng, shape) -> np.ndarray:
    """Lines of period 2, 3 or 4 px, 1-2 px wide, in columns, rows, diagonals or a checkerboard;
    two colours (black and white, a grey pair, or two random colours)."""
    period = int(rng.choice([2, 2, 3, 4]))
    width = 1 if period < 4 else int(rng.integers(1, 3))
    rows, columns = np.mgrid[0:shape[0], 0:shape[1]]
    position = {"columns": columns, "rows": rows, "diagonal": rows + columns, "antidiagonal": rows - columns,
                "checker": columns // width + rows // width}[rng.choice(["columns", "rows", "diagonal", "antidiagonal",
                                                                        "checker"])]
    on = (position % period < width) if period > 2 or width > 1 else (position % 2 == 0)
    pair = rng.integers(0, 3)
    first, second = ((np.full(3, 255), np.zeros(3)) if pair == 0 else
                     (_colour(rng, grey=True), _colour(rng, grey=True)) if pair == 1 else (_colour(rng), _colour(rng)))
    return np.where(on[..., None], first, second)


def chart(rng, shape) -> np.ndarray:
    """A grid of 4 x 6 flat patches of random colours on a dark border, like a colour chart."""
    image = np.empty(shape + (3,))
    image[:] = rng.integers(0, 60)
    step_r, step_c = shape[0] / 4, shape[1] / 6
    for i in range(4):
        for j in range(6):
            r0, c0 = int(i * step_r + 2), int(j * step_c + 2)
            image[r0:int((i + 1) * step_r - 2), c0:int((j + 1) * step_c - 2)] = _colour(rng)
    return image


def gradient(rng, shape) -> np.ndarray:
    """A ramp between two random colours: horizontal, vertical, diagonal or radial."""
    rows, columns = np.mgrid[0:shape[0], 0:shape[1]] / np.array(shape, float)[:, None, None]
    kind = rng.integers(0, 4)
    t = [columns, rows, (rows + columns) / 2, np.hypot(rows - 0.5, columns - 0.5) / 0.71][kind]
    start, end = _colour(rng), _colour(rng)
    return start + t[..., None] * (end - start)


def night(rng, shape) -> np.ndarray:
    """A dark scene (codes 0..40) with a few bright lights; converted at the profile's top ISO."""
    image = texture(rng, shape) * rng.uniform(0.02, 0.16)
    rows, columns = np.mgrid[0:shape[0], 0:shape[1]]
    for _ in range(int(rng.integers(0, 5))):
        centre = rng.uniform(0, shape[0]), rng.uniform(0, shape[1])
        image[(rows - centre[0]) ** 2 + (columns - centre[1]) ** 2 < rng.uniform(1, 6) ** 2] = _colour(rng)
    return image


def flat(rng, shape) -> np.ndarray:
    """One colour everywhere: grey, white, a random colour."""
    return np.broadcast_to(_colour(rng, grey=rng.random() < 0.4), shape + (3,))


def dark(rng, shape) -> np.ndarray:
    """A black frame (all 0) or codes 0..3."""
    if rng.random() < 0.5:
        return np.zeros(shape + (3,))
    return rng.integers(0, 4, shape + (3,))


KINDS = {
    "noise": white_noise, "grey_noise": lambda rng, shape: white_noise(rng, shape, grey=True), "texture": texture,
    "lines": lines, "chart": chart, "gradient": gradient, "night": night, "flat": flat, "dark": dark,
    "saturated": texture,   # converted, then scaled and clipped at WhiteLevel (`saturate`)
}


def write_inputs(folder: Path, per_kind: int, rng) -> dict:
    """{kind: [png paths]}: `per_kind` images of each kind, sizes drawn from `SHAPES`."""
    from PIL import Image

    folder.mkdir(parents=True)
    made = collections.defaultdict(list)
    for kind, make in KINDS.items():
        for k in range(per_kind):
            shape = SHAPES[int(rng.integers(len(SHAPES)))]
            image = np.clip(np.round(make(rng, shape)), 0, 255).astype(np.uint8)
            made[kind].append(folder / f"{kind}_{k:03d}.png")
            Image.fromarray(np.ascontiguousarray(image)).save(made[kind][-1])
    return made


# ----------------------------------------------------------------------------- DNGs

def convert(paths, profile, out: Path, seed: int, iso=None) -> list:
    """The DNGs of `paths` converted as g2r-convert does; a failed conversion stops the campaign."""
    from g2r_jax.batch.conversion import ConvertOptions, convert_files

    options = ConvertOptions(seed=seed, iso=iso, progress=False)
    result = convert_files(paths, profile, out, options=options)
    if result.errors:
        raise SystemExit(f"conversion failed: {result.errors[:3]}")
    return [out / record["output"] for record in result.records]


def rephased(mosaic: np.ndarray, info, rows: int, columns: int):
    """(mosaic, info) of the same scene cropped by `rows` rows and `columns` columns at the top
    left (and as many at the bottom right, so the sides stay even): its true CFA phase moves by
    that many sites, and CFAPattern and BlackLevel move with it (DNG spec ch. 4 'CFAPattern':
    the pattern starts at the ActiveArea's top-left pixel)."""
    height, width = mosaic.shape
    cropped = mosaic[rows:height - 2 + rows, columns:width - 2 + columns]
    order = [2 * ((i + rows) % 2) + (j + columns) % 2 for i in (0, 1) for j in (0, 1)]
    pattern = tuple(int(info.cfa_pattern[k]) for k in order)
    black = np.asarray(info.black_level, np.float64)[order]
    return np.ascontiguousarray(cropped), dataclasses.replace(info, cfa_pattern=pattern, black_level=black,
                                                              warnings=[], path="")


def saturate(mosaic: np.ndarray, info, rng):
    """The frame overexposed: levels above black scaled by 3..12 and clipped at WhiteLevel."""
    black = float(np.min(info.black_level))
    gain = rng.uniform(3, 12)
    scaled = black + (mosaic.astype(np.float64) - black) * gain
    return np.clip(np.round(scaled), 0, info.white_level).astype(np.uint16)


def read(path: Path):
    """('refused' | 'warned' | 'read', message, mosaic or None, info or None) as the commands
    read a DNG: `read_dng_info`, then `read_dng_pixels`."""
    from g2r_jax.io.dng_info import DngError
    from g2r_jax.io.dng_read import read_dng_info, read_dng_pixels

    try:
        info = read_dng_info(path)
    except DngError as error:
        return "refused", str(error), None, None
    before = len(info.warnings)
    try:
        with warnings.catch_warnings():   # counted from info.warnings, not printed
            warnings.simplefilter("ignore")
            mosaic = read_dng_pixels(path, info)
    except DngError as error:
        return "refused", str(error), None, info
    added = info.warnings[before:]
    return ("warned" if added else "read"), "; ".join(added), mosaic, info


def decoded(path: Path):
    """(mosaic, info) of one of our conversions, decoded by LibRaw without the reader's checks of
    the raster: the source of its other phases whatever the reader says about the file itself."""
    import rawpy

    from g2r_jax.io.dng_read import read_dng_info

    with rawpy.imread(str(path)) as raw:
        return np.array(raw.raw_image_visible, copy=True), read_dng_info(path)


def shifted_outcomes(mosaic: np.ndarray, info) -> list:
    """What `decoded_finding` makes of the raster shifted by one column and by one row (corrupt
    rasters: pixel data read one pixel or one row off): 'refused', 'warned' or 'unflagged'."""
    from g2r_jax.io import pixel_layout

    out = []
    for axis in (1, 0):
        shifted = np.roll(mosaic, -1, axis=axis)
        if hasattr(pixel_layout, "decoded_finding"):
            found = pixel_layout.decoded_finding(shifted, info.black_level, info.white_level, info.cfa_pattern)
            refusal, warning = found.refusal, found.warning
        else:   # the reader before issue 44: refusals only
            refusal = pixel_layout.decoded_problem(shifted, info.black_level, info.white_level, info.cfa_pattern)
            warning = None
        out.append("refused" if refusal else "warned" if warning else "unflagged")
    return out


@dataclasses.dataclass
class Tally:
    files: int = 0
    outcomes: collections.Counter = dataclasses.field(default_factory=collections.Counter)
    kinds: dict = dataclasses.field(default_factory=lambda: collections.defaultdict(collections.Counter))
    phases: dict = dataclasses.field(default_factory=lambda: collections.defaultdict(collections.Counter))
    shifted: dict = dataclasses.field(default_factory=lambda: collections.defaultdict(collections.Counter))
    refused: list = dataclasses.field(default_factory=list)
    warned: list = dataclasses.field(default_factory=list)

    def add(self, name: str, kind: str, path: Path, with_shifts: bool, source=None):
        """Read one file and count it; with `with_shifts`, also its raster shifted (`source`:
        the (mosaic, info) written, else what the reader returned)."""
        outcome, message, mosaic, info = read(path)
        self.files += 1
        self.outcomes[outcome] += 1
        self.kinds[kind][outcome] += 1
        phase = PHASE_NAMES.get(tuple(info.cfa_pattern), "other") if info is not None else "?"
        self.phases[phase][outcome] += 1
        if outcome == "refused":
            self.refused.append(f"{name}: {message}")
        elif outcome == "warned":
            self.warned.append(f"{name}: {message}")
        mosaic, info = source or (mosaic, info)
        if with_shifts and mosaic is not None:
            for outcome in shifted_outcomes(mosaic, info):
                self.shifted[kind][outcome] += 1


def campaign_run(tally: Tally, inputs: dict, profile_name: str, seed: int, work: Path, args, rng):
    """Convert every input with one profile and seed; read each DNG in its four phases."""
    import g2r_jax
    from g2r_jax.io.atomic import atomic_write_bytes
    from g2r_jax.io.dng_write import write_dng_bytes

    profile = g2r_jax.load_profile(profile_name)
    out = work / f"{profile_name}_{seed}"
    plain = [p for kind, paths in inputs.items() if kind != "night" for p in paths]
    dngs = convert(plain, profile, out / "plain", seed)
    top_iso = float(np.max(np.asarray(profile.noise.iso_range)))
    dngs += convert(inputs["night"], profile, out / "night", seed, iso=top_iso)
    for dng in dngs:
        kind = dng.stem.rsplit("_", 1)[0]
        name = f"{profile_name}/seed{seed}/{dng.stem}"
        mosaic, info = decoded(dng)
        if kind != "saturated":   # the converted file itself; saturated frames are made from it
            tally.add(name, kind, dng, args.shifted, (mosaic, info))
        if kind == "saturated":
            mosaic = saturate(mosaic, info, rng)
        for rows, columns in ((0, 0), (0, 1), (1, 0), (1, 1)):
            if kind != "saturated" and rows == columns == 0:
                continue   # the converted file itself, read above
            variant, variant_info = rephased(mosaic, info, rows, columns)
            path = out / f"{dng.stem}_{PHASE_NAMES.get(variant_info.cfa_pattern, 'other')}.dng"
            atomic_write_bytes(path, write_dng_bytes(variant, variant_info, where=path))
            tally.add(f"{name} as {PHASE_NAMES.get(variant_info.cfa_pattern)}", kind, path, args.shifted,
                      (variant, variant_info))
            path.unlink()
        dng.unlink()


def real_files(tally: Tally, args):
    """Every real DNG under ../shared/data; a file whose tags say its pixels cannot be decoded
    (a header-only DNG, LinearRaw) is counted apart, it is not a CFA raster to check."""
    if not DATA.is_dir():
        print(f"{DATA}: absent, real DNGs skipped")
        return
    from g2r_jax.io.dng_info import DngError
    from g2r_jax.io.dng_read import read_dng_info, require_bayer_cfa

    for path in sorted(p for p in DATA.rglob("*") if p.suffix.lower() == ".dng"):
        try:
            info = require_bayer_cfa(read_dng_info(path))
            if info.pixel_data_problem:
                raise DngError(path, info.pixel_data_problem)
        except DngError as error:
            tally.outcomes["real, not a decodable CFA file"] += 1
            print(f"not counted (not a decodable CFA file): {error}")
            continue
        tally.add(str(path.relative_to(DATA)), "real", path, args.shifted)


def run(args) -> dict:
    began = time.time()
    rng = np.random.default_rng(args.seed)
    tally = Tally()
    with tempfile.TemporaryDirectory(prefix="g2r_valid_reader_") as folder:
        work = Path(folder)
        inputs = write_inputs(work / "inputs", args.per_kind, rng)
        for profile_name in args.profiles:
            for seed in args.seeds:
                campaign_run(tally, inputs, profile_name, seed, work, args, rng)
                print(f"{profile_name} seed {seed}: {tally.files} files, {dict(tally.outcomes)}, "
                      f"{time.time() - began:.0f} s", flush=True)
    real_files(tally, args)
    return {"files": tally.files, "refused": tally.outcomes["refused"], "warned": tally.outcomes["warned"],
            "read": tally.outcomes["read"], "seconds": round(time.time() - began),
            "kinds": {k: dict(v) for k, v in sorted(tally.kinds.items())},
            "phases": {k: dict(v) for k, v in sorted(tally.phases.items())},
            "shifted": {k: dict(v) for k, v in sorted(tally.shifted.items())},
            "refused_files": tally.refused, "warned_files": tally.warned}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--per-kind", type=int, default=11, help="CG images of each kind (each read in 4 phases)")
    parser.add_argument("--profiles", nargs="+", default=list(PROFILES))
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2], help="conversion seeds")
    parser.add_argument("--seed", type=int, default=0, help="seed of the CG content")
    parser.add_argument("--shifted", action="store_true", help="also check each raster shifted by a column and a row")
    parser.add_argument("--json", help="write the counts here")
    args = parser.parse_args(argv)
    result = run(args)
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=1))
    print(json.dumps({k: result[k] for k in ("files", "refused", "warned", "read", "seconds")}))
    for part in ("kinds", "phases", "shifted"):
        for key, counts in result[part].items():
            print(f"{part[:-1] if part != 'shifted' else 'shifted'} {key}: {counts}")
    for line in result["refused_files"]:
        print(f"refused: {line}")
    for line in result["warned_files"][:40]:
        print(f"warned: {line}")
    return 1 if result["refused"] else 0


if __name__ == "__main__":
    sys.exit(main())
