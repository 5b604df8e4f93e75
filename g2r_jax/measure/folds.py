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
    """A digest of an array's shape, dtype and bytes: equal for the same pixels under any name."""
    array = np.ascontiguousarray(array)
    digest = hashlib.blake2b(digest_size=16)
    digest.update(f"{array.dtype.str}{array.shape}".encode())
    digest.update(array.data)
    return digest.hexdigest()


def duplicate_groups(arrays) -> np.ndarray:
    """(n,) group labels: arrays with the same pixels (by `pixel_hash`) share a label."""
    labels, seen = [], {}
    for array in arrays:
        labels.append(seen.setdefault(pixel_hash(array), len(seen)))
    return np.asarray(labels, int)
