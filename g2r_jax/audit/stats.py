"""Per-file statistics that describe the sensor rather than the scene.

Each function takes one file's normalised CFA planes (4, H/2, W/2) (x = (DN - BlackLevel) /
(WhiteLevel - BlackLevel), tile positions in row-major order) and returns a small vector. All
but `dark_floor` work on planes from which the sensor's black (the BlackLevel tag plus the
pedestal known from scene-independent evidence, `black_evidence`) was subtracted; `dark_floor`
(the darkest scene content) is reported, never tested. `file_statistics` computes them all.
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np

from g2r_jax.measure import mad_sd
from g2r_jax.measure.robust import MAD_TO_STD as _MAD_TO_STD
from g2r_jax.measure.robust import trimmed_variance as _robust_variance
from g2r_jax.sensor.noise.estimation import to_normalised_planes


NLF_EDGES = np.array([-0.02, 0.01, 0.03, 0.06, 0.12, 0.25, 0.45, 0.7, 0.92])
RINGS = 7


LARGE_BLOCKS = 3000       # files with this many 8x8 blocks per plane carry their own noise evidence
STRIDE_PIXELS = 750_000   # per-plane pixel count above which some statistics read a strided subset


def _stride(planes) -> int:
    """Step for statistics that need many pixels but not all (about STRIDE_PIXELS per plane)."""
    return max(1, int(round(np.sqrt(planes[0].size / STRIDE_PIXELS))))   # mosaics with more pixels are held in float32 (half the memory traffic)


def block_means(planes, size: int) -> np.ndarray:
    """Means over non-overlapping size x size blocks of each plane (edges trimmed)."""
    p, h, w = planes.shape
    h, w = h - h % size, w - w % size
    return planes[:, :h, :w].reshape(p, h // size, size, w // size, size).mean(axis=(2, 4))


def radial_r2(plane_shape, *, step: int = 1) -> np.ndarray:
    """r^2 of every plane pixel (4, H/2, W/2), r = 1 in the corners (as the shading model,
    `sensor.radial_distance_squared`); with `step`, of every step-th plane pixel only."""
    half_h, half_w = plane_shape
    height, width = 2 * half_h, 2 * half_w
    norm = (height - 1) ** 2 / 4 + (width - 1) ** 2 / 4
    out = np.empty((4, len(range(0, half_h, step)), len(range(0, half_w, step))), np.float32)
    for p, (dy, dx) in enumerate(((0, 0), (0, 1), (1, 0), (1, 1))):
        rows = (np.arange(dy, height, 2)[::step] - (height - 1) / 2) ** 2
        cols = (np.arange(dx, width, 2)[::step] - (width - 1) / 2) ** 2
        out[p] = (rows[:, None] + cols[None, :]) / norm
    return out


def dark_floor(planes) -> np.ndarray:
    """(4,) dark floor: 0.5th percentile of 4x4 block means per plane.

    Black areas of a scene read BlackLevel + pedestal; block means shrink the noise (so the low
    percentile sits close to the floor, not in the noise tail). Compare with the BlackLevel tag.
    """
    return np.percentile(block_means(planes, 4).reshape(4, -1), 0.5, axis=1)


def clipping_level(planes, white_dn: float, span: np.ndarray) -> np.ndarray:
    """(4,) the level where each plane saturates, NaN where the file has no saturated area.

    Clipped pixels pile up at one value: the most populated DN in the top half of the range,
    kept when it holds at least 0.2% of the pixels (and 20) and five times the average count of
    the 3-12 DN below it (a spike, not a bright smooth area). Histogram method of e.g. Foi,
    "Clipped noisy images: heteroskedastic modeling and practical denoising", Signal Processing 2009.
    """
    out = np.full(4, np.nan)
    for p in range(4):
        dn = np.rint(planes[p] * span[p]).astype(np.int64).ravel()
        dn = dn[(dn > 0.5 * span[p])]
        if dn.size < 20:
            continue
        counts = np.bincount(dn - dn.min())
        peak = int(np.argmax(counts))
        below = counts[max(peak - 12, 0):max(peak - 2, 0)]
        background = below.mean() if below.size else 0.0
        if counts[peak] >= max(20, 0.002 * planes[p].size) and counts[peak] >= 5 * background:
            out[p] = (peak + dn.min()) / span[p]
    return out


def banding(planes) -> np.ndarray:
    """(2,) variance of per-row and per-column offsets (normalised units^2), averaged over planes.

    Differences of neighbouring same-colour rows, median over the left and over the right half
    of the columns: a row offset is common to both halves, noise and most scene content are not,
    so the covariance of the two halves estimates var(offset difference) = 2 var(offset); robust
    version from MADs: cov = (S(a+b)^2 - S(a-b)^2) / 4 (Gnanadesikan & Kettenring, Biometrics
    1972, robust covariance by the identity cov = (var(a+b) - var(a-b)) / 4).
    """
    result = []
    for axis_planes in (planes, np.swapaxes(planes, 1, 2)):
        values = []
        step = _stride(planes)
        for plane in axis_planes:
            diff = np.diff(plane[:, ::step], axis=0)
            half = diff.shape[1] // 2
            a, b = np.median(diff[:, :half], axis=1), np.median(diff[:, half:], axis=1)
            values.append((mad_sd(a + b) ** 2 - mad_sd(a - b) ** 2) / 8.0)
        result.append(np.mean(values))
    return np.asarray(result)


def flat_mask(planes, block: int = 2, relative: float = 0.06, absolute: float = 0.006) -> np.ndarray:
    """(4, H/2, W/2) True in flat areas: block x block means that differ from all four neighbour
    blocks by less than max(relative * mean, absolute). A scale-separated detail test (the
    smoothness selection of Foi et al. 2008, Sec. IV, with block means instead of wavelets)
    that does not use any noise model, so it cannot bias the noise estimate towards the profile."""
    means = block_means(planes, block)
    padded = np.pad(means, ((0, 0), (1, 1), (1, 1)), mode="edge")
    tolerance = np.maximum(relative * np.abs(means), absolute)
    flat = np.ones(means.shape, bool)
    for dy, dx in ((-1, 0), (1, 0), (0, -1), (0, 1)):
        neighbour = padded[:, 1 + dy:1 + dy + means.shape[1], 1 + dx:1 + dx + means.shape[2]]
        flat &= np.abs(neighbour - means) < tolerance
    mask = np.zeros(planes.shape, bool)
    h, w = means.shape[1] * block, means.shape[2] * block
    mask[:, :h, :w] = np.repeat(np.repeat(flat, block, axis=1), block, axis=2)
    return mask


def noise_level_function(planes, clip: np.ndarray, band: np.ndarray):
    """Noise variance per plane and signal bin (4, B) and the bin's mean signal (4, B).

    From differences of horizontally and vertically neighbouring same-colour pixels,
    d = (a - b) / sqrt(2), binned by their mean; var from the trimmed mean of d^2 (robust to edges),
    i.e. the flat-region local-variance method of Foi et al., "Practical Poissonian-Gaussian noise
    modeling and fitting for single-image raw-data", IEEE TIP 2008, with a robust scale instead
    of their ML fit. Column (row) banding adds its variance to the horizontal (vertical)
    differences; it is subtracted. Pairs near the clipping level are excluded, and so are pairs
    within `CENSORED_MARGIN` of the plane's floor when pixels pile up there (a sensor whose black
    level is 0 DN clips its noise at 0: there the variance measures the clipping, not the noise,
    and by how much depends on how much of the scene is black).
    """
    nb = len(NLF_EDGES) - 1
    variance, level = np.full((4, nb), np.nan), np.full((4, nb), np.nan)
    flat = flat_mask(planes)
    for p in range(4):
        top = (clip[p] if np.isfinite(clip[p]) else 1.0) - 0.06
        bottom = _censored_floor(planes[p])
        pieces = []
        for d_axis, excess in ((1, band[1]), (0, band[0])):
            a, f = planes[p], flat[p]
            lo = a[:, :-1] if d_axis == 1 else a[:-1]
            hi = a[:, 1:] if d_axis == 1 else a[1:]
            both = (f[:, :-1] & f[:, 1:]) if d_axis == 1 else (f[:-1] & f[1:])
            both &= (hi + lo) / 2 > bottom + CENSORED_MARGIN
            pieces.append(((hi - lo)[both] / np.sqrt(2), ((hi + lo) / 2)[both],
                           np.maximum(lo, hi)[both], excess))
        for b in range(nb):
            estimates, means = [], []
            for d, m, mx, excess in pieces:
                sel = (m >= NLF_EDGES[b]) & (m < NLF_EDGES[b + 1]) & (mx < top)
                if sel.sum() >= 40:
                    estimates.append(_robust_variance(d[sel]) - max(excess, 0.0))
                    means.append(m[sel].mean())
            if estimates:
                variance[p, b], level[p, b] = np.mean(estimates), np.mean(means)
    return variance, level


CENSORED_SHARE = 1e-3   # share of a plane's pixels at its lowest value above which the floor is a clip
CENSORED_MARGIN = 0.01  # normalised signal above a clipped floor below which no variance is measured


def _censored_floor(plane) -> float:
    """The plane's lowest value when at least `CENSORED_SHARE` of its pixels sit on it (noise
    clipped at 0 DN), else -inf (nothing to exclude)."""
    low = float(np.min(plane)) if plane.size else -np.inf
    return low if np.count_nonzero(plane <= low) >= CENSORED_SHARE * plane.size else -np.inf


def green_ratio(planes, green_positions, clip, floor=None) -> np.ndarray:
    """(1,) log(G2 / G1): the median over 4x4 blocks with both greens well exposed.

    The two green sites of a Bayer tile sample the same colour one pixel apart, so their ratio
    is 1 for any scene up to edge noise that the median removes; green imbalance shifts it.
    `planes` must carry one dark floor common to both greens (`floor`: the per-position floors
    that were subtracted; the greens get their mean back and lose it again): subtracting each
    green's own floor estimate, a noisy 0.5th percentile, adds a per-file Gr/Gb offset that in
    dark, high-ISO files (10-bit night profiles) is several DN and dominates the ratio.
    A radial fall-off acts on both greens alike, so shading does not move the ratio.
    """
    g1, g2 = green_positions
    greens = planes[[g1, g2]]
    if floor is not None:
        greens = greens + (np.asarray(floor)[[g1, g2]] - np.mean(np.asarray(floor)[[g1, g2]]))[:, None, None]
    blocks = block_means(greens, 4)
    top = 0.9 * np.nanmin(np.where(np.isfinite(clip[[g1, g2]]), clip[[g1, g2]], 1.0))
    ok = (blocks.min(0) > 0.03) & (blocks.max(0) < top)
    if ok.sum() < 20:
        return np.array([np.nan])
    return np.array([np.median(np.log(blocks[1][ok] / blocks[0][ok]))])


def shading_profile(planes, clip) -> np.ndarray:
    """(4,) log-gain at the corners per plane, c1 + c2 of log g(r) = c1 r^2 + c2 r^4, from radial
    gradients.

    Radial gradient symmetry (Zheng, Yu, Kang, Lin & Kambhamettu, "Single-image vignetting
    correction using radial gradient symmetry", CVPR 2008): in a scene without vignetting the
    radial derivative of log brightness is symmetric about zero; vignetting g(r) adds
    d log g / dr everywhere. The *median* radial derivative per ring (pixels whose four
    neighbours are exposed and unclipped) therefore measures d log g / dr = 2 c1 r + 4 c2 r^3,
    fitted by weighted least squares; any leftover scene bias is the same in measured and
    simulated files. The median, not a mean over a "flat" mask: at low signal (night files,
    10 bits, high ISO) a noise-blind flat test keeps only pixel pairs whose noise happened to
    cancel, which truncates the gradients towards zero by an amount that depends on the ISO,
    and leaves too few pixels in some rings; the median ignores scene edges and noise alike.
    """
    _, h, w = planes.shape
    half_diagonal = np.hypot(h - 1, w - 1) / 2
    y = (np.arange(h) - (h - 1) / 2)[:, None] / half_diagonal
    x = (np.arange(w) - (w - 1) / 2)[None, :] / half_diagonal
    r = np.broadcast_to(np.hypot(y, x), (h, w))
    unit_y, unit_x = y / np.maximum(r, 1e-9), x / np.maximum(r, 1e-9)
    inner = (slice(1, -1), slice(1, -1))
    r_in = r[inner]
    rings = np.minimum((r_in**2 * RINGS).astype(int), RINGS - 1)
    uy, ux = np.broadcast_to(unit_y, (h, w))[inner], np.broadcast_to(unit_x, (h, w))[inner]
    out = np.full(4, np.nan)
    for p in range(4):
        top = 0.9 * (clip[p] if np.isfinite(clip[p]) else 1.0)
        plane = planes[p]
        around = (plane[2:, 1:-1], plane[:-2, 1:-1], plane[1:-1, 2:], plane[1:-1, :-2], plane[inner])
        ok = (np.minimum.reduce(around) > 0.02) & (np.maximum.reduce(around) < top)
        log_p = np.log(np.maximum(plane, 1e-4))
        gy = (log_p[2:, 1:-1] - log_p[:-2, 1:-1]) / 2 * half_diagonal   # per unit of r
        gx = (log_p[1:-1, 2:] - log_p[1:-1, :-2]) / 2 * half_diagonal
        radial = gy * uy + gx * ux
        rows, targets, weights = [], [], []
        for k in range(RINGS):
            sel = ok & (rings == k)
            if sel.sum() < 20:
                continue
            rk = r_in[sel]
            rows.append([2 * rk.mean(), 4 * np.mean(rk**3)])
            targets.append(np.median(radial[sel]))
            weights.append(np.sqrt(sel.sum()))
        if len(rows) < 3:
            continue
        wts = np.asarray(weights)
        c = np.linalg.lstsq(np.asarray(rows) * wts[:, None], np.asarray(targets) * wts, rcond=None)[0]
        out[p] = c[0] + c[1]
    return out


def brightness(planes, r2, clip) -> np.ndarray:
    """(1,) exposure of the file: mean of the 30th-70th percentiles of log2 signal in the image
    centre (r^2 < 0.35, where shading is small). A global gain 2^e moves every percentile by
    exactly e as long as fewer than 30% of the pixels are black or clipped, so the statistic is
    equivariant to exposure; averaging nine percentiles smooths the steps of a piecewise-flat scene.
    `r2`: `radial_r2` of the planes, or None (computed on the strided grid only).
    """
    step = _stride(planes)
    r2 = radial_r2(planes.shape[1:], step=step) if r2 is None else r2[:, ::step, ::step]
    centre = planes[:, ::step, ::step][:, r2[0] < 0.35]
    levels = np.quantile(np.log2(np.maximum(centre, 1e-4)), np.linspace(0.3, 0.7, 9))
    return np.array([levels.mean()])


def centre_quantiles(planes) -> np.ndarray:
    """(9,) the 30th-70th percentiles of the image centre's signal that `brightness` averages in
    log2, in linear units: a constant added to every pixel moves each by exactly that constant,
    so the brightness the file would have from another black is known without measuring again
    (`audit.scene_pedestal`)."""
    step = _stride(planes)
    r2 = radial_r2(planes.shape[1:], step=step)
    return np.quantile(planes[:, ::step, ::step][:, r2[0] < 0.35], np.linspace(0.3, 0.7, 9))


def noise_correlation(planes) -> np.ndarray:
    """(1,) log of robust var(s2) / var(s1) along rows, mean of planes, where s1 = a[j+1] - 2 a[j]
    + a[j-1] and s2 = a[j+2] - 2 a[j] + a[j-2] are second differences at lags 1 and 2.

    For spatially white noise of variance v both are 6 v (ratio 1, log 0); noise correlated at lag
    1 (denoising, compression, demosaicing) makes s1 smaller: var(s1) = v (6 - 8 r1 + 2 r2),
    var(s2) = v (6 - 8 r2 + 2 r4) for correlations r_k. Second differences cancel the scene's
    linear trends, which first differences keep (a slope g adds g^2 to a lag-1 difference and 4 g^2
    to a lag-2 one): with first differences, the smooth shading of a clean rendered scene read as
    correlated noise (the README tour's file, p < 0.001). No vocabulary cause changes it.
    """
    values = []
    for plane, flat in zip(planes, flat_mask(planes)):
        centre = plane[:, 2:-2]
        s1 = plane[:, 3:-1] - 2 * centre + plane[:, 1:-3]
        s2 = plane[:, 4:] - 2 * centre + plane[:, :-4]
        level = (plane[:, 4:] + plane[:, 3:-1] + centre + plane[:, 1:-3] + plane[:, :-4]) / 5
        sel = (level > 0.05) & (level < 0.6) & flat[:, 4:] & flat[:, 2:-2] & flat[:, :-4]   # flat, noise-dominated
        if sel.sum() < 100:
            continue
        values.append(np.log(_robust_variance(s2[sel]) / max(_robust_variance(s1[sel]), 1e-20)))
    if not values:
        return np.array([np.nan])
    return np.array([np.mean(values)])


def outliers(planes, clip, threshold: float = 0.12):
    """Full-mosaic (row, col) of pixels far from the median of their 8 same-colour neighbours,
    and their values: candidate defective pixels (impulse detection by deviation from the
    neighbourhood median, as in median-based impulse detectors, e.g. Chan, Ho & Nikolova,
    "Salt-and-pepper noise removal by median-type noise detectors", IEEE TIP 2005). The
    threshold grows with the local spread (MAD of the 3x3 neighbourhood) so edges rarely qualify.
    Pixels on a plane's border are not candidates: three of their eight neighbours are reflected
    copies, which biases the median and the spread; in clean 120x180 files they were flagged in 4
    of 8 files often enough to pass the consistency test against its position-blind chance level."""
    rows, cols, values = [], [], []
    _, h, w = planes.shape
    padded = np.pad(planes, ((0, 0), (1, 1), (1, 1)), mode="reflect")
    shifts = [(dy, dx) for dy in (-1, 0, 1) for dx in (-1, 0, 1) if dy or dx]
    # |x - median| > threshold needs at least 4 of the 8 neighbours below x - threshold (or above
    # x + threshold): the median of 8 is the mean of the 4th and 5th smallest. Then any 5 of the
    # neighbours include one below (above) it: that cheap test on the whole plane leaves ~1 % of
    # the pixels, where the 8 neighbours are gathered, counted, and the medians taken.
    margin = planes.dtype.type(threshold * (1 - 1e-6))   # a superset of the pixels that can qualify
    view = lambda dy, dx: padded[:, 1 + dy:1 + dy + h, 1 + dx:1 + dx + w]
    low, high = view(*shifts[0]).copy(), view(*shifts[0]).copy()
    for dy, dx in shifts[1:5]:
        np.minimum(low, view(dy, dx), out=low)
        np.maximum(high, view(dy, dx), out=high)
    rough = np.nonzero((low < planes - margin) | (high > planes + margin))
    del low, high
    inside = (rough[1] > 0) & (rough[1] < h - 1) & (rough[2] > 0) & (rough[2] < w - 1)
    rough = tuple(index[inside] for index in rough)
    p_idx, r_idx, c_idx = rough
    neighbours = np.stack([padded[p_idx, r_idx + 1 + dy, c_idx + 1 + dx] for dy, dx in shifts])
    centre = planes[rough]
    candidate = (np.sum(neighbours < centre - margin, axis=0) >= 4) | (np.sum(neighbours > centre + margin, axis=0) >= 4)
    p_idx, r_idx, c_idx, centre, neighbours = p_idx[candidate], r_idx[candidate], c_idx[candidate], centre[candidate], neighbours[:, candidate]
    middle = np.partition(neighbours, (3, 4), axis=0)
    median = 0.5 * (middle[3] + middle[4])
    absolute = np.partition(np.abs(neighbours - median), (3, 4), axis=0)
    spread = _MAD_TO_STD * 0.5 * (absolute[3] + absolute[4])
    hit = np.abs(centre - median) > threshold + 6 * spread
    for p in range(4):
        chosen = hit & (p_idx == p)
        r, c = r_idx[chosen], c_idx[chosen]
        rows.append(2 * r + p // 2)
        cols.append(2 * c + p % 2)
        values.append(centre[chosen])
    return np.concatenate(rows), np.concatenate(cols), np.concatenate(values)


def gain_map_log_corner(opcode_lists, shape, cfa_pattern) -> np.ndarray:
    """(4,) log gain at the corners that a file's own lens-shading opcodes (GainMap,
    FixVignetteRadial in OpcodeList2) put on the raw: c1 + c2 of a least-squares fit
    log(1 / gain) = c1 r^2 + c2 r^4 on the plane grid (the form `shading_profile` measures).
    Zeros for a file without such opcodes."""
    if not opcode_lists or "OpcodeList2" not in dict(opcode_lists):
        return np.zeros(4)
    data = dict(opcode_lists)["OpcodeList2"]
    data = bytes.fromhex(data) if isinstance(data, str) else bytes(data)
    return _gain_map_log_corner(data, tuple(int(v) for v in shape), tuple(int(c) for c in np.asarray(cfa_pattern))).copy()


@functools.lru_cache(maxsize=16)
def _gain_map_log_corner(data: bytes, shape, cfa_pattern) -> np.ndarray:
    from g2r_jax.sensor.shading import rescale_opcode_list, shading_gain_planes

    height, width = shape
    step = max(1, min(height, width) // 400)          # the gains are smooth: a coarse grid will do
    small = (height // step // 2 * 2, width // step // 2 * 2)
    if small != (height, width):
        data = rescale_opcode_list(data, (height, width), small, shading_only=True)
    gain = shading_gain_planes({"OpcodeList2": data}, *small, tuple(np.asarray(cfa_pattern)))
    r2 = radial_r2(gain.shape[1:]).reshape(4, -1).astype(np.float64)
    log_inverse = -np.log(gain.astype(np.float64)).reshape(4, -1)
    out = np.zeros(4)
    for p in range(4):
        c = np.linalg.lstsq(np.stack([r2[p], r2[p] ** 2], 1), log_inverse[p], rcond=None)[0]
        out[p] = c[0] + c[1]
    return out


def thumbnail(planes, side: int = 16) -> np.ndarray:
    """(4, side, side) block means of each plane on a side x side grid: the scene at a glance
    (the frames of one burst have the same thumbnail up to noise); NaN for tiny planes."""
    size = min(planes.shape[1:]) // side
    if size < 1:
        return np.full((4, side, side), np.nan)
    return block_means(np.asarray(planes, np.float64), size)[:, :side, :side]


SHADING_SIDE = 600   # planes larger than this (shorter side) are binned before the shading fit


def file_statistics(mosaic, info, profile, *, with_outliers: bool = True, seed: int = 0,
                    nlf_tiles: int | None = None, pedestal_dn=None) -> dict:
    """All statistics of one file (mosaic (H, W) DN, its DngInfo) as a dict of numpy arrays.

    Keys: dark_floor (4), clip (4), band (2), nlf {"A", "B", "all"} (noise level function of each
    checkerboard half of the tiles, `evidence.nlf_halves`, its `signal` above the BlackLevel tag, not
    above the measured floor; None in files of fewer than
    LARGE_BLOCKS blocks a plane, which have nlf_var, nlf_level instead), quantisation (4), iso, green (1),
    shading (4, raw shading minus what the file's own GainMap puts there), gain_map_shading (4),
    brightness (1), noise_corr (1), outliers (rows, cols, values) or None, neutral (3), shape, name, span.
    `nlf_tiles`: tiles per half for the NLF (default `evidence.MAX_TILES`; `evidence.tiles_per_half`).
    `pedestal_dn`: (4,) the sensor's black above the BlackLevel tag in DN, subtracted from the planes
    of every statistic but `dark_floor` and `black` (default: the profile's `black_pedestal`). Only
    scene-independent evidence (`black_evidence`) may set it: the measured dark floor reads the
    darkest scene content, which in a dim scene is far above black.
    Also: black (`black_evidence.file_evidence`: optical-black pixels or a dark frame, else None),
    dark_frame (bool), thumbnail (4, 16, 16) block means (burst detection, `bursts`).
    """
    from g2r_jax.audit import black_evidence, evidence

    black = np.resize(np.asarray(info.black_level, np.float64).reshape(-1), 4)
    white = float(info.white_level)
    raw = to_normalised_planes(mosaic, black, white)
    span = white - black
    floor = dark_floor(raw)
    found_black = black_evidence.file_evidence(mosaic, info, black, span)
    dark_frame = found_black is not None and found_black["source"] == "dark frame"
    pedestal = np.resize(np.asarray(profile.effects.black_pedestal if pedestal_dn is None else pedestal_dn,
                                    np.float64), 4) / span
    planes = raw - pedestal[:, None, None].astype(raw.dtype)
    spike = clipping_level(raw, white, span)
    # a spike at WhiteLevel is the tag's clamp (whatever the pedestal), not an early clip
    clip = np.where(spike >= 1.0 - 0.5 / span, 1.0, spike - pedestal)
    band = banding(planes)
    top = np.where(np.isfinite(spike), spike, 1.0) - 2.0 / span
    blocks = planes[0].size / 64
    # large files: the NLF of each half of the tiles, tested in closed form (on the
    # black-subtracted planes, like every statistic but the floor);
    # small files: the neighbour-pair NLF, compared with simulated files over files
    nlf = (evidence.nlf_halves(planes, clip=top - pedestal, clip_low=-black / span + 2.0 / span - pedestal,
                               seed=seed, max_tiles=nlf_tiles or evidence.MAX_TILES)
           if blocks >= LARGE_BLOCKS and not dark_frame else None)
    if nlf is not None:
        # the NLF's signal axis is above the BlackLevel tag (`causes.noise_model.above_black`)
        nlf = {half: dataclasses.replace(e, signal=e.signal + pedestal[:, None]) for half, e in nlf.items()}
    nlf_var, nlf_level = noise_level_function(planes, clip, band) if blocks < LARGE_BLOCKS else (None, None)
    greens = tuple(int(i) for i in np.flatnonzero(np.asarray(info.cfa_pattern) == 1)[:2])
    from g2r_jax.profile import fitting as _fit
    neutral = _fit.as_shot_neutral(info)
    iso = info.iso if info.iso else float(np.sqrt(np.prod(np.asarray(profile.noise.iso_range, np.float64))))
    binning = max(1, min(planes.shape[1:]) // SHADING_SIDE)
    shading_planes = block_means(planes, binning) if binning > 1 else planes
    gain_map = gain_map_log_corner(getattr(info, "opcode_lists", None), np.shape(mosaic), info.cfa_pattern)
    return {
        "dark_floor": floor, "black": found_black, "dark_frame": dark_frame, "thumbnail": thumbnail(planes),
        "clip": clip, "band": band, "nlf": nlf, "blocks": blocks,
        "nlf_var": nlf_var, "nlf_level": nlf_level,
        "quantisation": evidence.quantisation_variance(black, white),
        "iso": float(iso), "green": green_ratio(planes, greens, clip),
        "shading": shading_profile(shading_planes, clip) - gain_map, "gain_map_shading": gain_map,
        "brightness": brightness(planes, None, clip), "centre_quantiles": centre_quantiles(planes),
        "noise_corr": noise_correlation(planes if _stride(planes) == 1 else evidence.tile_halves(planes)[0]),
        "outliers": outliers(planes, clip) if with_outliers else None,
        "neutral": None if neutral is None else np.asarray(neutral, np.float64),
        "shape": tuple(np.shape(mosaic)), "name": str(getattr(info, "path", "")), "span": span,
    }
