"""g2r-downstream: a user's check of what training on g2r_jax RAW of their CG images gives on their
real DNGs; refuses bad input by name and leaves nothing half-written."""

from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image

import g2r_jax
from g2r_jax.cli import downstream


@pytest.fixture(scope="module")
def camera_folders(tmp_path_factory):
    """14 DNGs of a NikonD40 (dead-leaves scenes under drawn lights), 4 CG PNGs, one broken file each."""
    from g2r_jax.audit import scenes, simulate
    from g2r_jax.io.dng_write import write_dng

    root = tmp_path_factory.mktemp("downstream")
    dngs, cg = root / "dngs", root / "cg"
    dngs.mkdir()
    cg.mkdir()
    profile = g2r_jax.load_profile("NikonD40")
    for i, (mosaic, info) in enumerate(simulate.simulate(profile, scenes.scene_set(14, 3, 144, 192), 1)):
        write_dng(dngs / f"real_{i:02d}.dng", mosaic, info)
    (dngs / "zz_truncated.dng").write_bytes((dngs / "real_00.dng").read_bytes()[:2000])
    for i, scene in enumerate(scenes.scene_set(4, 9, 160, 224)):
        Image.fromarray((np.clip(scene, 0, 1) * 255).round().astype(np.uint8) if scene.dtype != np.uint8 else scene).save(cg / f"render_{i}.png")
    (cg / "tiny.png").write_bytes(b"\x89PNG\r\n\x1a\nnot really")
    return dngs, cg


def run(capsys, *argv):
    status = downstream.main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return status, out, err


def test_argument_errors_are_named_before_any_work(tmp_path, capsys):
    status, _, err = run(capsys, "--measured", tmp_path / "missing", "--cg", tmp_path, "--report", tmp_path / "r")
    assert status == 2 and "--measured" in err and "missing" in err
    status, _, err = run(capsys, "--measured", tmp_path, "--cg", tmp_path, "--report", tmp_path / "r",
                         "--estimators", "cnn,oracle")
    assert status == 2 and "--estimators cnn,oracle" in err
    assert not (tmp_path / "r").exists()


def test_too_few_real_files_is_refused_with_the_folder_named(camera_folders, tmp_path, capsys):
    dngs, cg = camera_folders
    few = tmp_path / "few"
    few.mkdir()
    for path in sorted(dngs.glob("real_0[0-4].dng")):
        (few / path.name).write_bytes(path.read_bytes())
    status, _, err = run(capsys, "--measured", few, "--cg", cg, "--report", tmp_path / "r", "--quiet")
    assert status == 2 and str(few) in err and "5 usable DNG file(s)" in err
    assert not (tmp_path / "r" / "report.json").exists()


def test_check_runs_names_bad_files_and_writes_the_report(camera_folders, tmp_path, capsys):
    dngs, cg = camera_folders
    report = tmp_path / "report"
    status, out, err = run(capsys, "--measured", dngs, "--cg", cg, "--report", report, "--profile", "NikonD40",
                           "--estimators", "moments", "--seeds", 1, "--n", 64, "--folds", 2, "--quiet")
    assert status == 1                                              # two files left out, both named
    assert "zz_truncated.dng" in err and "tiny.png" in err
    assert "errs" in out and "UPI" in out and "trained on the real files" in out
    document = json.loads((report / "report.json").read_text())
    assert document["label"].startswith("AsShotNeutral")
    assert {p["path"].rsplit("/", 1)[-1] for p in document["problems"]} == {"zz_truncated.dng", "tiny.png"}
    summary = document["summary"]
    for row in ("upi", "fitted", "real", "real_profile_light", "shipped"):
        assert np.isfinite(summary[f"{row}/moments"]["mean"])
    # the real files' own labels, cross-validated, are learned better than chance
    assert summary["real/moments"]["mean"] < 10
    assert document["content"] and "excess" in document["content"][0]
    assert "| row |" in (report / "report.md").read_text()
    assert not list(report.glob("*.tmp"))


@pytest.mark.slow
def test_burst_check_adds_denoising_and_names_a_frame_it_cannot_use(camera_folders, tmp_path, capsys):
    from g2r_jax.downstream.bursts import write_synthetic_burst

    dngs, cg = camera_folders
    burst = tmp_path / "burst"
    burst.mkdir()
    write_synthetic_burst(burst, g2r_jax.load_profile("NikonD40"), n_frames=4, height=128, width=160)
    (burst / "frame_zz.dng").write_bytes(b"II*\x00broken")
    report = tmp_path / "report"
    status, out, err = run(capsys, "--measured", dngs, "--cg", cg, "--report", report, "--profile", "NikonD40",
                           "--burst", burst, "--denoiser-steps", 20, "--estimators", "moments", "--seeds", 1,
                           "--n", 64, "--folds", 2, "--quiet")
    assert status == 1 and "frame_zz.dng" in err
    document = json.loads((report / "report.json").read_text())
    psnr = document["denoising"]["psnr"]
    assert {"shipped/cg", "upi/cg", "real/scene", "truth/scene"} <= set(psnr)
    assert all(np.isfinite(v).all() for v in psnr.values())
    assert "Denoising on the burst" in (report / "report.md").read_text()


def test_a_burst_too_short_is_refused_before_training(camera_folders, tmp_path, capsys):
    from g2r_jax.downstream.bursts import write_synthetic_burst

    dngs, cg = camera_folders
    burst = tmp_path / "burst"
    burst.mkdir()
    write_synthetic_burst(burst, g2r_jax.load_profile("NikonD40"), n_frames=2, height=128, width=160)
    status, _, err = run(capsys, "--measured", dngs, "--cg", cg, "--report", tmp_path / "r", "--burst", burst,
                         "--quiet")
    assert status == 2 and str(burst) in err
    assert not (tmp_path / "r" / "report.json").exists()
