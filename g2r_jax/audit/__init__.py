"""Audit: measured DNGs against the profile's simulation (issue 3, `g2r-diagnose`).

Show what the simulation gets wrong (scene-independent statistics, tested over files), name
the cause from a fixed vocabulary, fit the effect as a profile extension on a fit split, and
keep it only if it lowers the discrepancy on held-out files.

One place per cause: `causes/` holds one module per cause (what it measures, how it is tested,
how its extension is fitted, applied and validated) and the registry `causes.REGISTRY`; its
docstring states the interface. Adding a cause = one file + one registry line.

Other modules: `scenes` (built-in dead-leaves scenes), `simulate` (profile -> simulated files),
`stats` (per-file statistics), `significance` (tests over files), `vocabulary` (cause ids,
derived from the registry), `gain` (held-out cross-validation over any cause), `diagnose` (the
order: test, explain away, cross-validate, report), `report` (JSON, summary, HTML), `synthetic`
(demo camera and hidden-effect injection for tests and benchmarks), `loading` (files).
"""

from g2r_jax.audit.runner import diagnose
from g2r_jax.audit.vocabulary import CAUSES, UNEXPLAINED

__all__ = ["diagnose", "CAUSES", "UNEXPLAINED"]
