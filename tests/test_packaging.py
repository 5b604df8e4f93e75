"""Packaging: the wheel's package list covers the source tree and carries the shipped profiles;
shipped-profile lookup works from a checkout (the wheel case is run by .ci/run)."""

from __future__ import annotations

from pathlib import Path

import pytest

from g2r_jax.profile import schema as profile_module

ROOT = Path(__file__).resolve().parents[1]


def pyproject():
    tomllib = pytest.importorskip("tomllib")
    return tomllib.loads((ROOT / "pyproject.toml").read_text())


def test_every_source_package_is_listed_for_the_wheel():
    listed = set(pyproject()["tool"]["setuptools"]["packages"])
    on_disk = {".".join(p.parent.relative_to(ROOT).parts) for p in (ROOT / "g2r_jax").rglob("__init__.py")}
    assert on_disk <= listed, f"add {sorted(on_disk - listed)} to [tool.setuptools] packages in pyproject.toml"


def test_profiles_folder_is_mapped_into_the_package_with_its_json():
    config = pyproject()["tool"]["setuptools"]
    assert config["package-dir"]["g2r_jax.profiles"] == "profiles"
    assert "*.json" in config["package-data"]["g2r_jax.profiles"]
    assert "g2r_jax.profiles" in config["packages"]


def test_shipped_profiles_found_from_a_checkout():
    names = profile_module.shipped_profiles()
    assert names == sorted(p.stem for p in (ROOT / "profiles").glob("*.json")) and "Canon600D" in names


def test_installed_layout_is_preferred(tmp_path, monkeypatch):
    package = tmp_path / "site" / "g2r_jax"
    (package / "profiles").mkdir(parents=True)
    from g2r_jax.profile import shipped

    monkeypatch.setattr(shipped, "__file__", str(package / "profile" / "shipped.py"))
    assert shipped._shipped_profiles_dir() == (package / "profiles").resolve()
