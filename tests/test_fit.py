"""Profile fitting from DNG tags: noise from NoiseProfile, per-file matrices, single DNG."""

import jax.numpy as jnp
import numpy as np

from g2r_jax.colour import dng_model as dng
from g2r_jax.colour.conversions import CCT_to_xy
from g2r_jax.profile.fitting import fit_color_matrix_pair, fit_profile
from g2r_jax.io.dng_info import DngInfo

CM_A = np.array([0.7164, -0.1916, -0.0431, -0.3361, 1.06, 0.32, -0.0272, 0.1058, 0.6442]).reshape(3, 3)
CM_D65 = np.array([0.6461, -0.0907, -0.0882, -0.43, 1.2184, 0.2378, -0.0819, 0.1944, 0.5931]).reshape(3, 3)


def info(**kwargs):
    base = dict(path="x.dng", cfa_pattern=(1, 0, 2, 1), black_level=np.full(4, 256.0), white_level=4095.0,
                calibration_illuminants=(17, 21), color_matrices=(CM_A, CM_D65), unique_camera_model="Cam")
    base.update(kwargs)
    return DngInfo(**base)


def test_per_file_matrices_are_explained_by_one_fitted_pair():
    """Phones often write the matrix for the shot's own illuminant; the pair is recovered."""
    model = dng.DngColourModel.from_tags((17, 21), [CM_A, CM_D65], dtype=np.float64)
    infos = []
    for cct in (2900, 3400, 4100, 5000, 6000):
        xy = jnp.asarray(CCT_to_xy(cct)[0])
        weight = float(dng.interpolation_weight(dng._colour.xy_to_CCT(xy), model))
        per_shot = weight * CM_A + (1 - weight) * CM_D65
        neutral = np.asarray(dng.xy_to_camera_neutral(xy, model))
        infos.append(info(color_matrices=(per_shot, per_shot), as_shot_neutral=neutral))
    fitted = fit_color_matrix_pair(infos, dtype=np.float64)
    np.testing.assert_allclose(np.asarray(fitted.color_matrix[0]), CM_A, atol=2e-3)
    np.testing.assert_allclose(np.asarray(fitted.color_matrix[1]), CM_D65, atol=2e-3)
    profile = fit_profile(infos)
    np.testing.assert_allclose(np.asarray(profile.colour.color_matrix[1]), CM_D65, atol=2e-3)


def test_noise_model_from_noise_profile_tags_by_iso():
    infos = [info(noise_profile=np.array([[2e-5, 1e-7], [1e-5, 5e-8], [3e-5, 2e-7]]), iso=100,
                  as_shot_neutral=np.array([0.5, 1, 0.6])),
             info(noise_profile=np.array([[8e-5, 4e-7]]), iso=400, as_shot_neutral=np.array([0.6, 1, 0.5])),
             info(noise_profile=np.array([[8e-5, 4e-7]]), iso=400, as_shot_neutral=np.array([0.55, 1, 0.7]))]
    profile = fit_profile(infos)
    np.testing.assert_allclose(np.asarray(profile.noise.iso), [100, 400])
    # GRBG tile: positions G, R, B, G
    np.testing.assert_allclose(np.asarray(profile.noise.shot[0]), [1e-5, 2e-5, 3e-5, 1e-5], rtol=1e-5)
    # the tag's O less the rounding to integer DN, which the simulation adds (1/12 DN^2)
    np.testing.assert_allclose(np.asarray(profile.noise.read[1]), [4e-7 - 1 / 12 / (4095 - 256) ** 2] * 4, rtol=1e-5)
    assert profile.noise.read_excludes_quantisation
    # 3 lights: fewer than the kernel model needs (MIN_LIGHTS_FOR_KERNEL): 'auto' takes the pooled lights
    assert "pooled (auto" in profile.info.provenance
    assert profile.cfa_string == "GRBG"


def test_one_dng_gives_the_pooled_lights_the_locus_stays_selectable_and_ten_lights_give_the_kernel_model():
    one = [info(as_shot_neutral=np.array([0.5, 1, 0.6]))]
    assert "pooled (auto, 1 measured light" in fit_profile(one).info.provenance
    assert fit_profile(one, illuminant_model="prior").illuminants.kind == "prior"
    assert fit_profile(one, illuminant_model="locus").illuminants.kind == "locus"
    neutrals = [np.array([0.45 + 0.02 * k, 1, 0.75 - 0.015 * k + 0.01 * (k % 3)]) for k in range(10)]
    ten = fit_profile([info(as_shot_neutral=n) for n in neutrals])
    assert ten.illuminants.kind == "kernel" and "10 measured lights" in ten.info.provenance
    assert "pooled (auto" in fit_profile([info(as_shot_neutral=n) for n in neutrals[:9]]).info.provenance
