"""What adding g2r_jax RAW is worth by the number of labelled real files (issue 48): the colour
check's rows 'real' and 'real_plus_fitted' (`downstream.illuminant.augmentation`) trained on 10, 30, 100...
of the training folds' files (`experiment.illuminant_experiment(labelled=...)`), beside the full
check's figures at all files and g2r_jax alone ('fitted', which does not depend on the labels).
`g2r-downstream --curve 10,30,100` adds it to the report (a table and `augmentation.png`).
"""

from __future__ import annotations

import dataclasses
from typing import Callable, Optional, Sequence

import numpy as np

from g2r_jax.downstream.illuminant import experiment

__all__ = ["LabelledCurve", "run_curve", "ROWS"]

ROWS = ("real", "real_plus_fitted")


@dataclasses.dataclass
class LabelledCurve:
    """`points[estimator][count][row]`: the mean error (degrees, pooled over folds and seeds) and
    the seeds' range; count 'all' is the full check's; `alone[estimator]` g2r_jax alone."""

    camera: str
    points: dict
    alone: dict

    def to_dict(self) -> dict:
        return {"camera": self.camera, "points": self.points, "g2r_jax_alone": self.alone}

    def table(self) -> str:
        """Markdown: per estimator and number of labelled files, real alone and real + g2r_jax."""
        out = ["| estimator | labelled files | real alone | real + g2r_jax | change | g2r_jax alone |",
               "|---|---|---|---|---|---|"]
        for estimator, by_count in self.points.items():
            for count, rows in by_count.items():
                alone, added = rows["real"]["mean"], rows["real_plus_fitted"]["mean"]
                g2r = self.alone.get(estimator)
                out.append(f"| {estimator} | {count} | {alone:.2f} | {added:.2f} | {added / alone - 1:+.0%} | "
                           f"{'' if g2r is None else f'{g2r:.2f}'} |")
        return "\n".join(out)

    def figure(self, path) -> bool:
        """The curve as a PNG (written atomically); False without matplotlib."""
        return _figure(self, path)


def _point(result: experiment.ExperimentResult, estimator: str) -> dict:
    return {row: {k: result.summary(row, estimator)[k] for k in ("mean", "seed_min", "seed_max")} for row in ROWS}


def run_curve(real, profile, cg_images, full: experiment.ExperimentResult, *, counts: Sequence[int],
              estimators: Sequence[str], seeds, n: int, folds: int, workers: Optional[int] = None,
              progress: Optional[Callable[[str], None]] = None, cache=None) -> LabelledCurve:
    """The curve for `counts` labelled files (those below the training folds' size; the full
    check `full`, which must hold 'real' and 'real_plus_fitted', is the point 'all'); `cache` as
    the experiment's.

    **Returns:** a `LabelledCurve`. **Raises:** ValueError when `full` lacks the rows."""
    if not set(ROWS) <= set(full.rows):
        raise ValueError(f"the labelled-files curve needs the rows {', '.join(ROWS)} in the check")
    training = len(real.images) * (folds - 1) // folds
    points = {e: {} for e in estimators}
    for count in sorted(c for c in set(counts) if 0 < c < training):
        result = experiment.illuminant_experiment(real, profile, cg_images, rows=ROWS, estimators=estimators,
                                                  seeds=seeds, n=n, folds=folds, progress=progress, workers=workers,
                                                  labelled=count, cache=cache)
        for e in estimators:
            points[e][str(count)] = _point(result, e)
    for e in estimators:
        points[e]["all"] = _point(full, e)
    alone = {e: full.summary("fitted", e)["mean"] for e in estimators if "fitted" in full.rows}
    return LabelledCurve(camera=full.camera, points=points, alone=alone)


def trainings(counts, rows_files: int, estimators, seeds, folds: int) -> int:
    """Trainings of `run_curve` for the progress bar (an augmented row counts as one)."""
    return sum(experiment.trainings(ROWS, estimators, seeds, folds) for c in set(counts) if 0 < c < rows_files)


def _figure(curve: LabelledCurve, path) -> bool:
    try:
        import matplotlib
    except ImportError:
        return False
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from g2r_jax.downstream.base.figures import save_figure

    fig, axes = plt.subplots(1, len(curve.points), figsize=(4.2 * len(curve.points), 3.4), squeeze=False)
    for ax, (estimator, by_count) in zip(axes[0], curve.points.items()):
        labels = list(by_count)
        x = np.arange(len(labels))
        for row, name in (("real", "real files alone"), ("real_plus_fitted", "real files + g2r_jax")):
            means = [by_count[c][row]["mean"] for c in labels]
            low = [max(m - by_count[c][row]["seed_min"], 0.0) for m, c in zip(means, labels)]
            high = [max(by_count[c][row]["seed_max"] - m, 0.0) for m, c in zip(means, labels)]
            ax.errorbar(x, means, yerr=[low, high], marker="o", capsize=3, label=name)
        if estimator in curve.alone:
            ax.axhline(curve.alone[estimator], color="grey", linestyle="--", label="g2r_jax alone")
        ax.set_xticks(x, labels)
        ax.set_xlabel("labelled real files")
        ax.set_ylabel("mean angular error (degrees)")
        ax.set_title(f"{curve.camera}: {estimator}")
        ax.legend(fontsize=7)
    return save_figure(fig, path)
