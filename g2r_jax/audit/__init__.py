"""Audit: measured DNGs against the profile's simulation (issue 3, `g2r-diagnose`).

Show what the simulation gets wrong (scene-independent statistics, tested over files), name
the cause from a fixed vocabulary, fit the effect as a profile extension on a fit split, and
keep it only if it lowers the discrepancy on held-out files.

Modules: `scenes` (built-in dead-leaves scenes), `simulate` (profile -> simulated files),
`stats` (per-file statistics), `measures` (statistic vector per cause), `significance` (tests
over files), `vocabulary` (cause ids), `extensions` (fit/apply per cause), `gain` (held-out
cross-validation), `diagnose` (the pipeline), `report` (JSON, summary, HTML), `synthetic`
(demo camera and hidden-effect injection for tests and benchmarks), `loading` (files).
"""

from .diagnose import diagnose
from .vocabulary import CAUSES, UNEXPLAINED

__all__ = ["diagnose", "CAUSES", "UNEXPLAINED"]
