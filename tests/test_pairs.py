"""`g2r-convert --pairs` (issue 51): the pair each task trains on, consistent by construction.

For every shipped profile (content model on, as shipped): the clean DNG carries the noisy DNG's
light, exposure and tags and no noise, its pixels are `unprocess_batch(..., return_clean=True)`'s
bytes; developed through the DNG colour model (colour_hdri) at its AsShotNeutral it gives back the
scene target; the manifest's light is the DNG's AsShotNeutral."""

from __future__ import annotations

import json

import colour
import jax
import numpy as np
import pytest

pytest.importorskip("colour_hdri")
import conformance_colour as cc  # noqa: E402
from dng_reference import mean_delta_E_2000, patch_camera_rgb, patch_scene, render_patches_to_XYZ_D65  # noqa: E402

from g2r_jax.batch.conversion import file_keys  # noqa: E402
from g2r_jax.cli.convert import main as convert_main  # noqa: E402
from g2r_jax.colour import conversions as gc  # noqa: E402
from g2r_jax.io.dng_read import read_dng_info, read_dng_pixels  # noqa: E402
from g2r_jax.io.images import read_image  # noqa: E402
from g2r_jax.pipeline import unprocess_batch  # noqa: E402
from g2r_jax.profile.shipped import shipped_profiles  # noqa: E402
from g2r_jax.profile.schema import load_profile  # noqa: E402

# In the default run's long-lived test workers these tests crashed the worker inside JAX's persistent
# compilation-cache read (segmentation fault / abort in get_executable_and_time) in three of four
# full runs, a different test of this file each time; alone they pass. Until that is understood
# they run in the slow suite (`python -m pytest -m slow tests/test_pairs.py`), not silently.
pytestmark = pytest.mark.slow

SAME_TAGS = ("as_shot_neutral", "baseline_exposure", "black_level", "white_level", "cfa_pattern", "color_matrices",
             "calibration_illuminants", "forward_matrices", "analog_balance", "iso", "width", "height")


def _convert(folder, out, *flags):
    status = convert_main([str(folder), "-o", str(out), "--no-progress", "--quiet", "--pairs", *flags])
    assert status == 0
    return [json.loads(line) for line in (out / "manifest.jsonl").read_text().splitlines()]


def _box_means(image, boxes):
    return np.array([image[t:b, l:r].reshape(-1, 3).mean(0) for t, l, b, r in boxes])


@pytest.mark.parametrize("name", shipped_profiles())
def test_clean_dng_develops_to_the_scene_target(tmp_path, name):
    folder, codes, boxes = patch_scene(tmp_path)
    record, = _convert(folder, tmp_path / "out", "--profile", name)
    out = tmp_path / "out"
    noisy_path, clean_path = out / record["output"], out / record["pair"]["clean"]
    assert record["pair"] == {"clean": "patches.clean.dng", "scene": "patches.scene.png"}
    noisy, clean = read_dng_info(noisy_path), read_dng_info(clean_path)

    for tag in SAME_TAGS:
        assert np.array_equal(np.asarray(getattr(noisy, tag)), np.asarray(getattr(clean, tag))), tag
    assert clean.noise_profile is None
    np.testing.assert_allclose(np.asarray(record["illuminant_rgb"]) * 1.0,
                               noisy.as_shot_neutral / np.sum(noisy.as_shot_neutral), atol=1e-7)

    # the clean pixels are return_clean's bytes for the file's key; the noisy ones differ
    profile = load_profile(name)
    image = np.round(read_image(folder / "patches.png")[0] * 255).astype(np.uint8)[None]
    keys = file_keys(0, ["patches.png"])
    _, expected, _ = unprocess_batch(keys, image, profile, return_clean=True)
    clean_pixels, noisy_pixels = read_dng_pixels(clean_path, clean), read_dng_pixels(noisy_path, noisy)
    assert np.array_equal(clean_pixels, np.asarray(expected[0]))
    if noisy.noise_profile is not None:
        assert np.std(noisy_pixels.astype(float) - clean_pixels) > 0.1

    # Developed through the DNG colour model (colour_hdri) at the file's AsShotNeutral, the clean
    # mosaic gives back the scene target up to one exposure scale. Compared before the file's
    # rounding to integers: a flat patch of a noise-free file rounds every pixel alike, a bias of up
    # to half a DN that no model removes (a 10-bit night file keeps a few DN of blue in dark patches)
    _, unrounded, _ = unprocess_batch(keys, image, profile, return_clean=True, quantize=False)
    camera_rgb = _patch_camera_rgb(np.asarray(unrounded[0], np.float64), clean, boxes)
    np.testing.assert_allclose(patch_camera_rgb(clean_path, boxes), camera_rgb,
                               atol=0.5 / (clean.white_level - np.max(clean.black_level)))
    XYZ_out = _render_to_XYZ_D65(camera_rgb, clean)
    scene = colour.models.eotf_sRGB(read_image(out / record["pair"]["scene"])[0].astype(np.float64))
    XYZ_scene = _box_means(scene, boxes) @ np.asarray(gc.MATRIX_SRGB_TO_XYZ).T
    unclipped = (_box_means(scene, boxes).max(axis=1) < 0.95) & (camera_rgb.max(axis=1) < 0.95)
    assert unclipped.sum() >= 18
    delta_E, _ = mean_delta_E_2000(XYZ_out[unclipped], XYZ_scene[unclipped])
    assert delta_E <= 0.03, f"{name}: mean dE2000 {delta_E:.4f}"


# Adobe DNG SDK 1.6 (dng_illuminant_data, dng_xy_coord.h): the whites of the D55 and D75 codes
SDK_WHITES = {**cc.SDK_WHITE, 20: (0.3324, 0.3474), 22: (0.2990, 0.3149)}


def _render_to_XYZ_D65(camera_rgb, info):
    """A DNG renderer's XYZ: colour_hdri for one or two matrices, the restated SDK rules
    (`conformance_colour.Reference`) for three (colour_hdri has no third illuminant)."""
    if len(info.color_matrices) < 3:
        return render_patches_to_XYZ_D65(camera_rgb, info)
    codes = list(info.calibration_illuminants)
    reference = cc.Reference(codes, info.color_matrices, info.camera_calibrations, info.forward_matrices,
                             whites=[SDK_WHITES[c] for c in codes],
                             balance=(1, 1, 1) if info.analog_balance is None else info.analog_balance)
    return reference.render_to_XYZ_D65(camera_rgb, info.as_shot_neutral)


def _patch_camera_rgb(mosaic, info, boxes):
    """Mean camera RGB (black-subtracted, normalised) of a float mosaic inside each box."""
    height, width = mosaic.shape
    position = (np.arange(height)[:, None] % 2) * 2 + np.arange(width)[None] % 2
    black = np.broadcast_to(np.asarray(info.black_level, np.float64).reshape(-1), (4,))[position]
    normalised = (mosaic - black) / (info.white_level - black)
    colours = np.asarray(info.cfa_pattern)[position]
    return np.array([[normalised[t:b, l:r][colours[t:b, l:r] == c].mean() for c in range(3)]
                     for t, l, b, r in boxes])


def _scene_folder(tmp_path, names, size=(32, 48)):
    from PIL import Image

    folder = tmp_path / "renders"
    folder.mkdir(exist_ok=True)
    rng = np.random.default_rng(0)
    for name in names:
        Image.fromarray(rng.integers(0, 256, size + (3,), dtype=np.uint8)).save(folder / name)
    return folder


def test_developed_target_is_the_reference_developer_of_the_clean_dng(tmp_path):
    from g2r_jax.io.reference_render import develop

    folder = _scene_folder(tmp_path, ["a.png"])
    record, = _convert(folder, tmp_path / "out", "--profile", "NikonD40", "--developed")
    out = tmp_path / "out"
    assert record["pair"]["developed"] == "a.developed.png"
    developed = read_image(out / "a.developed.png")[0]
    expected = develop(out / "a.clean.dng")
    assert developed.shape == expected.shape == (32, 48, 3)
    assert np.max(np.abs(developed - expected)) <= 0.5 / 65535 + 1e-7


def test_linear_input_gets_a_linear_scene_target(tmp_path):
    import OpenEXR

    folder = tmp_path / "renders"
    folder.mkdir()
    linear = np.random.default_rng(1).random((16, 24, 3)).astype(np.float32) * 1.5
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with OpenEXR.File(header, {c: np.ascontiguousarray(linear[..., i]) for i, c in enumerate("RGB")}) as exr:
        exr.write(str(folder / "frame.exr"))
    record, = _convert(folder, tmp_path / "out", "--profile", "Canon600D")
    out = tmp_path / "out"
    assert record["pair"]["scene_linear"] == "frame.scene.exr"
    scene_linear = read_image(out / "frame.scene.exr")[0]
    profile = load_profile("Canon600D")
    _, scene, _ = unprocess_batch(file_keys(0, ["frame.exr"]), linear[None], profile, transfer="linear",
                                  return_scene=True)
    np.testing.assert_allclose(scene_linear, np.asarray(scene[0]), rtol=1e-6, atol=1e-7)
    assert not np.allclose(scene_linear, linear, atol=1e-3)      # the content model recoloured it
    srgb = read_image(out / "frame.scene.png")[0]
    np.testing.assert_allclose(srgb, colour.models.eotf_inverse_sRGB(np.clip(scene_linear, 0, 1)), atol=1e-4)


def test_adapted_scene_is_what_the_mosaic_holds():
    """return_scene: the content model's output (the input itself without a model)."""
    from g2r_jax.pipeline import decode, without_content

    profile = load_profile("Canon600D")
    image = np.random.default_rng(2).integers(0, 256, (1, 16, 16, 3), dtype=np.uint8)
    keys = file_keys(0, ["x.png"])
    mosaic, scene, _ = unprocess_batch(keys, image, profile, return_scene=True)
    assert np.array_equal(mosaic, unprocess_batch(keys, image, profile)[0])
    linear = np.asarray(decode(image[0], "srgb"))
    assert not np.allclose(scene[0], linear, atol=1e-3)
    _, plain, _ = unprocess_batch(keys, image, without_content(profile), return_scene=True)
    np.testing.assert_array_equal(plain[0], linear)


def _convert_in_a_process(*argv):
    """g2r-convert run as a user runs it, in its own process: (status, stderr)."""
    import subprocess
    import sys

    done = subprocess.run([sys.executable, "-m", "g2r_jax.cli.convert", *map(str, argv)], capture_output=True,
                          text=True, timeout=600)
    return done.returncode, done.stderr


def test_colliding_pair_names_are_refused_by_name_before_writing(tmp_path):
    folder = _scene_folder(tmp_path, ["a.png", "a.clean.png", "b.png"])
    status, err = _convert_in_a_process(folder, "--profile", "NikonD40", "-o", tmp_path / "out", "--pairs",
                                        "--no-progress")
    assert status == 1
    assert "a.clean.png" in err and "a.png" in err and "a.clean.dng" in err
    written = sorted(p.name for p in (tmp_path / "out").iterdir() if not p.name.startswith("."))
    assert written == ["b.clean.dng", "b.dng", "b.scene.png", "manifest.jsonl"]
    # writing into the input folder: a pair file that would overwrite an input is refused
    (folder / "a.clean.png").unlink()
    (folder / "b.scene.png").write_bytes((folder / "b.png").read_bytes())
    status, err = _convert_in_a_process(folder, "--profile", "NikonD40", "-o", folder, "--pairs", "--no-progress")
    assert status == 1
    assert "would overwrite the input" in err
    assert (folder / "b.scene.png").read_bytes() == (folder / "b.png").read_bytes()
    assert not (folder / "b.dng").exists() and (folder / "a.dng").exists()


def test_no_noise_writes_the_clean_dng_once_unless_banding_differs(tmp_path, capsys):
    from g2r_jax.profile.schema import replace, save_profile
    from g2r_jax.sensor.readout_stage import banding_effects

    folder = _scene_folder(tmp_path, ["a.png"])
    record, = _convert(folder, tmp_path / "quiet", "--profile", "NikonD40", "--no-noise")
    assert record["pair"]["clean"] == "a.dng" and not (tmp_path / "quiet" / "a.clean.dng").exists()
    status = convert_main([str(folder), "--profile", "NikonD40", "-o", str(tmp_path / "said"), "--pairs",
                           "--no-noise"])
    assert status == 0 and "its own clean target, written once" in capsys.readouterr().err
    # row/column banding is random too: the clean DNG differs and is written
    banded = tmp_path / "banded.json"
    save_profile(replace(load_profile("NikonD40"), effects=banding_effects(0.01, 0.01)), banded)
    record, = _convert(folder, tmp_path / "banded", "--profile", str(banded), "--no-noise")
    out = tmp_path / "banded"
    assert record["pair"]["clean"] == "a.clean.dng"
    clean = read_dng_pixels(out / "a.clean.dng", read_dng_info(out / "a.clean.dng"))
    noisy = read_dng_pixels(out / "a.dng", read_dng_info(out / "a.dng"))
    assert not np.array_equal(clean, noisy)


def test_a_second_run_lists_the_clean_dngs(tmp_path, capsys):
    folder = _scene_folder(tmp_path, ["a.png"])
    _convert(folder, tmp_path / "out", "--profile", "NikonD40")
    status = convert_main([str(folder), "--profile", "NikonD40", "-o", str(tmp_path / "out"), "--pairs",
                           "--no-progress"])
    assert status == 0 and "not listed in its manifest" not in capsys.readouterr().err


def test_the_guides_loader_reads_each_tasks_pair(tmp_path, monkeypatch):
    """The loader of docs/pages/guide/training_loop.md (its PyTorch part runs where torch is
    installed) gives the files' values: planes by colour, the light, the scene target."""
    import re
    from pathlib import Path

    from g2r_jax.downstream.isp.pairs import pack

    page = (Path(__file__).resolve().parents[1] / "docs/pages/guide/training_loop.md").read_text()
    block = next(b for b in re.findall(r"```python\n(.*?)\n```", page, re.S) if "def read_folder" in b)
    folder = _scene_folder(tmp_path, ["a.png", "b.png"])
    _convert(folder, tmp_path / "pairs", "--profile", "Canon600D")
    monkeypatch.chdir(tmp_path)
    namespace = {}
    exec(compile(block, "training_loop.md", "exec"), namespace)
    samples = namespace["samples"]
    assert len(samples) == 2
    info = read_dng_info(tmp_path / "pairs" / "a.clean.dng")
    expected = pack(read_dng_pixels(tmp_path / "pairs" / "a.clean.dng", info), info.cfa_pattern, info.black_level,
                    info.white_level)                              # R, G1, G2, B
    planes = samples[0]["clean"]                                   # R, G, B, G2
    np.testing.assert_allclose(planes[..., 0], expected[..., 0], atol=1e-6)
    np.testing.assert_allclose(planes[..., 2], expected[..., 3], atol=1e-6)
    np.testing.assert_allclose(np.sort([planes[..., 1].sum(), planes[..., 3].sum()]),
                               np.sort([expected[..., 1].sum(), expected[..., 2].sum()]), rtol=1e-6)
    np.testing.assert_allclose(samples[0]["light"], info.as_shot_neutral / info.as_shot_neutral.sum(), atol=1e-6)
    np.testing.assert_allclose(samples[0]["scene"], read_image(tmp_path / "pairs" / "a.scene.png")[0], atol=1e-6)
