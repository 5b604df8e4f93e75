"""How darktable's noise profiles relate to per-pixel raw noise (run from the repo root; ~20 s).

    python profiles/darktable_noise_scale.py

darktable's profiles (`data/noiseprofiles.json`) come from its profiling tool (`tools/noise/gen-profile`):
each raw is exported through darktable with the tool's history `profiling-shot.xmp` (white balance
coefficients 1, 1, 1; input and output profiles linear Rec709, so no colour matrix; the default PPG
demosaic), then `noiseprofile` splits the image with a one-level Haar transform and, per bin of the
low-pass brightness, takes the noise std as median(|HH|) / 0.6745; a line var = a x + b is fitted over
x in [0, 0.35] (red), [0, 0.9] (green), [0, 0.5] (blue). None of that is raw per-pixel variance: the HH
band holds a quarter of the variance of independent pixels, and the demosaic's interpolated (and
clamped) green is smoother than the raw.

This script emulates that measurement (our own implementation of the same steps) on mosaics of known
per-pixel Poisson-Gaussian noise and prints K = per-pixel variance slope / fitted slope for green, over
noise levels, scene colours and gradients. It also prints the channel ratios a_R/a_G and a_B/a_G that
the emulation gives without white balance: for daylight-coloured scenes about 2.3 and 1.6, as in
darktable's file (medians 2.16 and 1.72), which is how the file's red/blue slopes arise.
"""

from __future__ import annotations

import numpy as np

BINS = 300                                  # brightness bins of the measurement
FIT_RANGE = (0.35, 0.9, 0.5)                # x range of the line fit per channel (R, G, B)


def _shift(a, dy, dx):
    """a[y + dy, x + dx] (periodic; the borders are cut before measuring)."""
    return np.roll(a, (-dy, -dx), axis=(0, 1))


def demosaic_ppg(mosaic, cfa):
    """(3, H, W) RGB by a PPG-style demosaic: green at red/blue sites from the direction with the smaller
    gradient (a second-order guess clamped between the two neighbours), red/blue by colour differences."""
    s = lambda dy, dx: _shift(mosaic, dy, dx)
    guess_x = (s(0, -1) + mosaic + s(0, 1)) * 2 - s(0, 2) - s(0, -2)
    guess_y = (s(-1, 0) + mosaic + s(1, 0)) * 2 - s(2, 0) - s(-2, 0)
    grad_x = 3 * (abs(s(0, -2) - mosaic) + abs(s(0, 2) - mosaic) + abs(s(0, -1) - s(0, 1))) + \
        2 * (abs(s(0, 3) - s(0, 1)) + abs(s(0, -3) - s(0, -1)))
    grad_y = 3 * (abs(s(-2, 0) - mosaic) + abs(s(2, 0) - mosaic) + abs(s(-1, 0) - s(1, 0))) + \
        2 * (abs(s(3, 0) - s(1, 0)) + abs(s(-3, 0) - s(-1, 0)))
    clamp = lambda guess, a, b: np.clip(guess / 4, np.minimum(a, b), np.maximum(a, b))
    green = np.where(cfa == 1, mosaic, np.where(grad_x > grad_y, clamp(guess_y, s(-1, 0), s(1, 0)),
                                                clamp(guess_x, s(0, -1), s(0, 1))))

    def along(colour, dy, dx):   # colour-difference interpolation from the two neighbours along (dy, dx)
        known = np.where(cfa == colour, mosaic, 0.0)
        return (_shift(known, -dy, -dx) + _shift(known, dy, dx) + 2 * green
                - _shift(green, -dy, -dx) - _shift(green, dy, dx)) / 2

    def diagonal(colour):        # at the opposite colour's sites: the diagonal with the smaller gradient
        known = np.where(cfa == colour, mosaic, 0.0)
        pairs = [((-1, -1), (1, 1)), ((-1, 1), (1, -1))]
        grads, guesses = [], []
        for (ay, ax), (by, bx) in pairs:
            ka, kb, ga, gb = _shift(known, ay, ax), _shift(known, by, bx), _shift(green, ay, ax), _shift(green, by, bx)
            grads.append(abs(ka - kb) + abs(ga - green) + abs(gb - green))
            guesses.append(ka + kb + 2 * green - ga - gb)
        return np.where(grads[0] > grads[1], guesses[1] / 2,
                        np.where(grads[0] < grads[1], guesses[0] / 2, (guesses[0] + guesses[1]) / 4))

    red_in_row = (cfa == 1) & (_shift(cfa, 0, 1) == 0) | (cfa == 1) & (_shift(cfa, 0, -1) == 0)
    red = np.where(cfa == 0, mosaic, np.where(cfa == 2, diagonal(0),
                                              np.where(red_in_row, along(0, 0, 1), along(0, 1, 0))))
    blue = np.where(cfa == 2, mosaic, np.where(cfa == 0, diagonal(2),
                                               np.where(red_in_row, along(2, 1, 0), along(2, 0, 1))))
    return np.maximum(np.stack([red, green, blue]), 0.0)


def measured_slopes(rgb):
    """darktable's measurement: per channel, one-level Haar; std = median |HH| / 0.6745 per LL bin;
    slope a of the line var = a x + b over the channel's fit range."""
    slopes = []
    for channel, x_max in zip(rgb, FIT_RANGE):
        c = channel[: channel.shape[0] // 2 * 2, : channel.shape[1] // 2 * 2]
        low = (c[0::2, 0::2] + c[0::2, 1::2] + c[1::2, 0::2] + c[1::2, 1::2]) / 4
        high = np.abs(c[0::2, 0::2] - c[0::2, 1::2] - c[1::2, 0::2] + c[1::2, 1::2]) / 4
        bins = np.clip((low * BINS).astype(int), 0, BINS - 1)
        x, var = [], []
        for k in np.unique(bins):
            values = high[bins == k]
            if values.size >= 50 and k / BINS <= x_max:
                x.append(k / BINS)
                var.append((np.median(values) / 0.6745) ** 2)
        slopes.append(np.polyfit(x, var, 1)[0])
    return np.array(slopes)


def emulate(shot, raw_colour, scene, rng):
    """Slopes (R, G, B) darktable's measurement returns for a raw of per-pixel variance shot * x."""
    height, width = scene.shape
    cfa = np.ones((height, width), int)
    cfa[0::2, 0::2], cfa[1::2, 1::2] = 0, 2
    clean = scene * np.asarray(raw_colour)[cfa]
    mosaic = clean + np.sqrt(shot * clean) * rng.standard_normal(clean.shape)
    return measured_slopes(demosaic_ppg(mosaic, cfa)[:, 8:-8, 8:-8])


def scenes(rng, height=1024, width=1536):
    """Flat 32-pixel tiles, and smooth fields with mild and steep gradients (levels 0.01-0.9)."""
    from scipy.ndimage import zoom

    yield "flat tiles", np.kron(rng.uniform(0.01, 0.9, (height // 32, width // 32)), np.ones((32, 32)))
    for cells in (8, 96):
        coarse = rng.uniform(0.01, 0.9, (cells * 2 // 3 + 2, cells + 2))
        field = zoom(coarse, (height / coarse.shape[0], width / coarse.shape[1]), order=1)[:height, :width]
        yield f"gradients ({cells} cells)", field


def main() -> None:
    rng = np.random.default_rng(0)
    factors = []
    for name, scene in scenes(rng):
        for raw_colour in ((0.45, 1.0, 0.7), (0.8, 1.0, 0.35)):
            for shot in (5e-5, 8e-4):
                slopes = emulate(shot, raw_colour, scene, rng)
                factors.append(shot / slopes[1])
                print(f"{name:22s} raw colour {raw_colour}  shot {shot:g}:  K_green {shot / slopes[1]:5.2f}   "
                      f"a_R/a_G {slopes[0] / slopes[1]:.2f}  a_B/a_G {slopes[2] / slopes[1]:.2f}")
    print(f"K_green: median {np.median(factors):.2f}, range {min(factors):.2f}-{max(factors):.2f}")


if __name__ == "__main__":
    main()
