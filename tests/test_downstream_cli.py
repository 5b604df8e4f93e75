"""g2r-downstream: a user's check of what training on g2r_jax RAW of their CG images gives on their
real DNGs; refuses bad input by name and leaves nothing half-written."""

from __future__ import annotations

import json

import numpy as np
import pytest
from downstream_helpers import write_camera_folders
from PIL import Image

import g2r_jax
from g2r_jax.cli import downstream


@pytest.fixture(scope="module")
def camera_folders(tmp_path_factory):
    """14 DNGs of a NikonD40 (dead-leaves scenes under drawn lights), 4 CG PNGs, one broken file each."""
    dngs, cg = write_camera_folders(tmp_path_factory.mktemp("downstream"), 14, 4)
    (dngs / "zz_truncated.dng").write_bytes((dngs / "real_00.dng").read_bytes()[:2000])
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


class _Recorder:
    """A progress receiver like `downstream.base.progress.Progress`: keeps the lines, the planned and the done units."""

    def __init__(self):
        self.lines, self.planned, self.done, self.doing = [], 0, 0, []

    def __call__(self, line):
        self.lines.append(line)

    def plan(self, units):
        self.planned += units

    def advance(self, units=1, doing=""):
        self.done += units
        self.doing.append(doing)


def test_the_default_check_measures_the_product_and_plans_every_training(camera_folders):
    """Without a profile, the g2r_jax row is the profile g2r-fit-profile makes (lights and a content
    model fitted on the training folds only), the model-free row a control, and the sentence says
    both; the progress receives as many units as it was told to expect (its time left is right)."""
    from g2r_jax.downstream import run_check
    from g2r_jax.downstream.illuminant import experiment

    dngs, cg = camera_folders
    progress = _Recorder()
    result = run_check([dngs], [cg], estimators=("moments",), seeds=1, n=64, folds=2, progress=progress)
    assert {"fitted", "fitted_no_content", "single"} <= set(result.result.rows) and "shipped" not in result.result.rows
    assert progress.planned == progress.done == experiment.trainings(result.result.rows, ("moments",), (0,), 2)
    assert any("fold 2, fitted_no_content, moments" in d for d in progress.doing)
    assert sum("content model of the g2r_jax rows, seed 0, fold" in n for n in result.result.notes) == 2
    sentence = result.sentences[0]
    assert "as g2r-fit-profile makes it" in sentence and "the content model" in sentence
    assert "without it" in sentence and result.document["decomposition"]["moments"]["content_model"] is not None


def test_the_progress_bar_shows_the_time_left(capsys):
    import io

    from g2r_jax.downstream.base.progress import Progress

    stream = io.StringIO()
    lines = []
    with Progress(lines.append, stream=stream, desc="check") as progress:
        progress.plan(4)
        progress.advance(1, "fold 1")
        progress("a line")
        progress.advance(3)
    assert lines == ["a line"] and "left" in stream.getvalue() and "trainings" in stream.getvalue()


@pytest.mark.slow
def test_burst_check_adds_denoising_and_names_a_frame_it_cannot_use(camera_folders, tmp_path, capsys):
    from g2r_jax.downstream.denoising.bursts import write_synthetic_burst

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
    from g2r_jax.downstream.denoising.bursts import write_synthetic_burst

    dngs, cg = camera_folders
    burst = tmp_path / "burst"
    burst.mkdir()
    write_synthetic_burst(burst, g2r_jax.load_profile("NikonD40"), n_frames=2, height=128, width=160)
    status, _, err = run(capsys, "--measured", dngs, "--cg", cg, "--report", tmp_path / "r", "--burst", burst,
                         "--quiet")
    assert status == 2 and str(burst) in err
    assert not (tmp_path / "r" / "report.json").exists()


# ----------------------------------------------------------------------------- issue 34's fuzz classes

def _copy_folder(source, target, names=None):
    target.mkdir()
    for path in sorted(source.glob("real_*.dng")):
        if names is None or path.name in names:
            (target / path.name).write_bytes(path.read_bytes())
    return target


def test_report_folder_and_ranges_are_refused_up_front_by_option(camera_folders, tmp_path, capsys, monkeypatch):
    dngs, cg = camera_folders
    common = ["--measured", dngs, "--cg", cg, "--quiet"]
    monkeypatch.chdir(tmp_path)
    status, _, err = run(capsys, *common, "--report", "")
    assert status == 2 and "--report ''" in err and not list(tmp_path.iterdir())
    for report, word in ((dngs, "is the input folder --measured"), (cg / "sub", "inside the input folder --cg")):
        status, _, err = run(capsys, *common, "--report", report)
        assert status == 2 and word in err and not (cg / "sub").exists()
    status, _, err = run(capsys, *common, "--report", "/proc/g2r_probe/x")
    assert status == 2 and "--report /proc/g2r_probe/x" in err
    status, _, err = run(capsys, *common, "--report", tmp_path / ("n" * 300))      # found by the fuzz campaign
    assert status == 2 and "--report: cannot use the path (File name too long)" in err
    status, _, err = run(capsys, "--burst", tmp_path / ("n" * 300), "--report", tmp_path / "r")
    assert status == 2 and "--burst: cannot use the path" in err
    status, _, err = run(capsys, *common, "--report", tmp_path / "r", "--seeds", 10 ** 30)
    assert status == 2 and "--seeds" in err and "from 1 to 100" in err and "ssize_t" not in err
    status, _, err = run(capsys, "--cg", cg, "--report", tmp_path / "r")
    assert status == 2 and "--burst" in err and "--measured" in err
    status, _, err = run(capsys, "--measured", dngs, "--report", tmp_path / "r")
    assert status == 2 and "--measured needs --cg" in err
    assert not (tmp_path / "r").exists()


def test_probe_leaves_no_folder_behind(camera_folders, tmp_path, capsys):
    dngs, cg = camera_folders
    deep = tmp_path / "a" / "b" / "report"
    status, out, _ = run(capsys, "--measured", dngs, "--cg", cg, "--report", deep, "--dry-run", "--quiet")
    assert status == 1 and "dry run" in out and not (tmp_path / "a").exists()     # a dry run writes nothing
    from g2r_jax.cli.downstream import _parser, report_folder_problem

    args = _parser().parse_args(["--measured", str(dngs), "--cg", str(cg), "--report", str(deep)])
    assert report_folder_problem(args) is None and not (tmp_path / "a").exists()


def test_duplicates_are_read_once_or_kept_in_one_fold_and_named(camera_folders, tmp_path, capsys):
    dngs, cg = camera_folders
    copies = _copy_folder(dngs, tmp_path / "copies")
    (copies / "copy_of_03.dng").write_bytes((dngs / "real_03.dng").read_bytes())
    (copies / "copy_of_07.dng").write_bytes((dngs / "real_07.dng").read_bytes())
    status, out, err = run(capsys, "--measured", copies, copies, "--cg", cg, "--report", tmp_path / "r", "--dry-run",
                           "--quiet")
    assert status == 1 and "16 real DNG(s)" in out                  # the folder given twice: each file once
    assert err.count(": error: ") == 1 and "tiny.png" in err        # only the fixture's broken CG image left out
    assert "copy_of_03.dng" in err and "real_03.dng" in err and "one fold" in err
    from g2r_jax.downstream import read_inputs
    from g2r_jax.measure import folds_of

    real = read_inputs([copies], folds=2).real
    names = [f.rsplit("/", 1)[-1] for f in real.files]
    groups = real.groups
    assert groups[names.index("copy_of_03.dng")] == groups[names.index("real_03.dng")]
    assert len(set(groups)) == 14
    for fold in folds_of(len(groups), 3, 0, groups=groups):
        assert all(set(np.flatnonzero(groups == groups[i])) <= set(fold) for i in fold)


def test_experiment_never_tests_a_file_on_its_own_copy(monkeypatch):
    """A 1-nearest-neighbour 'estimator' remembers its training images: were a copy on the other
    side of a split, its error would be 0 (the issue's real-training row 4.60 -> 1.30 deg)."""
    from g2r_jax.downstream.base import real_sets
    from g2r_jax.downstream.illuminant import estimators, experiment
    from g2r_jax.measure import duplicate_groups

    rng = np.random.default_rng(0)
    images = rng.random((12, 64, 64, 3)).astype(np.float32)
    lights = rng.uniform(0.2, 0.5, (12, 3))
    images[6:], lights[6:] = images[:6], lights[:6]               # every file twice
    real = real_sets.RealSet("twice", images, lights / lights.sum(1, keepdims=True), groups=duplicate_groups(images))

    def nearest(name, train_images, train_lights, seed=0):
        flat = train_images.reshape(len(train_images), -1)
        return lambda test: train_lights[np.argmin(((test.reshape(len(test), 1, -1) - flat) ** 2).sum(-1), axis=1)]

    monkeypatch.setattr(estimators, "train_estimator", nearest)
    result = experiment.illuminant_experiment(real, g2r_jax.load_profile("NikonD40"), [images[0]], rows=("real",),
                                              estimators=("moments",), seeds=(0,), n=50, folds=3)
    assert result.errors[("real", "moments")][0].min() > 0.5


def _write(folder, name, mosaic, info):
    from g2r_jax.io.dng_write import write_dng

    write_dng(folder / name, mosaic, info)


def test_a_file_with_other_calibration_tags_or_constant_pixels_is_left_out_by_name(camera_folders, tmp_path, capsys):
    import dataclasses

    from g2r_jax.io.dng_read import read_dng_info, read_dng_pixels

    dngs, cg = camera_folders
    folder = _copy_folder(dngs, tmp_path / "mixed")
    info = read_dng_info(dngs / "real_00.dng")
    mosaic = read_dng_pixels(dngs / "real_00.dng", info)
    other = (23, 10) if sorted(info.calibration_illuminants) != [10, 23] else (17, 21)
    _write(folder, "zz_other_calibration.dng", np.roll(mosaic, 2, axis=1),   # another scene, same CFA phase
           dataclasses.replace(info, calibration_illuminants=other))
    _write(folder, "zz_constant.dng", np.full_like(mosaic, 700), info)
    status, out, err = run(capsys, "--measured", folder, "--cg", cg, "--report", tmp_path / "r", "--dry-run",
                           "--profile", "NikonD40", "--quiet")
    assert status == 1 and "14 real DNG(s)" in out
    assert "zz_constant.dng" in err and "every pixel reads 700" in err
    lines = [line for line in err.splitlines() if "zz_other_calibration.dng" in line]
    assert lines and "calibration illuminants" in lines[0]


def test_labels_of_one_light_are_refused_by_folder_with_what_is_needed(camera_folders, tmp_path, capsys):
    import dataclasses

    from g2r_jax.io.dng_read import read_dng_info, read_dng_pixels

    dngs, cg = camera_folders
    folder = tmp_path / "one_light"
    folder.mkdir()
    neutral = read_dng_info(dngs / "real_00.dng").as_shot_neutral
    for path in sorted(dngs.glob("real_*.dng")):
        info = read_dng_info(path)
        _write(folder, path.name, read_dng_pixels(path, info), dataclasses.replace(info, as_shot_neutral=neutral))
    status, _, err = run(capsys, "--measured", folder, "--cg", cg, "--report", tmp_path / "r", "--quiet")
    assert status == 2 and str(folder) in err and "1 distinct light" in err and "at least 3" in err
    assert not (tmp_path / "r").exists()


def test_burst_alone_needs_no_colour_set_and_oversized_cg_names_the_option(camera_folders, tmp_path, capsys):
    from g2r_jax.downstream.denoising.bursts import write_synthetic_burst

    dngs, cg = camera_folders
    burst = tmp_path / "burst"
    burst.mkdir()
    write_synthetic_burst(burst, g2r_jax.load_profile("NikonD40"), n_frames=4, height=128, width=160)
    status, out, _ = run(capsys, "--burst", burst, "--report", tmp_path / "r", "--dry-run", "--quiet")
    assert status == 0 and "a burst of 4 frames" in out
    status, _, err = run(capsys, "--measured", dngs, "--cg", cg, "--report", tmp_path / "r", "--dry-run", "--quiet",
                         "--max-megapixels", 0.01)
    assert status == 2 and "over the budget" in err and "--max-megapixels" in err   # every CG image refused
    assert "render_0.png" in err


def test_the_commands_page_lists_every_option():
    from pathlib import Path

    page = (Path(__file__).resolve().parents[1] / "docs" / "pages" / "commands.md").read_text()
    section = page.split("\n## g2r-downstream\n", 1)[1].split("\n## ", 1)[0]
    for action in downstream._parser()._actions:
        if action.help != "==SUPPRESS==":
            for option in action.option_strings:
                assert option in section, f"docs/pages/commands.md: g2r-downstream {option} missing (paste its --help)"


def test_a_registered_row_is_trained_and_reported_like_the_others(monkeypatch):
    """The place for extra training sets (e.g. with and without a content model)."""
    from g2r_jax.downstream.base import real_sets
    from g2r_jax.downstream.illuminant import estimators, experiment, reporting

    rng = np.random.default_rng(1)
    images = rng.random((8, 64, 64, 3)).astype(np.float32)
    lights = rng.uniform(0.2, 0.5, (8, 3))
    real = real_sets.RealSet("eight", images, lights / lights.sum(1, keepdims=True))
    calls = []

    def builder(sets, train, fold, seed):
        calls.append((tuple(train), fold, seed))
        return sets.real.images[train], sets.real.illuminants[train]

    monkeypatch.setattr(estimators, "train_estimator",
                        lambda name, x, y, seed=0: (lambda test: np.tile(y.mean(0), (len(test), 1))))
    try:
        experiment.register_row("mirror", "mirror of the real files", builder)
        with pytest.raises(ValueError, match="exists"):
            experiment.register_row("real", "again", builder)
        result = experiment.illuminant_experiment(real, g2r_jax.load_profile("NikonD40"), [images[0]],
                                                  rows=("real", "mirror"), estimators=("moments",), seeds=(0,), n=50,
                                                  folds=2)
        table = reporting.table(result)
    finally:
        experiment.ROWS.pop("mirror", None)
        experiment.EXTRA_ROWS.pop("mirror", None)
    assert len(calls) == 2 and "mirror of the real files" in table
    np.testing.assert_allclose(result.errors[("mirror", "moments")][0], result.errors[("real", "moments")][0])


def test_arguments_are_checked_before_jax_is_imported():
    import subprocess
    import sys

    from g2r_jax.downstream.illuminant.estimators import ESTIMATORS

    assert downstream.ESTIMATOR_NAMES == ESTIMATORS
    code = ("import sys; from g2r_jax.cli.downstream import main; "
            "status = main(['--burst', '/nonexistent', '--report', '/tmp/x']); print(status, 'jax' in sys.modules)")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert result.stdout.split() == ["2", "False"] and "--burst /nonexistent" in result.stderr


def test_the_isp_task_runs_on_the_real_dngs_with_its_rows_sentence_and_figure(camera_folders, tmp_path, capsys,
                                                                             monkeypatch):
    """`g2r-downstream --tasks isp`: the neural ISP on the same real DNGs (a short training here),
    its rows in report.json, its sentence printed and in report.md, and isp.png beside them."""
    import functools

    from g2r_jax.downstream.isp import task
    from g2r_jax.downstream.isp.net import IspTraining

    monkeypatch.setattr(task, "run_isp_task", functools.partial(task.run_isp_task, n=24,
                                                                training=IspTraining(steps=20, steps_per_round=10)))
    dngs, cg = camera_folders
    report = tmp_path / "report"
    status, out, err = run(capsys, "--measured", dngs, "--cg", cg, "--report", report, "--tasks", "isp",
                           "--seeds", 1, "--folds", 2, "--quiet")
    assert status == 1 and "zz_truncated.dng" in err                # the broken file is still named
    document = json.loads((report / "report.json").read_text())
    assert set(document["isp"]["rows"]) == {"upi", "fitted", "fitted_no_content", "single", "real",
                                            "real_profile_light"}
    for row in document["isp"]["rows"]:
        assert np.isfinite(document["isp"]["summary"][f"{row}/psnr"]["mean"]), row
    assert "summary" not in document                                 # no colour check was asked for
    assert "Result:" in out and "dB" in out
    markdown = (report / "report.md").read_text()
    assert "## Neural ISP" in markdown and "after best gains" in markdown      # where the colour error lies
    assert np.isfinite(document["isp"]["summary"]["fitted/delta_e_balance"]["mean"])
    assert (report / "isp.png").stat().st_size > 0 or not _has_matplotlib()


def test_an_unknown_task_is_refused_by_name(tmp_path, capsys):
    status, _, err = run(capsys, "--measured", tmp_path, "--cg", tmp_path, "--report", tmp_path / "r", "--tasks",
                         "colour,denoise")
    assert status == 2 and "--tasks colour,denoise" in err


def _has_matplotlib() -> bool:
    import importlib.util

    return importlib.util.find_spec("matplotlib") is not None
