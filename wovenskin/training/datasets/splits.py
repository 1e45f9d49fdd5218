"""Train/validation splits of a window data set, as index arrays (:class:`Split`).

:func:`random_split` (the paper's 85/15), :func:`grouped_split` (validation recordings,
people and skins never appear in training) and :func:`leave_one_group_out`.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from wovenskin.training.datasets.store import (
    GROUP_KEYS,
    DatasetError,
    WindowDataset,
    check_group_key,
)


@dataclass(frozen=True)
class Split:
    """Window indices for training and validation (sorted, disjoint, covering the set)."""

    name: str
    train: np.ndarray
    val: np.ndarray
    held_out: dict[str, list[str]] = field(default_factory=dict)  # key -> validation groups


def random_split(ds: WindowDataset, val_fraction: float = 0.15, seed: int = 0) -> Split:
    """The paper's split: a random ``val_fraction`` of all windows for validation.

    Windows of one recording land on both sides, so this measures fit to seen people and
    skins, not generalisation: report :func:`grouped_split` as the headline.
    """
    n = len(ds)
    n_val = _val_count(n, val_fraction)
    order = np.random.default_rng(seed).permutation(n)
    return Split("random", np.sort(order[n_val:]), np.sort(order[:n_val]))


def grouped_split(
    ds: WindowDataset,
    val_fraction: float = 0.15,
    seed: int = 0,
    by: Sequence[str] = ("person", "skin", "recording"),
) -> Split:
    """Validation groups never seen in training, for every key in ``by``.

    Windows linked through any shared group of ``by`` (the same person, the same skin or
    the same recording) form one component; whole components are drawn at random until
    validation holds the closest possible share to ``val_fraction``.  In simulated sets
    each recording has its own person and skin (:meth:`WindowDataset.unique_per_recording`),
    so the components are the recordings, and ``by=("recording",)`` gives the same split.
    Raises :class:`DatasetError` when everything forms one component.
    """
    keys = tuple(dict.fromkeys(by))
    if not keys:
        raise DatasetError("grouped_split needs at least one group key")
    for key in keys:
        check_group_key(key)
    n = len(ds)
    _val_count(n, val_fraction)
    component = _components(ds, keys)
    sizes = np.bincount(component)
    if sizes.size < 2:
        raise DatasetError(
            f"cannot split by {'+'.join(keys)}: every window shares a group with every other "
            "(one component); group by fewer keys"
        )
    order = np.random.default_rng(seed).permutation(sizes.size)
    cumulative = np.cumsum(sizes[order])[:-1]
    take = int(np.argmin(np.abs(cumulative - val_fraction * n))) + 1
    is_val = np.isin(component, order[:take])
    split = Split(
        f"grouped by {'+'.join(keys)}",
        np.flatnonzero(~is_val),
        np.flatnonzero(is_val),
        {key: _names(ds, key, np.flatnonzero(is_val)) for key in GROUP_KEYS},
    )
    for key in keys:
        leaked = shared_groups(ds, split, key)
        if leaked:
            raise DatasetError(f"internal error: {key} group(s) {leaked} on both sides")
    return split


def leave_one_group_out(ds: WindowDataset, by: str = "person") -> Iterator[Split]:
    """One split per group of ``by`` (sorted by name): that group validates, the rest train.

    For labelled captures ``by="person"`` is leave-one-participant-out (HAART: 7 folds).
    """
    check_group_key(by)
    ids = ds.group_ids(by)
    present = np.unique(ids)
    if present.size < 2:
        raise DatasetError(f"leave-one-group-out needs at least 2 {by} groups, got {present.size}")
    names = ds.group_names[by]
    for gid in sorted(present.tolist(), key=lambda g: names[g]):
        is_val = ids == gid
        yield Split(
            f"{by}={names[gid]}",
            np.flatnonzero(~is_val),
            np.flatnonzero(is_val),
            {key: _names(ds, key, np.flatnonzero(is_val)) for key in GROUP_KEYS},
        )


def shared_groups(ds: WindowDataset, split: Split, key: str) -> list[str]:
    """Names of ``key`` groups that appear in both training and validation."""
    ids = ds.group_ids(key)
    both = np.intersect1d(ids[split.train], ids[split.val])
    return sorted(ds.group_names[key][g] for g in both.tolist())


def _components(ds: WindowDataset, keys: tuple[str, ...]) -> np.ndarray:
    """Per-window connected-component id of the graph linking windows that share a group."""
    combos, inverse = np.unique(
        np.stack([ds.group_ids(k).astype(np.int64) for k in keys], axis=1),
        axis=0,
        return_inverse=True,
    )
    n_combos = len(combos)
    rows, cols, offset = [], [], n_combos
    for j, key in enumerate(keys):
        rows.append(np.arange(n_combos))
        cols.append(offset + combos[:, j])
        offset += len(ds.group_names[key])
    rows_a, cols_a = np.concatenate(rows), np.concatenate(cols)
    graph = coo_matrix((np.ones(rows_a.size), (rows_a, cols_a)), shape=(offset, offset))
    _, labels = connected_components(graph, directed=False)
    _, component = np.unique(labels[:n_combos], return_inverse=True)
    return component[inverse.ravel()]


def _names(ds: WindowDataset, key: str, indices: np.ndarray) -> list[str]:
    names = ds.group_names[key]
    return sorted(names[g] for g in np.unique(ds.group_ids(key)[indices]).tolist())


def _val_count(n: int, val_fraction: float) -> int:
    if not (0.0 < val_fraction < 1.0):
        raise DatasetError(f"val_fraction must lie strictly between 0 and 1, got {val_fraction}")
    if n < 2:
        raise DatasetError(f"cannot split {n} window(s)")
    return int(np.clip(round(val_fraction * n), 1, n - 1))
