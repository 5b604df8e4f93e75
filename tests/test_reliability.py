"""Issue 12's promises on hand-made cases: per-file tag checks, one profile validation for load
and save, convert checks the profile first and leaves nothing behind, effects out of physical
range refused, messages short and ours, CLI details (issue 8 'Packaging and interface')."""

from __future__ import annotations

import json

import numpy as np
import pytest

from test_io_dng import CM_D65, make_info, random_mosaic
from g2r_jax.profile import schema as pm
from g2r_jax.cli.common import error_message
from g2r_jax.cli.convert import main as convert_main
from g2r_jax.cli.diagnose import main as diagnose_main
from g2r_jax.cli.fit_profile import main as fit_main
from g2r_jax.io.dng_info import DngError
from g2r_jax.io.dng_write import write_dng
from g2r_jax.io.tag_checks import check_dng_tags


@pytest.mark.parametrize("changes, field", [
    ({"white_level": 60.0}, "BlackLevel"),                   # black at or above white
    ({"white_level": 90.0}, "WhiteLevel"),                   # 23 DN of range
    ({"black_level": np.array([-1.0, 0, 0, 0])}, "BlackLevel"),
    ({"color_matrices": (np.zeros((3, 3)), CM_D65)}, "ColorMatrix1"),
    ({"color_matrices": (CM_D65 * 9.2e18, CM_D65)}, "ColorMatrix1"),
    ({"color_matrices": (-CM_D65, CM_D65)}, "ColorMatrix1"),
    ({"camera_calibrations": (np.diag([1.0, -1.0, 1.0]), np.eye(3))}, "CameraCalibration1"),
    ({"as_shot_neutral": np.array([0.5, 1.0, 0.0])}, "AsShotNeutral"),
    ({"as_shot_neutral": np.array([0.5, 1.0, np.nan])}, "AsShotNeutral"),
    ({"analog_balance": np.array([1.0, 1.0, 1e6])}, "AnalogBalance"),
    ({"baseline_exposure": 1e9}, "BaselineExposure"),
    ({"noise_profile": np.array([[-1e-4, 1e-8]] * 3)}, "NoiseProfile"),
    ({"iso": -5.0}, "ISOSpeedRatings"),
])
def test_tag_checks_name_the_file_and_field(changes, field):
    info = make_info(path="cam/x.dng", **changes)
    with pytest.raises(DngError, match=f"^cam/x.dng: {field}: ") as error:
        check_dng_tags(info)
    assert len(str(error.value)) < 200


def test_good_tags_pass():
    assert check_dng_tags(make_info(path="x.dng")).path == "x.dng"


def document():
    return pm.profile_to_dict(pm.load_profile("Canon600D"))


@pytest.mark.parametrize("mutate, field", [
    (lambda d: d.update(baseline_exposure=float("nan")), "baseline_exposure"),
    (lambda d: d.update(white_level=1e308), "white_level"),
    (lambda d: d.update(black_level=[-1, 0, 0, 0]), "black_level"),
    (lambda d: d.update(white_level=1), "black_level"),    # black 512 not below white 1
    (lambda d: d["colour"]["color_matrices"][0][0].__setitem__(0, 9.2e18), "colour.color_matrices"),
    (lambda d: d["colour"]["color_matrices"][0][0].__setitem__(0, -1e308), "colour.color_matrices"),
    (lambda d: d["noise"]["shot"][0].__setitem__(0, -1e-3), "noise.shot"),
    (lambda d: d["colour"].update(calibration_illuminants=[None]), "colour.calibration_illuminants"),
    (lambda d: d.update(opcode_lists=["x"]), "opcode_lists"),
    (lambda d: d.update(camera=[1, 2]), "camera"),
    (lambda d: d["effects"].update(black_pedestal=[-1e308, 0, 0, 0]), "effects.black_pedestal"),
    (lambda d: d["effects"].update(black_pedestal=[1e308] * 4), "effects.black_pedestal"),
    (lambda d: d["effects"].update(channel_gain=[0, 1, 1, 1]), "effects.channel_gain"),
    (lambda d: d["effects"].update(clip_level=-1), "effects.clip_level"),
    (lambda d: d["effects"].update(shading=[[-3.0, 0.0]] * 4), "effects.shading"),
    (lambda d: d["effects"].update(row_noise_std=-0.1), "effects.row_noise_std"),
    (lambda d: d["effects"].update(column_noise_std=1), "effects.column_noise_std"),
    (lambda d: d["illuminants"].update(means=[[-0.5, 0.5]] * len(d["illuminants"]["means"])), "illuminants.means"),
    (lambda d: d["illuminants"].update(weights=[]), "illuminants.weights"),
    (lambda d: d["exposure"].update(log2_std="wide"), "exposure.log2_std"),
])
def test_profile_validation_names_file_and_field_and_convert_writes_nothing(tmp_path, capsys, mutate, field):
    doc = document()
    mutate(doc)
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(pm.ProfileError, match=f"bad.json: {field.replace('.', '[.]')}"):
        pm.load_profile(path)
    out = tmp_path / "out"
    assert convert_main(["--example", "--profile", str(path), "-o", str(out), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "bad.json" in err[0] and field in err[0] and len(err[0]) < 300
    assert not out.exists()                           # checked before any input: no folder, no manifest


def test_save_profile_refuses_what_the_loader_refuses(tmp_path):
    profile = pm.load_profile("Canon600D")
    broken = pm.replace(profile, white_level=profile.white_level * np.nan)
    with pytest.raises(pm.ProfileError, match="p.json: white_level: contains NaN"):
        pm.save_profile(broken, tmp_path / "p.json")
    assert not list(tmp_path.iterdir())


def test_fit_profile_drops_a_bad_file_and_fits_the_rest(tmp_path, capsys):
    folder = tmp_path / "in"
    folder.mkdir()
    for name, neutral in (("a", [0.5, 1.0, 0.6]), ("b", [0.45, 1.0, 0.7])):
        write_dng(folder / f"{name}.dng", random_mosaic(), make_info(as_shot_neutral=np.array(neutral)))
    write_dng(folder / "c.dng", random_mosaic(), make_info(white_level=70.0, black_level=np.full(4, 60.0)))
    before = {p.name: p.read_bytes() for p in folder.iterdir()}
    assert fit_main([str(folder), "-o", str(tmp_path / "p.json")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    about_c = [line for line in err if "c.dng" in line]
    assert len(about_c) == 1 and "WhiteLevel" in about_c[0] and "error" in about_c[0]
    assert all(line.startswith("g2r-fit-profile: ") and "Traceback" not in line for line in err)
    # the others: at most the note that these files' tiny read noise cannot be told from rounding
    assert all("rounding" in line for line in err if line not in about_c)
    pm.load_profile(tmp_path / "p.json")
    assert {p.name: p.read_bytes() for p in folder.iterdir()} == before


def test_library_errors_become_a_plain_line():
    class XlaRuntimeError(RuntimeError):
        pass

    XlaRuntimeError.__module__ = "jaxlib.xla_extension"
    text = "INTERNAL: CpuCallback error calling callback\n" + "equinox frame\n" * 30
    assert "equinox" not in error_message(XlaRuntimeError(text))
    assert error_message(DngError("a.dng", "x" * 100000)).startswith("a.dng: xxx")
    assert len(error_message(DngError("a.dng", "x" * 100000))) <= 300


def test_list_profiles_without_output_and_example_names_its_profile(tmp_path, capsys):
    assert convert_main(["--list-profiles"]) == 0
    assert "Canon600D" in capsys.readouterr().out.split()
    assert convert_main(["--example", "-o", str(tmp_path), "--profile", "NikonD40"]) == 0
    assert "'NikonD40'" in capsys.readouterr().err      # a note: not shown with --quiet (or --no-progress)
    assert convert_main(["--example", "--no-progress"]) == 2
    assert "-o/--output" in capsys.readouterr().err


def test_help_texts(capsys):
    assert convert_main(["--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    for option in ("--batch-size", "--engine", "--quiet", "--seed"):
        after = text.split(option, 1)[1].lstrip()
        assert not after.startswith("--"), f"{option} has no help text"


def test_diagnose_creates_the_report_folder(tmp_path, capsys):
    measured = tmp_path / "m"
    measured.mkdir()
    (measured / "only.dng").write_text("not a dng")
    report = tmp_path / "new" / "deeper" / "r.json"
    assert diagnose_main(["--profile", "Canon600D", "--measured", str(measured), "--report", str(report)]) == 2
    assert report.parent.is_dir()
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "only.dng" in err[0]


def test_no_colour_science_warning_without_matplotlib():
    import subprocess
    import sys

    code = ("import sys; sys.modules['matplotlib'] = None\n"
            "from g2r_jax.cli.convert import main\n"
            "sys.exit(main(['--list-profiles']))")
    done = subprocess.run([sys.executable, "-W", "default", "-c", code], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0 and done.stderr == "", done.stderr[-500:]


def test_illuminant_extension_on_a_small_fold_has_no_hull():
    from g2r_jax.audit.causes.illuminant_distribution import CAUSE

    profile = pm.load_profile("s20fe_night")          # a mixture model with a hull
    assert bool(profile.illuminants.use_hull)
    params = {"kind": "gaussian", "weights": [1.0], "means": [[0.6, 0.6]], "covariances": [[[1e-3, 0], [0, 1e-3]]],
              "hull_points": [[0.6, 0.6], [0.7, 0.5]]}   # two neutrals: fuzzing found the audit stopped here
    assert not bool(CAUSE.apply(profile, params).illuminants.use_hull)


@pytest.mark.parametrize("neutrals", [[], [[0.5, 1.0, 0.6]], [[0.5, 1.0, 0.6], [0.6, 1.0, 0.5]]])
def test_illuminant_extension_fits_a_fold_of_fewer_than_three_files(neutrals):
    from g2r_jax.audit.causes.illuminant_distribution import CAUSE

    profile = pm.load_profile("s20fe_night")
    params = CAUSE.fit([{"neutral": np.array(n)} for n in neutrals], [], profile)
    extended = CAUSE.apply(profile, params)
    assert np.all(np.isfinite(np.asarray(extended.illuminants.means)))


@pytest.mark.data
def test_two_files_at_one_white_with_slightly_different_matrices_fit_a_valid_profile(shared_data, tmp_path):
    """Fuzzing reproducer (the GoPro file with one ColorMatrix2 entry changed by -0.0033): the
    matrix-pair fit gave a matrix with a negative response to white and the batch was lost."""
    import dataclasses

    from g2r_jax.cli.fit_profile import validate_profile
    from g2r_jax.profile.fitting import fit_profile
    from g2r_jax.io.dng_read import read_dng_info

    good = read_dng_info(shared_data / "dng" / "gopro_hero6_GOPR0024.dng")
    changed = [np.array(m, copy=True) for m in good.color_matrices]
    changed[1][0, 2] -= 0.0033
    other = dataclasses.replace(good, path=str(tmp_path / "mutated.dng"), color_matrices=tuple(changed))
    validate_profile(fit_profile([good, other]), tmp_path / "p.json")


def test_fit_profile_removes_the_temporaries_a_killed_run_left_beside_its_output(tmp_path, capsys):
    folder = tmp_path / "in"
    folder.mkdir()
    for name, neutral in (("a", [0.5, 1.0, 0.6]), ("b", [0.45, 1.0, 0.7])):
        write_dng(folder / f"{name}.dng", random_mosaic(), make_info(as_shot_neutral=np.array(neutral)))
    out = tmp_path / "out"
    out.mkdir()
    stale = [out / ".p.json.k2j4x9_a.tmp", out / ".p.json.zz81mq0e.tmp"]   # as a SIGKILLed run leaves them
    for path in stale:
        path.write_text('{"half": ')
    other = out / ".q.json.k2j4x9_a.tmp"   # another output's temporary is not ours to remove
    other.write_text("x")
    assert fit_main([str(folder), "-o", str(out / "p.json")]) == 0
    err = capsys.readouterr().err
    assert "removed 2 temporary file(s) of p.json" in err
    assert not any(path.exists() for path in stale) and other.exists()
    pm.load_profile(out / "p.json")


def test_profile_read_noise_that_a_dng_noise_profile_cannot_hold_is_refused(tmp_path):
    doc = document()
    doc["noise"]["read"][0][0] = 1.0   # plus the rounding variance: NoiseProfile O above 1
    path = tmp_path / "p.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(pm.ProfileError, match="noise.read.*rounding variance"):
        pm.load_profile(path)


def test_diagnose_names_a_bad_chart_file_once(tmp_path, capsys):
    charts = tmp_path / "charts.csv"
    charts.write_text("image,patch,r,g,b\nim0,1,abc,0.2,0.3\n")
    assert diagnose_main(["--profile", "NikonD40", "--charts", str(charts), "--report", str(tmp_path / "r" / "R.json"),
                          "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].count("charts.csv") == 1 and "row 2" in err[0], err


@pytest.mark.parametrize("iso_range", [[1e-320, 3200.0], [0.5, 3200.0], [3200.0, 100.0]])
def test_profile_iso_range_below_one_or_reversed_is_refused(tmp_path, iso_range):
    doc = document()   # ISO 1e-320 is 0 in float32: every simulated file had ISO NaN and a black mosaic
    doc["noise"]["iso_range"] = iso_range
    path = tmp_path / "p.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(pm.ProfileError, match="noise.iso_range"):
        pm.load_profile(path)


@pytest.mark.slow
def test_xla_log_lines_do_not_reach_the_terminal(tmp_path):
    """XLA's C++ logger writes to descriptor 2 (under load: its slow-compilation alarm); here a
    dump folder it cannot create makes it log W and E lines on every compilation."""
    import os
    import subprocess
    import sys

    from PIL import Image

    (tmp_path / "in").mkdir()
    Image.fromarray(np.full((16, 24, 3), 120, np.uint8)).save(tmp_path / "in" / "a.png")
    env = {k: v for k, v in os.environ.items() if k != "TF_CPP_MIN_LOG_LEVEL"}
    env["XLA_FLAGS"] = "--xla_dump_to=/proc/g2r_no_such_folder"
    run = subprocess.run([sys.executable, "-m", "g2r_jax.cli.convert", str(tmp_path / "in"), "--profile", "NikonD40",
                          "-o", str(tmp_path / "out"), "--no-progress", "--no-compile-cache"],
                         capture_output=True, text=True, env=env, timeout=600)
    assert run.returncode == 0, run.stderr[-1000:]
    assert all(line.startswith("g2r-convert: ") for line in run.stderr.splitlines()), run.stderr[-1000:]
