"""The shipped profiles: where they are, their names, and how a profile argument is read (a
shipped name unless it is the path of a file). Plain JSON and paths, nothing numerical, so that
the commands can check a profile argument and list profiles without importing JAX."""

from __future__ import annotations

from pathlib import Path


class UnknownProfile(ValueError):
    """A profile argument that names no shipped profile and no file."""


def _shipped_profiles_dir() -> Path:
    """Where the shipped profiles are: `g2r_jax/profiles/` in an installed wheel (pyproject maps
    the repository's top-level `profiles/` there), else the checkout's top-level `profiles/`."""
    package = Path(__file__).resolve().parents[1]
    installed = package / "profiles"
    return installed if installed.is_dir() else package.parent / "profiles"


SHIPPED_PROFILES_DIR = _shipped_profiles_dir()


def shipped_profiles() -> list[str]:
    """Names of the profiles shipped in `profiles/`."""
    return sorted(p.stem for p in SHIPPED_PROFILES_DIR.glob("*.json"))


def profile_path(name_or_path) -> Path:
    """The file a profile argument means: the argument itself when it is a file, else the shipped
    profile of that name (a folder that happens to carry a shipped name is not a profile).

    **Returns:** the JSON path. Raises `UnknownProfile` (one line naming the argument) when it is
    neither a file nor a shipped name."""
    path = Path(name_or_path)
    if path.is_file():
        return path
    text = str(name_or_path)
    if not path.suffix and "/" not in text and "\\" not in text:
        shipped = SHIPPED_PROFILES_DIR / f"{text}.json"
        if shipped.is_file():
            return shipped
        folder = " (a folder of that name is here, but a profile is a JSON file)" if path.is_dir() else ""
        raise UnknownProfile(f"{text}: unknown profile name{folder}; shipped profiles are: "
                             f"{', '.join(shipped_profiles()) or '(none)'}")
    if path.is_dir():
        raise UnknownProfile(f"{path}: is a folder; a profile is a JSON file or a shipped name")
    raise UnknownProfile(f"{path}: no such profile file")

