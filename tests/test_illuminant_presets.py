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
    if reason.startswith("pooled (auto"):   # 'auto' below 10 lights: the pooled day lights, no night preset
        return "day"
    found = re.findall(r"\((day|night|day_night) preset", reason)
    assert len(found) == 1, reason
    return found[0]


def _left_out_share(reason: str) -> float:
    found = re.search(r"([0-9.]+)% of the prior's '\w+' lights \(the warmest\) left out", reason)
    return float(found.group(1)) / 100 if found else 0.0


def _daylight_neutrals(colour, ccts):
    return [np.asarray(dng.xy_to_camera_neutral(jnp.asarray(CCT_to_xy(c)[0]), colour), np.float64) for c in ccts]


def _daylight_infos(colour, count):
    """Tags of `count` Canon 5D files (this colour model's matrices) shot in daylight, 4800-7500 K."""
    tags = colour.dng_tags()
    return [DngInfo(path=f"f{k}.dng", cfa_pattern=(0, 1, 1, 2), black_level=np.full(4, 128.0), white_level=4095.0,
                    calibration_illuminants=tags["calibration_illuminants"], color_matrices=tuple(tags["color_matrices"]),
                    unique_camera_model="Canon EOS 5D", as_shot_neutral=neutral,
                    noise_profile=np.array([[2e-5, 1e-7]]), iso=100)
            for k, neutral in enumerate(_daylight_neutrals(colour, np.linspace(4800, 7500, count)))]


def test_a_one_matrix_d65_camera_fits_although_its_matrix_cannot_carry_all_night_lights():
    """The Canon 5D profile has one D65 ColorMatrix; through it the warmest night lights get a
    negative blue neutral. That used to end every fit ("no valid profile"); now those lights are
    left out of the night preset and counted, and daylight files still fit."""
    colour = load_profile("Canon5D").colour
    night = ch.choose_illuminant_model(np.zeros((0, 2)), colour, "prior-night")
    assert 0.0 < _left_out_share(night.reason) < P.MAX_UNREPRESENTABLE, night.reason
    assert _left_out_share(ch.choose_illuminant_model(np.zeros((0, 2)), colour, "prior").reason) == 0.0
    infos = _daylight_infos(colour, 12)
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


def test_random_sets_of_nus_day_and_indoor_lights_keep_the_day_preset(shared_data):
    """The NUS cameras' measured lights (day and indoor scenes), random sets of 1-9 through each
    camera's shipped profile: the camera that took the night preset most often before the rules
    (NikonD5200: 4-9 % of random sets) keeps the day preset in 200 sets."""
    from g2r_jax.downstream.base import real_sets
    from g2r_jax.illuminants.distributions import neutral_to_chromaticity

    nus = shared_data / "estimation" / "nus" / "NikonD5200.npz"
    if not nus.exists():
        pytest.skip(f"{nus} absent")
    lights = neutral_to_chromaticity(np.asarray(real_sets.load_nus(nus).illuminants, np.float64))
    colour = load_profile("NikonD5200").colour
    rng = np.random.default_rng(2)
    presets = [_preset_of(ch._prior_choice(lights[rng.choice(len(lights), size, replace=False)], colour, "prior",
                                           "auto", True, np.float32).reason)
               for size in (1, 2, 3, 4, 5, 9, 9, 9) for _ in range(25)]
    assert presets.count("day") == len(presets), presets


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


def _canon5d_folder(tmp_path, count):
    from PIL import Image

    from g2r_jax.cli.convert import main as convert

    renders = tmp_path / "renders"
    renders.mkdir()
    rng = np.random.default_rng(0)
    for k in range(count):
        Image.fromarray(rng.integers(30, 220, (32, 48, 3), dtype=np.uint8)).save(renders / f"r{k:02d}.png")
    assert convert([str(renders), "--profile", "Canon5D", "-o", str(tmp_path / "dngs"), "--seed", "0", "--quiet",
                    "--no-progress"]) == 0
    return tmp_path / "dngs"


@pytest.mark.slow
def test_fit_profile_of_a_canon5d_folder_with_the_night_preset_fits_and_counts_what_it_left_out(tmp_path, capsys):
    """The issue's failure: g2r-fit-profile of Canon5D DNGs ended with "no valid profile" because the
    night preset has lights the 5D's one matrix cannot carry. Now it fits and says how many it left out."""
    from g2r_jax.cli.fit_profile import main as fit_profile_cli

    folder = _canon5d_folder(tmp_path, 4)
    output = tmp_path / "p.json"
    assert fit_profile_cli([str(folder), "-o", str(output), "--illuminant-model", "prior-night"]) == 0
    out = capsys.readouterr().out
    assert "no valid profile" not in out and 0 < _left_out_share(out) < P.MAX_UNREPRESENTABLE, out
    assert 0 < _left_out_share(load_profile(output).info.provenance) < P.MAX_UNREPRESENTABLE


@pytest.mark.slow
def test_trial_fits_after_a_failure_print_their_warnings_once(tmp_path, capsys, monkeypatch):
    """When the fit of all files fails, g2r-fit-profile refits without each file in turn; each trial's
    warnings (before: the missing-NoiseProfile line once per trial, 300 lines for 300 files) are
    shown only for the fit it keeps: one line."""
    import warnings

    from g2r_jax.cli.fit_profile import main as fit_profile_cli
    from g2r_jax.profile import fitting

    folder = _canon5d_folder(tmp_path, 5)
    real_fit = fitting.fit_profile

    def fit_that_one_file_breaks(infos, **kwargs):
        names = sorted(str(i.path).rsplit("/", 1)[-1] for i in infos)
        warnings.warn_explicit(f"no usable NoiseProfile (missing: {', '.join(names)})", UserWarning,
                               fitting.__file__, 1)
        if "r02.dng" in names:
            raise ValueError("a fit-breaking file")
        return real_fit(infos, **kwargs)

    monkeypatch.setattr(fitting, "fit_profile", fit_that_one_file_breaks)
    assert fit_profile_cli([str(folder), "-o", str(tmp_path / "p.json")]) == 1
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if "no usable NoiseProfile" in line]
    assert len(lines) == 1 and "r02.dng" not in lines[0], err
    assert "r02.dng: dropped" in err


def test_fit_profile_names_the_illuminant_model_it_chose_not_its_stored_family():
    """A pooled model is stored as a kernel density (`IlluminantModel.kind` 'kernel'); g2r-fit-profile's
    "wrote ... (X illuminant model" line named it 'kernel' when 'auto' had chosen 'pooled'."""
    from g2r_jax.cli.fit_profile import illuminant_model_name

    infos = _daylight_infos(load_profile("Canon5D").colour, 3)
    few = fit_profile(infos)
    assert few.illuminants.kind == "kernel" and illuminant_model_name(few) == "pooled", few.info.provenance
    assert illuminant_model_name(fit_profile(infos, illuminant_model="locus")) == "locus"
