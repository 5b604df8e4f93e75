"""Independent reference rendering of a DNG: rawpy (LibRaw) pixels, colour_hdri (Adobe DNG SDK
colour processing) matrices, colour-science for adaptation and CIE Lab / dE2000."""

from __future__ import annotations

import colour
import numpy as np
from colour_hdri.models import dng as reference

D50 = colour.CCS_ILLUMINANTS["CIE 1931 2 Degree Standard Observer"]["D50"]
D65 = colour.CCS_ILLUMINANTS["CIE 1931 2 Degree Standard Observer"]["D65"]
I3 = np.eye(3)


class NotConverged(ArithmeticError):
    """The specification's plain iteration cycles instead of converging (it does not contract)."""


def neutral_to_xy(neutral, *args, iterations=500):
    """The DNG neutral -> xy iteration built on colour_hdri's XYZtoCamera, stopping when xy moves
    less than 1e-13. (colour_hdri's own `camera_neutral_to_xy` tests |sum(dx, dy)|, which can stop
    on a cancellation or loop forever, so its iteration is restated here around its matrices.)"""
    xy = np.array(D50)
    for _ in range(iterations):
        XYZ = np.linalg.solve(reference.matrix_XYZ_to_camera_space(xy, *args), neutral)
        new = XYZ[:2] / XYZ.sum()
        if np.max(np.abs(new - xy)) < 1e-13:
            return new
        xy = new
    raise NotConverged(f"reference iteration did not converge for {neutral}")


def colour_hdri_arguments(info):
    """(CCT1, CCT2, CM1, CM2, CC1, CC2, AB), (FM1, FM2) in colour_hdri's conventions from a DngInfo."""
    from g2r_jax.colour.dng_model import calibration_illuminant_cct

    ccts = [calibration_illuminant_cct(c) for c in info.calibration_illuminants]
    cms = list(info.color_matrices)
    ccs = list(info.camera_calibrations) or [I3] * len(cms)
    fms = list(info.forward_matrices) or [I3] * len(cms)
    if len(cms) == 1:
        ccts, cms, ccs, fms = [ccts[0]] * 2, [cms[0], I3], [ccs[0], I3], [fms[0], I3]
    order = np.argsort(ccts)
    pick = lambda ms: [ms[i] for i in order]
    balance = np.ones(3) if info.analog_balance is None else np.asarray(info.analog_balance)
    return (*sorted(ccts), *pick(cms), *pick(ccs), balance), tuple(pick(fms))


def render_patches_to_XYZ_D65(camera_rgb, info):
    """Camera RGB (N, 3), black-subtracted and normalised, -> XYZ (D65-adapted) as a DNG renderer does."""
    arguments, forward = colour_hdri_arguments(info)
    xy = neutral_to_xy(np.asarray(info.as_shot_neutral, np.float64), *arguments)
    camera_to_xyz = reference.matrix_camera_space_to_XYZ(xy, *arguments, *forward)
    XYZ_D50 = camera_rgb @ camera_to_xyz.T
    return colour.adaptation.chromatic_adaptation_VonKries(XYZ_D50, colour.xy_to_XYZ(D50), colour.xy_to_XYZ(D65),
                                                            transform="Bradford")


def patch_camera_rgb(path, boxes):
    """Mean camera RGB (black-subtracted, normalised to the white level) inside each box, read with rawpy."""
    import rawpy

    with rawpy.imread(str(path)) as raw:
        values = raw.raw_image_visible.astype(np.float64)
        colours = raw.raw_colors_visible
        black = np.asarray(raw.black_level_per_channel, np.float64)[colours]
        normalised = (values - black) / (raw.white_level - black)
    rgb = []
    for top, left, bottom, right in boxes:
        region, region_colours = normalised[top:bottom, left:right], colours[top:bottom, left:right]
        green = np.isin(region_colours, (1, 3))
        rgb.append([region[region_colours == 0].mean(), region[green].mean(), region[region_colours == 2].mean()])
    return np.array(rgb)


def mean_delta_E_2000(XYZ_rendered, XYZ_input):
    """Mean CIEDE2000 after one global exposure scale (least squares on Y), both under D65."""
    scale = np.sum(XYZ_rendered[:, 1] * XYZ_input[:, 1]) / np.sum(XYZ_rendered[:, 1] ** 2)
    lab_rendered = colour.XYZ_to_Lab(XYZ_rendered * scale, D65)
    lab_input = colour.XYZ_to_Lab(XYZ_input, D65)
    return float(np.mean(colour.delta_E(lab_rendered, lab_input, method="CIE 2000"))), scale


PATCH, MARGIN = 16, 3


def patch_scene(tmp_path):
    """24 flat ColorChecker patches, 16x16 pixels each, as an 8-bit sRGB PNG in tmp_path/in.

    **Returns:** (folder, 8-bit codes (24, 3), boxes (top, left, bottom, right) inside each patch).
    """
    from PIL import Image

    from g2r_jax.examples import colour_checker_srgb

    codes = np.round(colour_checker_srgb() * 255).astype(np.uint8)
    image = np.zeros((4 * PATCH, 6 * PATCH, 3), np.uint8)
    boxes = []
    for index, code in enumerate(codes):
        row, col = divmod(index, 6)
        image[row * PATCH:(row + 1) * PATCH, col * PATCH:(col + 1) * PATCH] = code
        boxes.append((row * PATCH + MARGIN, col * PATCH + MARGIN, (row + 1) * PATCH - MARGIN, (col + 1) * PATCH - MARGIN))
    folder = tmp_path / "in"
    folder.mkdir(exist_ok=True)
    Image.fromarray(image).save(folder / "patches.png")
    return folder, codes, boxes
