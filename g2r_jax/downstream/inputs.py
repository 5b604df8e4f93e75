"""The downstream check's inputs, read and vetted before any training: a camera's real DNGs, CG
images, a burst. Every file that cannot be used is left out by name (`Inputs.problems`); what
makes the whole check impossible (too few files, labels that cannot teach anything, no usable CG
image, a burst too short) raises `DngError` naming the folder and what it needs.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Callable, Optional

import numpy as np

from g2r_jax.downstream.base import real_sets
from g2r_jax.io.dng_info import DngError
from g2r_jax.io.image_headers import DEFAULT_MAX_PIXELS

MIN_REAL_FILES = 12      # and 4 per fold: cross-validated real training needs files on both sides
MIN_CG_SIDE = 128        # a CG view's side (`training_sets.VIEW_SIZE`)


@dataclasses.dataclass
class Inputs:
    """What the check will use. `real`: the real set (None without `measured`); `cg`: linear
    float32 CG images and `cg_paths` their files; `burst`: a `bursts.Burst` or None; `problems`:
    (path, reason) of every input left out; `notes`: lines a user should know (duplicates)."""

    real: Optional[real_sets.RealSet] = None
    cg: list = dataclasses.field(default_factory=list)
    cg_paths: list = dataclasses.field(default_factory=list)
    burst: object = None
    problems: list = dataclasses.field(default_factory=list)
    notes: list = dataclasses.field(default_factory=list)


def read_measured(paths, *, folds: int, problem: Callable[[str, str], None]) -> tuple:
    """The real set of `paths` and notes; DngError naming the folders when the colour check cannot
    run on it (too few distinct files, or labels without enough distinct lights)."""
    real, skipped = real_sets.load_dng_folder(paths)
    for path, reason in skipped:
        problem(path, reason)
    where = " ".join(str(p) for p in paths)
    distinct = len(np.unique(real.groups)) if real.groups is not None else len(real.images)
    needed = max(MIN_REAL_FILES, 4 * folds)
    if distinct < needed:
        same = f" ({distinct} with distinct pixels)" if distinct < len(real.images) else ""
        raise DngError(where, f"{len(real.images)} usable DNG file(s){same}; the check needs at least {needed} "
                              "(cross-validated real training)")
    why = real_sets.label_problem(real)
    if why:
        raise DngError(where, why)
    notes = [f"{len(group)} files hold the same pixels (kept in one fold, so that none is tested on its own copy): "
             + ", ".join(Path(p).name for p in group) for group in real_sets.duplicates(real)]
    return real, notes


def read_cg_images(paths, *, max_pixels: Optional[int] = DEFAULT_MAX_PIXELS,
                   problem: Callable[[str, str], None]) -> tuple[list, list]:
    """Linear float32 CG images of `paths` (files or folders) and their paths; each unusable file
    is passed to `problem(path, reason)` and left out. sRGB files are decoded by IEC 61966-2-1; a
    scene-linear EXR is scaled so that its 99.5th percentile is the render's white."""
    from g2r_jax.colour.conversions import srgb_to_linear
    from g2r_jax.io.images import read_images

    images, used = [], []
    for path, values, encoding in read_images(paths, max_pixels=max_pixels, min_side=MIN_CG_SIDE, problem=problem):
        if encoding == "srgb":
            linear = np.asarray(srgb_to_linear(values), np.float32)
        else:
            linear = values / max(float(np.percentile(values.mean(-1), 99.5)), 1e-6)
        images.append(np.clip(linear, 0.0, 1.0).astype(np.float32))
        used.append(path)
    if not images:
        raise DngError(" ".join(str(p) for p in paths), "no usable CG image")
    return images, used


def read_inputs(measured=(), cg=(), burst=None, *, folds: int = 3, max_pixels: Optional[int] = DEFAULT_MAX_PIXELS,
                on_problem: Optional[Callable[[str, str], None]] = None,
                progress: Optional[Callable[[str], None]] = None) -> Inputs:
    """Read and vet every input of the check (see the module docstring).

    **Arguments:** `measured`: folders or files of a camera's real DNGs (the colour check; may be
    empty with a `burst`); `cg`: folders or files of CG images; `burst`: a folder of DNGs of one
    static scene (the denoising check) or None; `folds`: the colour check's cross-validation
    folds (it needs 4 distinct files per fold, and at least 12); `max_pixels`: the largest CG
    image read; `on_problem(path, reason)`: called as each input is left out; `progress`: a
    callable taking one line of text.

    **Returns:** `Inputs`. **Raises:** `DngError` naming the folder when a check cannot run.
    """
    say = progress or (lambda line: None)
    inputs = Inputs()

    def problem(path, reason):
        inputs.problems.append((str(path), reason))
        if on_problem:
            on_problem(str(path), reason)

    if measured:
        inputs.real, inputs.notes = read_measured(measured, folds=folds, problem=problem)
        say(f"{len(inputs.real.images)} real DNG(s) of {inputs.real.name!r}, labelled by their "
            f"{inputs.real.label.split(' (')[0]}")
    if cg:
        inputs.cg, inputs.cg_paths = read_cg_images(cg, max_pixels=max_pixels, problem=problem)
        say(f"{len(inputs.cg)} CG image(s) read")
    if burst is not None:   # read before any training: a burst that cannot be used is refused first
        from g2r_jax.downstream.denoising.bursts import read_burst

        inputs.burst = read_burst(burst)
        for name, reason in inputs.burst.skipped:
            problem(str(Path(burst) / name), reason)
        say(f"burst of {inputs.burst.n} frames read")
    return inputs
