"""The simulation the audit compares measured files with is the one the user gets: the audit's
simulated file of a scene image and a seed is `g2r-convert`'s file for that image and seed."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

import g2r_jax
from g2r_jax.audit import loading, scenes, simulate
from g2r_jax.batch.conversion import ConvertOptions, convert_files, file_key
from g2r_jax.io.dng_read import read_dng_info, read_dng_pixels

SEED = 3


@pytest.mark.slow
@pytest.mark.parametrize("name, lens", [("gopro_hero6", False), ("gopro_hero6", True), ("s20fe_night", False)])
def test_audit_simulation_is_g2r_convert_output(tmp_path, name, lens):
    profile = g2r_jax.load_profile(name)
    folder = tmp_path / "scenes"
    folder.mkdir()
    for i in range(2):
        image = scenes.dead_leaves(40 + i, 64, 96)
        Image.fromarray(np.round(image * 255).astype(np.uint8)).save(folder / f"scene_{i}.png")
    inputs = sorted(folder.glob("*.png"))
    convert_files(inputs, profile, tmp_path / "dng",
                  options=ConvertOptions(seed=SEED, progress=False, lens_shading=lens))
    images, names = loading.load_scenes(folder, 2, 64, 96, with_names=True)
    simulated = simulate.simulate(profile, images, SEED, keys=[file_key(SEED, n) for n in names], lens_shading=lens)
    for path, (mosaic, info) in zip(inputs, simulated):
        written = tmp_path / "dng" / f"{path.stem}.dng"
        tags = read_dng_info(written)
        assert np.array_equal(read_dng_pixels(written, tags), mosaic), path.name
        assert tags.iso == info.iso
        assert np.allclose(tags.as_shot_neutral, info.as_shot_neutral, rtol=1e-6)
        assert ("OpcodeList2" in tags.opcode_lists) == lens == ("OpcodeList2" in info.opcode_lists)
