"""Spectral options of the commands: g2r-fit-profile --sensitivities, g2r-convert --colour spectral."""

from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image

from g2r_jax.cli.convert import main as convert
from g2r_jax.cli.fit_profile import main as fit_profile_cli
from g2r_jax.io.dng_read import read_dng_info
from g2r_jax.profile.schema import load_profile
from g2r_jax.colour.spectral.tables import LAMP_FAMILIES


def write_png(path, seed, shape=(24, 32)):
    Image.fromarray(np.random.default_rng(seed).integers(0, 256, shape + (3,), dtype=np.uint8)).save(path)


@pytest.mark.slow
def test_convert_spectral_writes_the_lights_response_and_the_profiles_tags(tmp_path, capsys):
    write_png(tmp_path / "a.png", 0)
    matrix_dir, spectral_dir = tmp_path / "matrix", tmp_path / "spectral"
    assert convert([str(tmp_path / "a.png"), "--profile", "s20fe_night", "-o", str(matrix_dir), "--no-noise"]) == 0
    assert convert([str(tmp_path / "a.png"), "--profile", "s20fe_night", "-o", str(spectral_dir), "--no-noise",
                    "--colour", "spectral"]) == 0
    assert "estimated from 1 ColorMatrix" in capsys.readouterr().err
    matrix_info, spectral_info = (read_dng_info(d / "a.dng") for d in (matrix_dir, spectral_dir))
    # same seed, same sampled neutral: the spectrum's response is that neutral; colour tags unchanged
    np.testing.assert_allclose(spectral_info.as_shot_neutral, matrix_info.as_shot_neutral, rtol=1e-4)
    np.testing.assert_allclose(spectral_info.color_matrices[0], matrix_info.color_matrices[0])
    assert (spectral_dir / "a.dng").read_bytes() != (matrix_dir / "a.dng").read_bytes()


def test_fit_profile_stores_measured_sensitivities(tmp_path):
    wavelengths = np.arange(400, 701, 5)
    rows = ["wavelength,r,g,b"] + [f"{w},{np.exp(-((w - 600) / 40) ** 2)},{np.exp(-((w - 530) / 40) ** 2)},"
                                   f"{np.exp(-((w - 460) / 30) ** 2)}" for w in wavelengths]
    (tmp_path / "cam.csv").write_text("\n".join(rows))
    out = tmp_path / "p.json"
    assert fit_profile_cli(["--illuminants", "/dev/null", "--calibration", "profiles/Canon600D.json", "-o", str(out)]) != 0
    (tmp_path / "ill.csv").write_text("r_over_g,g,b_over_g\n0.5,1,0.6\n0.6,1,0.5\n0.45,1,0.7\n0.7,1,0.42\n")
    assert fit_profile_cli(["--illuminants", str(tmp_path / "ill.csv"), "--calibration", "profiles/Canon600D.json",
                            "--sensitivities", str(tmp_path / "cam.csv"), "-o", str(out)]) == 0
    document = json.loads(out.read_text())
    assert document["spectral"]["sensitivities_source"] == "CSV cam.csv"
    families = document["spectral"]["illuminant_families"]
    assert families[0] == "locus" and set(families[1:]) <= set(LAMP_FAMILIES)
    assert len(document["spectral"]["sensitivities"]) == 81
    assert load_profile(out).spectral is not None


def test_fit_profile_bad_sensitivity_file_is_one_line(tmp_path, capsys):
    (tmp_path / "bad.csv").write_text("wavelength,r,g,b\n400,1,1\n")
    (tmp_path / "ill.csv").write_text("r_over_g,g,b_over_g\n0.5,1,0.6\n0.6,1,0.5\n0.45,1,0.7\n")
    status = fit_profile_cli(["--illuminants", str(tmp_path / "ill.csv"), "--calibration", "profiles/Canon600D.json",
                              "--sensitivities", str(tmp_path / "bad.csv"), "-o", str(tmp_path / "p.json")])
    assert status == 2
    errors = [line for line in capsys.readouterr().err.strip().splitlines() if "error:" in line]
    assert len(errors) == 1 and "bad.csv: line 2: not four numbers" in errors[0]
    assert not (tmp_path / "p.json").exists()


@pytest.mark.data
@pytest.mark.slow
def test_fit_profile_night_set_gets_sodium_family(tmp_path, shared_data):
    out = tmp_path / "night.json"
    assert fit_profile_cli(["--illuminants", str(shared_data / "illuminants" / "s20fe_night_graycard_45.csv"),
                            "--calibration", "profiles/s20fe_night.json", "--sensitivities",
                            str(shared_data / "spectral/rawtoaces/camera/Canon_EOS_600D_380_780_5.json"),
                            "-o", str(out)]) == 0
    families = json.loads(out.read_text())["spectral"]["illuminant_families"]
    assert any(f.startswith("HP") for f in families)
