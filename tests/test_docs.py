"""The README and the documentation site: the site builds with warnings as errors, and every code
block runs as written (python and bash blocks of a page in order, in a fresh folder; a block after
`<!-- not-run: reason -->` is skipped, e.g. installs)."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = ROOT / "docs" / "pages"
BLOCK = re.compile(r"(?P<skip><!-- not-run:[^>]*-->\s*\n)?```(?P<lang>\w*)\n(?P<code>.*?)\n```", re.S)
# Pages whose blocks run several commands (each compiles the pipeline once): the slow suite.
SLOW_PAGES = {"getting_started.md", "guide/your_camera.md", "guide/converting.md", "guide/night_scenes.md",
              "guide/spectral.md", "guide/reading_an_audit.md"}


def code_blocks(text: str) -> list[tuple[str, str]]:
    """(language, code) of the blocks that run: python and bash, not marked not-run."""
    return [(m["lang"], m["code"]) for m in BLOCK.finditer(text)
            if m["lang"] in ("python", "bash") and not m["skip"]]


def run_blocks(path: Path, workdir: Path) -> None:
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}",
           "PYTHONPATH": str(ROOT)}
    for index, (lang, code) in enumerate(code_blocks(path.read_text())):
        command = [sys.executable, "-c", code] if lang == "python" else ["bash", "-euo", "pipefail", "-c", code]
        result = subprocess.run(command, cwd=workdir, env=env, capture_output=True, text=True, timeout=900)
        assert result.returncode == 0, (f"{path.relative_to(ROOT)} block {index + 1} ({lang}) failed:\n{code}\n"
                                        f"--- stdout\n{result.stdout[-3000:]}\n--- stderr\n{result.stderr[-3000:]}")


def _pages():
    names = sorted(str(p.relative_to(PAGES)) for p in PAGES.rglob("*.md") if code_blocks(p.read_text()))
    return [pytest.param(name, marks=pytest.mark.slow) if name in SLOW_PAGES else name for name in names]


def test_block_parser_skips_marked_and_other_languages():
    text = "```python\nx = 1\n```\n<!-- not-run: installs -->\n```bash\npip install x\n```\n```text\nno\n```\n"
    assert code_blocks(text) == [("python", "x = 1")]


def test_readme_blocks_run(tmp_path):
    run_blocks(ROOT / "README.md", tmp_path)


@pytest.mark.parametrize("page", _pages())
def test_docs_page_blocks_run(page, tmp_path):
    run_blocks(PAGES / page, tmp_path)


def test_docs_site_builds_strict(tmp_path):
    mkdocs = shutil.which("mkdocs", path=str(Path(sys.executable).parent)) or shutil.which("mkdocs")
    if mkdocs is None:
        pytest.skip("mkdocs is not installed (pip install -e '.[test]')")
    result = subprocess.run([mkdocs, "build", "--strict", "-f", str(ROOT / "docs" / "mkdocs.yml"),
                             "--site-dir", str(tmp_path / "site")], capture_output=True, text=True,
                            env={**os.environ, "NO_MKDOCS_2_WARNING": "1"})
    assert result.returncode == 0, result.stderr[-4000:]


def test_readme_is_short():
    assert len((ROOT / "README.md").read_text().splitlines()) <= 200


def test_readme_links_resolve():
    text = (ROOT / "README.md").read_text()
    for target in re.findall(r"\]\(([^)#]+)\)", text):
        if "://" not in target:
            assert (ROOT / target).exists(), target


def test_every_shipped_profile_is_on_the_shipped_cameras_page():
    from g2r_jax.profile.schema import shipped_profiles

    page = (PAGES / "guide" / "shipped_cameras.md").read_text()
    assert [name for name in shipped_profiles() if f"`{name}`" not in page] == []
