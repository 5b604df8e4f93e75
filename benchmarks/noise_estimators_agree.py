"""Do the noise estimators agree on the same pixels? Photon transfer over a synthetic burst
(`g2r_jax.measure.photon_transfer.temporal_nlf`, fitted by weighted least squares) and the profile fallback
(`sensor.noise.fallback.measure_pooled`: flat 8 x 8 blocks of the 8 frames pooled), against the
truth of `g2r_jax.audit.synthetic_bursts` (8 frames of 512 x 768, 10 and 14 bits).

    python benchmarks/noise_estimators_agree.py FPN   (FPN: 0 = none, 1 = 1 % / 0.5 % PRNU and 0.3 / 1 DN DSNU)
"""
import sys, tempfile, numpy as np
from pathlib import Path
from g2r_jax.audit.synthetic_bursts import BurstTruth, burst, scene_signal
from g2r_jax.audit import bursts
from g2r_jax.measure.photon_transfer import temporal_nlf
from g2r_jax.audit.evidence import nlf_edges
from g2r_jax.io.dng_write import write_dng
from g2r_jax.io.dng_read import read_dng_info
from g2r_jax.sensor.noise import fallback
import g2r_jax
tags = g2r_jax.load_profile('s20fe_night').colour.dng_tags()
for name, truth, low, high in (("10-bit", BurstTruth(black_tag=64, white=1023, shot=0.8/80/959, read=1.2/959**2, prnu=float(sys.argv[1])*0.01, dsnu_dn=float(sys.argv[1])*0.3), 0.004, 0.3),
                                ("14-bit", BurstTruth(black_tag=512, white=16383, shot=2e-5, read=4e-7, iso=200, prnu=float(sys.argv[1])*0.005, dsnu_dn=float(sys.argv[1])*1.0), 0.002, 0.5)):
    files = burst(truth, scene_signal(11, 512, 768, low=low, high=high), 8, seed=11)
    d = Path(tempfile.mkdtemp())
    infos = []
    for k, (m, info) in enumerate(files):
        info.cfa_pattern = (0, 1, 1, 2); info.calibration_illuminants = tags['calibration_illuminants']; info.color_matrices = tags['color_matrices']; info.illuminant_data = tags['illuminant_data']; p = d / f"f{k}.dng"; write_dng(p, m, info); infos.append(read_dng_info(p))
    (shot, read), _ = fallback.measure_pooled(infos)
    frames = np.stack([bursts.frame_planes(m, i.black_level, i.white_level, 0.0) for m, i in files])
    t = temporal_nlf(frames, pedestal=np.zeros(4), clip=np.full(4, 0.95), clip_low=np.full(4, -0.06), edges=nlf_edges())["all"]
    q = 1 / 12 / truth.span**2
    # photon transfer fit of the temporal NLF: var = s x + r, weighted least squares
    ok = np.isfinite(t.variance)
    A = np.stack([t.signal[ok], np.ones(ok.sum())], 1); w = 1 / t.se[ok]
    s_pt, r_pt = np.linalg.lstsq(A * w[:, None], t.variance[ok] * w, rcond=None)[0]
    print(f"{name}: truth shot {truth.shot:.3g} read+q {truth.read + q:.3g} | photon transfer shot {s_pt:.3g} ({s_pt/truth.shot-1:+.1%}) read {r_pt:.3g} ({r_pt/(truth.read+q)-1:+.1%}) | fallback (8 frames pooled) shot {np.mean(shot):.3g} ({np.mean(shot)/truth.shot-1:+.1%}) read {np.mean(read):.3g} ({np.mean(read)/(truth.read+q)-1:+.1%})")
