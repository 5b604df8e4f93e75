"""The real GoPro HERO6 frame's noise against its own NoiseProfile, and the fitted noise extension
(issue 9): measured noise level function per CFA channel with 95 % intervals, the noise's
spatial correlation, the held-out gain of the extension, and a simulation check.

    PYTHONPATH=$PWD python benchmarks/noise_gopro.py [--dng ../shared/data/dng/gopro_hero6_GOPR0024.dng]
        [--json out.json] [--sim-size 1500x2000]

1. Whole frame: `noise_estimation.estimate_noise_level_function` / `estimate_noise_correlation`
   on the normalised planes (BlackLevel 0, so raw DN 0 clips: clip_low = 0); the model is the
   file's NoiseProfile S x + O plus rounding (1/12 DN^2).
2. Hold-out: the planes' 64 x 64 squares in a checkerboard; the extension (monotone level
   function, correlation kernel: `profile.editing.fit_noise_extension`) is fitted on one half
   and judged on the other: mean |log(model / measured)| over the held-out bins, before
   (NoiseProfile) and after; mean |rho_model - rho_measured| at lags (0,1), (1,0), (1,1).
3. Simulation: `unprocess` with the extended profile on dead-leaves scenes (ISO 100, noise on,
   several exposures), measured by the same estimator on the measured frame's bins; the share of
   bins whose simulated variance lies inside the measured 95 % interval, and the mean |log ratio|.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from g2r_jax import load_profile  # noqa: E402
from g2r_jax.sensor.noise import estimation as ne  # noqa: E402
from g2r_jax.profile.editing import fit_noise_extension  # noqa: E402
from g2r_jax.sensor.noise import extension as nx  # noqa: E402
from g2r_jax.sensor.noise.estimation import to_normalised_planes  # noqa: E402
from g2r_jax.io.dng_read import read_dng_info, read_dng_pixels  # noqa: E402

N_BINS = 24
NEIGHBOURS = [ne.LAGS.index(l) for l in ((0, 1), (1, 0), (1, 1))]


def mean_abs_log_ratio(model, estimate):
    ok = estimate.valid()
    return float(np.mean(np.abs(np.log(model[ok] / estimate.variance[ok]))))


def simulate_planes(profile, height, width, seed=0, exposures=(0.06, 0.25, 1.0)):
    """Normalised planes of the profile's simulation of dead-leaves scenes at several exposures,
    concatenated side by side (one mosaic per exposure)."""
    import jax

    from g2r_jax.audit import scenes
    from g2r_jax.pipeline import unprocess

    out = []
    for i, gain in enumerate(exposures):
        image = scenes.dead_leaves(seed + i, height, width, n_leaves=400, r_min=12.0)
        mosaic, _ = unprocess(jax.random.PRNGKey(seed + i), image, profile, iso=100.0, exposure_gain=gain,
                              effects=False)
        out.append(to_normalised_planes(np.asarray(mosaic), np.asarray(profile.black_level, np.float64),
                                        float(profile.white_level)))
    return np.concatenate(out, axis=2)


def resimulate_frame(planes, profile, black, white, seed=0, blur=3.0):
    """The measured frame's own scene with the profile's simulated noise: each plane smoothed by
    a Gaussian (sigma `blur` plane pixels; the smoothing leaves ~1/(4 pi sigma^2) of the measured
    noise variance) as the clean signal, then the simulator's noise stage (`sensor.add_noise`
    with the profile's level function and kernel at ISO 100) and rounding to DN. Same scene,
    same blocks, same bins as the measurement."""
    import jax
    import jax.numpy as jnp
    from scipy.ndimage import gaussian_filter

    from g2r_jax import sensor

    clean = np.stack([gaussian_filter(plane, blur) for plane in planes]).astype(np.float32)
    iso = jnp.asarray(100.0, jnp.float32)
    shot, read = sensor.noise_parameters(iso, profile.noise)
    noisy = jax.jit(lambda key, mosaic: sensor.add_noise(
        key, mosaic, shot, read, level_knots=profile.noise.level_knots,
        level_variance=sensor.noise_level_at(iso, profile.noise),
        correlation_kernel=profile.noise.correlation_kernel))(jax.random.PRNGKey(seed), sensor.from_planes(jnp.asarray(clean)))
    span = white - black
    dn = np.clip(np.round(np.asarray(noisy, np.float64) * span.mean() + black.mean()), 0, white)
    return to_normalised_planes(dn, black, white)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--dng", default=str(REPO / ".." / "shared" / "data" / "dng" / "gopro_hero6_GOPR0024.dng"))
    parser.add_argument("--json", type=Path)
    parser.add_argument("--sim-size", default="1500x2000")
    args = parser.parse_args(argv)
    started = time.perf_counter()
    info = read_dng_info(args.dng)
    mosaic = read_dng_pixels(args.dng, info)
    black = np.resize(np.asarray(info.black_level, np.float64), 4)
    white = float(info.white_level)
    planes = to_normalised_planes(mosaic, black, white)
    clip_low = -black / (white - black)
    profile = load_profile("gopro_hero6")
    quant = ne.quantisation_variance(black, white)[:, None]
    report = {"file": str(args.dng), "noise_profile": np.asarray(info.noise_profile).tolist()}

    # 1. whole frame
    whole = ne.estimate_noise_level_function(planes, clip_low=clip_low, n_bins=N_BINS)
    correlation = ne.estimate_noise_correlation(planes, clip_low=clip_low, n_bins=N_BINS)
    model = nx.predicted_variance(profile.noise, 100.0, whole.signal) + quant
    print(f"measured noise level function of {Path(args.dng).name} ({mosaic.shape[1]}x{mosaic.shape[0]}), "
          f"normalised units; model = NoiseProfile S x + O + 1/12 DN^2")
    channels = "R Gr Gb B".split()
    report["whole"] = {"estimate": whole.as_dict(), "model": model.tolist()}
    for p in range(4):
        print(f"  {channels[p]}: signal   variance [95% interval]        model/measured  blocks kept/rejected")
        for b in np.flatnonzero(whole.valid()[p]):
            print(f"      {whole.signal[p, b]:.4f}  {whole.variance[p, b]:.3e} [{whole.lower[p, b]:.3e}, "
                  f"{whole.upper[p, b]:.3e}]  {model[p, b] / whole.variance[p, b]:6.2f}  "
                  f"{whole.counts[p, b]}/{whole.rejected[p, b]}")
    print("  noise correlation rho at lags (0,1), (1,0), (1,1) within each CFA plane [95% interval]; white?")
    for p in range(4):
        values = ", ".join(f"{correlation.rho[p, k]:.3f} [{correlation.lower[p, k]:.3f}, {correlation.upper[p, k]:.3f}]"
                           for k in NEIGHBOURS)
        print(f"  {channels[p]}: {values}; white: {bool(correlation.white[p])}")
    report["correlation"] = correlation.as_dict()

    # 2. hold-out over regions
    fit_half, test_half = ne.checkerboard_regions(planes.shape[1:], 64)
    fit_est = ne.estimate_noise_level_function(planes, clip_low=clip_low, region=fit_half, n_bins=N_BINS)
    fit_corr = ne.estimate_noise_correlation(planes, clip_low=clip_low, region=fit_half, n_bins=N_BINS)
    test_est = ne.estimate_noise_level_function(planes, clip_low=clip_low, region=test_half, n_bins=N_BINS)
    test_corr = ne.estimate_noise_correlation(planes, clip_low=clip_low, region=test_half, n_bins=N_BINS)
    before = nx.predicted_variance(profile.noise, 100.0, test_est.signal) + quant
    report["heldout"] = {}
    extended = {}
    for name, monotone in (("monotone", True), ("free", False)):
        ext = fit_noise_extension(fit_est, profile, correlation=fit_corr, monotone=monotone)
        extended[name] = ext
        after = nx.predicted_variance(ext.noise, 100.0, test_est.signal) + quant
        kernel_rho = np.stack([nx.kernel_autocorrelation(k) for k in np.asarray(ext.noise.correlation_kernel)])
        rho_before = float(np.mean(np.abs(test_corr.rho[:, NEIGHBOURS])))
        rho_after = float(np.mean(np.abs(test_corr.rho[:, NEIGHBOURS] - kernel_rho[:, NEIGHBOURS])))
        report["heldout"][name] = {
            "variance_mean_abs_log_ratio": {"before": mean_abs_log_ratio(before, test_est),
                                            "after": mean_abs_log_ratio(after, test_est)},
            "rho_mean_abs_difference": {"before": rho_before, "after": rho_after},
            "bins": int(test_est.valid().sum()),
            "level_knots": np.asarray(ext.noise.level_knots).tolist(),
            "level_variance": np.asarray(ext.noise.level_variance)[0].tolist(),
            "correlation_kernel": np.asarray(ext.noise.correlation_kernel).tolist()}
        r = report["heldout"][name]
        print(f"held-out regions ({name} level function): mean |log(model/measured)| over {r['bins']} bins "
              f"{r['variance_mean_abs_log_ratio']['before']:.3f} -> {r['variance_mean_abs_log_ratio']['after']:.3f}; "
              f"mean |rho difference| {rho_before:.3f} -> {rho_after:.3f}")

    # 3. simulation with the extended profile, measured by the same estimator
    height, width = (int(v) for v in args.sim_size.split("x"))
    report["simulation"] = {}
    for name, ext in extended.items():
        simulated = simulate_planes(ext, height, width)
        sim = ne.estimate_noise_level_function(simulated, clip_low=clip_low, edges=whole.edges)
        sim_corr = ne.estimate_noise_correlation(simulated, clip_low=clip_low, edges=whole.edges)
        both = sim.valid() & whole.valid()
        inside = (whole.lower[both] <= sim.variance[both]) & (sim.variance[both] <= whole.upper[both])
        overlap = (sim.lower[both] <= whole.upper[both]) & (whole.lower[both] <= sim.upper[both])
        ratio = sim.variance[both] / whole.variance[both]
        report["simulation"][name] = {
            "bins": int(both.sum()), "inside_measured_interval": float(inside.mean()),
            "intervals_overlap": float(overlap.mean()),
            "mean_abs_log_ratio": float(np.mean(np.abs(np.log(ratio)))),
            "ratio_sim_over_measured": np.where(both, sim.variance / whole.variance, np.nan).tolist(),
            "rho_sim": sim_corr.rho[:, NEIGHBOURS].tolist()}
        s = report["simulation"][name]
        print(f"simulation with the extended profile ({name}): {s['bins']} common bins, simulated variance inside "
              f"the measured 95% interval in {s['inside_measured_interval']:.0%}, intervals overlap in "
              f"{s['intervals_overlap']:.0%}, mean |log(sim/measured)| {s['mean_abs_log_ratio']:.3f}; "
              f"ratios per channel and bin:")
        for p in range(4):
            print(f"  {channels[p]}: " + " ".join(f"{v:.2f}" for v in sim.variance[p][both[p]] / whole.variance[p][both[p]]))
        print(f"  simulated rho (0,1),(1,0),(1,1): {np.round(sim_corr.rho[:, NEIGHBOURS], 3).tolist()}")
    report["resimulated_frame"] = {}
    for name, ext in extended.items():
        simulated = resimulate_frame(planes, ext, black, white)
        sim = ne.estimate_noise_level_function(simulated, clip_low=clip_low, edges=test_est.edges, region=test_half)
        both = sim.valid() & test_est.valid()
        inside = (test_est.lower[both] <= sim.variance[both]) & (sim.variance[both] <= test_est.upper[both])
        overlap = (sim.lower[both] <= test_est.upper[both]) & (test_est.lower[both] <= sim.upper[both])
        ratio = sim.variance[both] / test_est.variance[both]
        report["resimulated_frame"][name] = {
            "bins": int(both.sum()), "inside_measured_interval": float(inside.mean()),
            "intervals_overlap": float(overlap.mean()), "mean_abs_log_ratio": float(np.mean(np.abs(np.log(ratio)))),
            "ratio_sim_over_measured": np.where(both, sim.variance / test_est.variance, np.nan).tolist()}
        s = report["resimulated_frame"][name]
        print(f"the frame's own scene re-noised by the extended profile ({name}), held-out regions: {s['bins']} bins, "
              f"simulated variance inside the measured 95% interval in {s['inside_measured_interval']:.0%}, "
              f"intervals overlap in {s['intervals_overlap']:.0%}, mean |log(sim/measured)| {s['mean_abs_log_ratio']:.3f}")
        for p in range(4):
            print(f"  {channels[p]}: " + " ".join(f"{v:.2f}" for v in sim.variance[p][both[p]] / test_est.variance[p][both[p]]))
    report["seconds"] = time.perf_counter() - started
    print(f"{report['seconds']:.0f} s")
    if args.json:
        args.json.write_text(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
