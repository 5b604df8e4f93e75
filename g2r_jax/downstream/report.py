"""The downstream check's report: `Report`, what `g2r_jax.downstream.run_check` returns, and
`write_report`, its files. The colour check's words, tables and plot (the rows side by side, the
gap to real training split into the profile's share and the CG content's, and what differs in the
content) are `downstream.illuminant.reporting`'s."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np

from g2r_jax.downstream.illuminant.experiment import ExperimentResult
from g2r_jax.downstream.illuminant.reporting import plot


@dataclasses.dataclass
class Report:
    """One downstream check. `camera`; `sentences`: the result in words, one per estimator (and
    one for the burst); `document`: everything as JSON-able data (report.json); `markdown`: the
    report page (report.md); `result`: the `ExperimentResult` (None without a colour check or in
    a dry run); `denoising`: the burst check's result or None; `isp`: the neural-ISP task's
    `downstream.isp.task.IspResult` or None; `problems`: (path, reason) of each
    input left out; `notes`: lines a user should know (files with the same pixels)."""

    camera: str
    sentences: list
    document: dict
    markdown: str
    result: ExperimentResult | None = None
    denoising: object = None
    isp: object = None
    curve: object = None     # `labelled_curve.LabelledCurve` with `run_check(curve=...)`
    problems: list = dataclasses.field(default_factory=list)
    notes: list = dataclasses.field(default_factory=list)

    @property
    def status(self) -> int:
        """The command's exit status: 1 when some input was left out, else 0."""
        return 1 if self.problems else 0


def _finite(value):
    """`value` with every non-finite float as None (JSON has no NaN)."""
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(v) for v in value]
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.ndarray):
        return _finite(value.tolist())
    return value


def write_report(report: Report, folder) -> list[Path]:
    """Write report.json, report.md and (with matplotlib) errors.png of a colour check, isp.png
    of an ISP task and augmentation.png of a labelled-files curve into
    `folder` (created if missing), each atomically.

    **Arguments:** `report`: a `Report`; `folder`: a path. **Returns:** the paths written.
    """
    from g2r_jax.io.atomic import atomic_write_bytes

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    written = [folder / "report.json", folder / "report.md"]
    atomic_write_bytes(written[0], (json.dumps(_finite(report.document), indent=1) + "\n").encode())
    atomic_write_bytes(written[1], report.markdown.encode())
    if report.result is not None and plot(report.result, folder / "errors.png"):
        written.append(folder / "errors.png")
    if report.isp is not None and report.isp.figure(folder / "isp.png"):
        written.append(folder / "isp.png")
    if report.curve is not None and report.curve.figure(folder / "augmentation.png"):
        written.append(folder / "augmentation.png")
    return written

