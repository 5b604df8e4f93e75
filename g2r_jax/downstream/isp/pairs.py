"""The neural-ISP task's data: (packed RAW, display-sRGB target) pairs made from DNGs, real or
synthetic, all the same way (`pair_of`).

The task works on small DNGs (`WORKING_SIZE` x `WORKING_SIZE` pixels) whose every 2x2 CFA tile
holds one scene point (`tile_mosaic`): the mosaic of a small image, each pixel one tile. A larger
DNG is binned to one (`working_source`): its black-subtracted CFA planes area-averaged per colour
site over blocks (`thumbnails.area_average`), written as such a small DNG with the file's own
tags and levels (no lens-shading opcodes, no crop). Then, for every DNG alike:

- input: the mosaic black-subtracted, scaled by the range (WhiteLevel - BlackLevel) and packed by
  its CFA pattern into 4 planes in the order R, G1, G2, B whatever the pattern's phase (G1 the
  green on the red sites' rows, G2 the one on the blue sites' rows: `channel_positions`);
- target: the small DNG developed by the reference renderer (`g2r_jax.io.reference_render.develop`,
  LibRaw at its as-shot white balance), at the mosaic's full resolution.

Why tiles, and why the binned file is developed rather than the full one: a target binned from a
full-resolution development holds twice the detail of binned CFA planes (a colour fit knowing
each file's white balance reached about 20 dB on such pairs, NUS Canon 600D), and a 64 x 64
thumbnail mosaicked one site per pixel develops into colour fringes everywhere; on tiles the
target is the developer's rendering of exactly what the input holds, so the measures are about
colour and tone, the paper's subject.

Synthetic DNGs are made in memory (`DngSource`) the same way: CG views of `WORKING_SIZE / 2`
pixels, each pixel one tile, made RAW by g2r_jax (`g2r_pairs`) or UPI (`upi_pairs`, Brooks et al.
CVPR 2019), written with the camera's tags by our DNG writer (`g2r_jax.io.dng_write.write_dng_bytes`),
developed like the real files. No noise is added (the paper adds none for this task:
Graphics2RAW supplement S1.1).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import equinox as eqx
import jax
import numpy as np

from g2r_jax.downstream.base import thumbnails as _thumbnails
from g2r_jax.downstream.base import training_sets as _sets
from g2r_jax.io.dng_info import DngError, DngInfo

WORKING_SIZE = 64      # the target's side; the packed RAW's side is half of it
BATCH = 64             # views per compiled call (a fixed shape)


@dataclasses.dataclass(frozen=True)
class DngSource:
    """A DNG held in memory: its bytes (`data`, what the renderer develops) and what was written
    into them (`mosaic` (H, W) uint16 DN and its `info`, what the network reads); `name` for
    messages."""

    name: str
    data: bytes
    mosaic: np.ndarray
    info: DngInfo


def dng_source(mosaic: np.ndarray, info: DngInfo, name: str) -> DngSource:
    """`mosaic` and `info` written as DNG bytes (`write_dng_bytes`).

    **Arguments:** `mosaic` (H, W) integer DN; `info` its tags; `name` for messages.
    **Returns:** a `DngSource`.
    """
    from g2r_jax.io.dng_write import write_dng_bytes

    mosaic = np.asarray(mosaic, np.uint16)
    return DngSource(name=name, data=write_dng_bytes(mosaic, info, where=name), mosaic=mosaic, info=info)


def channel_positions(cfa_pattern) -> tuple:
    """Tile positions (0..3, row-major in the 2x2 tile) of R, G1, G2, B for a Bayer `cfa_pattern`
    (colour index per position, 0 R, 1 G, 2 B): G1 shares a row with R, G2 with B.

    **Arguments:** `cfa_pattern` 4 colour indices. **Returns:** 4 positions. **Raises:**
    ValueError for a pattern that is not one R, two G and one B.
    """
    cfa = [int(c) for c in np.asarray(cfa_pattern).reshape(-1)]
    if sorted(cfa) != [0, 1, 1, 2]:
        raise ValueError(f"CFA pattern {tuple(cfa)} is not a 2x2 Bayer pattern (one R, two G, one B)")
    red, blue = cfa.index(0), cfa.index(2)
    greens = [p for p in range(4) if cfa[p] == 1]
    g1 = next(p for p in greens if p // 2 == red // 2)
    g2 = next(p for p in greens if p != g1)
    return red, g1, g2, blue


def pack(mosaic: np.ndarray, cfa_pattern, black_level, white_level) -> np.ndarray:
    """A Bayer mosaic (H, W) in DN -> (H/2, W/2, 4) planes R, G1, G2, B, each (DN - black) /
    (white - black) at its own tile position's black level, clipped to [0, 1].

    **Arguments:** `cfa_pattern` colour per tile position; `black_level` scalar or 4 per position;
    `white_level` scalar. **Returns:** float32 planes (odd trailing rows/columns dropped).
    """
    mosaic = np.asarray(mosaic, np.float32)
    mosaic = mosaic[: mosaic.shape[0] // 2 * 2, : mosaic.shape[1] // 2 * 2]
    black = np.broadcast_to(np.asarray(black_level, np.float32).reshape(-1), (4,))
    span = np.float32(white_level) - black
    planes = [(mosaic[p // 2::2, p % 2::2] - black[p]) / span[p] for p in channel_positions(cfa_pattern)]
    return np.clip(np.stack(planes, -1), 0.0, 1.0).astype(np.float32)


def tile_mosaic(planes: np.ndarray, cfa_pattern, black_level, white_level) -> np.ndarray:
    """Planes (..., h, w, 4) in [0, 1] of the range, order R, G1, G2, B -> mosaics (..., 2h, 2w)
    uint16 of `cfa_pattern`, each 2x2 tile one pixel of the planes (each site its channel), at
    black + value * (white - black) of its tile position, rounded.

    **Arguments:** `cfa_pattern` colour per tile position; `black_level` scalar or 4 per position;
    `white_level` scalar. **Returns:** the mosaics.
    """
    planes = np.clip(np.asarray(planes, np.float64), 0.0, 1.0)
    black = np.broadcast_to(np.asarray(black_level, np.float64).reshape(-1), (4,))
    white = float(white_level)
    out = np.empty(planes.shape[:-3] + (2 * planes.shape[-3], 2 * planes.shape[-2]), np.float64)
    for k, p in enumerate(channel_positions(cfa_pattern)):
        out[..., p // 2::2, p % 2::2] = black[p] + planes[..., k] * (white - black[p])
    return np.round(out).astype(np.uint16)


def rgb_planes(rgb: np.ndarray) -> np.ndarray:
    """Camera RGB (..., 3) -> planes (..., 4) R, G1, G2, B (both greens the G)."""
    rgb = np.asarray(rgb)
    return np.stack([rgb[..., 0], rgb[..., 1], rgb[..., 1], rgb[..., 2]], -1)


def working_source(source, size: int = WORKING_SIZE) -> DngSource:
    """The small DNG the task uses for `source`: as it is when it is a `size` x `size` `DngSource`;
    otherwise its packed planes (`pack`) area-averaged to `size / 2` x `size / 2` blocks and
    written as a `size` x `size` tiled mosaic (`tile_mosaic`) with the file's tags and levels (no
    crop, opcodes or linearisation table: the pixels are linear already).

    **Arguments:** `source` a `DngSource` or the path of a Bayer DNG; `size` even. **Returns:** a
    `DngSource`. **Raises:** `DngError` naming the file when it cannot be read or is smaller than
    `size` x `size`.
    """
    if isinstance(source, DngSource):
        if source.mosaic.shape == (size, size):
            return source
        mosaic, info, name = source.mosaic, source.info, source.name
    else:
        from g2r_jax.io.dng_read import read_dng_info, read_dng_pixels, require_bayer_cfa, require_colour_tags

        name = str(source)
        info = require_colour_tags(require_bayer_cfa(read_dng_info(Path(source))))
        mosaic = read_dng_pixels(Path(source), info)
    if min(mosaic.shape) < size:
        raise DngError(name, f"{mosaic.shape[1]} x {mosaic.shape[0]} pixels are fewer than the task's {size} x {size}")
    planes = _thumbnails.area_average(pack(mosaic, info.cfa_pattern, info.black_level, info.white_level), size // 2)
    small = dataclasses.replace(info, path=name, width=size, height=size, active_area=None, default_crop_origin=None,
                                default_crop_size=None, opcode_lists={}, linearization_table=None, compression=1)
    return dng_source(tile_mosaic(planes, info.cfa_pattern, info.black_level, info.white_level), small, name)


def pair_of(source, size: int = WORKING_SIZE) -> tuple:
    """(packed (size/2, size/2, 4), target (size, size, 3)) of one DNG (module docstring).

    **Arguments:** `source`: a `DngSource` or the path of a Bayer DNG (its pixels read by
    `g2r_jax.io.dng_read.read_dng_pixels`); `size`: the target's side (even, at most the
    file's shorter side). **Returns:** two float32 arrays. **Raises:** `DngError`
    naming the file when it cannot be read or developed, or is smaller than the task.
    """
    from g2r_jax.io.reference_render import develop

    small = working_source(source, size)
    rendered = develop(small.data, name=small.name)
    if rendered.shape[:2] != (size, size):
        raise DngError(small.name, f"LibRaw developed {rendered.shape[1]} x {rendered.shape[0]} pixels of a "
                                   f"{size} x {size} mosaic")
    info = small.info
    return pack(small.mosaic, info.cfa_pattern, info.black_level, info.white_level), rendered


def pairs_of(sources, size: int = WORKING_SIZE) -> tuple:
    """`pair_of` for several DNGs, those that fail left out by name.

    **Arguments:** `sources`: `DngSource`s or paths. **Returns:** (packed (N, size/2, size/2, 4),
    targets (N, size, size, 3), kept indices (N,), skipped [(name, reason)]).
    """
    packed, targets, kept, skipped = [], [], [], []
    for index, source in enumerate(sources):
        try:
            p, t = pair_of(source, size)
        except DngError as error:
            skipped.append((error.path, error.problem))
            continue
        except (OSError, ValueError) as error:
            skipped.append((getattr(source, "name", str(source)), str(error)))
            continue
        packed.append(p)
        targets.append(t)
        kept.append(index)
    half = size // 2
    return (np.stack(packed) if packed else np.zeros((0, half, half, 4), np.float32),
            np.stack(targets) if targets else np.zeros((0, size, size, 3), np.float32), np.asarray(kept, int), skipped)


def _metadata(neutral, iso: float = 100.0) -> dict:
    """What `dng_info_for` reads of one noise-free image: its neutral and ISO."""
    return {"neutral": np.asarray(neutral, np.float64), "iso": iso, "noise_shot": np.zeros(4), "noise_read": np.zeros(4)}


def thumbnail_sources(images: np.ndarray, illuminants: np.ndarray, profile, names=None, *,
                      size: int = WORKING_SIZE) -> list:
    """Camera-RGB thumbnails written as small DNGs of the profile's camera (the NUS set's real
    images, `real_sets.load_nus`): each area-averaged to `size / 2` x `size / 2` and written as a
    `size` x `size` tiled mosaic at the profile's pattern (`tile_mosaic`: each pixel one CFA
    tile), between its black and white levels, saturated pixels (0 in the thumbnails) set to
    white, AsShotNeutral the measured light, the profile's colour tags. `thumbnail_masks` says
    which target pixels the white ones reach (out of the loss and the measures).

    **Arguments:** `images` (N, h, w, 3) in [0, 1], h and w at least size / 2; `illuminants`
    (N, 3); `profile` a `SensorProfile`; `names` per image (default image_NNN); `size`.
    **Returns:** N `DngSource`s.
    """
    from g2r_jax.profile.dng_tags import dng_info_for

    images = np.asarray(images, np.float32)
    saturated = np.all(images <= 0, axis=-1, keepdims=True)
    images = np.where(saturated, 1.0, images)
    small = np.stack([_thumbnails.area_average(image, size // 2) for image in images])
    mosaics = tile_mosaic(rgb_planes(small), profile.cfa_pattern, profile.black_level, profile.white_level)
    names = names if names is not None and len(names) == len(images) else [f"image_{i:03d}" for i in range(len(images))]
    sources = []
    for mosaic, light, name in zip(mosaics, np.asarray(illuminants, np.float64), names):
        info = dng_info_for(profile, _metadata(light / light[1]), *mosaic.shape, noise=False)
        sources.append(dng_source(mosaic, info, f"{name}.dng"))
    return sources


def _dilate(mask: np.ndarray) -> np.ndarray:
    """(N, H, W) bool, each True pixel spread to its 3 x 3 neighbourhood."""
    padded = np.pad(mask, ((0, 0), (1, 1), (1, 1)))
    height, width = mask.shape[1:]
    return np.any([padded[:, i:i + height, j:j + width] for i in range(3) for j in range(3)], axis=0)


def thumbnail_masks(images: np.ndarray, *, size: int = WORKING_SIZE) -> np.ndarray:
    """Where the targets of `thumbnail_sources` hold what the real data holds: False on every
    target pixel that a thumbnail pixel stored as 0 (the NUS thumbnails' masked ColorChecker and
    saturated pixels, written white) reaches: a tile whose area average takes in such a pixel,
    spread by one pixel (LibRaw's bilinear demosaic reads the 3 x 3 neighbourhood: measured, a
    changed tile changes the developed pixels one around it and no others).

    **Arguments:** `images` (N, h, w, 3) as `thumbnail_sources` takes them; `size`.
    **Returns:** (N, size, size) bool, True where the pixel is measured and trained on.
    """
    tiles = missing_tiles(images, size=size)
    return ~_dilate(np.repeat(np.repeat(tiles, 2, axis=1), 2, axis=2))


def missing_tiles(images: np.ndarray, *, size: int = WORKING_SIZE) -> np.ndarray:
    """(N, size/2, size/2) bool: the tiles of `thumbnail_sources`' mosaics whose area average takes
    in a thumbnail pixel stored as 0 (written white, i.e. saturated in every channel)."""
    images = np.asarray(images, np.float32)
    missing = np.all(images <= 0, axis=-1, keepdims=True).astype(np.float32)
    return np.stack([_thumbnails.area_average(m, size // 2)[..., 0] > 0 for m in missing])


@eqx.filter_jit
def _g2r_mosaics(keys, images, neutrals, profile):
    from g2r_jax.batch.pairs import clean_pairs

    _, clean, _, metadata = clean_pairs(keys, images, profile, neutral=neutrals, transfer="linear", noise=False,
                                        quantize=True)
    return clean, metadata


def _saturate(mosaic: np.ndarray, tiles: np.ndarray, white_level) -> np.ndarray:
    """`mosaic` with the 2 x 2 tiles marked in `tiles` at the white level."""
    sites = np.repeat(np.repeat(np.asarray(tiles, bool), 2, axis=0), 2, axis=1)
    return np.where(sites, np.uint16(round(float(white_level))), mosaic)


def _chunks(n: int):
    for start in range(0, n, BATCH):
        yield start, min(start + BATCH, n)


def _padded(x, count):
    x = np.asarray(x)
    return x if len(x) == BATCH else np.concatenate([x, np.repeat(x[:1], BATCH - count, axis=0)])


def _sources_to_pairs(sources, size):
    packed, targets, _, skipped = pairs_of(sources, size)
    if skipped:   # our own files: a failure is a bug, not an input to leave out
        raise RuntimeError(f"the reference renderer failed on a synthetic DNG: {skipped[0]}")
    return packed, targets


def _views(views, size: int, name: str) -> np.ndarray:
    views = np.asarray(views, np.float32)
    if views.ndim != 4 or views.shape[1:] != (size // 2, size // 2, 3):
        raise ValueError(f"{name}: views must be (n, {size // 2}, {size // 2}, 3) for {size} x {size} DNGs, "
                         f"got {views.shape}")
    return views


def g2r_pairs(views_linear: np.ndarray, profile, seed: int, *, neutrals=None, size: int = WORKING_SIZE,
              name: str = "g2r_jax", saturated=None) -> tuple:
    """Training pairs of g2r_jax RAW: linear sRGB views (n, size/2, size/2, 3), each pixel one CFA
    tile (repeated 2x2), made the way `g2r-convert --pairs --developed` makes its pairs
    (`g2r_jax.batch.pairs`): the clean mosaics of `profile` (`clean_pairs`: its lights, exposure,
    deterministic sensor effects, and its content model when it applies one by default), written
    as clean DNGs (`clean_dng_info`: its tags, the sampled AsShotNeutral), developed by the
    reference renderer.

    **Arguments:** `neutrals` (n, 3) fixes the lights instead of drawing them from the profile's
    illuminant model; `seed` draws lights and exposures; `size` the DNGs' side; `saturated`
    (n, size/2, size/2) bool: tiles written at the white level in every site, as
    `thumbnail_sources` writes the real thumbnails' missing pixels (real content made RAW again
    then holds what the real pairs hold there, `missing_tiles`).
    **Returns:** (packed (n, size/2, size/2, 4), targets (n, size, size, 3)).
    """
    from g2r_jax.batch.pairs import clean_dng_info
    from g2r_jax.pipeline import without_illuminants

    images = _views(views_linear, size, name)
    images = np.repeat(np.repeat(images, 2, axis=1), 2, axis=2)
    n = len(images)
    key_lights, key_images = jax.random.split(jax.random.PRNGKey(seed))
    if neutrals is None:
        from g2r_jax.illuminants.distributions import sample_neutrals

        # padded to fixed sizes (training_sets' helper): one compiled sampler for every fitted model
        neutrals = sample_neutrals(key_lights, _sets._padded_model(profile.illuminants), n)
    neutrals = np.asarray(neutrals, np.float32)
    neutrals = neutrals / neutrals[:, 1:2]
    fixed = without_illuminants(profile)
    keys = np.asarray(jax.random.split(key_images, n))
    sources = []
    for start, stop in _chunks(n):
        mosaics, metadata = _g2r_mosaics(_padded(keys[start:stop], stop - start), _padded(images[start:stop], stop - start),
                                         _padded(neutrals[start:stop], stop - start), fixed)
        mosaics, metadata = np.asarray(mosaics), {k: np.asarray(v) for k, v in metadata.items()}
        for i in range(stop - start):
            one = {k: v[i] for k, v in metadata.items()}
            info = clean_dng_info(fixed, one, *mosaics[i].shape)
            mosaic = mosaics[i] if saturated is None else _saturate(mosaics[i], saturated[start + i], fixed.white_level)
            sources.append(dng_source(mosaic, info, f"<{name} {start + i}>"))
    return _sources_to_pairs(sources, size)


@jax.jit
def _upi_rgb(keys, images):
    from g2r_jax.downstream.base.upi import unprocess_rgb

    return jax.vmap(lambda k, x: unprocess_rgb(k, x, noise=False))(keys, images)


def upi_pairs(views_srgb: np.ndarray, profile, seed: int, *, size: int = WORKING_SIZE) -> tuple:
    """Training pairs of UPI RAW (Brooks et al. CVPR 2019, `downstream.base.upi`, no noise): sRGB-coded
    views (n, size/2, size/2, 3) unprocessed to camera RGB by UPI's random camera matrix and gains,
    each pixel one CFA tile of the profile's pattern between its levels (`tile_mosaic`), written
    as DNGs with the camera's tags and AsShotNeutral = the inverse of UPI's sampled white-balance
    gains (1/red, 1, 1/blue), then developed by the reference renderer like every other DNG.

    **Arguments:** `profile` the camera whose tags the DNGs carry; `seed` UPI's draws.
    **Returns:** (packed (n, size/2, size/2, 4), targets (n, size, size, 3)).
    """
    from g2r_jax.profile.dng_tags import dng_info_for

    views = _views(views_srgb, size, "upi")
    n = len(views)
    keys = np.asarray(jax.random.split(jax.random.PRNGKey(seed), n))
    sources = []
    for start, stop in _chunks(n):
        rgb, lights = (np.asarray(a)[: stop - start] for a in _upi_rgb(_padded(keys[start:stop], stop - start),
                                                                        _padded(views[start:stop], stop - start)))
        mosaics = tile_mosaic(rgb_planes(rgb), profile.cfa_pattern, profile.black_level, profile.white_level)
        for i in range(stop - start):
            info = dng_info_for(profile, _metadata(lights[i]), size, size, noise=False)
            sources.append(dng_source(mosaics[i], info, f"<upi {start + i}>"))
    return _sources_to_pairs(sources, size)
