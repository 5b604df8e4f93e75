"""Downstream truth: does a network trained on synthetic RAW work on the real camera?

The paper's own test (Graphics2RAW, Seo et al. ICCV 2023, Tables 1, 2 and S1-S6): train a task
network on synthetic RAW made from CG images, test it on real RAW images of the target camera
with measured truth, beside the same network trained on UPI's synthetic RAW (Brooks et al.
CVPR 2019) and on the real images themselves, and controls that split the gap into the profile's
share and the CG content's.

The public API (loaded on first use, so that importing the package stays cheap):

- `run_check(measured, cg, *, burst=None, profile=None, estimators=..., seeds=2, n=600, folds=3,
  ...) -> Report`: the whole check, what `g2r-downstream` runs (`downstream.check`);
- `read_inputs(...) -> Inputs`: only the reading and vetting of the inputs (`downstream.inputs`);
- `write_report(report, folder)`: report.json, report.md and errors.png (`downstream.report`).
"""

_PUBLIC = {"run_check": "check", "default_rows": "check", "read_inputs": "inputs", "Inputs": "inputs",
           "Report": "report", "write_report": "report"}
__all__ = sorted(_PUBLIC)


def __getattr__(name):
    if name in _PUBLIC:
        import importlib

        return getattr(importlib.import_module(f"g2r_jax.downstream.{_PUBLIC[name]}"), name)
    raise AttributeError(f"module 'g2r_jax.downstream' has no attribute {name!r}")
