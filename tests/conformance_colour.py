"""Conformance corpus for the DNG colour tags (issue 8): small DNGs written here with tifffile
directly (not with g2r_jax's writer), and an independent reference of the DNG colour model for
one, two and three calibration illuminants.

Two illuminants: colour_hdri (Adobe DNG SDK colour processing). colour_hdri has no third
illuminant, so the three-illuminant reference is restated here from the Adobe DNG SDK 1.6
(dng_xy_coord.cpp CalculateTripleIlluminantWeights, dng_temperature.cpp, dng_color_spec.cpp
NeutralToXY), in plain numpy loops that share no code with g2r_jax.
"""

from __future__ import annotations

import io
from fractions import Fraction

import colour
import numpy as np
from colour.temperature.robertson1968 import DATA_ISOTEMPERATURE_LINES_ROBERTSON1968

D50 = np.array([0.3457, 0.3585])   # the SDK's D50_xy_coord (start of NeutralToXY)
OBSERVER = "CIE 1931 2 Degree Standard Observer"
D50_CIE = colour.CCS_ILLUMINANTS[OBSERVER]["D50"]
D65_CIE = colour.CCS_ILLUMINANTS[OBSERVER]["D65"]

# Matrices from public DNGs' tag layouts (ColorMatrix values of the shipped Canon 600D profile
# for A / D65; a mid matrix for a third, fluorescent-like calibration).
CM_A = np.array([[0.7164, -0.1916, -0.0431], [-0.3361, 1.0600, 0.3200], [-0.0272, 0.1058, 0.6442]])
CM_D65 = np.array([[0.6461, -0.0907, -0.0882], [-0.4300, 1.2184, 0.2378], [-0.0819, 0.1944, 0.5931]])
CM_F = np.array([[0.6900, -0.1500, -0.0700], [-0.3800, 1.1300, 0.2800], [-0.0500, 0.1600, 0.6100]])
FM_A = np.array([[0.7090, 0.1510, 0.1042], [0.2581, 0.8524, -0.1105], [0.0383, -0.2180, 1.0048]])
FM_D65 = np.array([[0.7405, 0.1051, 0.1186], [0.3017, 0.7915, -0.0932], [0.0298, -0.1430, 0.9383]])
FM_F = np.array([[0.7250, 0.1300, 0.1092], [0.2800, 0.8200, -0.1000], [0.0340, -0.1800, 0.9711]])
CC_A = np.diag([1.02, 1.0, 0.97])
CC_D65 = np.diag([0.99, 1.0, 1.03])
CC_F = np.diag([1.01, 1.0, 1.0])

# Adobe DNG SDK 1.6 dng_illuminant_data: white xy per code for the codes used here.
SDK_WHITE = {17: (0.4476, 0.4074), 21: (0.3127, 0.3290), 23: (0.3457, 0.3585), 14: (0.37417, 0.37281),
             12: (0.31310, 0.33727)}
SDK_CCT = {17: 2850.0, 21: 6500.0, 23: 5000.0, 14: 4200.0, 12: 6400.0}


# ------------------------------------------------------------------ writing DNGs with tifffile

def _srational(values):
    out = []
    for v in np.asarray(values, np.float64).ravel():
        f = Fraction(float(v)).limit_denominator(1_000_000)
        out += [f.numerator, f.denominator]
    return out


def write_colour_dng(path, codes, color_matrices, camera_calibrations=(), forward_matrices=(),
                     illuminant_data=None, as_shot_neutral=(0.5, 1.0, 0.6), mosaic=None):
    """A minimal uncompressed Bayer (RGGB) DNG with the colour tag sets in the given order.

    `codes`: CalibrationIlluminant per matrix, or None to omit the tag (the spec's default 0);
    `illuminant_data`: per matrix None or (x, y), written as IlluminantData (type 0).
    """
    import tifffile

    mosaic = np.full((32, 32), 1000, np.uint16) if mosaic is None else mosaic
    tags = [(33421, 3, 2, (2, 2), True), (33422, 1, 4, bytes([0, 1, 1, 2]), True),
            (50706, 1, 4, bytes([1, 6, 0, 0] if len(color_matrices) > 2 or illuminant_data else [1, 4, 0, 0]), True),
            (50708, 2, 0, "Conformance camera", True), (50714, 4, 1, (64,), True),
            (50717, 4, 1, (16383,), True), (50728, 5, 3, tuple(_srational(as_shot_neutral)), True),
            (254, 4, 1, (0,), True)]
    for k, matrix in enumerate(color_matrices):
        tags.append(((50721, 50722, 52531)[k], 10, 9, tuple(_srational(matrix)), True))
        if codes is not None and codes[k] is not None:
            tags.append(((50778, 50779, 52529)[k], 3, 1, (int(codes[k]),), True))
        if camera_calibrations:
            tags.append(((50723, 50724, 52530)[k], 10, 9, tuple(_srational(camera_calibrations[k])), True))
        if forward_matrices:
            tags.append(((50964, 50965, 52532)[k], 10, 9, tuple(_srational(forward_matrices[k])), True))
        if illuminant_data and illuminant_data[k] is not None:
            x, y = (Fraction(float(v)).limit_denominator(1_000_000) for v in illuminant_data[k])
            blob = np.array([0], "<u2").tobytes() + np.array([x.numerator, x.denominator, y.numerator,
                                                               y.denominator], "<u4").tobytes()
            tags.append((52533 + k, 7, len(blob), blob, True))
    tags.sort(key=lambda t: t[0])
    buffer = io.BytesIO()
    with tifffile.TiffWriter(buffer, byteorder="<") as tif:
        tif.write(mosaic, photometric=32803, compression=None, software=False, extratags=tags,
                  metadata=None)
    with open(path, "wb") as handle:
        handle.write(buffer.getvalue())
    return path


def illuminant_data_spectrum_bytes(min_wavelength, spacing, samples) -> bytes:
    """IlluminantData type 1 (spectrum) as the DNG SDK lays it out, little-endian."""
    header = np.array([1], "<u2").tobytes() + np.array([len(samples)], "<u4").tobytes()
    rationals = []
    for v in (min_wavelength, spacing, *samples):
        f = Fraction(float(v)).limit_denominator(100_000)
        rationals += [f.numerator, f.denominator]
    return header + np.array(rationals, "<u4").tobytes()


# ------------------------------------------------------------------ SDK reference (numpy, loops)

def sdk_temperature_tint(xy):
    """dng_temperature::Set_xy_coord (DNG SDK 1.6), restated with an explicit loop."""
    table = np.asarray(DATA_ISOTEMPERATURE_LINES_ROBERTSON1968, np.float64)
    x, y = xy
    u = 2.0 * x / (1.5 - x + 6.0 * y)
    v = 3.0 * y / (1.5 - x + 6.0 * y)
    last_dt = last_du = last_dv = 0.0
    for index in range(1, 31):
        du, dv = 1.0, table[index, 3]
        length = np.sqrt(1.0 + dv * dv)
        du, dv = du / length, dv / length
        uu, vv = u - table[index, 1], v - table[index, 2]
        dt = -uu * dv + vv * du
        if dt <= 0.0 or index == 30:
            dt = -min(dt, 0.0)
            f = 0.0 if index == 1 else dt / (last_dt + dt)
            temperature = 1e6 / (table[index - 1, 0] * f + table[index, 0] * (1.0 - f))
            uu = u - (table[index - 1, 1] * f + table[index, 1] * (1.0 - f))
            vv = v - (table[index - 1, 2] * f + table[index, 2] * (1.0 - f))
            du, dv = du * (1.0 - f) + last_du * f, dv * (1.0 - f) + last_dv * f
            length = np.sqrt(du * du + dv * dv)
            return temperature, (uu * du / length + vv * dv / length) * -3000.0
        last_dt, last_du, last_dv = dt, du, dv
    raise AssertionError("unreachable")


def sdk_triple_weights(xy, whites):
    """CalculateTripleIlluminantWeights (DNG SDK 1.6), one white at a time."""
    def point(w):
        temperature, tint = sdk_temperature_tint(w)
        return np.array([tint / 200.0, min(1500.0 / temperature, 1.0)])
    here = point(xy)
    weights = np.array([1.0 / (np.sum((here - point(w)) ** 2) + 1e-8) for w in whites])
    weights = weights / weights.sum()
    weights = weights * weights * (3.0 - 2.0 * weights)
    weights = np.clip((weights - 0.02) / 0.98, 0.0, 1.0)
    w1, w2 = weights[:2] / weights.sum()
    return np.array([w1, w2, max(1.0 - w1 - w2, 0.0)])


class Reference:
    """The DNG colour model of one camera (1, 2 or 3 tag sets, any order), spec / SDK rules."""

    def __init__(self, codes, cms, ccs=(), fms=(), whites=None, balance=(1, 1, 1)):
        self.n = len(cms)
        self.cms = [np.asarray(m, np.float64) for m in cms]
        self.ccs = [np.asarray(m, np.float64) for m in ccs] or [np.eye(3)] * self.n
        self.fms = [np.asarray(m, np.float64) for m in fms] or None
        self.codes = codes
        self.whites = whites or [SDK_WHITE.get(c) for c in codes]
        self.ccts = [SDK_CCT.get(c, 5000.0) for c in codes]
        self.balance = np.diag(np.asarray(balance, np.float64))

    def weights(self, xy):
        if self.n == 1:
            return np.array([1.0])
        if self.n == 3:
            return sdk_triple_weights(xy, self.whites)
        # two illuminants: colour_hdri's rule (mired, clamped), whichever tag comes first
        temperature, _ = sdk_temperature_tint(xy)
        (t1, t2), swap = sorted(self.ccts), self.ccts[0] > self.ccts[1]
        g = 1.0 if temperature <= t1 else 0.0 if temperature >= t2 else \
            (1 / temperature - 1 / t2) / (1 / t1 - 1 / t2)
        return np.array([1 - g, g]) if swap else np.array([g, 1 - g])

    def _mix(self, matrices, xy):
        return sum(w * m for w, m in zip(self.weights(xy), matrices))

    def xyz_to_camera(self, xy):
        return self.balance @ self._mix(self.ccs, xy) @ self._mix(self.cms, xy)

    def neutral_to_xy(self, neutral, passes=500):
        xy = D50.copy()
        for _ in range(passes):
            XYZ = np.linalg.solve(self.xyz_to_camera(xy), neutral)
            new = XYZ[:2] / XYZ.sum()
            if np.max(np.abs(new - xy)) < 1e-13:
                return new
            xy = new
        raise ArithmeticError(f"reference iteration did not converge for {neutral}")

    def camera_to_XYZ_D50(self, xy):
        if self.fms is not None:
            balance_calibration = self.balance @ self._mix(self.ccs, xy)
            neutral = self.xyz_to_camera(xy) @ colour.xy_to_XYZ(xy)
            reference_neutral = np.linalg.solve(balance_calibration, neutral / neutral[1])
            return self._mix(self.fms, xy) @ np.diag(1 / reference_neutral) @ np.linalg.inv(balance_calibration)
        adaptation = colour.adaptation.matrix_chromatic_adaptation_VonKries(
            colour.xy_to_XYZ(xy), colour.xy_to_XYZ(D50_CIE), transform="Bradford")
        return adaptation @ np.linalg.inv(self.xyz_to_camera(xy))

    def render_to_XYZ_D65(self, camera_rgb, neutral):
        """Camera RGB (N, 3) -> XYZ adapted to D65, as a DNG renderer does at AsShotNeutral."""
        XYZ_D50 = camera_rgb @ self.camera_to_XYZ_D50(self.neutral_to_xy(np.asarray(neutral, np.float64))).T
        return colour.adaptation.chromatic_adaptation_VonKries(XYZ_D50, colour.xy_to_XYZ(D50_CIE),
                                                                colour.xy_to_XYZ(D65_CIE), transform="Bradford")
