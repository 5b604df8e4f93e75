"""The commands: example run, manifest, determinism, bad inputs (batch goes on, clear errors,
no partial outputs, inputs untouched), g2r-fit-profile on folders and illuminant lists."""

from __future__ import annotations

import hashlib
import json
import os
import shutil

import numpy as np
import pytest
import rawpy
from PIL import Image

from g2r_jax.cli.convert import main as convert
from g2r_jax.cli.fit_profile import main as fit_profile_cli
from g2r_jax.profile.schema import load_profile


def digest(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


def write_png(path, seed, shape=(24, 32)):
    Image.fromarray(np.random.default_rng(seed).integers(0, 256, shape + (3,), dtype=np.uint8)).save(path)


def write_exr(path, array):
    import OpenEXR

    channels = {name: np.ascontiguousarray(array[..., i].astype(np.float32)) for i, name in enumerate("RGB")}
    OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}, channels).write(str(path))


def test_example_writes_a_dng_rawpy_reads_with_the_profile_layout(tmp_path):
    assert convert(["--example", "-o", str(tmp_path), "--no-progress"]) == 0
    record = json.loads((tmp_path / "manifest.jsonl").read_text().splitlines()[0])
    assert set(record) >= {"input", "output", "neutral", "cct", "iso", "seed"}
    profile = load_profile("Canon600D")
    with rawpy.imread(str(tmp_path / record["output"])) as raw:   # manifest outputs: relative to its folder
        assert raw.raw_image_visible.shape == (480, 640)
        assert "".join("RGBG"[c] for c in raw.raw_pattern.reshape(-1)) == profile.cfa_string
        assert list(raw.black_level_per_channel) == [int(b) for b in np.asarray(profile.black_level)]
        assert raw.white_level == int(profile.white_level)
        wb = np.asarray(raw.camera_whitebalance[:3])
        np.testing.assert_allclose(wb / wb[1], 1 / np.asarray(record["neutral"]), rtol=1e-5)


@pytest.mark.parametrize("profile_name", ["s20fe_night", "gopro_hero6"])
def test_every_bayer_layout_reads_back_with_its_pattern(tmp_path, profile_name):
    folder = tmp_path / "in"
    folder.mkdir()
    write_png(folder / "a.png", 0)
    assert convert([str(folder), "--profile", profile_name, "-o", str(tmp_path / "out"), "--no-progress"]) == 0
    profile = load_profile(profile_name)
    with rawpy.imread(str(tmp_path / "out" / "a.dng")) as raw:
        colours = raw.raw_colors_visible[:2, :2].reshape(-1)
        letters = "".join("RGBG"[c] for c in colours)
        assert letters == profile.cfa_string


def test_same_seed_same_bytes_whatever_the_order_and_batch_size(tmp_path):
    folder = tmp_path / "in"
    folder.mkdir()
    for i in range(5):
        write_png(folder / f"img{i}.png", i)
    out_a, out_b = tmp_path / "a", tmp_path / "b"
    files = sorted(folder.iterdir())
    assert convert([str(folder), "--profile", "s20fe_night", "-o", str(out_a), "--seed", "7", "--no-progress"]) == 0
    assert convert([*map(str, reversed(files)), "--profile", "s20fe_night", "-o", str(out_b), "--seed", "7",
                    "--batch-size", "3", "--no-progress"]) == 0
    for f in files:
        assert digest(out_a / f"{f.stem}.dng") == digest(out_b / f"{f.stem}.dng")
    out_c = tmp_path / "c"
    assert convert([str(files[0]), "--profile", "s20fe_night", "-o", str(out_c), "--seed", "8", "--no-progress"]) == 0
    assert digest(out_c / f"{files[0].stem}.dng") != digest(out_a / f"{files[0].stem}.dng")


def test_illuminant_csv_rows_follow_sorted_input_order(tmp_path):
    folder = tmp_path / "in"
    folder.mkdir()
    for name in ("b", "a", "c"):
        write_png(folder / f"{name}.png", 1)
    csv = tmp_path / "ill.csv"
    csv.write_text("r_over_g,g,b_over_g\n0.5,1,0.7\n0.6,1,0.6\n0.9,1,0.3\n")
    assert convert([str(folder), "--profile", "s20fe_night", "-o", str(tmp_path / "out"), "--illuminants", str(csv),
                    "--no-progress"]) == 0
    records = {json.loads(l)["input"].split("/")[-1]: json.loads(l) for l in (tmp_path / "out" / "manifest.jsonl").read_text().splitlines()}
    np.testing.assert_allclose(records["a.png"]["neutral"], [0.5, 1, 0.7], rtol=1e-6)
    np.testing.assert_allclose(records["c.png"]["neutral"], [0.9, 1, 0.3], rtol=1e-6)


def test_bad_inputs_are_reported_and_the_batch_goes_on(tmp_path, capsys):
    folder = tmp_path / "in"
    folder.mkdir()
    write_png(folder / "good.png", 3)
    (folder / "text.png").write_text("this is not an image")
    good_bytes = (folder / "good.png").read_bytes()
    (folder / "truncated.png").write_bytes(good_bytes[: len(good_bytes) // 2])
    write_png(folder / "odd.png", 4, shape=(25, 32))
    hdr = np.full((8, 8, 3), 0.5, np.float32)
    hdr[0, 0, 0] = np.nan
    write_exr(folder / "nan.exr", hdr)
    hdr = np.full((8, 8, 3), 0.5, np.float32)
    hdr[1, 1, 1] = -0.2
    write_exr(folder / "negative.exr", hdr)
    write_exr(folder / "fine.exr", np.full((8, 8, 3), 0.25, np.float32))
    before = {p.name: digest(p) for p in folder.iterdir()}
    empty = tmp_path / "empty"
    empty.mkdir()
    out = tmp_path / "out"
    status = convert([str(folder), str(empty), "--profile", "s20fe_night", "-o", str(out), "--no-progress"])
    err = capsys.readouterr().err
    assert status == 1
    assert sorted(p.name for p in out.iterdir() if p.name != ".g2r.lock") == ["fine.dng", "good.dng", "manifest.jsonl"]
    for name in ("text.png", "truncated.png", "odd.png", "nan.exr", "negative.exr"):
        lines = [l for l in err.splitlines() if name in l]
        assert len(lines) == 1, (name, err)
    assert str(empty) in err
    assert "Traceback" not in err
    assert {p.name: digest(p) for p in folder.iterdir()} == before


def test_unknown_profile_is_one_line_and_debug_shows_the_traceback(tmp_path, capsys):
    assert convert(["--example", "--profile", "nikon_d1x", "-o", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "nikon_d1x" in err[0] and "unknown profile" in err[0]
    broken = tmp_path / "broken.json"
    broken.write_text("{")
    with pytest.raises(Exception, match="broken.json: not valid JSON"):
        convert(["--example", "--profile", str(broken), "-o", str(tmp_path / "out"), "--debug"])


def test_fit_profile_from_a_folder_reports_bad_files_and_fits_the_good_ones(tmp_path, shared_data, capsys):
    folder = tmp_path / "dngs"
    folder.mkdir()
    shutil.copy(shared_data / "dng" / "gopro_hero6_GOPR0024.dng", folder / "gopro.dng")
    shutil.copy(shared_data / "dng" / "canon_350d_header_only.dng", folder / "canon350d.dng")
    shutil.copy(shared_data / "dng" / "canon_eos_6d_linear_raw.dng", folder / "linear.dng")
    (folder / "notes.dng").write_text("not a dng")
    out = tmp_path / "p.json"
    status = fit_profile_cli([str(folder), "-o", str(out)])
    err = capsys.readouterr().err
    assert status == 1
    assert "linear.dng" in err and "notes.dng" in err and "Traceback" not in err
    profile = load_profile(out)
    assert profile.info.calibration_illuminants in ((3, 23), (17, 21))


def test_fit_profile_from_gopro_dng_keeps_its_tags(tmp_path, shared_data):
    out = tmp_path / "gopro.json"
    assert fit_profile_cli([str(shared_data / "dng" / "gopro_hero6_GOPR0024.dng"), "-o", str(out)]) == 0
    profile = load_profile(out)
    assert profile.info.calibration_illuminants == (3, 23)
    assert profile.cfa_string == "RGGB" and float(profile.white_level) == 16383
    assert "pooled (auto, 1 measured light" in profile.info.provenance   # one DNG: the pooled lights (issue 33)
    assert float(np.max(profile.noise.shot)) > 0


def test_fit_profile_from_illuminant_list_and_noise_table(tmp_path, shared_data):
    out = tmp_path / "night.json"
    status = fit_profile_cli(["--illuminants", str(shared_data / "illuminants" / "s20fe_night_graycard_45.csv"),
                              "--calibration", "profiles/s20fe_night.json", "--illuminant-model", "gaussian",
                              "--noise-table", str(shared_data / "noise" / "s20fe_heteroscedastic_gaussian.csv"),
                              "-o", str(out)])
    assert status == 0
    profile = load_profile(out)
    assert profile.illuminants.kind == "gaussian"
    np.testing.assert_allclose(np.asarray(profile.noise.iso), [100, 200, 400, 800, 1600, 3200])


def test_lens_shading_option_divides_by_the_written_opcode_gain(tmp_path, capsys):
    from g2r_jax.io.dng_read import read_dng_info
    from g2r_jax.sensor.shading import shading_gain_planes
    from g2r_jax.sensor import to_planes

    folder = tmp_path / "in"
    folder.mkdir()
    Image.fromarray(np.full((64, 96, 3), 150, np.uint8)).save(folder / "flat.png")
    common = [str(folder), "--profile", "gopro_hero6", "--no-noise", "--seed", "1", "--no-progress"]
    assert convert(common + ["-o", str(tmp_path / "plain")]) == 0
    assert convert(common + ["-o", str(tmp_path / "shaded"), "--lens-shading"]) == 0
    plain = rawpy.imread(str(tmp_path / "plain" / "flat.dng")).raw_image.astype(float)
    shaded = rawpy.imread(str(tmp_path / "shaded" / "flat.dng")).raw_image.astype(float)
    info = read_dng_info(tmp_path / "shaded" / "flat.dng")
    assert "OpcodeList2" in info.opcode_lists and "OpcodeList2" not in read_dng_info(tmp_path / "plain" / "flat.dng").opcode_lists
    gain = shading_gain_planes(info.opcode_lists, 64, 96, info.cfa_pattern)
    black = float(info.black_level[0])
    restored = np.asarray(to_planes(shaded - black)) * gain
    np.testing.assert_allclose(restored, np.asarray(to_planes(plain - black)), atol=1.5)
    assert gain.max() > 1.5  # the corners really were darkened
    assert convert(common + ["-o", str(tmp_path / "x"), "--lens-shading", "--profile", "Canon600D"]) == 2
    assert "no lens-shading opcodes" in capsys.readouterr().err


def test_commands_request_deterministic_gpu_ops_and_keep_a_user_choice(monkeypatch):
    from g2r_jax.runtime import deterministic

    monkeypatch.setenv("XLA_FLAGS", "--xla_dump_to=/tmp/x")
    assert deterministic.request_deterministic_gpu_ops()
    assert os.environ["XLA_FLAGS"] == "--xla_dump_to=/tmp/x --xla_gpu_deterministic_ops=true"
    monkeypatch.setenv("XLA_FLAGS", "--xla_gpu_deterministic_ops=false")
    assert not deterministic.request_deterministic_gpu_ops()
    assert os.environ["XLA_FLAGS"] == "--xla_gpu_deterministic_ops=false"
