"""Where a profile's numbers come from, and the listing line built from it.

A profile document's `provenance` is either one readable text (older profiles, fitted ones) or an
object with one text per part: `colour` (matrices), `levels` (CFA, black and white levels), `noise`,
`illuminants`, `exposure`, `content` (the CG content model). The first sentence of each part is its
summary (what `describe_profile` prints); the rest says how the numbers were derived. Plain JSON
and text, no JAX, so a command can list profiles without the numerical stack.
"""

from __future__ import annotations

import dataclasses

PARTS = ("colour", "levels", "noise", "illuminants", "exposure", "content")
LISTED_PARTS = ("colour", "noise", "illuminants", "content")


def split_provenance(value) -> tuple[str, tuple]:
    """A document's `provenance` as (one text, ((part, text), ...)): a string has no parts; an object
    gives its parts in document order and the text 'part: text; ...' for readers of one string."""
    if isinstance(value, dict):
        parts = tuple((str(part), " ".join(str(text).split())) for part, text in value.items())
        return "; ".join(f"{part}: {text}" for part, text in parts), parts
    return ("" if value is None else str(value)), ()


def provenance_value(info):
    """What `profile_to_dict` writes for a `ProfileInfo`: the object of parts, else the text. Text
    appended to the flat provenance after the parts were set (a refit's note) becomes part
    `notes`; a provenance replaced altogether is written as that text."""
    if not info.provenance_parts:
        return info.provenance
    parts = dict(info.provenance_parts)
    flat, _ = split_provenance(parts)
    if info.provenance == flat:
        return parts
    if info.provenance.startswith(flat):
        return {**parts, "notes": info.provenance[len(flat):].strip()}
    return info.provenance


def with_provenance(profile, **parts):
    """`profile` with its provenance given per part (keywords from `PARTS`, readable texts; the
    first sentence of each is its summary). Raises ValueError for an unknown part or an empty text."""
    unknown = sorted(set(parts) - set(PARTS))
    if unknown:
        raise ValueError(f"unknown provenance part(s) {unknown}; the parts are {', '.join(PARTS)}")
    for part, text in parts.items():
        if not isinstance(text, str) or not text.strip():
            raise ValueError(f"provenance part {part!r} must be a non-empty text")
    ordered = {part: parts[part] for part in PARTS if part in parts}
    text, pairs = split_provenance(ordered)
    info = dataclasses.replace(profile.info, provenance=text, provenance_parts=pairs)
    return dataclasses.replace(profile, info=info)


def summary(text: str) -> str:
    """The first sentence of a provenance text (up to the first '. ' or the end)."""
    text = " ".join(str(text).split())
    head = text.split(". ")[0]
    return head if head.endswith(".") or head == text else head + "."


def describe_profile(document: dict) -> str:
    """The `g2r-convert --list-profiles` entry of one profile document: its name, camera and ISO
    range, then where its colour, noise and illuminants come from and its content model (first
    sentence of each provenance part). A profile without noise says so: its conversions are noise-free.

    **Returns:** a few lines of text (no trailing newline)."""
    name = document.get("name", "?")
    camera = (document.get("camera") or {}).get("unique_camera_model") or "camera not named"
    noise = document.get("noise") or {}
    iso_range = noise.get("iso_range") or [min(noise.get("iso") or [0]), max(noise.get("iso") or [0])]
    noiseless = not any(value > 0 for row in (noise.get("shot") or []) + (noise.get("read") or [])
                        for value in (row if isinstance(row, list) else [row]))
    head = f"{name}  {camera}, ISO {iso_range[0]:g}-{iso_range[1]:g}"
    if noiseless:
        head += "  [NO NOISE MODEL: its conversions are noise-free]"
    text, parts = split_provenance(document.get("provenance"))
    parts = dict(parts)
    if not parts:
        return f"{head}\n    provenance: {summary(text) if text.strip() else 'not stated'}"
    return "\n".join([head] + [f"    {part}: {summary(parts[part]) if part in parts else 'not stated'}"
                               for part in LISTED_PARTS])


def describe_shipped_profiles() -> str:
    """`describe_profile` of every shipped profile, one after another (what `g2r-convert
    --list-profiles` prints); a file that cannot be read is named with the problem."""
    import json

    from g2r_jax.profile.shipped import SHIPPED_PROFILES_DIR, shipped_profiles

    entries = []
    for name in shipped_profiles():
        try:
            document = json.loads((SHIPPED_PROFILES_DIR / f"{name}.json").read_text())
            entries.append(describe_profile({"name": name, **document}))
        except (OSError, ValueError, TypeError, AttributeError, IndexError) as error:
            entries.append(f"{name}  unreadable ({type(error).__name__})")
    return "\n".join(entries)
