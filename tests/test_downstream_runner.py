"""benchmarks/downstream_runner.py, the runner of the per-camera downstream benchmarks: it runs only
the cameras its JSON lacks, rewrites the JSON after each camera, and `--summary` merges runs by
camera and row (two runs of different rows give the union of the rows). No data, no training: the
cameras here are fakes, and the scripts' tables are fed JSON written in their format."""

import json
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import downstream_runner as runner  # noqa: E402


def _benchmark(run, is_done=lambda entry: True) -> runner.CameraBenchmark:
    """A fake benchmark: a camera's result is one number, stored as the 'real/cnn' summary."""
    return runner.CameraBenchmark(
        run=run, entry=lambda value: {"rows": ["real"], "summary": {"real/cnn": value}},
        camera_lines=lambda key, value: [f"## {key} ran", ""], kept_lines=lambda key, entry: [f"## {key} kept", ""],
        closing_lines=lambda entries, seconds: [f"{len(entries)} cameras"],
        header=lambda seconds: {"seconds": seconds, "n": 7}, is_done=is_done)


def _saved(path: Path) -> dict:
    """The entries of a run's JSON file."""
    return json.loads(path.read_text())["cameras"]


def test_only_the_cameras_missing_from_the_json_run_and_the_kept_ones_stay(tmp_path):
    path = tmp_path / "run.json"
    kept = {"B": {"rows": ["real"], "summary": {"real/cnn": 9.0}}}
    path.write_text(json.dumps({"seconds": 1.0, "n": 7, "cameras": kept}))
    calls = []

    def run(job):
        calls.append(job)
        return float(len(job))

    runner.run_cameras(_benchmark(run), {"A": "a", "B": "bb", "C": "ccc"}, json_path=path)
    assert calls == ["a", "ccc"]
    saved = json.loads(path.read_text())
    assert saved["n"] == 7 and set(saved) == {"seconds", "n", "cameras"}
    assert saved["cameras"]["B"]["summary"]["real/cnn"] == 9.0           # kept as it was, not run again
    assert saved["cameras"]["A"]["summary"]["real/cnn"] == 1.0
    assert saved["cameras"]["C"]["summary"]["real/cnn"] == 3.0


def test_an_entry_that_is_not_done_runs_again(tmp_path):
    path = tmp_path / "run.json"
    path.write_text(json.dumps({"cameras": {"A": {"rows": ["real"]}, "B": {"rows": ["real"], "errors": {}}}}))
    calls = []
    runner.run_cameras(_benchmark(lambda job: calls.append(job) or 2.0, is_done=lambda entry: "errors" in entry),
                       {"A": "a", "B": "b"}, json_path=path)
    assert calls == ["a"]
    assert _saved(path)["A"]["summary"]["real/cnn"] == 2.0


def test_the_json_and_markdown_are_written_after_each_camera_and_a_stopped_run_resumes(tmp_path):
    path, markdown = tmp_path / "run.json", tmp_path / "run.md"

    def stops_at_b(job):
        if job == "b":
            raise RuntimeError("stopped")
        return 4.0

    with pytest.raises(RuntimeError, match="stopped"):
        runner.run_cameras(_benchmark(stops_at_b), {"A": "a", "B": "b", "C": "c"}, json_path=path,
                           markdown_path=markdown)
    assert list(_saved(path)) == ["A"]
    assert markdown.read_text() == "## A ran\n\n1 cameras\n"
    calls = []
    runner.run_cameras(_benchmark(lambda job: calls.append(job) or 5.0), {"A": "a", "B": "b", "C": "c"},
                       json_path=path, markdown_path=markdown)
    assert calls == ["b", "c"]
    assert {key: entry["summary"]["real/cnn"] for key, entry in _saved(path).items()} == {"A": 4.0, "B": 5.0, "C": 5.0}
    assert markdown.read_text() == "## A kept\n\n## B ran\n\n## C ran\n\n3 cameras\n"


def test_cameras_run_in_several_processes_keep_their_order(tmp_path):
    path = tmp_path / "run.json"
    runner.run_cameras(_benchmark(len), {"A": "a", "B": "bbb", "C": "cc"}, json_path=path, processes=2)
    assert {key: entry["summary"]["real/cnn"] for key, entry in _saved(path).items()} == {"A": 1, "B": 3, "C": 2}


def test_an_unreadable_json_is_named_and_every_camera_runs(tmp_path, capsys):
    path = tmp_path / "run.json"
    path.write_text("{not json")
    calls = []
    runner.run_cameras(_benchmark(lambda job: calls.append(job) or 1.0), {"A": "a"}, json_path=path)
    assert calls == ["a"]
    assert "not read" in capsys.readouterr().err


def test_merging_runs_of_different_rows_gives_the_union_of_the_rows_a_later_run_winning():
    earlier = {"Canon600D": {"rows": ["real", "fitted"], "estimators": ["cnn"], "seconds": 5.0,
                             "summary": {"real/cnn": 1.0, "fitted/cnn": 2.0}},
               "NikonD40": {"rows": ["real"], "estimators": ["cnn"], "summary": {"real/cnn": 8.0}}}
    later = {"Canon600D": {"rows": ["real", "real_plus_upi"], "estimators": ["cnn", "histogram"], "seconds": 7.0,
                           "summary": {"real/cnn": 10.0, "real_plus_upi/cnn": 3.0, "real/histogram": 4.0}}}
    merged = runner.merge_runs([earlier, later])
    assert merged["Canon600D"]["rows"] == ["real", "real_plus_upi", "fitted"]
    assert merged["Canon600D"]["estimators"] == ["cnn", "histogram"]
    assert merged["Canon600D"]["summary"] == {"real/cnn": 10.0, "fitted/cnn": 2.0, "real_plus_upi/cnn": 3.0,
                                              "real/histogram": 4.0}
    assert merged["Canon600D"]["seconds"] == 7.0
    assert merged["NikonD40"] == earlier["NikonD40"]
    assert earlier["Canon600D"]["rows"] == ["real", "fitted"]        # the runs themselves are left as they were


def test_merging_isp_runs_merges_each_part_of_a_camera():
    earlier = {"X": {"all": {"rows": ["upi", "fitted"], "summary": {"upi/psnr": 1.0, "fitted/psnr": 2.0}},
                     "10": {"rows": ["fitted"], "summary": {"fitted/psnr": 3.0}}}}
    later = {"X": {"all": {"rows": ["fitted"], "summary": {"fitted/psnr": 20.0}}}}
    merged = runner.merge_runs([earlier, later], nesting=2)
    assert merged["X"]["all"] == {"rows": ["upi", "fitted"], "summary": {"upi/psnr": 1.0, "fitted/psnr": 20.0}}
    assert merged["X"]["10"] == earlier["X"]["10"]


def test_merged_order_keeps_each_list_order():
    assert runner.merged_order(["real", "fitted"], ["real", "upi", "fitted"]) == ["real", "upi", "fitted"]
    assert runner.merged_order(["a", "b"], ["c"], ["b", "d"]) == ["c", "a", "b", "d"]


def test_read_runs_sums_the_seconds_and_leaves_out_entries_not_done(tmp_path):
    a, b = tmp_path / "a.json", tmp_path / "b.json"
    a.write_text(json.dumps({"seconds": 60.0, "cameras": {"A": {"rows": ["real"], "errors": {}}}}))
    b.write_text(json.dumps({"seconds": 30.0, "cameras": {"B": {"rows": ["real"]}}}))
    entries, seconds = runner.read_runs([a, b, tmp_path / "missing.json"], is_done=lambda entry: "errors" in entry)
    assert seconds == 90.0
    assert list(entries) == ["A"]


def _nus_entry(camera: str, rows, error: float) -> dict:
    """The JSON entry downstream_nus.py writes for one camera, each row's errors `error` degrees
    (plus the row's index / 10), one seed, the cnn estimator."""
    import downstream_nus
    from g2r_jax.downstream.illuminant.experiment import ExperimentResult

    errors = {(row, "cnn"): [np.full(4, error + i / 10)] for i, row in enumerate(rows)}
    result = ExperimentResult(camera=camera, rows=tuple(rows), estimators=("cnn",), seeds=(0,), errors=errors)
    return downstream_nus.result_entry(result)


def test_nus_summary_of_runs_of_different_rows_is_one_table_of_every_row(tmp_path, capsys):
    import downstream_nus

    a, b = tmp_path / "a.json", tmp_path / "b.json"
    a.write_text(json.dumps({"seconds": 1.0, "n": 500, "cameras": {
        "Canon600D": _nus_entry("Canon600D", ["real", "fitted"], 2.0),
        "NikonD40": _nus_entry("NikonD40", ["real", "fitted"], 3.0)}}))
    b.write_text(json.dumps({"seconds": 1.0, "n": 500, "cameras": {
        "Canon600D": _nus_entry("Canon600D", ["real", "real_plus_upi"], 5.0)}}))
    assert downstream_nus.main(["--summary", f"{a},{b}"]) == 0
    lines = capsys.readouterr().out.splitlines()
    head = next(line for line in lines if line.startswith("| camera"))
    assert head.count("|") == 7      # camera, estimator, three rows, fitted vs UPI
    assert "| Canon600D | cnn | 5.00 | 5.10 | 2.10 |  |" in lines      # real and real_plus_upi of b, fitted of a
    assert "| NikonD40 | cnn | 3.00 |  | 3.10 |  |" in lines            # no real_plus_upi: an empty cell


def test_isp_summary_of_runs_of_different_rows_is_one_table_of_every_row(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("OMP_NUM_THREADS", "1")     # what the script sets when imported, undone after the test
    import downstream_isp_nus

    def part(rows, psnr):
        return {"rows": rows, "summary": {f"{r}/{m}": {"mean": psnr + i} for i, r in enumerate(rows)
                                          for m in ("psnr", "ssim", "delta_e")}}

    a, b = tmp_path / "a.json", tmp_path / "b.json"
    a.write_text(json.dumps({"seconds": 60.0, "cameras": {"X": {"all": part(["upi", "fitted"], 20.0)},
                                                          "Y": {"all": part(["upi", "fitted"], 30.0)}}}))
    b.write_text(json.dumps({"seconds": 60.0, "cameras": {"X": {"all": part(["fitted", "real"], 40.0)}}}))
    assert downstream_isp_nus.main(["--summary", f"{a},{b}"]) == 0
    out = capsys.readouterr().out
    assert "| camera | upi | fitted | real |" in out
    assert "| X | 20.00 / 20.000 / 20.00 | 40.00 / 40.000 / 40.00 | 41.00 / 41.000 / 41.00 |" in out
    assert "| Y | 30.00 / 30.000 / 30.00 | 31.00 / 31.000 / 31.00 |  |" in out
    assert "Total 2.0 min" in out


def test_a_row_whose_cameras_come_from_different_files_is_named(tmp_path):
    """A later run that holds a row for some cameras only (stopped early): the merged table mixes
    it with an earlier run's row for the others, and a line says which came from where."""
    old, new = tmp_path / "old.json", tmp_path / "new.json"
    result = lambda rows: {"rows": rows, "summary": {}}
    old.write_text(json.dumps({"cameras": {c: {"all": result(["upi", "fitted"]), "10": result(["fitted"])}
                                           for c in ("A", "B", "C")}}))
    new.write_text(json.dumps({"cameras": {c: {"10": result(["fitted"])} for c in ("A", "B")}}))
    lines = []
    entries, _ = runner.read_runs([old, new], nesting=2, say=lines.append)
    assert lines == [f"note: row fitted (10) merges files: C from {old}; A, B from {new}"]
    assert set(entries) == {"A", "B", "C"}
    complete = tmp_path / "complete.json"
    complete.write_text(json.dumps({"cameras": {c: {"10": result(["fitted"])} for c in ("A", "B", "C")}}))
    quiet = []
    runner.read_runs([old, complete], nesting=2, say=quiet.append)
    assert quiet == []
