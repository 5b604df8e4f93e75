"""CPU cost of training the downstream illuminant estimators (g2r_jax.downstream.illuminant.estimators).

The NUS benchmark trains each estimator about 800 times within 40 minutes on two cores, so one
training must cost about a second of CPU. This measures, on `--n` thumbnails (the NUS Canon600D
set resampled with replacement when ../shared/data is there, synthetic scenes otherwise):
- the CNN's compile (once per set capacity, a power of two) and one training after it;
- the same training with lax.conv in place of the shifted-copies matrix product (`SameConv`);
- `train_many` of `--many` sets in one vmapped program against as many separate trainings;
- moments and histogram trainings.
Times are process CPU seconds (both cores count), medians of `--repeats`.

usage: python benchmarks/downstream_estimators_speed.py [--n 1000] [--many 4] [--repeats 3]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

NUS = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "estimation" / "nus" / "Canon600D.npz"


def thumbnails(n: int, seed: int):
    rng = np.random.default_rng(seed)
    if NUS.exists():
        data = np.load(NUS)
        pick = rng.integers(0, len(data["images"]), n)
        return data["images"][pick].astype(np.float32), data["illuminants"][pick], "NUS Canon600D, resampled"
    lights = np.stack([rng.uniform(0.3, 0.9, n), np.ones(n), rng.uniform(0.3, 0.9, n)], 1)
    surfaces = np.repeat(np.repeat(rng.uniform(0.05, 1, (n, 8, 8, 3)), 8, 1), 8, 2)
    images = surfaces * lights[:, None, None]
    return (images / images.reshape(n, -1).max(1)[:, None, None, None]).astype(np.float32), lights, "synthetic"


def cpu(function, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.process_time()
        function()
        times.append(time.process_time() - start)
    return float(np.median(times))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--n", type=int, default=1000)
    parser.add_argument("--many", type=int, default=4)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()

    import jax
    from g2r_jax.downstream.illuminant import estimators as est

    images, lights, source = thumbnails(args.n, 0)
    print(f"{args.n} thumbnails ({source}); CnnConfig: {est.CnnConfig()}")

    start = time.process_time()
    est.train_cnn(images, lights, seed=0)
    first = time.process_time() - start
    one = cpu(lambda: est.train_cnn(images, lights, seed=1), args.repeats)
    print(f"cnn: first training (compile included) {first:.2f} s CPU; each further training {one:.2f} s CPU")

    sets = [thumbnails(args.n, s)[:2] for s in range(args.many)]
    est.train_many_cnn(sets, list(range(args.many)))
    many = cpu(lambda: est.train_many_cnn(sets, list(range(args.many))), args.repeats)
    print(f"cnn: train_many of {args.many} sets {many:.2f} s CPU ({many / args.many:.2f} per model) "
          f"against {one * args.many:.2f} s for {args.many} separate trainings")

    from g2r_jax.downstream.base import training

    matrix_product = est.SameConv.__call__

    def lax_conv(layer, x):
        return jax.lax.conv_general_dilated(x, layer.weight, (1, 1), "SAME",
                                            dimension_numbers=("NHWC", "HWIO", "NHWC")) + layer.bias

    est.SameConv.__call__ = lax_conv
    training._compiled.cache_clear()
    try:
        est.train_cnn(images, lights, seed=0)
        with_lax = cpu(lambda: est.train_cnn(images, lights, seed=1), args.repeats)
    finally:
        est.SameConv.__call__ = matrix_product
        training._compiled.cache_clear()
    print(f"cnn: one training with lax.conv {with_lax:.2f} s CPU, with the shifted-copies product {one:.2f} s")

    for kind in ("moments", "histogram"):
        seconds = cpu(lambda: est.train_estimator(kind, images, lights, seed=0)(images), args.repeats)
        print(f"{kind}: one training + prediction on the {args.n} images {seconds:.2f} s CPU")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
