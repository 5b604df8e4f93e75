"""Side inputs validated where they are read, errors naming the file and its line or field:
noise tables (g2r_jax.io.noise_table), spectral sensitivities (g2r_jax.io.sensitivities),
chart CSVs (g2r_jax.colour.charts)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from g2r_jax.colour.charts import ChartError, read_charts
from g2r_jax.io.dng_info import DngError
from g2r_jax.io.noise_table import read_noise_table_rows
from g2r_jax.io.sensitivities import read_sensitivities

BLACK, WHITE = [64.0] * 4, 1023.0


def _table(scale=1.0, extra=""):
    rows = ["iso,cfa_channel_index,beta1_shot,beta2_read"]
    rows += [f"{iso},{p},{0.14 * scale},{-8.9 * scale}" for iso in (100, 200) for p in range(4)]
    return "\n".join(rows) + "\n" + extra


def test_a_noise_table_in_dn_is_read(tmp_path):
    (tmp_path / "n.csv").write_text(_table())
    isos, beta1, beta2 = read_noise_table_rows(tmp_path / "n.csv", BLACK, WHITE)
    assert list(isos) == [100, 200] and beta1.shape == beta2.shape == (2, 4)


@pytest.mark.parametrize("text, expected", [
    (_table(scale=1e4), r"n\.csv: line 2, beta1_shot: the normalised shot noise is .* must be in DN"),
    (_table().replace("200,3,", "200,7,"), r"n\.csv: line 9, cfa_channel_index: must be 0, 1, 2 or 3"),
    (_table().replace("100,1,0.14", "100,1,nan"), r"n\.csv: line 3, beta1_shot: must be finite"),
    (_table().replace("100,2,0.14", "100,2,abc"), r"n\.csv: line 4, beta1_shot: 'abc' is not a number"),
    (_table(extra="100,0,0.14,-8.9\n"), r"n\.csv: line 10: a second row for ISO 100, CFA position 0"),
    ("iso,beta1_shot\n100,1\n", r"n\.csv: line 1: expected a header"),
])
def test_a_bad_noise_table_is_named_with_its_line(tmp_path, text, expected):
    (tmp_path / "n.csv").write_text(text)
    with pytest.raises(DngError, match=expected):
        read_noise_table_rows(tmp_path / "n.csv", BLACK, WHITE)


@pytest.mark.parametrize("document, expected", [
    ({"header": "x", "spectral_data": {"data": {"main": {}}}}, "field header must be an object"),
    ("just a string", "the top level has no object field 'spectral_data'"),
    ({"spectral_data": {"data": {"main": {"400": [1, 2]}}}}, r"main\['400'\]: expected three numbers"),
    ({"spectral_data": {"data": {"main": {"4\x1b[31m": [1, 2, 3]}}}}, "is not a wavelength in nm"),
    ({"spectral_data": {"data": {"main": {str(w): [1e300, 1, 1] for w in range(380, 790, 10)}}}}, "values beyond"),
])
def test_a_malformed_sensitivities_json_names_its_field(tmp_path, document, expected):
    (tmp_path / "s.json").write_text(json.dumps(document))
    with pytest.raises(DngError, match=expected) as caught:
        read_sensitivities(tmp_path / "s.json")
    assert str(caught.value).startswith(str(tmp_path / "s.json"))


def _charts(patch="0.2", illuminant="0.5,1.0,0.6"):
    rows = ["image,patch,r,g,b"] + [f"a,{p},{patch},{patch},{patch}" for p in range(1, 25)]
    return "\n".join(rows + [f"a,illuminant,{illuminant}"]) + "\n"


def test_charts_with_every_patch_nan_are_refused_by_name(tmp_path):
    (tmp_path / "c.csv").write_text(_charts(patch="nan"))
    with pytest.raises(ChartError, match=r"c\.csv: no image has a measured chromatic patch"):
        read_charts(tmp_path / "c.csv")


def test_a_degenerate_illuminant_is_refused_with_its_row(tmp_path):
    (tmp_path / "c.csv").write_text(_charts(illuminant="1e-300,1,1"))
    with pytest.raises(ChartError, match=r"c\.csv: row 26: the illuminant of image 'a' is degenerate"):
        read_charts(tmp_path / "c.csv")
    (tmp_path / "ok.csv").write_text(_charts())
    assert np.isfinite(read_charts(tmp_path / "ok.csv").patches).all()
