"""Bursts for the denoising test: several DNGs of one static scene from one camera, read into
normalised CFA planes, their clean references, and the noise they measure themselves.

A burst is the truth a real denoising test needs (Graphics2RAW, Seo et al. ICCV 2023, Table 1;
the protocol of Plotz and Roth, "Benchmarking Denoising Algorithms with Real Photographs", CVPR
2017, and of SIDD, Abdelhamed et al. CVPR 2018, which average many frames of a static scene):
the mean of the other frames of a static scene is a clean reference for each frame.

- `read_burst(source)`: a folder or list of DNGs -> `Burst`. Every file is either a frame or
  named in `Burst.skipped` with the reason (unreadable, another camera / size / ISO / levels, or
  not the same static scene as the others); fewer than MIN_FRAMES usable frames is an error.
- `photon_transfer_noise(burst)`: variance = shot * x + read per CFA position from the frames'
  own per-pixel temporal means and variances (Janesick, *Photon Transfer*, SPIE 2007, ch. 2-5;
  `g2r_jax.measure.photon_transfer.regression_shot_read`), with the rounding to DN taken out of `read`.
- `write_synthetic_burst(folder, profile, ...)`: DNGs of a dead-leaves scene with a known
  heteroscedastic noise (`g2r_jax.audit.synthetic_bursts`), for tests and the benchmark.
"""

from __future__ import annotations

import dataclasses
from collections import Counter
from pathlib import Path

import numpy as np

from g2r_jax.io.dng_info import DngError
from g2r_jax.measure.bursts import scene_outliers
from g2r_jax.measure.photon_transfer import regression_shot_read

MIN_FRAMES = 3
BLACK_FRAME_SHARE = 0.1     # a frame whose mean signal is under this share of the median frame's is black
SATURATED = 0.98            # normalised level at which a pixel counts as clipped (as in photon transfer)
MIN_UNCLIPPED_SHARE = 0.1   # a burst needs at least this share of pixels below SATURATED in every frame
COPY = "the same pixels as"


@dataclasses.dataclass(frozen=True)
class Burst:
    """Frames of one static scene. `planes` (n, 4, H/2, W/2) float32, x = (DN - BlackLevel) /
    (WhiteLevel - BlackLevel) per CFA tile position (row-major in the 2 x 2 tile); `black` (4,)
    DN, `white` DN, `iso`, `cfa_pattern` of the frames; `names` the frames' file names;
    `skipped` ((file name, reason), ...) for every input file that is not a frame."""

    planes: np.ndarray
    names: tuple
    paths: tuple
    infos: tuple
    black: np.ndarray
    white: float
    iso: float
    cfa_pattern: tuple
    skipped: tuple = ()

    @property
    def n(self) -> int:
        return self.planes.shape[0]

    @property
    def span(self) -> np.ndarray:
        """(4,) DN of the normalised range per tile position: WhiteLevel - BlackLevel."""
        return self.white - self.black

    def mean_of_others(self, index: int, among=None) -> np.ndarray:
        """(4, H/2, W/2) mean of the frames in `among` (default: all) other than `index`."""
        chosen = [k for k in (range(self.n) if among is None else among) if k != index]
        return self.planes[chosen].mean(0)


def _candidates(source) -> tuple[list[Path], list[tuple[str, str]]]:
    """DNG paths of a folder (every visible file that is not a .dng is named as skipped) or list."""
    if isinstance(source, (str, Path)) and Path(source).is_dir():
        files = sorted((f for f in Path(source).iterdir() if not f.name.startswith(".") and f.is_file()),
                       key=lambda f: f.name)
        dngs = [f for f in files if f.suffix.lower() == ".dng"]
        others = [(f.name, f"not a DNG ('{f.suffix or 'no extension'}')") for f in files if f.suffix.lower() != ".dng"]
        return dngs, others
    if isinstance(source, (str, Path)):
        source = [source]
    paths, skipped = [], []
    for item in source:
        path = Path(item)
        if not path.is_file():
            skipped.append((path.name or str(path), "no such file"))
        elif path.suffix.lower() != ".dng":
            skipped.append((path.name, f"not a DNG ('{path.suffix or 'no extension'}')"))
        elif path not in paths:
            paths.append(path)
    return paths, skipped


def _camera_key(info, mosaic) -> tuple:
    return (mosaic.shape, tuple(int(c) for c in info.cfa_pattern),
            tuple(np.round(np.resize(np.asarray(info.black_level, np.float64), 4), 3)), float(info.white_level),
            None if info.iso is None else round(float(info.iso)), info.unique_camera_model or info.model)


def _key_difference(key, reference) -> str:
    names = ("size", "CFA pattern", "BlackLevel", "WhiteLevel", "ISO", "camera model")
    for name, mine, theirs in zip(names, key, reference):
        if mine != theirs:
            show = lambda v: f"{v[1]}x{v[0]}" if name == "size" else str(v)
            return f"{name} {show(mine)} differs from the burst's {show(theirs)}"
    return "differs from the burst"


def _where(source, paths) -> str:
    """The folder to name in a refusal: `source` itself, or the folder of a list's files."""
    if isinstance(source, (str, Path)):
        return str(source)
    folders = sorted({str(Path(p).parent) for p in paths})
    return folders[0] if len(folders) == 1 else f"burst of {len(paths)} file(s) in {', '.join(folders)}"


def _degenerate_frames(planes: np.ndarray, names) -> dict[int, str]:
    """{frame index: reason} for frames that would corrupt the others' statistics: exact copies of
    an earlier frame (same pixels, by `measure.pixel_hash`: no temporal noise between them) and
    black frames (mean signal under BLACK_FRAME_SHARE of the median frame's: a capped lens or a
    dark frame, which would pull the mean of the others down and reject every real frame)."""
    from g2r_jax.measure import duplicate_groups

    out: dict[int, str] = {}
    if len(planes) == 0:
        return out
    groups = duplicate_groups(list(planes))
    first = {}
    for k, group in enumerate(groups):
        if group in first:
            out[k] = f"{COPY} {names[first[group]]}: a copy, not another exposure"
        else:
            first[group] = k
    levels = planes.reshape(len(planes), -1).mean(1, dtype=np.float64)
    typical = float(np.median(levels))
    for k, level in enumerate(levels):
        if k not in out and typical > 0 and level < BLACK_FRAME_SHARE * typical:
            out[k] = (f"a black frame: its mean signal is {100 * level / typical:.1f} % of the median frame's "
                      f"(a capped lens or a dark frame, not an exposure of the scene)")
    return out


def _refuse_saturated(planes: np.ndarray, where: str) -> None:
    """DngError naming `where` when under MIN_UNCLIPPED_SHARE of the pixels stay below the white
    level in every frame: such a burst has no noise to measure or learn from."""
    unclipped = float(np.mean(planes.max(0) < SATURATED))
    if unclipped < MIN_UNCLIPPED_SHARE:
        raise DngError(where, f"{100 * (1 - unclipped):.1f} % of the burst's pixels reach the white level in some "
                              f"frame (at most {100 * (1 - MIN_UNCLIPPED_SHARE):.0f} % may): a saturated burst "
                              f"carries no noise to learn from; expose it shorter")


def read_burst(source, *, min_frames: int = MIN_FRAMES) -> Burst:
    """A `Burst` from a folder of DNGs or a list of DNG paths (see the module docstring).

    Files that cannot be read, that differ from the most common size / CFA / levels / ISO /
    camera of the others, copies of another frame, black frames (`_degenerate_frames`), or whose
    scene differs from the others' (`g2r_jax.measure.bursts.scene_outliers`) are named in
    `skipped` with the reason. Raises `DngError` naming `source` (and every skipped file) when
    fewer than `min_frames` (at least 3) frames remain, or when the burst is saturated
    (`_refuse_saturated`).
    """
    from g2r_jax.io.dng_read import read_dng_info, read_dng_pixels, require_bayer_cfa
    from g2r_jax.sensor.noise.estimation import to_normalised_planes

    min_frames = max(int(min_frames), MIN_FRAMES)
    paths, skipped = _candidates(source)
    read = []
    for path in paths:
        try:
            info = require_bayer_cfa(read_dng_info(path))
            mosaic = read_dng_pixels(path, info)
        except Exception as error:  # noqa: BLE001 - DngError, LibRaw, OS errors: named, not fatal
            skipped.append((path.name, str(getattr(error, "problem", error))))
            continue
        if mosaic.shape[0] % 2 or mosaic.shape[1] % 2 or min(mosaic.shape) < 8:
            skipped.append((path.name, f"active area {mosaic.shape[1]}x{mosaic.shape[0]} is odd or under 8 pixels"))
            continue
        read.append((path, info, mosaic))
    frames = []
    if read:
        keys = [_camera_key(info, mosaic) for _, info, mosaic in read]
        reference = Counter(keys).most_common(1)[0][0]
        for key, item in zip(keys, read):
            if key == reference:
                frames.append(item)
            else:
                skipped.append((item[0].name, _key_difference(key, reference)))
    planes = np.stack([to_normalised_planes(m, info.black_level, info.white_level).astype(np.float32)
                       for _, info, m in frames]) if frames else np.zeros((0, 4, 1, 1), np.float32)
    where = _where(source, paths)
    if frames:
        _refuse_saturated(planes, where)
    degenerate = _degenerate_frames(planes, [p.name for p, _, _ in frames])
    skipped += [(frames[k][0].name, reason) for k, reason in sorted(degenerate.items())]
    keep = [k for k in range(len(frames)) if k not in degenerate]
    frames, planes = [frames[k] for k in keep], planes[keep]
    if len(frames) >= MIN_FRAMES:
        outliers = scene_outliers(planes)
        skipped += [(frames[k][0].name, reason) for k, reason in sorted(outliers.items())]
        keep = [k for k in range(len(frames)) if k not in outliers]
        frames, planes = [frames[k] for k in keep], planes[keep]
    if len(frames) < min_frames:
        listing = "; ".join(f"{name}: {reason}" for name, reason in skipped) or "none skipped"
        copies = " no temporal noise between identical frames;" if any(
            reason.startswith(COPY) for _, reason in skipped) else ""
        raise DngError(where, f"a burst needs at least {min_frames} DNG frames of one static scene from one camera,"
                              f"{copies} {len(frames)} usable (skipped: {listing})")
    info = frames[0][1]
    return Burst(planes=planes, names=tuple(p.name for p, _, _ in frames), paths=tuple(p for p, _, _ in frames),
                 infos=tuple(i for _, i, _ in frames), black=np.resize(np.asarray(info.black_level, np.float64), 4),
                 white=float(info.white_level), iso=float(info.iso) if info.iso else 100.0,
                 cfa_pattern=tuple(int(c) for c in info.cfa_pattern), skipped=tuple(skipped))


def photon_transfer_noise(burst: Burst, frames=None) -> tuple[np.ndarray, np.ndarray]:
    """(shot (4,), read (4,)) of variance = shot * x + read, normalised, from the temporal mean
    and variance of every pixel over `frames` (indices; default all) of the burst, by the
    toolkit's regression corrected for the noise in the mean
    (`g2r_jax.measure.photon_transfer.regression_shot_read`: Janesick 2007, Fuller 1987) over the
    pixels above the DN floor that never clip. The measured variance holds the rounding to
    integer DN once (1/12 DN^2); it is taken out of `read`, since a simulation rounds its own
    output. NaN where the pixels do not span a range of signals."""
    from g2r_jax.sensor.noise.quantisation import rounding_variance

    planes = burst.planes if frames is None else burst.planes[list(frames)]
    shot, read = regression_shot_read(planes, -burst.black / burst.span + 0.5 / burst.span)
    return shot, read - rounding_variance(burst.black, burst.white)


def write_synthetic_burst(folder, profile, *, n_frames: int = 8, height: int = 192, width: int = 256,
                          iso: float = 1600.0, seed: int = 0, noise_scale: float = 1.0, low: float = 0.004,
                          high: float = 0.08, fine: bool = True, blur: float = 0.0):
    """Write `n_frames` DNGs (frame_000.dng, ...) of one static dead-leaves scene into `folder`
    with the profile's levels, CFA and colour tags, and no NoiseProfile tag; return (paths,
    truth) with truth a `g2r_jax.audit.synthetic_bursts.BurstTruth`.

    The frames' noise is the profile's noise at `iso` (the mean of its four tile positions,
    `noise_scale` times the variance): DN = round(black + span * (x + n)), n ~ N(0, shot x +
    read), written in numpy independently of the simulation (`synthetic_bursts.burst`). The
    scene spans [`low`, `high`] of the range (a dim scene, where denoising matters); `blur` > 0
    defocuses it (a Gaussian of that sd in mosaic pixels per CFA site)."""
    from g2r_jax import sensor
    from g2r_jax.audit.synthetic_bursts import BurstTruth, burst, scene_signal
    from g2r_jax.profile.dng_tags import dng_info_for
    from g2r_jax.io.dng_write import write_dng

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    shot, read = (np.asarray(v, np.float64) for v in sensor.noise_parameters(iso, profile.noise))
    black = np.asarray(profile.black_level, np.float64)
    truth = BurstTruth(black_tag=float(black.mean()), white=float(profile.white_level), shot=float(shot.mean()),
                       read=float(read.mean()), iso=float(iso))
    signal = scene_signal(seed, height, width, low=low, high=high, fine=fine)
    if blur > 0:   # defocus: each CFA site's plane blurred (Gaussian, `blur` mosaic pixels)
        from scipy.ndimage import gaussian_filter

        for dy in (0, 1):
            for dx in (0, 1):
                signal[dy::2, dx::2] = gaussian_filter(signal[dy::2, dx::2], blur / 2, mode="reflect")
    frames = burst(truth, signal, n_frames, seed + 1, noise_scale=noise_scale)
    metadata = {"neutral": np.array([0.5, 1.0, 0.6]), "iso": iso, "noise_shot": shot, "noise_read": read}
    info = dng_info_for(profile, metadata, height, width, noise=False)
    info = dataclasses.replace(info, black_level=np.full(4, truth.black_tag))
    paths = []
    for k, (mosaic, _) in enumerate(frames):
        path = folder / f"frame_{k:03d}.dng"
        write_dng(path, mosaic, info)
        paths.append(path)
    return paths, truth
