"""Inputs for g2r-downstream tests: a folder of simulated camera DNGs and one of CG PNGs."""

from __future__ import annotations

import numpy as np


def write_camera_folders(root, dng_count: int, cg_count: int, profile_name: str = "NikonD40"):
    """(dngs, cg): `dng_count` DNGs of `profile_name` (dead-leaves scenes of 144 x 192 under drawn
    lights, real_NN.dng) and `cg_count` CG PNGs of 160 x 224 (render_N.png) under `root`."""
    from PIL import Image

    import g2r_jax
    from g2r_jax.audit import scenes, simulate
    from g2r_jax.io.dng_write import write_dng

    dngs, cg = root / "dngs", root / "cg"
    dngs.mkdir()
    cg.mkdir()
    profile = g2r_jax.load_profile(profile_name)
    for i, (mosaic, info) in enumerate(simulate.simulate(profile, scenes.scene_set(dng_count, 3, 144, 192), 1)):
        write_dng(dngs / f"real_{i:02d}.dng", mosaic, info)
    for i, scene in enumerate(scenes.scene_set(cg_count, 9, 160, 224)):
        Image.fromarray((np.clip(scene, 0, 1) * 255).round().astype(np.uint8)).save(cg / f"render_{i}.png")
    return dngs, cg
