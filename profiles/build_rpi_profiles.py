"""Build the Raspberry Pi camera profiles from Raspberry Pi's libcamera tuning files.

    python profiles/build_rpi_profiles.py              # writes profiles/rpi_*.json, prints the CCM table
    python profiles/build_rpi_profiles.py --compare    # the calibration-illuminant choices compared
    python profiles/build_rpi_profiles.py --validate   # also samples and converts with the profiles

Source: ../shared/data/cameras/rpi_libcamera/vc4/<sensor>.json (raspberrypi/libcamera, BSD-2-Clause;
see its PROVENANCE.md). What each part of a profile is made of, and why, is written into the profile's
`provenance` and into docs/pages/validation/raspberry_pi_cameras.md.

- Levels: `rpi.black_level` is on a 16-bit scale (libcamera's camera tuning tool shifts raw values
  left by 16 - bits), so black = black_level >> (16 - bits); white = 2**bits - 1.
- Colour: `rpi.ccm` holds 3x3 matrices from white-balanced camera RGB to linear sRGB measured at
  several colour temperatures, applied after the AWB gains 1/r, 1/b of `rpi.awb.ct_curve` and
  interpolated linearly in CT (libcamera `ccm.cpp`). At each calibration illuminant of the profile
  the tuning's own matrix at that CCT becomes a DNG ForwardMatrix (white-balanced camera -> XYZ D50:
  Bradford D65 -> D50 after sRGB -> XYZ) and a ColorMatrix (XYZ -> camera, Bradford-adapted from the
  illuminant's white to D65 and normalised so the white of Y = 1 has maximum channel 1), so a DNG
  renderer reproduces the tuning exactly at the calibration illuminants and interpolates between them.
- Illuminants: a Gaussian mixture along the measured AWB locus `ct_curve` (CT -> r = R/G, b = B/G,
  extrapolated linearly beyond its ends like libcamera's Pwl) over the auto-AWB CT range, each node
  weighted by the AWB prior (`rpi.awb.priors`, log-likelihoods over CT per lux level), with the
  transverse band (`transverse_pos/neg`) as the spread across the locus.
- Noise: `rpi.noise.reference_slope` is the slope of noise std against sqrt(signal) fitted by the
  tuning tool on ColorChecker patches, on the 16-bit scale, black subtracted and divided by the
  analogue gain (ctt_noise.py), so variance_DN = slope**2 / 2**(16 - bits) * gain * x_DN.
  ISO = 100 x analogue gain (the tuning tool's and libcamera's DNG convention).
"""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

import colour
import numpy as np

from build_shipped_profiles import with_prior_content   # this folder's script: the same content model
from g2r_jax.colour import conversions, dng_model
from g2r_jax.profile.provenance import with_provenance
from g2r_jax.profile.schema import SCHEMA_NAME, SCHEMA_VERSION, profile_from_dict, save_profile
from g2r_jax.runtime import x64

HERE = Path(__file__).resolve().parent
DATA = HERE.parent / ".." / "shared" / "data"
TUNING_DIR = DATA / "cameras" / "rpi_libcamera" / "vc4"
GEHLER_SHI_CHARTS = DATA / "illuminants" / "gehler_shi" / "colourchecker_gamma1_bit12.mat"
SOURCE = ("Raspberry Pi libcamera tuning file src/ipa/rpi/vc4/data/{sensor}.json (raspberrypi/libcamera "
          "26bfadc6, BSD-2-Clause)")

# Sensor facts not in the tuning files, each from a named public source.
#   bits: raw bit depth of the full-resolution mode; cfa: Bayer order libcamera delivers with the
#   module's default orientation; gain: analogue gain range (kernel driver limits through the
#   libcamera camera helper's code -> gain formula).
CAMERAS = {
    "rpi_hq_imx477": dict(
        sensor="imx477", model="High Quality Camera (Sony IMX477)", bits=12, cfa="BGGR",
        gain=(1.0, 1024.0 / (1024 - 978)),
        facts=("12-bit raw (IMX477 12-bit modes of the raspberrypi/linux imx477 driver); CFA BGGR: the sensor's "
               "native RGGB read out with both flips, since the module is mounted rotated 180 degrees (device-tree "
               "rotation = <180>; Raspberry Pi, picamera2 issues 368 and 405); analogue gain 1-22.26 (driver gain "
               "codes 0-978, gain = 1024 / (1024 - code), libcamera cam_helper_imx477.cpp)")),
    "rpi_camera_module_3_imx708": dict(
        sensor="imx708", model="Camera Module 3 (Sony IMX708)", bits=10, cfa="BGGR",
        gain=(1024.0 / (1024 - 112), 1024.0 / (1024 - 960)),
        facts=("10-bit raw (SBGGR10/SRGGB10 modes of the raspberrypi/linux imx708 driver); CFA BGGR: native RGGB "
               "with both flips for the 180-degree mounting (device-tree rotation = <180>); analogue gain 1.12-16 "
               "(driver gain codes 112-960, gain = 1024 / (1024 - code), libcamera cam_helper_imx708.cpp)")),
    "rpi_global_shutter_imx296": dict(
        sensor="imx296", model="Global Shutter Camera (Sony IMX296)", bits=10, cfa="BGGR",
        gain=(1.0, 10.0 ** (239 / 200)),
        facts=("10-bit raw, CFA BGGR (the imx296 driver's colour format MEDIA_BUS_FMT_SBGGR10_1X10); analogue gain "
               "1-15.7 (gain codes 0-239 in 0.1 dB, libcamera cam_helper_imx296.cpp)")),
}

# Calibration illuminants of every profile (EXIF LightSource codes): Standard light A, D55, D75.
# Chosen among A+D65, A+D75, A+D50+D65, A+D55+D75 and the measured extremes (code 255) by the
# smallest mean CIEDE2000 over all the tuning's measured temperatures of the three cameras
# (table in docs/pages/validation/raspberry_pi_cameras.md).
CALIBRATION_ILLUMINANTS = (17, 20, 22)

# Read noise of the IMX477 measured on black frames of a Raspberry Pi HQ camera by J. Hogan,
# "Pi HQ Cam Sensor Performance" (strollswithmydog.com, 2020): 1.53 DN at analogue gain 1 and
# 11.50 DN at gain 16 (12-bit DN), with a system gain of 0.47 DN/e- at gain 1.
HQ_BLACK_FRAME_STD_DN = {1.0: 1.53, 16.0: 11.50}
HQ_READ_NOISE_SOURCE = ("J. Hogan, 'Pi HQ Cam Sensor Performance', strollswithmydog.com (2020): black-frame "
                        "std 1.53 DN at analogue gain 1 and 11.50 DN at gain 16 (12-bit)")
QUANTISATION_VARIANCE_DN = 1.0 / 12.0   # rounding to integer DN, already in integer black frames
THIRD_STOP_ISOS = (100, 125, 160, 200, 250, 320, 400, 500, 640, 800, 1000, 1250, 1600, 2000)


# ------------------------------------------------------------------------------ tuning file

def read_tuning(sensor: str, directory: Path = TUNING_DIR) -> dict:
    """The algorithms of a tuning file as one dict (`rpi.ccm` -> {...}); tolerates trailing
    commas, which libcamera's YAML-based reader accepts."""
    path = Path(directory) / f"{sensor}.json"
    try:
        text = path.read_text()
        document = json.loads(re.sub(r",(\s*[}\]])", r"\1", text))
        return {name: value for algorithm in document["algorithms"] for name, value in algorithm.items()}
    except (OSError, ValueError, KeyError, TypeError) as error:
        raise ValueError(f"{path}: not a readable libcamera tuning file ({error})") from None


def ct_curve(tuning: dict) -> np.ndarray:
    """(N, 3) rows (CT, r = R/G, b = B/G) of `rpi.awb.ct_curve`, ascending CT."""
    return np.asarray(tuning["rpi.awb"]["ct_curve"], np.float64).reshape(-1, 3)


def piecewise_linear(x, knots, values):
    """libcamera's Pwl::eval: linear between knots, extended linearly beyond the end segments."""
    x = np.asarray(x, np.float64)
    index = np.clip(np.searchsorted(knots, x, side="right") - 1, 0, len(knots) - 2)
    x0, x1, y0, y1 = knots[index], knots[index + 1], values[index], values[index + 1]
    return y0 + (x - x0) * (y1 - y0) / (x1 - x0)


def locus_neutral(curve: np.ndarray, ct) -> np.ndarray:
    """Camera neutral (r, 1, b) of a grey under a light of colour temperature `ct` (..., 3)."""
    r = piecewise_linear(ct, curve[:, 0], curve[:, 1])
    b = piecewise_linear(ct, curve[:, 0], curve[:, 2])
    return np.stack([r, np.ones_like(r), b], axis=-1)


def measured_ccms(tuning: dict) -> tuple[np.ndarray, np.ndarray]:
    """(CTs (M,), matrices (M, 3, 3)) of `rpi.ccm`: white-balanced camera RGB -> linear sRGB."""
    entries = tuning["rpi.ccm"]["ccms"]
    return (np.array([e["ct"] for e in entries], np.float64),
            np.array([np.reshape(e["ccm"], (3, 3)) for e in entries], np.float64))


def tuning_ccm(tuning: dict, ct: float) -> np.ndarray:
    """The matrix libcamera applies at `ct`: linear in CT between measured ones, clamped at the
    ends (libcamera src/ipa/rpi/controller/rpi/ccm.cpp, calculateCcm)."""
    cts, matrices = measured_ccms(tuning)
    ct = float(np.clip(ct, cts[0], cts[-1]))
    upper = int(np.clip(np.searchsorted(cts, ct), 1, len(cts) - 1))
    fraction = (ct - cts[upper - 1]) / (cts[upper] - cts[upper - 1])
    return fraction * matrices[upper] + (1 - fraction) * matrices[upper - 1]


# ------------------------------------------------------------------------------ colour

def _bradford(source_xy, target_xy) -> np.ndarray:
    with x64.enable_x64():
        return np.asarray(conversions.matrix_bradford(np.asarray(source_xy, np.float64),
                                                      np.asarray(target_xy, np.float64)), np.float64)


def dng_matrices(tuning: dict, curve: np.ndarray, cct: float, white_xy) -> tuple[np.ndarray, np.ndarray]:
    """(ColorMatrix, ForwardMatrix) that make a DNG renderer reproduce the tuning at `cct`.

    Renderer (DNG spec 1.6 ch. 6, with ForwardMatrix): sRGB = XYZ_to_sRGB . Bradford(D50 -> D65) .
    FM . diag(1 / neutral); the tuning: sRGB = CCM . diag(1 / neutral). Hence
    FM = Bradford(D65 -> D50) . sRGB_to_XYZ . CCM. The ColorMatrix maps the scene's XYZ under the
    illuminant (white `white_xy`) to camera RGB: CM = inverse(sRGB_to_XYZ . CCM . diag(1 / neutral))
    . Bradford(white -> D65), so that CM . XYZ(white) is the measured neutral.

    **Arguments:** `tuning` (`read_tuning`), `curve` (`ct_curve`), `cct` of the calibration illuminant
    and its `white_xy`.

    **Returns:** (ColorMatrix, ForwardMatrix), 3x3 each; the ColorMatrix scaled so that the white of
    Y = 1 has maximum channel 1, the ForwardMatrix mapping (1, 1, 1) to the D50 white.
    """
    ccm = tuning_ccm(tuning, cct)
    neutral = locus_neutral(curve, cct)
    srgb_to_xyz = np.asarray(conversions.MATRIX_SRGB_TO_XYZ, np.float64)
    camera_to_xyz_d65 = srgb_to_xyz @ ccm @ np.diag(1.0 / neutral)
    color_matrix = np.linalg.inv(camera_to_xyz_d65) @ _bradford(white_xy, conversions.XY_D65)
    white = np.asarray(white_xy, np.float64)
    white_xyz = np.array([white[0] / white[1], 1.0, (1 - white.sum()) / white[1]])
    color_matrix = color_matrix / np.max(color_matrix @ white_xyz)
    forward_matrix = _bradford(conversions.XY_D65, conversions.XY_D50) @ srgb_to_xyz @ ccm
    return color_matrix, forward_matrix


def colour_tags(tuning: dict, curve: np.ndarray, codes=CALIBRATION_ILLUMINANTS, illuminant_data=None) -> dict:
    """The profile's `colour` object for calibration illuminants `codes` (EXIF LightSource; 255 with
    `illuminant_data` xy), at the CCTs and whites the Adobe DNG SDK assigns to them."""
    data = list(illuminant_data or [None] * len(codes))
    colour_matrices, forward_matrices = [], []
    for code, xy in zip(codes, data):
        white = dng_model.calibration_illuminant_white_xy(code, xy)
        cct = dng_model.calibration_illuminant_cct(code, white)
        color_matrix, forward_matrix = dng_matrices(tuning, curve, cct, white)
        colour_matrices.append(color_matrix)
        forward_matrices.append(forward_matrix)
    tags = {"calibration_illuminants": list(codes),
            "color_matrices": np.asarray(colour_matrices).tolist(),
            "camera_calibrations": [np.eye(3).tolist()] * len(codes),
            "forward_matrices": np.asarray(forward_matrices).tolist(),
            "analog_balance": [1.0, 1.0, 1.0]}
    if any(d is not None for d in data):
        tags["illuminant_data"] = [None if d is None else [float(v) for v in d] for d in data]
    return tags


def colourchecker_linear_srgb() -> np.ndarray:
    """(24, 3) linear sRGB of the X-Rite ColorChecker (colour-science's 'After November 2014'
    xyY under D50, Bradford-adapted to D65)."""
    chart = colour.CCS_COLOURCHECKERS["ColorChecker24 - After November 2014"]
    xyz_d50 = colour.xyY_to_XYZ(np.array(list(chart.data.values()), np.float64))
    xyz_d65 = xyz_d50 @ _bradford(conversions.XY_D50, conversions.XY_D65).T
    return xyz_d65 @ np.asarray(conversions.MATRIX_XYZ_TO_SRGB, np.float64).T


def _lab(linear_srgb: np.ndarray) -> np.ndarray:
    xyz = linear_srgb @ np.asarray(conversions.MATRIX_SRGB_TO_XYZ, np.float64).T
    return colour.XYZ_to_Lab(xyz, np.asarray(conversions.XY_D65, np.float64))


def rendered_camera_to_srgb(colour_model, neutral) -> tuple[np.ndarray, float]:
    """(camera RGB -> linear sRGB matrix, CCT) a DNG renderer uses for a file with AsShotNeutral
    `neutral`: the DNG white point fixed point, CameraToXYZ_D50 there, Bradford D50 -> D65."""
    import jax.numpy as jnp

    with x64.enable_x64():
        neutral = jnp.asarray(neutral, jnp.float64)
        xy, _ = dng_model.camera_neutral_to_xy(neutral, colour_model)
        camera_to_d50 = np.asarray(dng_model.matrix_camera_to_XYZ_D50(xy, colour_model), np.float64)
        cct = float(conversions.xy_to_CCT(xy))
    to_srgb = np.asarray(conversions.MATRIX_XYZ_TO_SRGB, np.float64) @ _bradford(conversions.XY_D50, conversions.XY_D65)
    return to_srgb @ camera_to_d50, cct


def ccm_reproduction(tuning: dict, curve: np.ndarray, colour_model) -> list[dict]:
    """At each measured CCM temperature: CIEDE2000 (mean, max over the 24 ColorChecker colours)
    between the tuning's rendering (CCM . diag(1 / neutral)) and the DNG model's rendering of the
    same camera RGB (the camera responses the tuning's matrix implies for the chart), with the
    neutral from the AWB locus at that temperature, and the CCT the DNG model solves for it.

    **Arguments:** `tuning`, `curve` (`ct_curve`), `colour_model`: a float64 `DngColourModel`.

    **Returns:** one dict per measured CCM: ct, dng_cct, mean, max.
    """
    reference = colourchecker_linear_srgb()
    reference_lab = _lab(reference)
    rows = []
    for ct, ccm in zip(*measured_ccms(tuning)):
        neutral = locus_neutral(curve, ct)
        camera = reference @ np.linalg.inv(ccm).T * neutral
        rendered, cct = rendered_camera_to_srgb(colour_model, neutral)
        difference = colour.delta_E(reference_lab, _lab(camera @ rendered.T), method="CIE 2000")
        rows.append({"ct": float(ct), "dng_cct": cct, "mean": float(np.mean(difference)),
                     "max": float(np.max(difference))})
    return rows


# ------------------------------------------------------------------------------ illuminants

def ct_prior(tuning: dict, cts: np.ndarray) -> np.ndarray:
    """Probability of each CT node (nodes uniform in log CT, as libcamera's AWB search steps):
    per lux level of `rpi.awb.priors`, exp(prior log-likelihood) normalised over the nodes; the
    lux levels averaged with equal weight (the tuning does not say how often each occurs)."""
    total = np.zeros_like(cts)
    for level in tuning["rpi.awb"]["priors"]:
        table = np.asarray(level["prior"], np.float64).reshape(-1, 2)
        likelihood = np.exp(np.interp(cts, table[:, 0], table[:, 1]))   # libcamera clamps CT to the domain
        total += likelihood / likelihood.sum()
    return total / total.sum()


def illuminant_mixture(tuning: dict, curve: np.ndarray, step: float = 0.03) -> dict:
    """The `illuminants` object: one Gaussian per CT node (geometric steps of `step` over the auto
    AWB range), centred on the AWB locus shifted by the centre of the transverse band, with standard
    deviation the node spacing along the locus and the band's (uniform) std across it.

    **Arguments:** `tuning`, `curve` (`ct_curve`), `step`: relative CT spacing of the nodes.

    **Returns:** the profile's `illuminants` object (kind "mixture", no hull).
    """
    awb = tuning["rpi.awb"]
    low, high = float(awb["modes"]["auto"]["lo"]), float(awb["modes"]["auto"]["hi"])
    count = int(np.ceil(np.log(high / low) / np.log1p(step))) + 1
    cts = np.geomspace(low, high, count)
    points = locus_neutral(curve, cts)[:, [0, 2]]
    half = cts * step / 2
    tangent = locus_neutral(curve, cts + half)[:, [0, 2]] - locus_neutral(curve, cts - half)[:, [0, 2]]
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    normal = np.stack([tangent[:, 1], -tangent[:, 0]], axis=1)   # libcamera awb_bayes.cpp: (dB, -dR)
    positive, negative = float(awb["transverse_pos"]), float(awb["transverse_neg"])
    means = points + normal * (positive - negative) / 2
    along = np.linalg.norm(np.gradient(points, axis=0), axis=1)
    across = (positive + negative) / np.sqrt(12.0)
    covariances = (along[:, None, None] ** 2 * tangent[:, :, None] * tangent[:, None, :]
                   + across**2 * normal[:, :, None] * normal[:, None, :])
    return {"kind": "mixture", "weights": ct_prior(tuning, cts).tolist(), "means": means.tolist(),
            "covariances": covariances.tolist(), "hull": None}


# ------------------------------------------------------------------------------ levels and noise

def levels(tuning: dict, bits: int) -> tuple[float, float]:
    """(black, white) in DN of a `bits`-bit raw: the 16-bit-scale black level shifted down."""
    return float(int(tuning["rpi.black_level"]["black_level"]) >> (16 - bits)), float(2**bits - 1)


def conversion_gain(tuning: dict, bits: int) -> float:
    """DN per electron at analogue gain 1: (std16 = slope sqrt(x16)) -> var_DN = slope^2 / 2^(16-bits) x_DN."""
    return float(tuning["rpi.noise"]["reference_slope"]) ** 2 / 2.0 ** (16 - bits)


def hq_read_variance_dn(gain) -> np.ndarray:
    """IMX477 read variance in 12-bit DN^2 at analogue `gain`, quantisation removed: a pre-gain part
    (scales with gain^2) and a post-gain part, solved from the two measured black-frame stds."""
    (g1, s1), (g2, s2) = sorted(HQ_BLACK_FRAME_STD_DN.items())
    v1, v2 = s1**2 - QUANTISATION_VARIANCE_DN, s2**2 - QUANTISATION_VARIANCE_DN
    pre = (v2 - v1) / (g2**2 - g1**2)
    post = v1 - pre * g1**2
    return pre * np.asarray(gain, np.float64) ** 2 + post


def iso_nodes(gain_range) -> np.ndarray:
    """ISO rows of the noise table: the gain range's ends (ISO = 100 x gain, rounded) and the
    third-stop ISOs between them (the read variance is quadratic in gain, interpolated linearly)."""
    low, high = float(round(100.0 * gain_range[0])), float(round(100.0 * gain_range[1]))
    inner = [iso for iso in THIRD_STOP_ISOS if low < iso < high]
    return np.array([low, *inner, high])


def noise_model(tuning: dict, bits: int, gain_range, *, hq_tuning: dict) -> dict:
    """The `noise` object (normalised units: x in [0, 1] between black and white).

    shot(ISO) = k G / (white - black), k the tuning's conversion gain, G = ISO / 100. read(ISO) =
    the IMX477's measured read variance (quantisation removed) in electrons, k_HQ G per DN, converted
    with this sensor's own k (the same sensor for the HQ camera; a stated proxy for the others). The
    read term is the noise before rounding (`read_excludes_quantisation`): the conversion rounds once.

    **Arguments:** `tuning`, raw `bits`, analogue `gain_range` (low, high), `hq_tuning`: the IMX477's
    tuning (the conversion gain of the sensor the read noise was measured on).

    **Returns:** the profile's `noise` object, the same terms at all four CFA sites.
    """
    black, white = levels(tuning, bits)
    span = white - black
    isos = iso_nodes(gain_range)
    gains = isos / 100.0
    k = conversion_gain(tuning, bits)
    k_hq = conversion_gain(hq_tuning, 12)
    read_electrons = hq_read_variance_dn(gains) / (k_hq * gains) ** 2
    read_dn = read_electrons * (k * gains) ** 2
    shot = k * gains / span
    read = read_dn / span**2
    return {"iso": isos.tolist(), "shot": np.repeat(shot[:, None], 4, 1).tolist(),
            "read": np.repeat(read[:, None], 4, 1).tolist(), "iso_range": [float(isos[0]), float(isos[-1])],
            "read_excludes_quantisation": True}


# ------------------------------------------------------------------------------ exposure

def exposure_spread(data: Path = GEHLER_SHI_CHARTS) -> float:
    """Spread (stops) of a fixed reflectance's raw level over real auto-exposed photographs: robust
    std (1.4826 MAD) of log2 of the ColorChecker white patch's green over the Gehler-Shi Canon 5D
    images (87-568, black 129 subtracted; saturated or too dark patches, NaN, left out)."""
    from scipy.io import loadmat

    charts = loadmat(data)["real_rgb"]
    green = np.asarray(charts[86:, 18, 1], np.float64) - 129.0
    stops = np.log2(green[np.isfinite(green) & (green > 0)])
    return float(1.4826 * np.median(np.abs(stops - np.median(stops))))


def exposure_model(tuning: dict) -> dict:
    """The `exposure` object. Mean: libcamera's AGC drives the metered mean luminance of the
    white-balanced raw to `rpi.agc` y_target (about 0.16 of full scale), so a scene averaging 18 %
    grey gets gain y_target / 0.18 (y_target at 1000 lux). Spread: `exposure_spread`."""
    agc = tuning["rpi.agc"]
    channel = agc["channels"][0] if "channels" in agc else agc
    table = np.asarray(channel["y_target"], np.float64).reshape(-1, 2)
    target = float(np.interp(1000.0, table[:, 0], table[:, 1]))
    return {"log2_mean": float(np.log2(target / 0.18)), "log2_std": exposure_spread(), "y_target": target}


# ------------------------------------------------------------------------------ profile

def profile_document(name: str, camera: dict, tuning: dict, hq_tuning: dict) -> dict:
    """The JSON document of one profile (schema g2r_jax.sensor_profile)."""
    curve = ct_curve(tuning)
    black, white = levels(tuning, camera["bits"])
    noise = noise_model(tuning, camera["bits"], camera["gain"], hq_tuning=hq_tuning)
    exposure = exposure_model(tuning)
    k = conversion_gain(tuning, camera["bits"])
    source = SOURCE.format(sensor=camera["sensor"])
    tuning_name = f"{camera['sensor']}.json"
    awb = tuning["rpi.awb"]
    ccm_cts = [c["ct"] for c in tuning["rpi.ccm"]["ccms"]]
    if camera["sensor"] == "imx477":
        read_summary = "read noise measured on HQ camera black frames (Hogan 2020)"
        read_source = f"read: measured on this sensor, {HQ_READ_NOISE_SOURCE}"
    else:
        read_summary = "read noise ESTIMATED from the HQ camera's IMX477, not measured on this sensor"
        read_source = (f"read: an ESTIMATE, not a measurement of this sensor: the IMX477's read noise in electrons "
                       f"({HQ_READ_NOISE_SOURCE}) converted with this sensor's own conversion gain; the tuning's "
                       f"rpi.noise.reference_constant is 0, which the tuning tool writes when its fitted offset is "
                       f"negative, so the tuning has no read-noise measurement")
    provenance = {
        "colour": (f"Raspberry Pi's measured colour correction ({tuning_name}, {len(ccm_cts)} CCMs at "
                   f"{ccm_cts[0]}-{ccm_cts[-1]} K) as DNG matrices at Standard light A, D55 and D75. Source: "
                   f"{source}, rpi.ccm (CCMs at {', '.join(map(str, ccm_cts))} K) with the rpi.awb.ct_curve "
                   f"neutrals; ColorMatrix and ForwardMatrix at each calibration illuminant reproduce the tuning's own "
                   f"CCM at 2850, 5500 and 7500 K; the DNG interpolation error at the measured temperatures is in "
                   f"docs/pages/validation/raspberry_pi_cameras.md."),
        "levels": (f"Black {black:g}, white {white:g} ({camera['bits']} bit), CFA {camera['cfa']}. Black: {source}, "
                   f"rpi.black_level {tuning['rpi.black_level']['black_level']} on the 16-bit scale, shifted down by "
                   f"{16 - camera['bits']} bits; white 2^{camera['bits']} - 1. {camera['facts']}."),
        "noise": (f"Shot noise from Raspberry Pi's tuning ({tuning_name}, rpi.noise); {read_summary}. Shot: "
                  f"{source}, rpi.noise.reference_slope {tuning['rpi.noise']['reference_slope']} (std against "
                  f"sqrt(signal) on the 16-bit scale per unit analogue gain, fitted on ColorChecker patches by the "
                  f"tuning tool) gives {k:.4f} DN/e- at gain 1, variance proportional to gain; ISO = 100 x analogue "
                  f"gain, {noise['iso_range'][0]:g}-{noise['iso_range'][1]:.0f}. {read_source}; pre- and post-gain "
                  f"parts solved from the two gains, extrapolated beyond gain 16; the rounding variance 1/12 DN^2 "
                  f"taken out, since the conversion rounds once."),
        "illuminants": (f"Raspberry Pi's measured AWB locus and priors ({tuning_name}, rpi.awb) as a Gaussian mixture "
                        f"over {awb['modes']['auto']['lo']}-{awb['modes']['auto']['hi']} K. Source: {source}: "
                        f"components along rpi.awb.ct_curve (measured grey R/G, B/G per CT, {len(curve)} points, "
                        f"extended linearly past its ends as libcamera does) at CTs 3 % apart, weighted by "
                        f"rpi.awb.priors (exp of each lux level's prior log-likelihood, the lux levels averaged with "
                        f"equal weight: an assumption), spread across the locus by the transverse AWB band "
                        f"(-{awb['transverse_neg']}, +{awb['transverse_pos']}) and along it by the node spacing."),
        "exposure": (f"log2 gain ~ Normal({exposure['log2_mean']:.3f}, {exposure['log2_std']:.3f}) from the tuning's "
                     f"AGC target and real auto-exposed photographs. Mean: {source}, rpi.agc y_target "
                     f"{exposure['y_target']:g} at 1000 lux (the AGC's metered mean, so an 18 % grey scene gets "
                     f"y_target / 0.18); spread: robust std of log2 of the ColorChecker white patch's raw green over "
                     f"the auto-exposed Gehler-Shi Canon 5D photographs (../shared/data/illuminants/gehler_shi)."),
    }
    return {
        "schema": SCHEMA_NAME, "version": SCHEMA_VERSION, "name": name,
        "camera": {"unique_camera_model": f"Raspberry Pi {camera['model']}", "make": "Raspberry Pi",
                   "model": camera["model"]},
        "provenance": provenance,
        "cfa_pattern": camera["cfa"], "black_level": [black] * 4, "white_level": white, "baseline_exposure": 0.0,
        "colour": colour_tags(tuning, curve),
        "illuminants": illuminant_mixture(tuning, curve),
        "exposure": {"log2_mean": exposure["log2_mean"], "log2_std": exposure["log2_std"]},
        "noise": noise,
        "opcode_lists": {},
    }


# The calibration-illuminant choices compared by `--compare` (EXIF codes; None: the lowest and the
# highest measured CCM temperature as code 255 with IlluminantData).
ILLUMINANT_CHOICES = {"A + D65": (17, 21), "A + D75": (17, 22), "A + D50 + D65": (17, 23, 21),
                      "A + D55 + D75": (17, 20, 22), "measured ends (255)": None}


def compare_illuminant_choices(tunings: dict) -> None:
    """Print, per choice of calibration illuminants and camera, the mean over the measured
    temperatures of the mean CIEDE2000 and the largest maximum (`ccm_reproduction`)."""
    from g2r_jax.colour.dng_model import DngColourModel

    print("| calibration illuminants | " + " | ".join(tunings) + " | all |")
    print("|---|" + "---|" * (len(tunings) + 1))
    for label, codes in ILLUMINANT_CHOICES.items():
        cells, means = [], []
        for tuning in tunings.values():
            curve = ct_curve(tuning)
            data = None
            if codes is None:
                cts, _ = measured_ccms(tuning)
                codes_here = (255, 255)
                data = [conversions.CCT_to_xy([cts[0]])[0], conversions.CCT_to_xy([cts[-1]])[0]]
            else:
                codes_here = codes
            tags = colour_tags(tuning, curve, codes_here, data)
            with x64.enable_x64():
                model = DngColourModel.from_tags(tags["calibration_illuminants"], tags["color_matrices"],
                                                 tags["camera_calibrations"], tags["forward_matrices"], None,
                                                 np.float64, illuminant_data=tags.get("illuminant_data", ()))
            rows = ccm_reproduction(tuning, curve, model)
            mean = float(np.mean([r["mean"] for r in rows]))
            means.append(mean)
            cells.append(f"{mean:.2f} / {max(r['max'] for r in rows):.2f}")
        print(f"| {label} | " + " | ".join(cells) + f" | {np.mean(means):.2f} |")


def transverse_offsets(points, curve: np.ndarray, low: float, high: float, samples: int = 4000):
    """(signed offset across the locus, CT of the nearest locus point) of each (r/g, b/g) point,
    the sign as libcamera's transverse direction (towards larger r and b)."""
    cts = np.geomspace(low, high, samples)
    locus = locus_neutral(curve, cts)[:, [0, 2]]
    points = np.asarray(points, np.float64)
    nearest = np.argmin(np.linalg.norm(points[:, None, :] - locus[None], axis=-1), axis=1)
    tangent = np.gradient(locus, axis=0)[nearest]
    normal = np.stack([tangent[:, 1], -tangent[:, 0]], 1) / np.linalg.norm(tangent, axis=1, keepdims=True)
    return np.sum((points - locus[nearest]) * normal, axis=1), cts[nearest]


def validate(name: str, camera: dict, tuning: dict) -> None:
    """Print what the profile as saved does: its illuminant samples against the AWB locus and band,
    and the noise of flat greys converted at its lowest and highest ISO (and of black frames)."""
    import jax
    import jax.numpy as jnp

    from g2r_jax.illuminants.distributions import sample_neutrals
    from g2r_jax.pipeline import unprocess
    from g2r_jax.profile.schema import load_profile

    profile = load_profile(HERE / f"{name}.json")
    awb = tuning["rpi.awb"]
    low, high = awb["modes"]["auto"]["lo"], awb["modes"]["auto"]["hi"]
    neutrals = np.asarray(sample_neutrals(jax.random.PRNGKey(0), profile.illuminants, 4000), np.float64)
    offset, cts = transverse_offsets(neutrals[:, [0, 2]], ct_curve(tuning), low, high)
    inside = np.mean((offset >= -awb["transverse_neg"]) & (offset <= awb["transverse_pos"]))
    print(f"  illuminants: {inside:.1%} of 4000 samples inside the transverse band, largest offset "
          f"{np.max(np.abs(offset)):.4f}; locus CT percentiles 5/25/50/75/95: "
          f"{' / '.join(f'{v:.0f}' for v in np.percentile(cts, [5, 25, 50, 75, 95]))} K")
    black, white = float(profile.black_level[0]), float(profile.white_level)
    span = white - black
    for level in (0.18, 0.0):
        image = jnp.full((256, 256, 3), level, jnp.float32)
        convert = jax.jit(lambda iso: unprocess(jax.random.PRNGKey(7), image, profile, transfer="linear", iso=iso,
                                                neutral=jnp.array([0.45, 1.0, 0.6]), exposure_gain=1.0,
                                                effects=False)[0])
        for iso in np.asarray(profile.noise.iso_range, np.float64):
            mosaic = np.asarray(convert(jnp.float32(iso)), np.float64)
            shot = np.interp(iso, profile.noise.iso, np.asarray(profile.noise.shot)[:, 0])
            read = np.interp(iso, profile.noise.iso, np.asarray(profile.noise.read)[:, 0])
            ratios = []
            for p in range(4):
                plane = mosaic[p // 2::2, p % 2::2]
                x = (plane.mean() - black) / span
                ratios.append(plane.var() / ((shot * x + read) * span**2 + QUANTISATION_VARIANCE_DN))
            what = "grey 0.18" if level else "black frame"
            print(f"  {what} at ISO {iso:.0f}: std {np.std(mosaic):.3f} DN (one plane), variance / "
                  f"((shot x + read) span^2 + 1/12): {min(ratios):.3f}-{max(ratios):.3f}")


def noise_summary(name: str, camera: dict, tuning: dict, hq_tuning: dict) -> None:
    """Print the noise model's derived numbers: conversion gain, full well, read noise at the ISO ends."""
    black, white = levels(tuning, camera["bits"])
    k = conversion_gain(tuning, camera["bits"])
    noise = noise_model(tuning, camera["bits"], camera["gain"], hq_tuning=hq_tuning)
    read_dn = np.sqrt(np.asarray(noise["read"])[:, 0]) * (white - black)
    print(f"  noise: {k:.4f} DN/e- at gain 1, full well {(white - black) / k:.0f} e-, ISO "
          f"{noise['iso_range'][0]:g}-{noise['iso_range'][1]:g}, read std {read_dn[0]:.2f} / {read_dn[-1]:.2f} DN "
          f"({read_dn[0] / k:.2f} / {read_dn[-1] / (k * noise['iso'][-1] / 100):.2f} e-) at the lowest / highest ISO")


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if not TUNING_DIR.exists():
        print(f"{TUNING_DIR} not found: the Raspberry Pi profiles are built from ../shared/data", file=sys.stderr)
        return 1
    hq_tuning = read_tuning("imx477")
    if "--compare" in argv:
        compare_illuminant_choices({name: read_tuning(camera["sensor"]) for name, camera in CAMERAS.items()})
        return 0
    for name, camera in CAMERAS.items():
        tuning = read_tuning(camera["sensor"])
        document = profile_document(name, camera, tuning, hq_tuning)
        path = HERE / f"{name}.json"
        with x64.enable_x64():
            profile = profile_from_dict(document, str(path), np.float64)
        profile, content = with_prior_content(profile)
        profile = with_provenance(profile, **dict(profile.info.provenance_parts), content=content)
        save_profile(profile, path)
        print(f"{name}: CCM reproduction (CT K: DNG CCT, mean / max CIEDE2000)")
        for row in ccm_reproduction(tuning, ct_curve(tuning), profile.colour):
            print(f"  {row['ct']:6.0f}: {row['dng_cct']:6.0f}  {row['mean']:.2f} / {row['max']:.2f}")
        noise_summary(name, camera, tuning, hq_tuning)
        if "--validate" in argv:
            validate(name, camera, tuning)
    return 0


if __name__ == "__main__":
    sys.exit(main())
