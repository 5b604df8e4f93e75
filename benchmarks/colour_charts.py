"""Colour against a real camera (issue 10): how well does each colour model predict the raw RGB of
the 24 ColorChecker patches in real photographs, and what does the refit gain on held-out images?

Rows (angular error between predicted and measured patch RGB, degrees):
- g2r_jax with the camera's Adobe D65 ColorMatrix: `unprocess_batch` on a chart image (the
  ColorChecker N Ohta reflectances under D65 as sRGB), neutral = each photo's measured
  illuminant, no noise, exposure 1, per-channel patch means of the mosaic;
- the published recipe (`recipe="published"`), same matrix;
- g2r_jax with a ColorMatrix pair refitted on the other two folds of the release's standard
  3-fold split (`colour_fit.cross_validated_refit`; every image scored by a fit that did not see it);
- no colour transform: the chart's linear sRGB times the measured illuminant.

    python benchmarks/gehler_shi_charts.py -o out/
    python benchmarks/colour_charts.py --charts out/gehler_shi_5d.csv --profile out/gehler_shi_5d.json
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from g2r_jax.colour import charts as C  # noqa: E402
from g2r_jax.colour import chart_fit as F  # noqa: E402
from g2r_jax.pipeline import simulate_patches  # noqa: E402


def run(charts_path, profile_path, progress=print) -> dict:
    from g2r_jax.profile.schema import load_profile

    charts = C.read_charts(charts_path)
    profile = load_profile(profile_path)
    rows = {}
    rows["g2r_jax, Adobe D65 ColorMatrix"] = F.patch_errors(simulate_patches(profile, charts.illuminant), charts)
    rows["published recipe, same matrix"] = F.patch_errors(
        simulate_patches(profile, charts.illuminant, recipe="published"), charts)
    cv = F.cross_validated_refit(profile, charts, C.folds_of(charts), progress=progress)
    rows["g2r_jax, refitted ColorMatrix pair (held-out)"] = cv["after"]
    no_transform = np.clip(C.chart_linear_srgb(), 0, None)[None] * charts.illuminant[:, None, :]
    rows["no colour transform (sRGB x neutral)"] = F.patch_errors(no_transform, charts)
    return {"rows": {name: F.summarise(e) for name, e in rows.items()}, "n_images": len(charts),
            "fold_before": cv["fold_before"], "fold_after": cv["fold_after"],
            "closed_form_before": F.summarise(cv["before"])}


def table(result) -> str:
    lines = ["| colour model | chromatic patches mean / median / p95 | red patch median | neutral patches mean |",
             "|---|---|---|---|"]
    for name, s in result["rows"].items():
        lines.append(f"| {name} | {s['chromatic_mean']:.2f} / {s['chromatic_median']:.2f} / {s['chromatic_p95']:.1f} "
                     f"| {s['patch_median'][14]:.1f} | {s['neutral_mean']:.2f} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--charts", required=True, help="chart CSV (benchmarks/gehler_shi_charts.py)")
    parser.add_argument("--profile", required=True, help="profile with the camera's Adobe matrix")
    args = parser.parse_args(argv)
    started = time.perf_counter()
    result = run(args.charts, args.profile)
    print(f"\n{result['n_images']} real charts ({Path(args.charts).name}); angular error in degrees\n")
    print(table(result))
    print(f"\nheld-out chromatic mean per fold, before -> after the refit: "
          + ", ".join(f"{b:.2f} -> {a:.2f}" for b, a in zip(result["fold_before"], result["fold_after"])))
    print(f"({time.perf_counter() - started:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
