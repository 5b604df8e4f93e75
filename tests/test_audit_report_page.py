"""The HTML page of g2r-diagnose read as a user would (issue 19): what was compared with what,
the result in one sentence, where the outputs are, the order explained before the findings,
each finding with a plain title and its state. Built from a report dict (no audit run); the
page on real audits is looked at in a browser in tests/test_audit_gopro.py."""

from __future__ import annotations

import re

from g2r_jax.audit import report


def _report(tmp_path, findings, **extra):
    return {"findings": findings, "alpha": 0.01, "score_cap": 40.0, "n_measured": 2, "n_simulated": 24,
            "size": [3000, 4000], "sizes": [(3000, 4000)], "simulated_size": [424, 564],
            "timing": {"total_s": 12.3}, "profile_name": "gopro_hero6", "measured_files": ["A.dng", "B.dng"],
            "report_path": str(tmp_path / "REPORT.json"), **extra}


def _finding(cause, **extra):
    return {"cause": cause, "significant": True, "score": 50.0, "p": 0.0, "statistic": "s", "evidence": "mean = [nan 1]",
            "difference": [-0.05, -0.01, 0.0, 0.0], **extra}


def test_page_says_what_was_compared_the_result_and_where_the_outputs_are(tmp_path):
    gain = {"metric": "rms", "before": 1.0, "after": 0.4, "heldout": "regions"}
    findings = [_finding("noise_model", kept=True, gain=gain, worst={"ratio": 0.45, "level": 0.02}),
                _finding("white_level", kept=True, gain=dict(gain, heldout=False)),
                dict(_finding("unexplained", source="noise_correlation", candidate=None), kept=False),
                dict(_finding("banding"), significant=False, score=1.0, p=0.5)]
    page = report.write_html(_report(tmp_path, findings, extended_profile=str(tmp_path / "REPORT_profile.json")),
                             tmp_path / "html")
    text = page.read_text()
    body = text.split("<body>")[1]
    assert "Profile: gopro_hero6." in body and "(A.dng, B.dng)" in body and "3000 x 4000" in body
    assert "<b>Result:</b> 3 significant difference(s): 2 fixed by the extended profile" in body
    assert "1 not fixed" in body and f"g2r-convert --profile {tmp_path / 'REPORT_profile.json'}" in body
    assert str(tmp_path / "REPORT.json") in body and str(page) in body   # where everything was written
    assert body.index("Findings are ordered by") < body.index("1. Noise (noise_model)")
    assert "2. Clipping level (white_level)" in body and "3. Correlated noise (noise_correlation)" in body
    assert body.count("fixed by the extended profile</span>") == 2 and "not explained</span>" in body
    assert not re.search(r"\bnan\b", body) and "p 0" not in body and "no candidate" not in body


def test_page_without_findings_says_the_profile_fits(tmp_path):
    page = report.write_html(_report(tmp_path, [dict(_finding("banding"), significant=False, score=1.0, p=0.5)]),
                             tmp_path / "html")
    body = page.read_text().split("<body>")[1]
    assert "No significant difference" in body and "Findings are ordered" not in body and "1. " not in body
