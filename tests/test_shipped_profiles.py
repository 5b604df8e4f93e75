"""The shipped camera profiles against their sources.

Data-free: every shipped profile has noise at every ISO, levels that are not the old placeholder
(RGGB, black 512, white 16383), a provenance for each part, and a `--list-profiles` entry.

With ../shared/data: each profile built by profiles/build_shipped_profiles.py converts flat greys at
each of its measured ISOs through the pipeline, and the variance of the mosaic (DN^2, per CFA site)
is compared with the numbers re-derived here from the source files: darktable's noise profiles for
the DSLRs (through the build script's documented conversion factor and camera tables), the DNG
NoiseProfile tag for the GoPro, the calibration table for the S20 FE. Shot gain within 5 %; read
noise positive and equal to its source (measured, or the build script's stated estimate) with the
rounding to integers counted once.
"""

from __future__ import annotations

import csv
import functools
import importlib.util
import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from conftest import REPO_ROOT, SHARED_DATA
from g2r_jax.illuminants.distributions import chromaticity_to_neutral
from g2r_jax.pipeline import unprocess
from g2r_jax.profile.provenance import PARTS, describe_profile
from g2r_jax.profile.schema import SHIPPED_PROFILES_DIR, load_profile, shipped_profiles

PLACEHOLDER_LEVELS = ("RGGB", 512.0, 16383.0)
ROUNDING = 1.0 / 12.0                      # DN^2 added by rounding to integers (Widrow & Kollar)
SIZE = (256, 256)                          # 16384 pixels per CFA site: variance to ~1 %


def _document(name: str) -> dict:
    return json.loads((SHIPPED_PROFILES_DIR / f"{name}.json").read_text())


@functools.cache
def _build_script():
    spec = importlib.util.spec_from_file_location("build_shipped_profiles",
                                                  REPO_ROOT / "profiles" / "build_shipped_profiles.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


# ------------------------------------------------------------------------------ data-free

@pytest.mark.parametrize("name", shipped_profiles())
def test_shipped_profile_is_a_measured_camera(name):
    document = _document(name)
    profile = load_profile(name)
    shot, read = np.asarray(profile.noise.shot), np.asarray(profile.noise.read)
    assert np.all(shot > 0) and np.all(read > 0), f"{name}: zero noise at some ISO"
    levels = (profile.cfa_string, float(np.max(profile.black_level)), float(profile.white_level))
    assert levels != PLACEHOLDER_LEVELS, f"{name}: placeholder levels"
    provenance = document["provenance"]
    assert isinstance(provenance, dict), f"{name}: provenance is one text, not one per part"
    for part in PARTS:
        assert isinstance(provenance.get(part), str) and provenance[part].strip(), f"{name}: no {part} provenance"
    listing = describe_profile(document)
    low, high = np.asarray(profile.noise.iso_range)
    assert listing.startswith(f"{name}  {profile.info.unique_camera_model}, ISO {low:g}-{high:g}")
    assert "NO NOISE MODEL" not in listing
    for part in ("colour", "noise", "illuminants", "content"):
        assert f"    {part}: " in listing
    family = "cast, each frame's mean colour" if name == "s20fe_night" else "scenes, each frame's cast and brightness"
    assert f"    content: {family}" in listing and "applied by default" in listing


NUS_SHIPPED = ("Canon600D", "NikonD40", "NikonD5200", "OlympusEPL6", "PanasonicGX1", "SonyA57")


@pytest.mark.parametrize("name", shipped_profiles())
def test_shipped_profile_carries_the_prior_scenes_model_applied_by_default(name):
    """Out of the box a shipped profile converts CG frames as a fitted one does (issues 33, 50): the
    prior's 'scenes' table through its own matrices (the night profile: the prior's cast alone),
    its median cast the prior's; a NUS camera's within the spread of the nine cameras' medians of
    the all-camera prior (its own scenes are left out of it)."""
    from g2r_jax.content import as_cast, prior_cast_model

    profile = load_profile(name)
    model = profile.content
    assert model is not None and model.apply_by_default
    assert model.family == ("cast" if name == "s20fe_night" else "scenes")
    if model.family == "scenes":
        brightness = np.asarray(model.scene_brightness)
        assert len(brightness) == 64 and np.ptp(brightness) > 0.1      # a spread of scenes, not one
    expected = np.asarray(prior_cast_model(profile.colour).cast_target)
    tolerance = 0.05 if name in NUS_SHIPPED else 1e-6
    assert np.allclose(np.asarray(as_cast(model).cast_target), expected, atol=tolerance), (name, model.cast_target, expected)


@pytest.mark.data
@pytest.mark.parametrize("name", NUS_SHIPPED)
def test_nus_profile_cast_target_leaves_its_own_scenes_out(name, shared_data):
    from g2r_jax.content import prior_cast_model
    from g2r_jax.content.prior import real_scenes_without

    profile = load_profile(name)
    own_left_out = prior_cast_model(profile.colour, real_scenes_without(shared_data, name))
    assert np.allclose(np.asarray(profile.content.cast_target), np.asarray(own_left_out.cast_target), atol=1e-6)
    assert f"{name}'s own left out" in _document(name)["provenance"]["content"]


def test_listing_flags_a_noise_free_profile():
    document = _document(shipped_profiles()[0])
    document["noise"] = {"iso": [100.0], "shot": [[0.0] * 4], "read": [[0.0] * 4], "iso_range": [100.0, 100.0]}
    document["provenance"] = "fitted from one DNG. Nothing else."
    listing = describe_profile(document)
    assert "NO NOISE MODEL" in listing and "provenance: fitted from one DNG." in listing


# ------------------------------------------------------------------------------ against the sources

@functools.cache
def _converter(name: str):
    """jit(isos (B,), levels (B,)) -> (B, H, W) DN mosaics of flat greys of linear `level` (green reaches
    `level`) at a fixed illuminant, noise on, no other random part; one compilation per profile."""
    profile = load_profile(name)
    neutral = chromaticity_to_neutral(jnp.asarray(profile.illuminants.means[0]))
    green_gain = 1.0 / float(jnp.max(neutral / neutral[1]))

    def convert(iso, level):
        image = jnp.full(SIZE + (3,), level, jnp.float32)
        return unprocess(jax.random.PRNGKey(7), image, profile, transfer="linear", neutral=neutral, iso=iso,
                         exposure_gain=1.0 / green_gain, effects=False, content=False)[0]
    return profile, jax.jit(jax.vmap(convert))


def _site_stats(mosaic, black):
    """Mean above black and variance (DN) of each of the four CFA sites."""
    m = np.asarray(mosaic, np.float64)
    sites = [m[i::2, j::2].ravel() for i in range(2) for j in range(2)]
    return np.array([s.mean() - b for s, b in zip(sites, black)]), np.array([s.var(ddof=1) for s in sites])


def _check_against_source(name, isos, slopes, reads):
    """Convert a bright and a dim grey at each ISO of `isos`; `slopes` (DN of variance per DN of
    signal) and `reads` (DN^2 at zero signal, rounding included) per ISO, scalar or per CFA site,
    from the source. Shot slope within 5 % on all sites; read on the green sites within 10 % plus
    four standard errors of the measured variance."""
    profile, convert = _converter(name)
    black = np.asarray(profile.black_level, np.float64)
    span = float(profile.white_level) - float(np.max(black))
    count = len(isos)
    slopes = np.broadcast_to(np.asarray(slopes, np.float64).reshape(count, -1), (count, 4))
    reads = np.broadcast_to(np.asarray(reads, np.float64).reshape(count, -1), (count, 4))
    # the dim grey: read noise at least half the variance where the mean can stay 8 sigma above black
    dim = np.max(np.maximum.reduce([reads / slopes, 8 * np.sqrt(reads), np.full((count, 4), 8.0)]), axis=1)
    levels = np.concatenate([np.full(count, 0.5), dim / span])
    mosaics = np.asarray(convert(jnp.asarray(np.concatenate([isos, isos]), jnp.float32),
                                 jnp.asarray(levels, jnp.float32)))
    green = [p for p in range(4) if int(profile.cfa_pattern[p]) == 1]
    error_scale = np.sqrt(2.0 / (SIZE[0] * SIZE[1] / 4))
    table = []
    for k, iso in enumerate(isos):
        slope, read = slopes[k], reads[k]
        mean, var = _site_stats(mosaics[k], black)                      # shot-dominated
        measured_slope = (var - read) / mean
        assert np.all(np.abs(measured_slope / slope - 1) < 0.05), \
            f"{name} ISO {iso:g}: shot slope {measured_slope} DN vs source {slope}"
        mean, var = _site_stats(mosaics[count + k], black)              # read-dominated as far as can be
        measured_read = var - slope * mean
        table.append((iso, np.mean(measured_slope / slope), np.mean(measured_read[green] / read[green]),
                      np.mean(read[green]), np.mean(mean[green])))
        for p in green:
            assert abs(measured_read[p] - read[p]) < 0.1 * read[p] + 4 * error_scale * var[p], \
                f"{name} ISO {iso:g} site {p}: read {measured_read[p]:.4g} DN^2 vs source {read[p]:.4g} " \
                f"(mean {mean[p]:.1f} DN)"
    return table


def _darktable_rows(maker, model):
    """darktable's green (ISO, a, b), re-derived here: skip entries dropped, repeats averaged."""
    database = json.loads((SHARED_DATA / "noise" / "darktable" / "noiseprofiles.json").read_text())
    rows = {}
    for entry in database["noiseprofiles"]:
        for block in entry["models"]:
            if entry["maker"] == maker and block["model"] == model:
                for row in block["profiles"]:
                    if not row.get("skip"):
                        rows.setdefault(float(row["iso"]), []).append((row["a"][1], row["b"][1]))
    return [(iso, *np.mean(v, axis=0)) for iso, v in sorted(rows.items())]


DSLR_NAMES = ["Canon600D", "Canon5D", "NikonD40", "NikonD5200", "OlympusEPL6", "PanasonicGX1", "SonyA57"]


@pytest.mark.slow
@pytest.mark.data
@pytest.mark.parametrize("name", DSLR_NAMES)
def test_dslr_noise_matches_darktable(name, shared_data):
    _dslr_against_darktable(name)


@pytest.mark.slow
@pytest.mark.data
def test_gopro_noise_matches_its_noise_profile_tag(shared_data):
    _gopro_against_tag()


@pytest.mark.slow
@pytest.mark.data
def test_s20fe_noise_matches_its_calibration_table(shared_data):
    _s20fe_against_table()


def _dslr_against_darktable(name):
    build = _build_script()
    camera = build.DSLRS[name]
    factor = build.DARKTABLE_TO_RAW_VARIANCE
    rows = _darktable_rows(*camera["darktable"])
    positive = [(a, b) for _, a, b in rows if b > 0]
    assert positive, f"{name}: darktable has no positive read term"
    input_referred = np.median([b / a**2 for a, b in positive])     # the stated estimate's one number
    profile = load_profile(name)
    assert np.allclose(np.asarray(profile.noise.iso), [r[0] for r in rows]), f"{name}: ISOs differ from darktable's"
    isos, slopes, reads = [], [], []
    for iso, a, b in rows:
        span = build.white_at(camera, iso) - camera["black"]           # darktable's normalisation at this ISO
        isos.append(iso)
        slopes.append(factor * a * span)
        reads.append(factor * b * span**2 if b > 0 else factor * input_referred * (a * span) ** 2 + ROUNDING)
    return _check_against_source(name, np.array(isos), slopes, reads)


def _gopro_against_tag():
    from g2r_jax.io.dng_read import read_dng_info

    info = read_dng_info(SHARED_DATA / "dng" / "gopro_hero6_GOPR0024.dng")
    span = info.white_level - float(np.max(info.black_level))
    shot, offset = np.asarray(info.noise_profile, np.float64)[0]
    return _check_against_source("gopro_hero6", np.array([float(info.iso)]), [shot * span], [offset * span**2])


def _s20fe_against_table():
    table = {}
    with open(SHARED_DATA / "noise" / "s20fe_heteroscedastic_gaussian.csv", newline="") as handle:
        for row in csv.DictReader(handle):
            table.setdefault(float(row["iso"]), {})[int(row["cfa_channel_index"])] = (
                float(row["beta1_shot"]), float(row["beta2_read"]))
    black = 64.0                                                     # the table's x includes the black level
    isos = np.array(sorted(table))
    beta1 = np.array([[table[iso][p][0] for p in range(4)] for iso in isos])
    beta2 = np.array([[table[iso][p][1] for p in range(4)] for iso in isos])
    return _check_against_source("s20fe_night", isos, beta1, beta1 * black + beta2)


if __name__ == "__main__":   # the table of docs/pages/validation/shipped_cameras.md
    checks = {name: functools.partial(_dslr_against_darktable, name) for name in DSLR_NAMES}
    checks.update(gopro_hero6=_gopro_against_tag, s20fe_night=_s20fe_against_table)
    print("| profile | ISOs | shot gain / source | read / source | read at the lowest ISO (DN^2) |")
    print("|---|---|---|---|---|")
    for name, check in checks.items():
        rows = np.array(check())
        print(f"| {name} | {rows[0, 0]:g}-{rows[-1, 0]:g} ({len(rows)}) | {rows[:, 1].min():.3f}-{rows[:, 1].max():.3f} "
              f"| {rows[:, 2].min():.2f}-{rows[:, 2].max():.2f} | {rows[0, 3]:.3g} |")
