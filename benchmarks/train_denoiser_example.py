"""On-the-fly RAW synthesis inside a JAX training step: a small denoiser trained on noisy/clean
mosaic pairs made from sRGB crops by `unprocess_batch(..., return_clean=True)` in the jitted step.

    python benchmarks/train_denoiser_example.py                    # 8 crops of 256 x 256, 20 steps
    python benchmarks/train_denoiser_example.py --crop 512 --batch 16 --steps 50 --json out.json

One call gives the noisy input and its clean target (same illuminant, exposure and deterministic
sensor effects; the colour path is computed once). The script times the whole step and the
synthesis alone (the same jitted `unprocess_batch` call) and prints the share of the step that
synthesis takes. The model is deliberately plain JAX (three 3x3 convolutions on the packed
4-channel mosaic, residual, SGD) so the example needs nothing beyond g2r_jax's dependencies;
swap in any flax/equinox model and optax optimiser.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))


def pack(mosaic):
    """(B, H, W) mosaic -> (B, H/2, W/2, 4) CFA planes, channels last."""
    b, h, w = mosaic.shape
    return mosaic.reshape(b, h // 2, 2, w // 2, 2).transpose(0, 1, 3, 2, 4).reshape(b, h // 2, w // 2, 4)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--profile", default="Canon600D")
    parser.add_argument("--crop", type=int, default=256, help="square sRGB crop side (even)")
    parser.add_argument("--batch", type=int, default=8)
    parser.add_argument("--steps", type=int, default=20)
    parser.add_argument("--width", type=int, default=32, help="hidden channels of the denoiser")
    parser.add_argument("--lr", type=float, default=0.002, help="SGD step size")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args(argv)

    import jax
    import jax.numpy as jnp

    from g2r_jax.profile.schema import load_profile
    from g2r_jax.pipeline import unprocess_batch
    from throughput import test_image

    profile = load_profile(args.profile)
    black, white = float(np.mean(np.asarray(profile.black_level))), float(profile.white_level)
    scene = test_image(4 * args.crop, 4 * args.crop, seed=1)       # stands in for a folder of renders

    def crops(key):
        corners = jax.random.randint(key, (args.batch, 2), 0, 3 * args.crop)
        corners = corners - corners % 2          # keep the CFA phase of the crop
        cut = lambda c: jax.lax.dynamic_slice(jnp.asarray(scene), (c[0], c[1], 0), (args.crop, args.crop, 3))
        return jax.vmap(cut)(corners)

    def synthesise(key):
        k_crop, k_raw = jax.random.split(key)
        noisy, clean, _ = unprocess_batch(jax.random.split(k_raw, args.batch), crops(k_crop), profile,
                                          return_clean=True, quantize=False)
        normalise = lambda m: (pack(m) - black) / (white - black)
        return normalise(noisy), normalise(clean)

    def init(key):
        shapes = [(3, 3, 4, args.width), (3, 3, args.width, args.width), (3, 3, args.width, 4)]
        keys = jax.random.split(key, len(shapes))
        return [jax.random.normal(k, s) * np.sqrt(2.0 / (9 * s[2])) * (0.1 if i == 2 else 1.0)
                for i, (k, s) in enumerate(zip(keys, shapes))]

    def denoise(params, x):
        h = x
        for i, w in enumerate(params):
            h = jax.lax.conv_general_dilated(h, w, (1, 1), "SAME", dimension_numbers=("NHWC", "HWIO", "NHWC"))
            h = jax.nn.relu(h) if i < len(params) - 1 else h
        return x + h

    def loss(params, noisy, clean):
        return jnp.mean(jnp.abs(denoise(params, noisy) - clean))

    @jax.jit
    def step(params, key):
        noisy, clean = synthesise(key)                  # the RAW batch, made inside the step
        value, grads = jax.value_and_grad(loss)(params, noisy, clean)
        return [p - args.lr * g for p, g in zip(params, grads)], value

    synth_only = jax.jit(synthesise)
    params = init(jax.random.PRNGKey(0))
    keys = jax.random.split(jax.random.PRNGKey(1), args.steps)

    start = time.perf_counter()
    params, first = step(params, keys[0])
    jax.block_until_ready(params)
    compile_seconds = time.perf_counter() - start
    jax.block_until_ready(synth_only(keys[0]))

    losses, step_times, synth_times = [float(first)], [], []
    for key in keys[1:]:
        start = time.perf_counter()
        params, value = step(params, key)
        jax.block_until_ready(params)
        step_times.append(time.perf_counter() - start)
        start = time.perf_counter()
        jax.block_until_ready(synth_only(key))
        synth_times.append(time.perf_counter() - start)
        losses.append(float(value))
    step_s, synth_s = float(np.median(step_times)), float(np.median(synth_times))
    result = {"device": str(jax.devices()[0].device_kind), "profile": args.profile, "crop": args.crop,
              "batch": args.batch, "steps": args.steps, "first_step_seconds": compile_seconds,
              "step_seconds_median": step_s, "synthesis_seconds_median": synth_s,
              "synthesis_share": synth_s / step_s, "loss_first": losses[0], "loss_last": losses[-1]}
    print(f"{args.batch} crops of {args.crop}x{args.crop} on {result['device']}: step {1e3 * step_s:.1f} ms "
          f"(median of {len(step_times)}), synthesis alone {1e3 * synth_s:.1f} ms = "
          f"{100 * synth_s / step_s:.0f}% of the step; L1 loss {losses[0]:.4f} -> {losses[-1]:.4f}")
    if args.json:
        args.json.write_text(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
