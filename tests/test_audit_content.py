"""The audit report shows the scenes' content statistics, measured against simulated (issue 32's
wiring): medians of `g2r_jax.content` statistics on white-balanced camera-RGB thumbnails, no
test and no verdict. Files written in numpy (`synthetic_bursts`), independent of the simulation."""

from __future__ import annotations

import numpy as np
import pytest

from g2r_jax.audit import content_report, report
from g2r_jax.audit import synthetic_bursts as sb


def files(high, n=3, size=(256, 384)):
    out = []
    for seed in range(n):
        (mosaic, info), = sb.burst(sb.BurstTruth(), sb.scene_signal(seed, *size, low=0.0, high=high), 1, seed)
        out.append({"content_thumbnail": content_report.thumbnail(mosaic, info)})
    return out


def test_dim_measured_scenes_read_darker_than_bright_simulated_ones():
    section = content_report.compare(files(0.05), files(0.8))
    assert section["n_measured"] == 3 and section["n_simulated"] == 3
    # brightness is relative to each image's peak: the dim set's noise floor fills more of it as dark
    assert section["measured"]["dark_share"] > section["simulated"]["dark_share"], section
    text = "\n".join(content_report.lines(section))
    assert "not tested" in text and "dark share" in text
    page = report._content_html(section)
    assert "no verdict" in page and page.count("<tr>") == 1 + len(section["names"])


def test_small_files_and_missing_neutrals_give_no_section():
    (mosaic, info), = sb.burst(sb.BurstTruth(), sb.scene_signal(0, 120, 180), 1, 0)
    assert content_report.thumbnail(mosaic, info) is None          # under 128 x 128 thumbnails' worth
    (mosaic, info), = sb.burst(sb.BurstTruth(), sb.scene_signal(0, 256, 384), 1, 0)
    info.as_shot_neutral = None
    assert content_report.thumbnail(mosaic, info) is None
    assert content_report.compare([{"content_thumbnail": None}], files(0.5, n=1)) is None
    assert content_report.lines(None) == [] and report._content_html(None) == ""


@pytest.mark.slow
def test_diagnose_reports_the_content_of_both_sets():
    """An audit of demo-camera files of 200 x 300 carries the section, over the measured scenes
    (dark frames left out) and the simulated files, and its summary shows it."""
    from g2r_jax.audit import diagnose, synthetic
    from audit_helpers import dark_frames, measured_set

    camera = synthetic.demo_profile()
    files = measured_set(camera, 3, n=6) + dark_frames(camera, 3, n=2)
    found = diagnose(camera, files, seed=3, n_permutations=200)
    section = found["content"]
    assert section["n_measured"] == 6 and section["n_simulated"] == found["n_simulated"]
    assert all(section["measured"][name] is not None for name in section["names"])
    assert "scene content" in report.summary(found)
