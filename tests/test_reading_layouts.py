"""Conformance corpus for reading real cameras' tag layouts (issue 8, 'pixels we cannot decode,
levels that disagree'): compressed raw kinds, LinearizationTable, Samsung-style black levels,
differing levels across files, stray library log lines; each checked through the reader and the
commands' one-line messages."""

from __future__ import annotations

import json

import numpy as np
import pytest
import rawpy

from dng_layouts import write_layout
from test_io_dng import make_info, random_mosaic
from g2r_jax.audit.loading import load_measured
from g2r_jax.cli.fit_profile import main as fit_main
from g2r_jax.io.dng_info import DngError
from g2r_jax.io.dng_read import read_dng_info, read_dng_pixels
from g2r_jax.io.dng_write import write_dng

LONG, SHORT = 4, 3


@pytest.mark.parametrize("code, name", [(9, "VC-5"), (52546, "JPEG XL")])
def test_undecodable_compression_is_one_warning_and_tags_still_fit(tmp_path, capsys, code, name):
    folder = tmp_path / "in"
    folder.mkdir()
    write_layout(folder / "packed.dng", random_mosaic(), make_info(), compression=code)
    info = read_dng_info(folder / "packed.dng")
    assert info.compression == code and name in info.pixel_data_problem
    with pytest.raises(DngError, match=f"packed.dng: .*{name}.*cannot decode"):
        read_dng_pixels(folder / "packed.dng")
    assert fit_main([str(folder), "-o", str(tmp_path / "p.json")]) == 0
    err = [line for line in capsys.readouterr().err.strip().splitlines() if not _rounding_note(line)]
    assert len(err) == 1 and "packed.dng" in err[0] and name in err[0] and "tags still used" in err[0]
    assert json.loads((tmp_path / "p.json").read_text())["white_level"] == 1023.0



def _rounding_note(line: str) -> bool:
    """Lines these fixtures earn that are not about the file's pixel data: the warning of their tiny
    read noise (0.2 DN, cannot be told from rounding)."""
    return "cannot be told apart reliably" in line

def test_diagnose_loading_skips_undecodable_files_with_that_line(tmp_path):
    good = tmp_path / "good.dng"
    write_dng(good, random_mosaic(), make_info())
    packed = write_layout(tmp_path / "packed.dng", random_mosaic(), make_info(), compression=9)
    lines = []
    loaded = load_measured([good, packed], on_error=lines.append)
    assert [info.path for _, info in loaded] == [str(good)]
    assert len(lines) == 1 and "packed.dng" in lines[0] and "VC-5" in lines[0]


def test_linearization_table_applied_to_pixels_and_default_white(tmp_path):
    mosaic = random_mosaic(high=1024)
    table = (np.arange(1024) * 3 // 2).astype(np.uint16)           # stored -> linear
    path = write_layout(tmp_path / "lin.dng", mosaic, make_info(),
                        add=[(50712, SHORT, table.size, table.tolist())], drop=[50717])   # no WhiteLevel
    info = read_dng_info(path)
    np.testing.assert_array_equal(info.linearization_table, table)
    assert info.white_level == float(table.max())                  # linear values end at the table's top
    np.testing.assert_array_equal(read_dng_pixels(path, info), table[mosaic])


def test_linearization_table_not_above_black_is_refused(tmp_path):
    path = write_layout(tmp_path / "flat.dng", random_mosaic(), make_info(),
                        add=[(50712, SHORT, 4, [0, 10, 20, 30])])
    with pytest.raises(DngError, match="flat.dng: LinearizationTable"):
        read_dng_info(path)


def test_samsung_black_level_count_12(tmp_path):
    values = [64] * 12                      # 2x2 repeat, 12 values that every reading agrees on
    path = write_layout(tmp_path / "s6.dng", random_mosaic(), make_info(),
                        add=[(50713, SHORT, 2, [2, 2]), (50714, LONG, 12, values)])
    np.testing.assert_allclose(read_dng_info(path).black_level, [64] * 4)
    with rawpy.imread(str(path)) as raw:    # LibRaw reads the same levels from this layout
        assert list(raw.black_level_per_channel) == [64] * 4
    # 3 values per position (row-column-sample order) disagree with LibRaw's reading (first 4)
    differing = [64] * 3 + [65] * 3 + [66] * 3 + [67] * 3
    path = write_layout(tmp_path / "odd.dng", random_mosaic(), make_info(),
                        add=[(50713, SHORT, 2, [2, 2]), (50714, LONG, 12, differing)])
    with pytest.raises(DngError, match="odd.dng: BlackLevel has 12 values, expected 2x2x1"):
        read_dng_info(path)
    path = write_layout(tmp_path / "five.dng", random_mosaic(), make_info(),
                        add=[(50713, SHORT, 2, [2, 2]), (50714, LONG, 5, [64] * 5)])
    with pytest.raises(DngError, match="five.dng: BlackLevel has 5 values"):
        read_dng_info(path)


def test_levels_that_differ_give_one_note_and_the_median(tmp_path, capsys):
    folder = tmp_path / "in"
    folder.mkdir()
    for name, black, white in (("a", 60.0, 1000.0), ("b", 64.0, 1023.0), ("c", 70.0, 1023.0)):
        write_dng(folder / f"{name}.dng", random_mosaic(), make_info(black_level=np.full(4, black), white_level=white))
    assert fit_main([str(folder), "-o", str(tmp_path / "p.json")]) == 0
    err = [line for line in capsys.readouterr().err.strip().splitlines() if not _rounding_note(line)]
    assert len(err) == 1 and "note:" in err[0] and "black levels differ" in err[0] and "white levels differ" in err[0]
    assert "a.dng" in err[0] and "c.dng" in err[0] and "Warning" not in err[0]
    document = json.loads((tmp_path / "p.json").read_text())
    assert document["black_level"] == [64.0] * 4 and document["white_level"] == 1023.0


def test_truncated_files_print_no_library_log_line(tmp_path, capfd):
    source = tmp_path / "full.dng"
    write_dng(source, random_mosaic(), make_info())
    data = source.read_bytes()
    for cut in (9, 16, 200, 1000, len(data) // 2, len(data) - 1):
        path = tmp_path / f"cut{cut}.dng"
        path.write_bytes(data[:cut])
        try:
            read_dng_info(path)
        except DngError as error:
            assert f"cut{cut}.dng" in str(error) and len(str(error)) < 400
    out, err = capfd.readouterr()
    assert out == "" and err == ""
