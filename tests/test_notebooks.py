"""Every notebook in notebooks/ runs top to bottom in a fresh kernel; a cell that raises fails the test.

The kernel is this interpreter (a kernel spec written to a temporary folder), so the notebooks see the
same installed g2r_jax as the tests. Notebooks that read ../shared/data (those naming the
G2R_JAX_SHARED_DATA override) also run with that folder hidden, as on a user's fresh clone (marked
slow where the folder exists). The default run executes the quick notebooks once; the slow suite
executes all of them (SLOW_NOTEBOOKS).
Before every `plt.show()` a check injected by the test asserts that each figure has axis labels and
a legend. Stored notebooks must carry no outputs, so diffs stay readable.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import pytest

nbformat = pytest.importorskip("nbformat")
nbclient = pytest.importorskip("nbclient")
pytest.importorskip("ipykernel")
from jupyter_client.kernelspec import KernelSpecManager  # noqa: E402  (after the importorskips)
from jupyter_client.manager import KernelManager  # noqa: E402

REPO_ROOT = Path(__file__).resolve().parents[1]
NOTEBOOK_DIR = REPO_ROOT / "notebooks"
NOTEBOOKS = sorted(NOTEBOOK_DIR.glob("*.ipynb"))
SHARED_DATA = REPO_ROOT / ".." / "shared" / "data"
DATA_OVERRIDE = "G2R_JAX_SHARED_DATA"
CELL_TIMEOUT_S = 300
KERNEL_NAME = "g2r_jax_notebook_test"

# Runs in the kernel before the notebook: every figure shown must have labelled axes and a legend.
FIGURE_CHECK = '''
import matplotlib.pyplot as _plt

_g2r_original_show = _plt.show


def _g2r_checked_show(*args, **kwargs):
    for number in _plt.get_fignums():
        figure = _plt.figure(number)
        axes = [ax for ax in figure.axes if ax.get_label() != "<colorbar>"]
        title = figure.texts[0].get_text() if figure.texts else next((a.get_title() for a in axes if a.get_title()), "")
        assert any(ax.get_xlabel() for ax in axes), f"figure {number} ({title!r}) has no x-axis label"
        assert any(ax.get_ylabel() for ax in axes), f"figure {number} ({title!r}) has no y-axis label"
        assert any(ax.get_legend() is not None for ax in axes) or figure.legends, \\
            f"figure {number} ({title!r}) has no legend"
    return _g2r_original_show(*args, **kwargs)


_plt.show = _g2r_checked_show
'''


@pytest.fixture(scope="session")
def kernel_specs(tmp_path_factory) -> KernelSpecManager:
    """A kernel spec that starts ipykernel with this very interpreter."""
    root = tmp_path_factory.mktemp("kernels")
    spec_dir = root / KERNEL_NAME
    spec_dir.mkdir()
    spec = {"argv": [sys.executable, "-m", "ipykernel_launcher", "-f", "{connection_file}"],
            "display_name": "g2r_jax (tests)", "language": "python"}
    (spec_dir / "kernel.json").write_text(json.dumps(spec))
    return KernelSpecManager(kernel_dirs=[str(root)])


def _reads_shared_data(path: Path) -> bool:
    return DATA_OVERRIDE in path.read_text()


# Notebooks that take 35-70 s each even at their quick settings (measured on 2 cores, with and
# without ../shared/data): they run in the slow suite (`python -m pytest -m slow
# tests/test_notebooks.py`), so that the default run stays a few minutes.
SLOW_NOTEBOOKS = {"measured_data_audit", "illuminant_distributions", "colour_charts"}


def _cases():
    # Every other notebook runs once in the default (not slow) run, on whatever data is there; where
    # the shared data is present, the extra fresh-clone run of the notebooks that read it is slow.
    fresh_clone_marks = [pytest.mark.slow] if SHARED_DATA.is_dir() else []
    for path in NOTEBOOKS:
        marks = [pytest.mark.slow] if path.stem in SLOW_NOTEBOOKS else []
        yield pytest.param(path, "shared-data", id=f"{path.stem}[shared-data]", marks=marks)
        if _reads_shared_data(path):
            yield pytest.param(path, "no-shared-data", id=f"{path.stem}[no-shared-data]",
                               marks=marks or fresh_clone_marks)


def _run(path: Path, kernel_specs: KernelSpecManager) -> float:
    notebook = nbformat.read(path, as_version=4)
    notebook.cells.insert(0, nbformat.v4.new_code_cell(FIGURE_CHECK))
    manager = KernelManager(kernel_name=KERNEL_NAME, kernel_spec_manager=kernel_specs)
    client = nbclient.NotebookClient(notebook, km=manager, timeout=CELL_TIMEOUT_S, allow_errors=False,
                                     resources={"metadata": {"path": str(path.parent)}})
    start = time.perf_counter()
    client.execute()
    return time.perf_counter() - start


def test_there_are_notebooks():
    names = {path.name for path in NOTEBOOKS}
    assert {"illuminant_distributions.ipynb", "quick_start.ipynb", "measured_data_audit.ipynb"} <= names


@pytest.mark.parametrize("path, data", list(_cases()))
def test_notebook_runs(path: Path, data: str, kernel_specs, monkeypatch):
    if data == "shared-data" and not SHARED_DATA.is_dir() and _reads_shared_data(path):
        pytest.skip("../shared/data is absent; the no-shared-data run covers this notebook")
    if data == "no-shared-data":
        monkeypatch.setenv(DATA_OVERRIDE, str(REPO_ROOT / "does-not-exist" / "shared-data"))
    else:
        monkeypatch.delenv(DATA_OVERRIDE, raising=False)
    seconds = _run(path, kernel_specs)
    print(f"{path.name} [{data}]: {seconds:.1f} s")


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_notebook_is_stored_without_outputs(path: Path):
    notebook = nbformat.read(path, as_version=4)
    nbformat.validate(notebook)
    for index, cell in enumerate(notebook.cells):
        if cell.cell_type == "code":
            assert not cell.outputs, f"{path.name}: cell {index} has stored outputs (strip them)"
            assert cell.execution_count is None, f"{path.name}: cell {index} has an execution count"
