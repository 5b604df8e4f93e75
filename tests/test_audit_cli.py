"""g2r-diagnose end to end on DNG files written to disk, report format, and one-line errors."""

from __future__ import annotations

import json

import pytest

from g2r_jax.audit import CAUSES, synthetic
from g2r_jax.cli.diagnose import main
from g2r_jax.io.dng_write import write_dng
from g2r_jax.profile.schema import save_profile
from audit_helpers import dark_frames, measured_set


@pytest.fixture(scope="module")
def camera(tmp_path_factory):
    """A folder of 16 small DNGs and 3 dark frames from the demo camera with a black pedestal, and
    its clean profile."""
    root = tmp_path_factory.mktemp("camera")
    base = synthetic.demo_profile()
    truth = synthetic.inject(base, "black_level", offset=0.02)
    folder = root / "dng"
    folder.mkdir()
    files = measured_set(truth, 5, n=16, height=120, width=180) + dark_frames(truth, 5, n=3, height=120, width=180)
    for i, (mosaic, info) in enumerate(files):
        write_dng(folder / f"IMG_{i:03d}.dng", mosaic, info)
    save_profile(base, root / "profile.json")
    return root


def test_cli_writes_report_and_extended_profile(camera, capsys):
    report_path = camera / "REPORT.json"
    status = main(["--profile", str(camera / "profile.json"), "--measured", str(camera / "dng"),
                   "--report", str(report_path), "--extended-profile", str(camera / "extended.json"),
                   "--seed", "3", "--quiet"])
    assert status == 0
    report = json.loads(report_path.read_text())
    assert {"findings", "unexplained"} <= set(report)
    for finding in report["findings"]:
        assert finding["cause"] in CAUSES + ("unexplained",)
        assert {"cause", "significant", "score", "statistic", "evidence", "params", "gain"} <= set(finding)
    scores = [f["score"] for f in report["findings"] if f["significant"]]
    assert scores == sorted(scores, reverse=True)
    first = report["findings"][0]
    assert first["cause"] == "black_level" and first["significant"]
    assert first["gain"]["heldout"] is True and first["gain"]["after"] < first["gain"]["before"]
    extended = json.loads((camera / "extended.json").read_text())
    assert extended["effects"]["black_pedestal"][0] == pytest.approx(0.02 * (4095 - 256), rel=0.15)
    out = capsys.readouterr().out
    assert "black_level" in out and "3 dark frame(s)" in out
    assert f"report: {report_path}" in out and str(camera / "REPORT_html" / "report.html") in out
    assert (camera / "REPORT_html" / "report.html").exists()
    assert " nan" not in out and "p 0" not in out


def test_cli_writes_the_extended_profile_by_default(camera, capsys, tmp_path):
    report_path = tmp_path / "REPORT.json"
    assert main(["--profile", str(camera / "profile.json"), "--measured", str(camera / "dng"),
                 "--report", str(report_path), "--seed", "3", "--quiet"]) == 0
    out = capsys.readouterr().out
    assert (tmp_path / "REPORT_profile.json").exists()
    assert f"g2r-convert --profile {tmp_path / 'REPORT_profile.json'}" in out


def test_cli_missing_folder_is_one_line(camera, capsys):
    status = main(["--profile", str(camera / "profile.json"), "--measured", str(camera / "nope"),
                   "--report", str(camera / "r.json")])
    err = capsys.readouterr().err.strip()
    assert status != 0 and len(err.splitlines()) == 1 and "nope" in err and "Traceback" not in err


def test_cli_measured_may_be_one_dng_file(camera, tmp_path, capsys):
    """`--measured` takes one DNG as well as a folder (a single real frame is a common first try)."""
    one = camera / "dng" / "IMG_000.dng"
    status = main(["--profile", str(camera / "profile.json"), "--measured", str(one),
                   "--report", str(tmp_path / "r.json"), "--quiet"])
    assert status == 0, capsys.readouterr().err
    assert json.loads((tmp_path / "r.json").read_text())["n_measured"] == 1
    (tmp_path / "notes.txt").write_text("not a dng")
    status = main(["--profile", str(camera / "profile.json"), "--measured", str(tmp_path / "notes.txt"),
                   "--report", str(tmp_path / "r2.json")])
    err = capsys.readouterr().err.strip()
    assert status != 0 and len(err.splitlines()) == 1 and "notes.txt" in err and "Traceback" not in err


def test_cli_bad_dng_names_the_file(camera, tmp_path, capsys):
    folder = tmp_path / "bad"
    folder.mkdir()
    (folder / "broken.dng").write_text("not a dng")
    status = main(["--profile", str(camera / "profile.json"), "--measured", str(folder),
                   "--report", str(tmp_path / "r.json")])
    err = capsys.readouterr().err.strip()
    assert status != 0 and len(err.splitlines()) == 1 and "broken.dng" in err


def test_cli_bad_profile_names_the_file(camera, tmp_path, capsys):
    (tmp_path / "p.json").write_text("{}")
    status = main(["--profile", str(tmp_path / "p.json"), "--measured", str(camera / "dng"),
                   "--report", str(tmp_path / "r.json")])
    err = capsys.readouterr().err.strip()
    assert status != 0 and "p.json" in err and len(err.splitlines()) == 1
