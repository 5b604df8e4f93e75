"""Cross-validation folds, with repeated items kept together so that a file given twice (a folder
named twice, a copy under another name) never sits on both sides of a split."""

from __future__ import annotations

import hashlib

import numpy as np


def folds_of(n: int, k: int, seed: int = 0, *, groups=None) -> list[np.ndarray]:
    """k disjoint held-out index sets covering range(n), shuffled by `seed`.

    **Arguments:** `n` items; `k` folds (1 <= k <= number of groups); `groups`: optional (n,) labels,
    items with one label land in one fold (e.g. `duplicate_groups` of the files' pixel hashes).

    **Returns:** k sorted integer arrays. Without `groups` the j-th element of a seeded
    permutation goes to fold j mod k (the folds of earlier releases, unchanged).
    """
    if groups is None:
        order = np.random.default_rng(seed).permutation(n)
        return [np.sort(order[i::k]) for i in range(k)]
    labels = np.asarray(groups)
    if labels.shape != (n,):
        raise ValueError(f"groups has shape {labels.shape}, expected ({n},)")
    unique, inverse = np.unique(labels, return_inverse=True)
    if not 1 <= k <= len(unique):
        raise ValueError(f"{k} folds need at least {k} distinct items; {len(unique)} given")
    order = np.random.default_rng(seed).permutation(len(unique))
    fold_of_group = np.empty(len(unique), int)
    fold_of_group[order] = np.arange(len(unique)) % k
    return [np.flatnonzero(fold_of_group[inverse] == i) for i in range(k)]


def pixel_hash(array) -> str:
    """A digest of an array's bytes (BLAKE2b, 16 bytes, hex): equal for the same pixels under any
    name. Hex digests sort as their bytes do, so a set ordered by them is ordered as by the digests."""
    return hashlib.blake2b(np.ascontiguousarray(array).tobytes(), digest_size=16).hexdigest()


def duplicate_groups(arrays, *, order: str = "appearance") -> np.ndarray:
    """(n,) group labels: arrays with the same shape, dtype and pixels (by `pixel_hash`) share a label.

    `order`: "appearance" numbers the groups as they first occur (a set without copies gets
    0..n-1, so `folds_of(..., groups=...)` gives the folds drawn without groups); "hash" numbers
    them by their digest (a labelling that does not depend on the arrays' order).
    """
    keys = [(np.shape(a), np.asarray(a).dtype.str, pixel_hash(a)) for a in arrays]
    if order == "hash":
        ranks = sorted(set(keys), key=lambda key: key[2])
        index = {key: i for i, key in enumerate(ranks)}
        return np.asarray([index[key] for key in keys], int)
    if order != "appearance":
        raise ValueError(f"order must be 'appearance' or 'hash', not {order!r}")
    seen = {}
    return np.asarray([seen.setdefault(key, len(seen)) for key in keys], int)
