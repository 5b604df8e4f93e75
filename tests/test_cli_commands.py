"""The three commands behave alike: usage on no arguments, required options and defaults in the
help, an example in each help, one --quiet; argument and output-path errors found while parsing,
before JAX is imported; inputs of several folders keep their folders; a profile argument is a
shipped name unless it is a file. Timings are in benchmarks/cli_startup.py, not here."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from g2r_jax.batch.conversion import output_names
from g2r_jax.cli import convert, diagnose, fit_profile
from g2r_jax.profile.shipped import SHIPPED_PROFILES_DIR, UnknownProfile, profile_path

COMMANDS = {"g2r-convert": convert.main, "g2r-fit-profile": fit_profile.main, "g2r-diagnose": diagnose.main}


@pytest.mark.parametrize("name", COMMANDS)
def test_no_arguments_print_the_usage_and_an_example(name, capsys):
    assert COMMANDS[name]([]) == 2
    err = capsys.readouterr().err
    assert err.startswith("usage: ") and "examples:" in err and f"\n  {name} " in err


@pytest.mark.parametrize("name, required", [("g2r-convert", ["--profile", "-o OUT_DIR, --output OUT_DIR"]),
                                            ("g2r-fit-profile", ["-o PROFILE_JSON, --output PROFILE_JSON"]),
                                            ("g2r-diagnose", ["--profile", "--report"])])
def test_help_shows_required_options_defaults_an_example_and_quiet(name, required, capsys):
    assert COMMANDS[name](["--help"]) == 0
    text = capsys.readouterr().out
    required_section = text.split("\nrequired:\n", 1)[1].split("\n\n", 1)[0]
    for option in required:
        assert f"  {option}" in required_section, (option, required_section)
    seed_help = " ".join(text.split("\n  --seed SEED", 1)[1].split("\n  -", 1)[0].split())
    assert "(default: 0)" in seed_help                  # every command has --seed, default 0
    assert "-q, --quiet" in text and "--no-progress" not in text
    examples = text.split("\nexamples:\n", 1)[1]
    assert examples.strip().startswith(name)


def test_convert_help_shows_the_workers_default(capsys):
    assert convert.main(["--help"]) == 0
    assert "(default: 2)" in " ".join(capsys.readouterr().out.split("--workers", 1)[1].split()[:8])


def test_no_progress_is_kept_as_a_hidden_alias_of_quiet():
    for parser, required in ((convert.build_parser(), ["-o", "x"]), (fit_profile.build_parser(), ["-o", "x"]),
                             (diagnose._parser(), ["--profile", "p", "--report", "r"])):
        assert parser.parse_args(required + ["--no-progress"]).quiet is True
        assert parser.parse_args(required + ["--quiet"]).quiet is True
        assert parser.parse_args(required).quiet is False


# Each: arguments, the words the one error line must hold. All are found while parsing.
PARSING_ERRORS = [
    ("g2r-convert", ["in.png", "--profile", "gopro_hero6"], "-o/--output"),
    ("g2r-convert", ["-o", "out"], "no INPUT"),
    ("g2r-convert", ["in.png", "-o", "out"], "--profile"),
    ("g2r-convert", ["in.png", "--profile", "gopro_hero6", "-o", "out", "--seed", "x"], "--seed"),
    ("g2r-convert", ["in.png", "--profile", "gopro_hero6", "-o", "a_file"], "a_file: is a file; a folder"),
    ("g2r-convert", ["in.png", "--profile", "gopro_hero6", "-o", "a_file/sub"], "a_file is a file"),
    ("g2r-convert", ["in.png", "--profile", "no_such_camera", "-o", "out"], "unknown profile name"),
    ("g2r-convert", ["in.png", "--profile", "gopro_hero6", "-o", "out", "--workers", "0"], "--workers"),
    ("g2r-fit-profile", ["dngs", "-o", "missing/dir/p.json"], "missing/dir does not exist"),
    ("g2r-fit-profile", ["dngs", "-o", "a_folder"], "a_folder: is a folder"),
    ("g2r-fit-profile", ["-o", "p.json"], "no DNG_DIR"),
    ("g2r-fit-profile", ["--illuminants", "a_file", "-o", "p.json"], "--calibration"),
    ("g2r-diagnose", ["--profile", "gopro_hero6", "--measured", "a_folder", "--report", "r.json", "--alpha", "2"],
     "--alpha"),
    ("g2r-diagnose", ["--profile", "gopro_hero6", "--measured", "a_folder", "--report", "r.json", "--folds", "1"],
     "--folds"),
    ("g2r-diagnose", ["--profile", "gopro_hero6", "--report", "r.json"], "--measured"),
    ("g2r-diagnose", ["--profile", "gopro_hero6", "--measured", "a_folder", "--scenes", "nowhere", "--report", "r.json"],
     "--scenes nowhere: no such folder"),
    ("g2r-diagnose", ["--profile", "gopro_hero6", "--measured", "a_folder", "--report", "a_folder"], "is a folder"),
    ("g2r-diagnose", ["--profile", "gopro_hero6", "--measured", "a_folder", "--report", "a_file/r.json"],
     "a_file is a file"),
]

_RUN_ALL = """
import contextlib, io, json, sys
from g2r_jax.cli import convert, diagnose, fit_profile
commands = {"g2r-convert": convert.main, "g2r-fit-profile": fit_profile.main, "g2r-diagnose": diagnose.main}
results = []
for name, arguments, _ in json.loads(sys.argv[1]):
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        code = commands[name](arguments)
    results.append([code, err.getvalue()])
print(json.dumps({"results": results, "jax": "jax" in sys.modules, "numpy": "numpy" in sys.modules}))
"""


def test_argument_and_output_path_errors_come_before_any_work_and_without_jax(tmp_path):
    (tmp_path / "a_file").write_text("x")
    (tmp_path / "a_folder").mkdir()
    before = sorted(p.name for p in tmp_path.iterdir())
    done = subprocess.run([sys.executable, "-c", _RUN_ALL, json.dumps(PARSING_ERRORS)], cwd=tmp_path,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    report = json.loads(done.stdout)
    assert not report["jax"], "an argument error imported jax"
    for (name, arguments, words), (code, err) in zip(PARSING_ERRORS, report["results"]):
        last = err.strip().splitlines()[-1]
        assert code == 2 and last.startswith(f"{name}: error: ") and words in last, (arguments, err)
        assert "Errno" not in err and ".tmp" not in err and "Traceback" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == before   # nothing created


def test_list_profiles_says_what_each_profile_is(capsys):
    assert convert.main(["--list-profiles"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    names = sorted(p.stem for p in SHIPPED_PROFILES_DIR.glob("*.json"))
    heads = [k for k, line in enumerate(lines) if not line.startswith(" ")]   # one per profile, then its sources
    assert sorted(lines[k].split()[0] for k in heads) == names
    gopro = next(k for k in heads if lines[k].startswith("gopro_hero6 "))
    assert "GoPro HERO6 Black" in lines[gopro] and "ISO 100-100" in lines[gopro]
    assert [line.split(":")[0].strip() for line in lines[gopro + 1:gopro + 5]] == ["colour", "noise", "illuminants",
                                                                                  "content"]


def test_a_profile_argument_is_a_shipped_name_unless_it_is_a_file(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "gopro_hero6").mkdir()                      # a folder named like a shipped profile
    assert profile_path("gopro_hero6") == SHIPPED_PROFILES_DIR / "gopro_hero6.json"
    (tmp_path / "mine").write_text("{}")                     # a file without a suffix is a file
    assert profile_path("mine") == Path("mine")
    (tmp_path / "folder_only").mkdir()
    with pytest.raises(UnknownProfile, match="folder_only: unknown profile name .a folder of that name"):
        profile_path("folder_only")
    with pytest.raises(UnknownProfile, match="sub/none.json: no such profile file"):
        profile_path("sub/none.json")


def test_output_names_keep_folders_only_when_inputs_come_from_several(tmp_path):
    one = [tmp_path / "a" / "0001.png", tmp_path / "a" / "0002.exr"]
    assert output_names(one) == ["0001", "0002"]
    two = [tmp_path / "sceneA" / "0001.png", tmp_path / "sceneB" / "0001.png", tmp_path / "sceneB" / "x" / "2.jpg"]
    assert output_names(two) == ["sceneA/0001", "sceneB/0001", "sceneB/x/2"]
    assert output_names([]) == []


def test_same_named_inputs_in_two_folders_are_written_under_their_folders(tmp_path, capsys):
    rng = np.random.default_rng(0)
    for scene in ("sceneA", "sceneB"):
        (tmp_path / scene).mkdir()
        Image.fromarray(rng.integers(0, 256, (16, 24, 3), dtype=np.uint8)).save(tmp_path / scene / "0001.png")
    out = tmp_path / "out"
    status = convert.main([str(tmp_path / "sceneA"), str(tmp_path / "sceneB"), "--profile", "gopro_hero6",
                           "-o", str(out), "--quiet"])
    captured = capsys.readouterr()
    assert status == 0, captured.err
    written = sorted(str(p.relative_to(out)) for p in out.rglob("*") if p.is_file() and not p.name.startswith("."))
    assert written == ["manifest.jsonl", "sceneA/0001.dng", "sceneB/0001.dng"]
    records = [json.loads(line) for line in (out / "manifest.jsonl").read_text().splitlines()]
    assert sorted(r["output"] for r in records) == ["sceneA/0001.dng", "sceneB/0001.dng"]   # relative
    assert records[0]["neutral"] != records[1]["neutral"]    # own random keys, not one shared by the name
    assert "LibRaw" not in captured.err                       # --quiet: no renderer note


def test_convert_ends_with_which_renderers_read_the_colour_tags(tmp_path, capsys):
    assert convert.main(["--example", "-o", str(tmp_path / "out")]) == 0
    err = capsys.readouterr().err
    assert "darktable" in err and "LibRaw" in err and err.count("\n") <= 4


@pytest.mark.skipif(os.name != "posix" or os.geteuid() == 0, reason="needs POSIX permissions that bind (not root)")
def test_a_read_only_output_folder_is_refused_while_parsing(tmp_path, capsys):
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o500)
    try:
        assert fit_profile.main(["x", "-o", str(locked / "p.json")]) == 2
        assert "no permission to write in" in capsys.readouterr().err
    finally:
        locked.chmod(0o700)


def test_the_commands_page_lists_every_option():
    from pathlib import Path as _Path

    page = (_Path(__file__).resolve().parents[1] / "docs" / "pages" / "commands.md").read_text()
    for name, parser in (("g2r-convert", convert.build_parser()), ("g2r-fit-profile", fit_profile.build_parser()),
                         ("g2r-diagnose", diagnose._parser())):
        section = page.split(f"\n## {name}\n", 1)[1].split("\n## ", 1)[0]
        for action in parser._actions:
            if action.help == "==SUPPRESS==":
                continue
            for option in action.option_strings:
                assert option in section, f"docs/pages/commands.md: {name} {option} missing (paste its --help)"


def test_a_profile_without_noise_is_announced_even_when_quiet(tmp_path, capsys):
    import json

    from g2r_jax.cli.convert import main as convert_main
    from g2r_jax.profile.shipped import profile_path

    document = json.loads(profile_path("gopro_hero6").read_text())
    document["noise"]["shot"] = [[0.0] * 4 for _ in document["noise"]["shot"]]
    document["noise"]["read"] = [[0.0] * 4 for _ in document["noise"]["read"]]
    silent = tmp_path / "silent.json"
    silent.write_text(json.dumps(document))
    assert convert_main(["--example", "--profile", str(silent), "-o", str(tmp_path / "out"), "--quiet"]) == 0
    err = capsys.readouterr().err
    assert "no noise model" in err and "silent" in err
    assert convert_main(["--example", "--profile", "gopro_hero6", "-o", str(tmp_path / "out2"), "--quiet"]) == 0
    assert "no noise model" not in capsys.readouterr().err
