"""The prior's presets follow the lights, and no preset or camera makes a fit fail (issue 33):
prior lights a camera's matrices cannot carry are left out and counted, never an error."""

import re

import jax.numpy as jnp
import numpy as np
import pytest

from g2r_jax.colour import dng_model as dng
from g2r_jax.colour.conversions import CCT_to_xy
from g2r_jax.illuminants import choice as ch
from g2r_jax.illuminants import prior as P
from g2r_jax.illuminants.distributions import neutral_to_chromaticity
from g2r_jax.io.dng_info import DngInfo
from g2r_jax.profile.fitting import fit_profile
from g2r_jax.profile.schema import load_profile


def _preset_of(reason: str) -> str:
    found = re.findall(r"\((day|night|day_night) preset", reason)
    assert len(found) == 1, reason
    return found[0]


def _left_out_share(reason: str) -> float:
    found = re.search(r"([0-9.]+)% of the prior's '\w+' lights \(the warmest\) left out", reason)
    return float(found.group(1)) / 100 if found else 0.0


def _daylight_neutrals(colour, ccts):
    return [np.asarray(dng.xy_to_camera_neutral(jnp.asarray(CCT_to_xy(c)[0]), colour), np.float64) for c in ccts]


def test_a_one_matrix_d65_camera_fits_although_its_matrix_cannot_carry_all_night_lights():
    """The Canon 5D profile has one D65 ColorMatrix; through it the warmest night lights get a
    negative blue neutral. That used to end every fit ("no valid profile"); now those lights are
    left out of the night preset and counted, and daylight files still fit."""
    colour = load_profile("Canon5D").colour
    night = ch.choose_illuminant_model(np.zeros((0, 2)), colour, "prior-night")
    assert 0.0 < _left_out_share(night.reason) < P.MAX_UNREPRESENTABLE, night.reason
    assert _left_out_share(ch.choose_illuminant_model(np.zeros((0, 2)), colour, "prior").reason) == 0.0
    tags = colour.dng_tags()
    infos = [DngInfo(path=f"f{k}.dng", cfa_pattern=(0, 1, 1, 2), black_level=np.full(4, 128.0), white_level=4095.0,
                     calibration_illuminants=tags["calibration_illuminants"], color_matrices=tuple(tags["color_matrices"]),
                     unique_camera_model="Canon EOS 5D", as_shot_neutral=neutral,
                     noise_profile=np.array([[2e-5, 1e-7]]), iso=100)
             for k, neutral in enumerate(_daylight_neutrals(colour, np.linspace(4800, 7500, 12)))]
    for kind in ("auto", "kernel", "prior-night", "prior-day-night"):
        profile = fit_profile(infos, illuminant_model=kind)
        assert np.all(np.isfinite(np.asarray(profile.illuminants.means))), kind
    assert _preset_of(fit_profile(infos).info.provenance) == "day"


def test_a_matrix_that_cannot_carry_most_of_a_preset_leaves_the_choice_to_the_others():
    """A blue row that turns negative for warm lights refuses the presets it cannot carry; the
    kernel of daylight lights still fits with a preset that it can."""
    cm = np.asarray(load_profile("Canon5D").colour.color_matrix[0], np.float64).copy()
    broken = cm.copy()
    broken[2] = [0.0, -0.5, 0.55]
    colour = dng.DngColourModel.from_tags((21,), [broken], dtype=np.float32)
    with pytest.raises(ValueError, match="cannot carry"):
        P.camera_prior(colour, "night")
    lights = neutral_to_chromaticity(np.stack(_daylight_neutrals(colour, [9000, 10000, 12000])))
    if np.all(lights > 0):
        try:
            choice = ch.choose_illuminant_model(lights, colour, "kernel")
        except ValueError as error:   # only when no preset at all is carried
            assert "cannot carry" in str(error)
        else:
            assert _preset_of(choice.reason) in ("day", "day_night")


def _gehler_shi_5d_lights(shared_data):
    scipy_io = pytest.importorskip("scipy.io")
    rgb = scipy_io.loadmat(str(shared_data / "illuminants" / "gehler_shi" / "real_illum_568.mat"))["real_rgb"]
    return neutral_to_chromaticity(np.asarray(rgb[86:], np.float64))   # images 87-568: the Canon EOS 5D


def test_day_scenes_never_get_the_night_preset(shared_data):
    """Random sets of 1-9 and of 40 real Gehler-Shi Canon 5D lights (day and indoor scenes) through the
    shipped Canon5D profile's matrix: 'auto' (the prior below 10 lights, the kernel above) picks the
    day preset every time."""
    colour = load_profile("Canon5D").colour
    lights = _gehler_shi_5d_lights(shared_data)
    rng = np.random.default_rng(0)
    for size in (1, 2, 3, 5, 9, 40):
        for _ in range(3):
            subset = lights[rng.choice(len(lights), size, replace=False)]
            choice = ch.choose_illuminant_model(subset, colour, "auto")
            assert _preset_of(choice.reason) == "day", (size, choice.reason)


def test_night_scenes_get_the_night_preset(shared_data):
    """The S20 FE's measured night lights (street and shop lamps) through its profile: the night
    preset once there are a few of them, for the prior ('auto' below 10 lights) and the kernel."""
    colour = load_profile("s20fe_night").colour
    table = np.loadtxt(shared_data / "illuminants" / "s20fe_night_graycard_105.csv", delimiter=",", skiprows=1)
    lights = table[:, [0, 2]]
    rng = np.random.default_rng(1)
    for size in (5, 9, 40):
        subset = lights[rng.choice(len(lights), size, replace=False)]
        assert _preset_of(ch.choose_illuminant_model(subset, colour, "auto").reason) == "night", size
    assert _preset_of(ch.choose_illuminant_model(lights, colour, "kernel").reason) == "night"
