"""Which CIE 1931 chromaticities a light can have: the convex hull of the spectrum locus.

Every light is a non-negative mixture of monochromatic lights, and chromaticity mixes by
centre of gravity, so the chromaticities of all physical lights form the convex hull of the
spectrum locus (the locus and the line of purples; Wyszecki & Stiles, *Color Science*, 2nd ed.,
sec. 3.3.1). The locus is the CIE 1931 2-degree observer of colour-science, 360-830 nm.

A white point solved from a camera's AsShotNeutral through its DNG matrices is that light seen
through a 3x3 approximation of the camera, so a real narrow-band light can land just outside
the hull. `LOCUS_MARGIN` allows for that; it is set from a measurement (docs page
`validation/dng_conformance.md`): 115 measured lamp spectra of colour-science (CIE
illuminants and light sources, sodium and LED lamps included), seen through the measured
spectral sensitivities of the Canon EOS 600D and EOS-1Ds Mark III and solved through their
Adobe DNG matrices, land at most 0.011 outside (low-pressure sodium, 600D); narrow-band light
(20 nm wide, 420-680 nm) up to 0.108; the S20 FE's real sodium lamp, 0.008.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

LOCUS_MARGIN = 0.12   # CIE xy units outside the hull still taken as a real light (see the docstring)


@lru_cache(maxsize=1)
def locus_halfplanes() -> np.ndarray:
    """(F, 3) half-planes (a, b, c) of the hull of the CIE 1931 spectrum locus, a x + b y + c <= 0
    inside, (a, b) of unit length: a x + b y + c is the signed distance to each edge's line."""
    import colour
    from scipy.spatial import ConvexHull

    XYZ = np.asarray(colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"].values, np.float64)
    xy = XYZ[:, :2] / XYZ.sum(axis=1, keepdims=True)
    return ConvexHull(xy).equations


def distance_outside_locus(xy) -> float:
    """How far (CIE xy units) a chromaticity lies outside the hull of the spectrum locus: the
    largest signed distance to its edges' lines (<= 0 inside; outside, a lower bound of the
    Euclidean distance to the hull, equal to it wherever the nearest point is on an edge)."""
    planes = locus_halfplanes()
    xy = np.asarray(xy, np.float64).reshape(2)
    return float(np.max(planes[:, :2] @ xy + planes[:, 2]))


def is_light_chromaticity(xy, margin: float = LOCUS_MARGIN) -> bool:
    """Could a light have chromaticity `xy` (finite, x > 0, y > 0, within `margin` of the
    locus hull)? x, y > 0 keeps XYZ = (x / y, 1, (1 - x - y) / y) finite and of positive X."""
    xy = np.asarray(xy, np.float64).reshape(-1)
    return bool(xy.size == 2 and np.all(np.isfinite(xy)) and xy[0] > 0 and xy[1] > 0
                and distance_outside_locus(xy) <= margin)
