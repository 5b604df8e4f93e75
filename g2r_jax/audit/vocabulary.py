"""The cause vocabulary of the audit (ids used in REPORT.json), derived from the registry
(`causes.REGISTRY`): every cause with an extension is a vocabulary word; a significant difference
that no extension explains is reported as `unexplained`.

`STATISTICS`, `FLOOR`, `TOLERANCE`: per registered cause, what it measures, the statistic's
resolution (added to standard errors) and the smallest difference worth reporting (in the
statistic's units), so that a statistically certain but physically irrelevant difference is not
called a finding. Each is defined in the cause's own module.
"""

from __future__ import annotations

from g2r_jax.audit.causes import REGISTRY

CAUSES = tuple(c.name for c in REGISTRY if c.extensible)
# causes whose evidence is measured DNG files (the others, e.g. colour_matrix, read measured charts)
FILE_CAUSES = tuple(c.name for c in REGISTRY if c.extensible and getattr(c, "evidence", "files") == "files")
UNEXPLAINED = "unexplained"
STATISTICS = {c.name: c.statistic for c in REGISTRY}
FLOOR = {c.name: c.floor for c in REGISTRY}
TOLERANCE = {c.name: c.tolerance for c in REGISTRY}
