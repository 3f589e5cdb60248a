"""The quality of a layout: the key the improvement lowers, and the brick graph it is read from.

:func:`quality` is the lexicographic key (components of the brick graph, failing joints, weak
points that are not thin, weak points, bricks) that :func:`core.layout.search.improve` never
makes worse; :func:`thin_weak_points` names the weak points that only hold a leaf on a
one-cell-thin feature.  The brick graph joins two bricks where one sits on the other with
overlapping footprints; it is kept as sorted pair keys with the cells each pair touches at
(:func:`contacts_of`), so that a search can change it window by window
(:func:`changed_contacts`) and judge it (:func:`key_of_graph`) without building it again from
the label grid.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from core.connectivity import articulation_points, component_labels, pairs_csr
from core.model import Layout


Key = tuple[int, int, int, int, int]

FailingJoints = Callable[[Layout], int]


def quality(layout: Layout, failing_joints: FailingJoints | None = None) -> Key:
    """The lexicographic key the improvement lowers: (components of the brick graph,
    failing joints, weak points (articulation points) that are not thin, weak points,
    bricks).  A thin weak point (:func:`thin_weak_points`) holds leaf bricks on
    one-cell-thin features only, which the shape forces more often than not; so of two
    layouts, one that traded a thin weak point for one that is not, even for fewer bricks,
    is the worse.  (The search's windows are kept on
    :data:`~core.layout.neighbourhood.SearchKey`, which counts all weak points before those that
    are not thin; :meth:`~core.layout.neighbourhood.Search.restore_best` judges on this one.)

    Bricks are joined where one sits on another with overlapping footprints
    (:func:`core.stability.brick_graph`).  ``failing_joints`` counts the
    joints a force model finds failing; None counts 0.
    """
    n = len(layout.bricks)
    comps, weak, thin, _, _ = _graph_key(layout.labels(), n, 0)
    return comps, int(failing_joints(layout)) if failing_joints else 0, weak - thin, weak, n


def thin_weak_points(layout: Layout) -> list[int]:
    """Ids of the weak points that hold a leaf brick on a one-cell-thin feature and no
    other leaf: a leaf (a brick with a single neighbour) that touches the rest of the model,
    above and below, through one cell only (a spike, pin or tip) hangs on it, and every
    leaf that hangs on it does so.  Such a point is often the shape's doing rather than the
    layout's, so report.json counts it apart, and :func:`quality` ranks it after one that
    is not; the search still removes one where covering the feature differently gives its
    leaf more neighbours.  A weak point that also holds a leaf touching two cells or more
    is the layout's doing, and not thin (the bound of
    :func:`~core.layout.search.one_piece_bound` forbids such leaves)."""
    n = len(layout.bricks)
    indptr, indices, touching = csr(layout.labels(), n)
    art = articulation_points(indptr, indices, n)
    return sorted(layout.bricks[b].id for b in np.flatnonzero(_thin(indptr, indices, art, touching)))


def _thin(indptr: np.ndarray, indices: np.ndarray, art: np.ndarray,
          touching: np.ndarray) -> np.ndarray:
    """Mask of the thin weak points (:func:`thin_weak_points`) of a brick graph (CSR
    ``indptr``, ``indices``; articulation mask ``art``; ``touching``: each brick's cells
    that touch another brick directly above or below)."""
    leaves = np.flatnonzero(np.diff(indptr) == 1)
    support = indices[indptr[leaves]]
    on_weak = art[support]
    leaves, support = leaves[on_weak], support[on_weak]
    thin = np.zeros(art.shape, dtype=bool)
    thick = np.zeros(art.shape, dtype=bool)
    thin[support[touching[leaves] <= 1]] = True
    thick[support[touching[leaves] > 1]] = True
    return thin & ~thick


#: A pair of bricks' key in the brick graph: the lower index shifted by this, or the other.
_KEY_BITS = 32


def vertical_pairs(lab: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(lower, upper) brick of every cell of a label grid (-1 empty) directly over a cell of
    another brick, once per such cell."""
    lower, upper = lab[:, :, :-1], lab[:, :, 1:]
    touch = (lower >= 0) & (upper >= 0) & (lower != upper)
    return lower[touch], upper[touch]


def pair_keys(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return (np.minimum(a, b) << _KEY_BITS) | np.maximum(a, b)


def contacts_of(lab: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The brick graph of a label grid: its pairs' keys (sorted), the cells each pair touches
    at, and each of the ``n`` bricks' cells that touch another brick above or below."""
    a, b = vertical_pairs(lab)
    keys, counts = np.unique(pair_keys(a, b), return_counts=True)
    return keys, counts.astype(np.int64), np.bincount(np.concatenate([a, b]), minlength=n)


def changed_contacts(keys: np.ndarray, counts: np.ndarray, added: np.ndarray,
                      removed: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`contacts_of`'s keys and counts with the touching cells of pairs ``added`` (one
    key per cell) counted in and those of ``removed`` counted out."""
    delta, inv = np.unique(np.concatenate([added, removed]), return_inverse=True)
    signs = np.concatenate([np.ones(len(added)), -np.ones(len(removed))])
    change = np.rint(np.bincount(inv, weights=signs, minlength=len(delta))).astype(np.int64)
    delta, change = delta[change != 0], change[change != 0]
    pos = np.searchsorted(keys, delta)
    hit = pos < len(keys)
    hit[hit] = keys[pos[hit]] == delta[hit]
    counts = counts.copy()
    counts[pos[hit]] += change[hit]
    keys = np.insert(keys, pos[~hit], delta[~hit])
    counts = np.insert(counts, pos[~hit], change[~hit])
    kept = counts > 0
    return keys[kept], counts[kept]


def csr_of(keys: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """CSR (indptr, indices) of the undirected graph of pair ``keys`` on ``n`` vertices."""
    return pairs_csr(keys >> _KEY_BITS, keys & ((1 << _KEY_BITS) - 1), n)


def csr(lab: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """CSR (indptr, indices) of the brick graph of a grid of brick indices (-1 empty), and
    each brick's cells that touch another brick directly above or below."""
    keys, _, touching = contacts_of(lab, n)
    return (*csr_of(keys, n), touching)


def _graph_key(lab: np.ndarray, n: int, dead: int):
    """(components, weak points, thin weak points (:func:`thin_weak_points`), degree per
    vertex, articulation mask) of the brick graph of ``lab`` with ``n`` vertices of which
    ``dead`` are unused (isolated, not counted)."""
    return key_of_graph(*csr(lab, n), n, dead)


def key_of_graph(indptr: np.ndarray, indices: np.ndarray, touching: np.ndarray, n: int,
                  dead: int):
    """:func:`_graph_key` of the brick graph given as CSR, with its bricks' touching cells."""
    comps = (int(component_labels(indptr, indices, n).max()) + 1 if n else 0) - dead
    art = articulation_points(indptr, indices, n)
    thin = int(np.count_nonzero(_thin(indptr, indices, art, touching)))
    return int(comps), int(np.count_nonzero(art)), thin, np.diff(indptr), art
