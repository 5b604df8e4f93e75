"""Rebuild the shipped profiles in this folder from ../shared/data (run from the repo root).

    python profiles/build_shipped_profiles.py

Each profile's `provenance` says, per part (colour, levels, noise, illuminants, exposure, content), where
its numbers come from. The Raspberry Pi profiles have their own script (build_rpi_profiles.py).

Sources besides ../shared/data: camera levels and CFA layouts read from public camera tables (rawspeed's
data/cameras.xml, LibRaw's src/tables/colordata.cpp); our own numbers, the table named in each profile.
"""

from __future__ import annotations

import csv
import json
import sys
from pathlib import Path

import numpy as np

from g2r_jax.cli.fit_profile import read_noise_table
from g2r_jax.illuminants.distributions import neutral_to_chromaticity
from g2r_jax.io.dng_info import DngInfo
from g2r_jax.io.dng_read import read_dng_info
from g2r_jax.profile.fitting import fit_profile
from g2r_jax.profile.provenance import with_provenance
from g2r_jax.profile.schema import parse_cfa, replace, save_profile
from g2r_jax.sensor import ExposureModel, NoiseModel
from g2r_jax.sensor.noise.estimation import quantisation_variance

HERE = Path(__file__).resolve().parent
DATA = HERE.parent / ".." / "shared" / "data"
PAPERS = ("public repositories of Graphics2RAW (ICCV 2023) and Day-to-Night (CVPR 2022), "
          "Samsung AI Center Toronto, CC BY-NC 4.0")
DARKTABLE = "darktable's noise profiles (../shared/data/noise/darktable/noiseprofiles.json, a 2016 copy, GPL-3.0)"

# darktable measures its profiles on an exported, demosaiced image (white balance 1/1/1, PPG demosaic),
# as the std of the HH band of a one-level Haar transform: per-pixel raw variance = 12.5 x darktable's
# green a x + b (11.6-13.0 over noise levels, scene colours and gradients; derivation and figures:
# profiles/darktable_noise_scale.py).
DARKTABLE_TO_RAW_VARIANCE = 12.5

RAWSPEED = "rawspeed data/cameras.xml (darktable-org/rawspeed 0ea84fa, 2024)"
RAWSPEED_2016 = "rawspeed's cameras.xml of 2016 as bundled in LibRaw (RawSpeed/rawspeed_xmldata.cpp, LibRaw e419de0)"
LIBRAW = "LibRaw src/tables/colordata.cpp (e419de0)"

# Levels and CFA of each camera, read from the named public table (our own numbers). `white_from_iso`:
# (ISO, white) steps where a table gives the white level per ISO; the profile keeps `white`.
DSLRS = {
    "Canon600D": dict(
        make="Canon", model="EOS 600D", darktable=("Canon", "EOS 600D"), matrices="nus", bits=14,
        cfa="GBRG", black=2026.0, white=13584.0, white_from_iso=((200.0, 15304.0),),
        levels=f"black 2026 and white 13584 below ISO 200, 15304 from ISO 200 ({RAWSPEED_2016}); LibRaw's maximum "
               f"0x3510 = 13584 ({LIBRAW}); the profile keeps the ISO-100 white and converts the noise of the higher "
               f"ISOs to it. CFA: {RAWSPEED} (its even crop 146, 54 keeps the sensor's pattern)."),
    "Canon5D": dict(
        make="Canon", model="EOS 5D", darktable=("Canon", "EOS 5D"), matrices="gehler_shi", bits=12,
        cfa="RGGB", black=127.0, white=3692.0, white_from_iso=(),
        levels=f"black 127, white 3692 ({RAWSPEED}; the same in {RAWSPEED_2016}); LibRaw's maximum 0xe6c = 3692 "
               f"({LIBRAW}); the Gehler-Shi release subtracts 129. CFA: {RAWSPEED} (even crop 90, 34)."),
    "NikonD40": dict(
        make="Nikon", model="D40", darktable=("Nikon", "D40"), matrices="nus", bits=12,
        cfa="BGGR", black=0.0, white=3880.0, white_from_iso=(),
        levels=f"black 0, white 3880 and the CFA: {RAWSPEED} (the same in {RAWSPEED_2016})."),
    "NikonD5200": dict(
        make="Nikon", model="D5200", darktable=("Nikon", "D5200"), matrices="nus", bits=14,
        cfa="RGGB", black=0.0, white=15892.0, white_from_iso=(),
        levels=f"black 0, white 15892 (14-bit compressed NEF) and the CFA: {RAWSPEED}."),
    "OlympusEPL6": dict(
        make="Olympus", model="E-PL6", darktable=("Olympus", "E-PL5"), matrices="nus", bits=12,
        cfa="RGGB", black=255.0, white=4095.0, white_from_iso=(),
        levels=f"white 4095 ({RAWSPEED}); black 255 is the same table's value for the E-M5 (same 16 MP sensor and "
               f"Adobe matrix), its E-PL5/E-PL6 entries leaving the black level to each file's makernote. CFA: "
               f"{RAWSPEED_2016}, E-PL5 entry (ORF files carry theirs in a tag)."),
    "PanasonicGX1": dict(
        make="Panasonic", model="DMC-GX1", darktable=("Panasonic", "DMC-GX1"), matrices="nus", bits=12,
        cfa="GRBG", black=150.0, white=3956.0, white_from_iso=(),
        levels=f"black 150, white 3956 ({RAWSPEED}; the same in {RAWSPEED_2016}). CFA: {RAWSPEED_2016} (RW2 files "
               f"carry theirs in a tag)."),
    "SonyA57": dict(
        make="Sony", model="SLT-A57", darktable=("Sony", "SLT-A57"), matrices="nus", bits=14,
        cfa="RGGB", black=512.0, white=16596.0, white_from_iso=(),
        levels=f"black 512, white 16596 and the CFA: {RAWSPEED} (the same in {RAWSPEED_2016})."),
}
# Cameras of the data whose noise nobody measured: not shipped (a clean simulation would mislead).
NOT_SHIPPED = {
    "Canon1DsMkIII": "no noise measurement (darktable has the EOS-1Ds Mark II and EOS-1D Mark III, other sensors)",
    "SamsungNX2000": "no noise measurement (not in darktable's noise profiles)",
    "Canon EOS-1D": "no noise measurement (darktable's Canon 1D series starts at the Mark II)",
}
S20_CHOICE = "mixture"


# ------------------------------------------------------------------------------ darktable noise

def darktable_rows(noise_db: dict, maker: str, model: str) -> np.ndarray:
    """(N, 3) rows (ISO, a, b) of darktable's green channel for one camera, ascending ISO: entries marked
    "skip" dropped, entries at the same ISO (several shots or contributors) averaged."""
    by_iso: dict[float, list] = {}
    for entry in noise_db["noiseprofiles"]:
        for block in (entry["models"] if entry["maker"] == maker else []):
            for row in (block["profiles"] if block["model"] == model else []):
                if not row.get("skip"):
                    by_iso.setdefault(float(row["iso"]), []).append((row["a"][1], row["b"][1]))
    if not by_iso:
        raise KeyError(f"{maker} {model}: not in darktable's noise profiles")
    return np.array([[iso, *np.mean(values, axis=0)] for iso, values in sorted(by_iso.items())])


def white_at(camera: dict, iso: float) -> float:
    """The camera table's white level at `iso`."""
    white = camera["white"]
    for threshold, level in camera["white_from_iso"]:
        white = level if iso >= threshold else white
    return white


def raw_noise(rows: np.ndarray, camera: dict) -> dict:
    """Per-pixel raw noise of a darktable profile in the profile's normalisation (0 at black, 1 at `white`).

    darktable normalises by R = white(ISO) - black, so per pixel var_DN = K (a R x_DN + b R^2) with
    K = DARKTABLE_TO_RAW_VARIANCE, the same at every CFA site (one conversion gain; the measurement had no
    white balance). In the profile's range R0: shot = K a R / R0, read = K b (R / R0)^2. darktable's b is
    negative at many ISOs (its fit, over values clipped at 0, is no read-noise measurement there); those
    ISOs get an ESTIMATE: the input-referred read noise implied by the camera's positive b, median of
    b / a^2, times a^2 (no output-referred part: an estimate on the low side).

    Rounding: darktable measured integer raws, so its b holds the rounding variance 1/12 DN^2, which the
    conversion adds again; it is taken out of the measured read terms (`read_excludes_quantisation`).
    """
    iso, a, b = rows.T
    span0 = camera["white"] - camera["black"]
    ratio = np.array([white_at(camera, s) - camera["black"] for s in iso]) / span0
    measured = b > 0
    if not np.any(measured):
        raise ValueError(f"{camera['model']}: no positive read term at any ISO")
    input_referred = float(np.median(b[measured] / a[measured] ** 2))
    rounding = quantisation_variance(camera["black"], camera["white"])[0]
    measured_read = DARKTABLE_TO_RAW_VARIANCE * b * ratio ** 2 - rounding
    estimated_read = DARKTABLE_TO_RAW_VARIANCE * input_referred * (a * ratio) ** 2
    read = np.where(measured, measured_read, estimated_read)
    if np.any(read <= 0):
        raise ValueError(f"{camera['model']}: read noise not above the rounding at ISO {iso[read <= 0]}")
    return dict(iso=iso, shot=DARKTABLE_TO_RAW_VARIANCE * a * ratio, read=read, measured=measured,
                input_referred=input_referred)


def noise_model(noise: dict) -> NoiseModel:
    """NoiseModel with the same shot and read at the four CFA sites."""
    f = lambda v: np.repeat(np.asarray(v, np.float32)[:, None], 4, axis=1)
    return NoiseModel(iso=np.asarray(noise["iso"], np.float32), shot=f(noise["shot"]), read=f(noise["read"]),
                      iso_range=np.asarray([noise["iso"][0], noise["iso"][-1]], np.float32),
                      read_excludes_quantisation=True)


def noise_provenance(camera: dict, noise: dict) -> str:
    iso = noise["iso"]
    estimated = iso[~noise["measured"]]
    maker, model = camera["darktable"]
    borrowed = "" if model == camera["model"] else (
        f" Measured on the {maker} {model} (same sensor; darktable itself ships this measurement for the "
        f"{camera['model']}).")
    estimate = ("" if not len(estimated) else
                f" Read noise at ISO {', '.join(f'{s:g}' for s in estimated)} is an ESTIMATE: darktable's fitted "
                f"intercept is negative there; used the input-referred read noise implied by its positive "
                f"intercepts (median b/a^2 = {noise['input_referred']:.3g}) times the gain, which leaves out "
                f"output-referred noise (shadows cleaner than the camera's).")
    flag = f"; read noise ESTIMATED at {len(estimated)} of {len(iso)} ISOs" if len(estimated) else ""
    return (f"darktable's measured noise profile of the {maker} {model}, ISO {iso[0]:g}-{iso[-1]:g}{flag}. "
            f"{DARKTABLE}, green channel, {len(iso)} ISOs (entries marked skip dropped, repeats averaged)."
            f"{borrowed} Per-pixel raw variance = "
            f"{DARKTABLE_TO_RAW_VARIANCE:g} x darktable's (its measurement is on a demosaiced image's Haar "
            f"band: profiles/darktable_noise_scale.py), the same at every CFA site.{estimate} Rounding 1/12 DN^2 "
            f"taken out of the measured read terms (the conversion adds it once).")


# ------------------------------------------------------------------------------ shared parts

def exposure_spread() -> tuple[ExposureModel, str]:
    """Exposure: log2 gain ~ Normal(0, s), s the spread of the ColorChecker white patch's green level over
    the Gehler-Shi Canon 5D images (robust: 1.4826 x MAD of log2; saturated or too dark patches, NaN in
    the data, left out); mean 0 keeps the input image's own exposure."""
    from scipy.io import loadmat

    charts = loadmat(DATA / "illuminants" / "gehler_shi" / "colourchecker_gamma1_bit12.mat")["real_rgb"]
    white = np.asarray(charts[86:, 18, 1], np.float64) - 129.0
    stops = np.log2(white[np.isfinite(white) & (white > 0)])
    spread = float(1.4826 * np.median(np.abs(stops - np.median(stops))))
    text = (f"log2 gain ~ Normal(0, {spread:.3f}), the spread of chart brightness in {len(stops)} Gehler-Shi "
            f"Canon 5D raw images. That is 1.4826 x MAD of log2 of the ColorChecker white patch's green level "
            f"(black 129 subtracted; {482 - len(stops)} saturated or dark patches left out; "
            f"../shared/data/illuminants/gehler_shi); mean 0 keeps the input image's own exposure. A scene "
            f"statistic, used for every camera built by this script but the S20 FE at night.")
    return ExposureModel(log2_mean=np.float32(0.0), log2_std=np.float32(spread)), text


WITHOUT_MEASURED_ILLUMINANTS = "prior"   # fit_profile's kind for cameras without measured scene illuminants


def with_pooled_lights(profile):
    """(profile with the pooled lights, their provenance) for a camera without measured scene lights:
    other cameras' measured lights carried through its own colour matrices (`g2r_jax.illuminants.pooled`),
    the best out-of-the-box lights of the few-DNG measurement (docs/pages/validation/illuminant_models.md).
    A pool source with this camera's own D65 ColorMatrix (its NUS lights, the benchmark's test images)
    is left out."""
    from g2r_jax.illuminants.choice import fit_pooled_for_camera
    from g2r_jax.illuminants.pooled import load_pool_matrices, load_pooled, same_camera_sources

    model, words = fit_pooled_for_camera(np.zeros((0, 2)), profile.colour)
    own = same_camera_sources(profile.colour, load_pool_matrices())
    left = f"; this camera's own lights ({', '.join(own)}) left out" if own else ""
    return replace(profile, illuminants=model), (
        f"pooled lights: {words}{left}. Pool: {load_pooled.__module__} data, "
        f"{sum(len(v) for v in load_pooled().values())} lights (python -m g2r_jax.illuminants.pooled ../shared/data).")


def prior_provenance() -> str:
    """Provenance of the illuminants of a camera with no measured scene illuminants: the
    cross-camera prior of real scene illuminants (`g2r_jax.illuminants.prior`, day preset) mapped
    through the camera's own colour model. It beats the supplement's A-D65 locus (S3) on every
    camera held out of its fit (docs/pages/validation/illuminant_prior.md)."""
    from g2r_jax.illuminants.prior import DEFAULT_PRESET, load_prior

    source = load_prior().source
    return (
        f"cross-camera prior of measured scene illuminants ({DEFAULT_PRESET} preset: daylight and artificial light "
        f"1:1), mapped through the camera's own colour model: no measured scene illuminants for this camera. "
        f"Prior {source}.")


def nus_info(name: str, tags: dict, camera: dict) -> DngInfo:
    return DngInfo(path=name, unique_camera_model=f"{camera['make']} {camera['model']}", make=camera["make"],
                   model=camera["model"], calibration_illuminants=(17, 21),
                   color_matrices=(np.reshape(tags["ColorMatrix_StandardLightA_tag17"], (3, 3)),
                                   np.reshape(tags["ColorMatrix_D65_tag21"], (3, 3))),
                   cfa_pattern=tuple(parse_cfa(camera["cfa"]).tolist()), black_level=np.full(4, camera["black"]), white_level=camera["white"])


def gehler_shi_info(camera: dict) -> tuple[DngInfo, str]:
    entry = json.loads((DATA / "cameras" / "gehler_shi_cameras.json").read_text())["Canon EOS 5D"]
    matrix = np.reshape(entry["color_matrix_d65"], (3, 3)) / entry["scale"]
    info = DngInfo(path="Canon5D", unique_camera_model="Canon EOS 5D", make="Canon", model="EOS 5D",
                   calibration_illuminants=(21,), color_matrices=(matrix,), cfa_pattern=tuple(parse_cfa(camera["cfa"]).tolist()),
                   black_level=np.full(4, camera["black"]), white_level=camera["white"])
    return info, ("Adobe DNG Converter ColorMatrix for D65 only (one calibration illuminant), from LibRaw's colour "
                  "table. Via ../shared/data/cameras/gehler_shi_cameras.json; no Standard light A matrix is published.")


def gehler_shi_5d_chromaticities() -> np.ndarray:
    """(482, 2) measured illuminants (r/g, b/g) of the Gehler-Shi Canon 5D images (87-568)."""
    from scipy.io import loadmat

    rgb = np.asarray(loadmat(DATA / "illuminants" / "gehler_shi" / "real_illum_568.mat")["real_rgb"], np.float64)
    return neutral_to_chromaticity(rgb[86:] / rgb[86:, 1:2])


# ------------------------------------------------------------------------------ profiles

def with_prior_content(profile, nus_camera: str | None = None, scenes_spread: bool = True):
    """(profile with the prior's content model applied by default, its provenance): a 'scenes'
    table drawn from the prior of real scenes (`content.prior_scenes_model`: each CG frame's cast
    and brightness those of one scene drawn from how real scenes spread about their medians), or
    with `scenes_spread` False the prior's median cast alone (`content.prior_cast_model`: the night
    profile, whose scenes' brightness the day scenes' spread does not describe), so that a shipped
    profile converts CG frames as a fitted one does (docs/pages/validation/content_model.md,
    findings 3 and 5), and the prior's texture (`prior.prior_texture`), which a neural ISP's pairs
    carry. A NUS camera's own scenes are left out of the prior (`prior.real_scenes_without`,
    `prior.scene_covariance`, `prior.texture_covariance`)."""
    import dataclasses

    from g2r_jax.content import describe, prior_cast_model, prior_scenes_model, with_default
    from g2r_jax.content.prior import prior_texture, real_scenes_without, scene_covariance, texture_covariance

    medians = real_scenes_without(DATA, nus_camera) if nus_camera else None
    scenes = (f"the other eight NUS cameras' scenes ({nus_camera}'s own left out)" if nus_camera
              else "the nine NUS cameras' scenes")
    source = f"prior: NUS 8-camera set, {scenes}"
    if scenes_spread:
        covariance = scene_covariance(DATA, nus_camera) if nus_camera else None
        model = with_default(prior_scenes_model(profile.colour, medians, covariance, source), True)
        target = (f"{len(np.asarray(model.scene_brightness))} scenes drawn (seed 0) from a Gaussian of (cast red, cast "
                  f"blue, log brightness) about the median of the per-camera medians of {scenes}, with the "
                  f"covariance of one camera's files about its own medians")
    else:
        model = with_default(prior_cast_model(profile.colour, medians, source), True)
        target = (f"the median grey-world cast of real white-balanced scenes, the median of the per-camera "
                  f"medians of {scenes}")
    texture = ""
    if scenes_spread:      # the day scenes' texture, like their spread, does not describe night scenes
        model = dataclasses.replace(model, texture=prior_texture(texture_covariance(DATA, nus_camera) if nus_camera
                                                                 else None, source))
        texture = (f" Texture (for a neural ISP's pairs, g2r_jax.content.texture): the covariance of the log texture "
                   f"at {model.texture.grid} pixels across of the thumbnails of {scenes}.")
    return replace(profile, content=model), (
        f"{describe(model)}; applied by default (g2r-convert --no-content-model turns it off). Target: {target} "
        f"(../shared/data/estimation/nus, g2r_jax.content.prior), carried to linear sRGB through this camera's "
        f"colour matrices at D65.{texture}")


def dslr_profiles(cameras: dict, noise_db: dict, exposure: tuple) -> None:
    for name, camera in DSLRS.items():
        noise = raw_noise(darktable_rows(noise_db, *camera["darktable"]), camera)
        if camera["matrices"] == "nus":
            info = nus_info(name, cameras[name], camera)
            colour = (f"Adobe DNG Converter ColorMatrix pair (Standard light A, D65) of the NUS 8-camera dataset. "
                      f"As released in the {PAPERS} (../shared/data/cameras/color_matrices.json).")
            profile, illuminants = with_pooled_lights(fit_profile([info], name=name,
                                                                  illuminant_model=WITHOUT_MEASURED_ILLUMINANTS,
                                                                  noise=noise_model(noise)))
        else:
            info, colour = gehler_shi_info(camera)
            profile = fit_profile([info], name=name, illuminant_model="mixture", noise=noise_model(noise),
                                  chromaticities=gehler_shi_5d_chromaticities())
            illuminants = ("482 measured scene illuminants of the Gehler-Shi Canon 5D images (Gaussian mixture "
                           "and convex hull). Images 87-568 of Shi and Funt's re-processing, "
                           "../shared/data/illuminants/gehler_shi/real_illum_568.mat; mixture BIC-selected.")
        levels = (f"{camera['cfa']}, black {camera['black']:g}, white {camera['white']:g} ({camera['bits']}-bit), "
                  f"from public camera tables. {camera['levels']}")
        profile, content = with_prior_content(profile, name if camera["matrices"] == "nus" else None)
        profile = with_provenance(replace(profile, exposure=exposure[0]), colour=colour, levels=levels,
                                  noise=noise_provenance(camera, noise), illuminants=illuminants, exposure=exposure[1],
                                  content=content)
        save_profile(profile, HERE / f"{name}.json")


def s20fe_night(cameras: dict) -> None:
    matrix = np.reshape(cameras["Samsung Galaxy S20 FE (main camera)"]["ColorMatrix_D65_tag21"], (3, 3))
    info = DngInfo(path="s20fe", unique_camera_model="Samsung Galaxy S20 FE main camera",
                   make="Samsung", model="Galaxy S20 FE", calibration_illuminants=(21,),
                   color_matrices=(matrix,), cfa_pattern=(0, 1, 1, 2), black_level=np.full(4, 64.0),
                   white_level=1023.0)
    with open(DATA / "illuminants" / "s20fe_night_graycard_45.csv") as handle:
        rows = np.array([[float(r["r_over_g"]), float(r["g"]), float(r["b_over_g"])] for r in csv.DictReader(handle)])
    noise = read_noise_table(DATA / "noise" / "s20fe_heteroscedastic_gaussian.csv", info.black_level, info.white_level)
    profile = fit_profile([info], name="s20fe_night", illuminant_model=S20_CHOICE, noise=noise,
                          chromaticities=neutral_to_chromaticity(rows))
    profile, content = with_prior_content(profile, scenes_spread=False)
    profile = with_provenance(
        profile,
        colour=f"its D65 ColorMatrix only (one calibration illuminant), from the Graphics2RAW release. The only "
               f"matrix released ({PAPERS}).",
        levels="black 64, white 1023 (10-bit), as stated with the noise calibration; CFA RGGB assumed. "
               "../shared/data/noise/s20fe_heteroscedastic_gaussian.csv; the CFA layout is not in the data.",
        noise=f"calibrated heteroscedastic Gaussian per CFA position, ISO 100-3200, from the Graphics2RAW release. "
              f"../shared/data/noise/s20fe_heteroscedastic_gaussian.csv ({PAPERS}).",
        illuminants=f"45 measured gray-card night illuminants ({S20_CHOICE} model and convex hull, sodium lamps kept). "
                    f"s20fe_night_graycard_45.csv ({PAPERS}).",
        exposure="constant (log2 gain 0): no measured exposure statistics of night scenes. The Gehler-Shi "
                 "spread of the other profiles is of day and indoor scenes.",
        content=content + " No night scenes' cast was measured: the prior's scenes are of day and indoor light.")
    save_profile(profile, HERE / "s20fe_night.json")


def gopro(exposure: tuple) -> None:
    path = DATA / "dng" / "gopro_hero6_GOPR0024.dng"
    profile, illuminants = with_pooled_lights(
        fit_profile([read_dng_info(path)], name="gopro_hero6", illuminant_model=WITHOUT_MEASURED_ILLUMINANTS))
    source = "the real GoPro HERO6 Black DNG gopro_hero6_GOPR0024.dng (gopro/gpr repository, Apache-2.0 or MIT)"
    profile, content = with_prior_content(profile)
    profile = with_provenance(
        replace(profile, exposure=exposure[0]),
        colour=f"ColorMatrix pair (Tungsten, D50) of a real GoPro HERO6 Black DNG. Tags of {source}.",
        levels=f"CFA, black and white levels of a real GoPro HERO6 Black DNG. Tags of {source}.",
        noise=f"NoiseProfile tag of a real GoPro HERO6 Black DNG (one ISO: 100). Tag of {source}.",
        illuminants=illuminants, exposure=exposure[1], content=content)
    save_profile(profile, HERE / "gopro_hero6.json")


def main() -> int:
    if not DATA.exists():
        print(f"{DATA} not found: the shipped profiles are built from ../shared/data", file=sys.stderr)
        return 1
    cameras = json.loads((DATA / "cameras" / "color_matrices.json").read_text())
    noise_db = json.loads((DATA / "noise" / "darktable" / "noiseprofiles.json").read_text())
    exposure = exposure_spread()
    dslr_profiles(cameras, noise_db, exposure)
    s20fe_night(cameras)
    gopro(exposure)
    for name, reason in NOT_SHIPPED.items():
        stale = HERE / f"{name}.json"
        if stale.exists():
            stale.unlink()
        print(f"not shipped: {name}: {reason}")
    print("\n".join(sorted(p.name for p in HERE.glob("*.json"))))
    return 0


if __name__ == "__main__":
    sys.exit(main())
