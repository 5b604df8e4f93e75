"""Evidence of the black level that does not depend on the scene.

A black pedestal (the sensor's black sitting above or below the BlackLevel tag) can only be
measured where the sensor sees no light:

- optical-black pixels: the `MaskedAreas` rectangles of the raw IFD and the margins of the raw
  frame outside `ActiveArea` (DNG specification 1.6, ch. 4, tags ActiveArea and MaskedAreas);
- dark frames in the measured set (a capture with the lens capped): a frame with no structure
  (its 8 x 8 block means spread no more than its pixel noise allows) whose level is near the tag
  (`g2r_jax.measure.dark_frames.is_dark_frame`, the detector profile fitting uses too).

The darkest content of a scene is not such evidence: a dim scene has no black, so its darkest
blocks read the scene, not the sensor. A file without optical-black pixels that is not a dark
frame carries no black-level evidence at all.

Per file the evidence is the mean of those pixels minus the tag, in DN per CFA position, with
its standard error, for each of two disjoint halves (even and odd rows of 2 x 2 tiles), so that
one file can fit a pedestal on one half and check it on the other.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from g2r_jax.measure.dark_frames import is_dark_frame

MIN_PIXELS = 256             # fewest optical-black pixels per CFA position worth a mean
CLIPPED_FRACTION = 1e-3      # evidence with more pixels at raw 0 than this is biased by the clip: not used
MASKED_AREAS_TAG = 50830


def _half_means(pixels_by_position) -> dict:
    """{"offset", "se", "count", "A", "B", "se_A", "se_B"} from per-position lists of (rows,
    values) in DN minus the tag; halves by the parity of the tile row."""
    out = {k: np.full(4, np.nan) for k in ("offset", "se", "A", "B", "se_A", "se_B")}
    out["count"] = np.zeros(4)
    for p, (rows, values) in enumerate(pixels_by_position):
        values = np.asarray(values, np.float64)
        if values.size < MIN_PIXELS:
            continue
        out["count"][p] = values.size
        out["offset"][p] = values.mean()
        out["se"][p] = values.std(ddof=1) / np.sqrt(values.size)
        for half, select in (("A", rows % 2 == 0), ("B", rows % 2 == 1)):
            part = values[select]
            if part.size >= MIN_PIXELS // 2:
                out[half][p] = part.mean()
                out["se_" + half][p] = part.std(ddof=1) / np.sqrt(part.size)
    return out


def masked_rectangles(info) -> list:
    """(top, left, bottom, right) rectangles of optical-black pixels in the full raw frame:
    the file's MaskedAreas and the margins outside its ActiveArea (empty when it has neither)."""
    height, width = int(info.height), int(info.width)
    rectangles = [tuple(int(v) for v in r) for r in (getattr(info, "masked_areas", None) or ())]
    area = getattr(info, "active_area", None)
    if area is not None and not rectangles:
        top, left, bottom, right = (int(v) for v in area)
        rectangles += [r for r in ((0, 0, top, width), (bottom, 0, height, width), (top, 0, bottom, left),
                                   (top, right, bottom, width)) if r[2] > r[0] and r[3] > r[1]]
    return rectangles


def read_masked_areas(path) -> tuple:
    """The MaskedAreas rectangles of the raw IFD of a DNG ((top, left, bottom, right), ...), or ()."""
    import tifffile

    try:
        with tifffile.TiffFile(str(path)) as tif:
            pages = list(tif.pages)
            for page in list(pages):
                pages.extend(getattr(page, "pages", None) or [])
            for page in pages:
                tag = page.tags.get(MASKED_AREAS_TAG) if hasattr(page, "tags") else None
                if tag is not None:
                    values = np.asarray(tag.value, np.int64).reshape(-1, 4)
                    return tuple(tuple(int(v) for v in row) for row in values)
    except Exception:  # noqa: BLE001 - no readable tag: no masked areas (the pixels are still audited)
        return ()
    return ()


def optical_black_pixels(info):
    """(full raw frame (H, W) uint16 or None, rectangles): the pixels outside the active image.
    In-memory files may carry them as `info.optical_black` ((rows, cols) array left of the active
    area, the CFA phase of the active area's columns); DNG files are read again in full by LibRaw
    when they have ActiveArea margins or MaskedAreas."""
    if getattr(info, "optical_black", None) is not None:
        return None, None
    path = Path(str(getattr(info, "path", "")))
    if not path.is_file():
        return None, []
    if getattr(info, "masked_areas", None) is None:
        info.masked_areas = read_masked_areas(path)
    rectangles = masked_rectangles(info)
    if not rectangles:
        return None, []
    import rawpy

    try:
        with rawpy.imread(str(path)) as raw:
            full = np.array(raw.raw_image, copy=True)
    except Exception:  # noqa: BLE001 - the active pixels decoded; margins that do not are no evidence
        return None, []
    if full.shape != (int(info.height), int(info.width)):
        return None, []
    return full, rectangles


def optical_black_evidence(info, black_dn) -> dict | None:
    """Black-level evidence of one file's optical-black pixels (see `_half_means`), or None."""
    black_dn = np.resize(np.asarray(black_dn, np.float64), 4)
    origin = (0, 0)
    values = [([], []) for _ in range(4)]
    in_memory = getattr(info, "optical_black", None)
    if in_memory is not None:
        block = np.asarray(in_memory)
        rows, cols = np.mgrid[0:block.shape[0], 0:block.shape[1]]
        pieces = [(block, rows, cols)]
    else:
        full, rectangles = optical_black_pixels(info)
        if full is None:
            return None
        area = getattr(info, "active_area", None)
        origin = (int(area[0]), int(area[1])) if area is not None else (0, 0)
        pieces = []
        for top, left, bottom, right in rectangles:
            rows, cols = np.mgrid[top:bottom, left:right]
            pieces.append((full[top:bottom, left:right], rows, cols))
    clipped, total = 0, 0
    for block, rows, cols in pieces:
        # the CFA pattern and BlackLevel repeat are anchored at the active area's top-left corner
        position = ((rows - origin[0]) % 2) * 2 + (cols - origin[1]) % 2
        clipped += int(np.sum(block == 0))
        total += block.size
        for p in range(4):
            select = position == p
            values[p][0].append(((rows[select] - origin[0]) // 2).ravel())
            values[p][1].append(block[select].astype(np.float64).ravel() - black_dn[p])
    if total == 0 or clipped > CLIPPED_FRACTION * total:
        return None
    merged = [(np.concatenate(r) if r else np.zeros(0, int), np.concatenate(v) if v else np.zeros(0))
              for r, v in values]
    out = _half_means(merged)
    if not np.any(out["count"] > 0):
        return None
    out["source"] = "optical black"
    return out


def dark_frame_evidence(mosaic, black_dn) -> dict:
    """Black-level evidence of a dark frame: its pixels' mean minus the tag (see `_half_means`)."""
    m = np.asarray(mosaic)
    black_dn = np.resize(np.asarray(black_dn, np.float64), 4)
    values = []
    for p, (dy, dx) in enumerate(((0, 0), (0, 1), (1, 0), (1, 1))):
        plane = m[dy::2, dx::2].astype(np.float64) - black_dn[p]
        rows = np.broadcast_to(np.arange(plane.shape[0])[:, None], plane.shape)
        values.append((rows.ravel(), plane.ravel()))
    out = _half_means(values)
    out["source"] = "dark frame"
    return out


def file_evidence(mosaic, info, black_dn, span) -> dict | None:
    """The black-level evidence of one file: its optical-black pixels, or, for a dark frame, all
    its pixels; None when it has neither (the usual case of a scene without masked pixels)."""
    found = optical_black_evidence(info, black_dn)
    if found is not None:
        return found
    black_dn = np.resize(np.asarray(black_dn, np.float64), 4)
    if is_dark_frame(mosaic, black_dn, black_dn + np.resize(np.asarray(span, np.float64), 4)):
        return dark_frame_evidence(mosaic, black_dn)
    return None


def pooled_offset(evidences, key: str = "offset"):
    """(offset (4,), se (4,), n_files (4,)) in DN over files' evidence (`key` "offset", "A" or
    "B"): inverse-variance mean, its standard error at least the between-file one (sd / sqrt(n))
    where three or more files have evidence (a dark frame's level drifts with temperature and
    time, which the within-file error does not show; random-effects safeguard as DerSimonian &
    Laird, Control. Clin. Trials 1986)."""
    se_key = "se" if key == "offset" else "se_" + key
    values = np.array([e[key] for e in evidences if e is not None]).reshape(-1, 4)
    errors = np.array([e[se_key] for e in evidences if e is not None]).reshape(-1, 4)
    ok = np.isfinite(values) & np.isfinite(errors) & (errors > 0)
    weights = np.where(ok, 1.0 / np.where(ok, errors, 1.0) ** 2, 0.0)
    total = weights.sum(0)
    n = ok.sum(0)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(total > 0, (weights * np.where(ok, values, 0.0)).sum(0) / total, np.nan)
        se = np.where(total > 0, 1.0 / np.sqrt(total), np.nan)
        spread = np.array([np.std(values[ok[:, p], p], ddof=1) / np.sqrt(n[p]) if n[p] >= 3 else 0.0
                           for p in range(4)])
    return mean, np.where(n >= 3, np.fmax(se, spread), se), n
