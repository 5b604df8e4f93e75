"""Mutation fuzzing of the commands against issue 12's promises (harness: tests/fuzz_harness.py).

Default run: the reproducers kept in tests/fuzz_corpus/, a few fresh cases per command (DNGs
mutated in their first 8 KB and anywhere), and a few hundred cases of each attack class of
tests/input_attacks.py (side inputs, charts, hostile names, lying image headers).
Slow run (`-m slow`): G2R_FUZZ_CASES cases (default 300) through g2r-fit-profile, a third of that
through g2r-convert and a few through g2r-diagnose. The full campaign's figures are in the
README's 'Reliability' section, with the command that reproduces them.
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import pytest

import fuzz_harness as fh
import input_attacks as attacks

# diagnose reproducers would each run a whole audit; the audit's findings are covered by unit tests
CORPUS_FILES = sorted(p for p in fh.CORPUS.glob("*") if not p.name.startswith("diagnose_")
                      and p.name.split("_", 1)[0] not in attacks.KINDS) if fh.CORPUS.is_dir() else []
ATTACK_FILES = sorted(p for p in fh.CORPUS.glob("*") if p.name.split("_", 1)[0] in attacks.KINDS) \
    if fh.CORPUS.is_dir() else []


@pytest.fixture(scope="module")
def seeds(tmp_path_factory):
    return fh.make_seeds(tmp_path_factory.mktemp("fuzz_seeds"), profiles=("NikonD40",))


@pytest.mark.parametrize("path", CORPUS_FILES, ids=[p.name for p in CORPUS_FILES])
def test_corpus_reproducers_keep_the_promises(seeds, tmp_path, path):
    assert fh.run_case(fh.corpus_case(path, seeds), tmp_path) == []


@pytest.mark.parametrize("kind, n, seed", [("fit", 8, 7), ("fit-deep", 3, 7), ("convert", 3, 7)])
def test_fresh_cases_keep_the_promises(seeds, kind, n, seed):
    result = fh.campaign(kind, n, seed, seeds_dir=seeds["image"][0].parents[1], profiles=("NikonD40",),
                         log=lambda line: None)
    assert result["findings"] == []


def test_harness_sees_foreign_lines_and_escaping_errors(tmp_path):
    def noisy(argv):
        os.write(2, b"<tifffile.TiffPages @1712> invalid offset to first page 1712\n")
        return 0

    status, _, err = fh.run_main(noisy, [])
    assert status == 0 and fh._line_problems("g2r-fit-profile", err)
    status, _, _ = fh.run_main(lambda argv: 1 / 0, [])
    assert str(status).startswith("exception")


@pytest.mark.parametrize("path", ATTACK_FILES, ids=[p.name for p in ATTACK_FILES])
def test_attack_corpus_keeps_the_promises(path):
    assert attacks.replay(path) == []


def _attack_campaign(kind: str, n: int, seed: int) -> dict:
    """A campaign of tests/input_attacks.py in its own process (its peak memory is measured)."""
    from fresh_process import run_measured

    run, _ = run_measured([sys.executable, str(Path(attacks.__file__)), kind, str(n), str(seed)], capture_output=True,
                          text=True, timeout=1800)   # its own peak memory, not the test worker's
    assert run.returncode == 0, run.stderr[-2000:]
    return json.loads(run.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize("kind, n", [("noise-table", 300), ("sensitivities", 200), ("charts", 300), ("names", 200),
                                     ("images", 100)])
def test_side_inputs_charts_names_and_lying_headers_keep_the_promises(kind, n):
    result = _attack_campaign(kind, n, seed=0)
    assert result["cases"] == n and result["n_findings"] == 0, result["findings"][:3]


@pytest.mark.slow
@pytest.mark.parametrize("kind", attacks.KINDS)
def test_attack_campaign(kind):
    result = _attack_campaign(kind, int(os.environ.get("G2R_ATTACK_CASES", "3000")), seed=1)
    assert result["n_findings"] == 0, result["findings"][:3]


@pytest.mark.slow
@pytest.mark.parametrize("kind, share", [("fit", 1.0), ("fit-deep", 1.0), ("convert", 1 / 3), ("diagnose", 0.01),
                                         ("diagnose-charts", 1 / 3)])
def test_campaign(tmp_path_factory, kind, share):
    n = max(3, int(int(os.environ.get("G2R_FUZZ_CASES", "300")) * share))
    result = fh.campaign(kind, n, seed=12, seeds_dir=tmp_path_factory.mktemp("seeds"))
    assert result["findings"] == [], result["findings"][:3]
