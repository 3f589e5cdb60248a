"""The order the instructions draw bricks in: back to front, as a painter would.

Boxes are painted back to front in an order valid for every subset of them, so hiding later
steps never needs a new order: of two boxes whose pictures overlap (their intervals along
``x - y``, ``x + z``, ``y + z`` all overlap), the one on the far side of a separating plane
(larger x, larger y, or lower z) goes first, in a topological sort of these pairs (Kahn's
algorithm, farthest free box first). Disjoint boxes can occlude each other in a cycle
(staggered LEGO walls do); :func:`drawing_pieces` draws the bricks on cycles as their 1 x
1-stud columns, which leaves none.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange
from scipy import sparse
from scipy.sparse.csgraph import connected_components

from core.instructions.picture import VIEW
from core.model import Layout


def brick_boxes(layout: Layout) -> np.ndarray:
    """(n, 2, 3) min and max corner of every brick in mm, relative to the grid origin."""
    cell = np.asarray(layout.grid.cell, dtype=float)
    c = np.array([b.cell for b in layout.bricks], dtype=float).reshape(-1, 3)
    s = np.array([b.size for b in layout.bricks], dtype=float).reshape(-1, 3)
    return np.stack([c * cell, (c + s) * cell], axis=1)


def _front_pairs(boxes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(back, front) index pairs of boxes whose pictures overlap, back drawn first.

    Pictures overlap when the boxes' intervals along the three picture
    directions ``x - y``, ``x + z``, ``y + z`` all overlap.  The boxes are
    binned on the first two directions with bins as wide as the widest
    interval, so each box is compared only with the boxes of its own and the
    eight neighbouring bins: the cost is the number of overlapping pairs, not
    the square of the number of boxes.
    """
    n = len(boxes)
    if n < 2:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    lo, hi = boxes[:, 0], boxes[:, 1]
    a_lo = np.stack([lo[:, 0] - hi[:, 1], lo[:, 0] + lo[:, 2], lo[:, 1] + lo[:, 2]], axis=1)
    a_hi = np.stack([hi[:, 0] - lo[:, 1], hi[:, 0] + hi[:, 2], hi[:, 1] + hi[:, 2]], axis=1)
    span = a_hi.max(axis=0) - a_lo.min(axis=0)
    width = np.maximum((a_hi - a_lo).max(axis=0)[:2], 1e-9)
    # at most about 4 million bins
    width = np.maximum(width, span[:2] / 2000.0)
    b = np.floor((a_lo[:, :2] - a_lo[:, :2].min(axis=0)) / width).astype(np.int64)
    nb = b.max(axis=0) + 1
    key = b[:, 0] * nb[1] + b[:, 1]
    order = np.argsort(key, kind="stable")
    start = np.searchsorted(key[order], np.arange(nb[0] * nb[1] + 1))
    args = (np.ascontiguousarray(lo), np.ascontiguousarray(hi), np.ascontiguousarray(a_lo),
            np.ascontiguousarray(a_hi), b, int(nb[0]), int(nb[1]), order, start)
    counts = np.zeros(n, np.int64)
    _pair_counts(*args, counts)
    offsets = np.concatenate([[0], np.cumsum(counts)])
    back, front = np.empty(offsets[-1], np.int64), np.empty(offsets[-1], np.int64)
    _pair_fill(*args, offsets, back, front)
    return back, front


@njit(cache=True, inline="always")
def _pairs_of(i, lo, hi, a_lo, a_hi, b, nb0, nb1, order, start, back, front, m, fill):
    """The (back, front) pairs of box ``i`` with the boxes ``j > i`` of its own and the
    neighbouring bins, written from ``m`` on when ``fill``; returns ``m`` plus their number."""
    eps = 1e-6
    for d0 in range(-1, 2):
        c0 = b[i, 0] + d0
        if c0 < 0 or c0 >= nb0:
            continue
        for d1 in range(-1, 2):
            c1 = b[i, 1] + d1
            if c1 < 0 or c1 >= nb1:
                continue
            cell = c0 * nb1 + c1
            for t in range(start[cell], start[cell + 1]):
                j = order[t]
                if j <= i:
                    continue
                over = True
                for d in range(3):
                    if not (a_lo[i, d] < a_hi[j, d] - eps and a_lo[j, d] < a_hi[i, d] - eps):
                        over = False
                        break
                if not over:
                    continue
                i_front = (hi[i, 0] <= lo[j, 0] + eps) or (hi[i, 1] <= lo[j, 1] + eps) \
                    or (lo[i, 2] >= hi[j, 2] - eps)
                j_front = (hi[j, 0] <= lo[i, 0] + eps) or (hi[j, 1] <= lo[i, 1] + eps) \
                    or (lo[j, 2] >= hi[i, 2] - eps)
                if i_front == j_front:
                    continue
                if fill:
                    if i_front:
                        back[m], front[m] = j, i
                    else:
                        back[m], front[m] = i, j
                m += 1
    return m


@njit(cache=True, parallel=True)
def _pair_counts(lo, hi, a_lo, a_hi, b, nb0, nb1, order, start, counts):
    """Per box, the number of its pairs (:func:`_pairs_of`)."""
    empty = np.zeros(0, np.int64)
    for i in prange(lo.shape[0]):
        counts[i] = _pairs_of(i, lo, hi, a_lo, a_hi, b, nb0, nb1, order, start, empty, empty,
                              0, False)


@njit(cache=True, parallel=True)
def _pair_fill(lo, hi, a_lo, a_hi, b, nb0, nb1, order, start, offsets, back, front):
    """Write every box's pairs (:func:`_pairs_of`) from its offset on."""
    for i in prange(lo.shape[0]):
        _pairs_of(i, lo, hi, a_lo, a_hi, b, nb0, nb1, order, start, back, front, offsets[i], True)


def painter_order(boxes: np.ndarray, pairs=None) -> tuple[np.ndarray, int]:
    """Drawing order of boxes (n, 2, 3), back to front, and the number of cycles broken.

    Without occlusion cycles the order is exact and stays exact for every
    subset of the boxes (see the module docstring); where the sort stalls on a
    cycle, the farthest remaining box goes first and is counted.  Among the
    boxes free to go, the farthest goes first (ties: the lower index).  ``pairs``
    are the boxes' :func:`_front_pairs` when already found.
    """
    n = len(boxes)
    if n == 0:
        return np.zeros(0, np.int64), 0
    back, front = _front_pairs(boxes) if pairs is None else pairs
    order_e = np.argsort(back, kind="stable")
    back, front = back[order_e], front[order_e]
    start = np.searchsorted(back, np.arange(n + 1))
    indeg = np.bincount(front, minlength=n).astype(np.int64)
    depth = np.ascontiguousarray(boxes.mean(axis=1) @ VIEW)
    out = np.empty(n, np.int64)
    cycles = _kahn(start, front.astype(np.int64), indeg, depth, out)
    return out, int(cycles)


@njit(cache=True, inline="always")
def _before(key, ids, a, b):
    """Whether heap slot ``a`` comes before slot ``b``: larger depth, then lower index."""
    return key[a] > key[b] or (key[a] == key[b] and ids[a] < ids[b])


@njit(cache=True)
def _heap_push(key, ids, size, k, v):
    key[size], ids[size] = k, v
    c = size
    while c > 0:
        p = (c - 1) // 2
        if _before(key, ids, c, p):
            key[c], key[p] = key[p], key[c]
            ids[c], ids[p] = ids[p], ids[c]
            c = p
        else:
            break
    return size + 1


@njit(cache=True)
def _heap_pop(key, ids, size):
    v = ids[0]
    size -= 1
    key[0], ids[0] = key[size], ids[size]
    c = 0
    while True:
        l, r, best = 2 * c + 1, 2 * c + 2, c
        if l < size and _before(key, ids, l, best):
            best = l
        if r < size and _before(key, ids, r, best):
            best = r
        if best == c:
            break
        key[c], key[best] = key[best], key[c]
        ids[c], ids[best] = ids[best], ids[c]
        c = best
    return v, size


@njit(cache=True)
def _kahn(start, front, indeg, depth, out):
    """Kahn's topological sort of the pairs (CSR ``start``/``front`` by back box) into
    ``out``, the farthest free box first; on a cycle the farthest box left goes. Returns
    the number of cycles broken."""
    n = depth.shape[0]
    cap = 2 * n + 1
    key = np.empty(cap, np.float64)
    ids = np.empty(cap, np.int64)
    size = 0
    for v in range(n):
        if indeg[v] == 0:
            size = _heap_push(key, ids, size, depth[v], v)
    done = np.zeros(n, np.bool_)
    placed = 0
    cycles = 0
    while placed < n:
        if size == 0:
            v = -1
            for w in range(n):
                if not done[w] and (v < 0 or depth[w] > depth[v]):
                    v = w
            cycles += 1
            indeg[v] = 0
            size = _heap_push(key, ids, size, depth[v], v)
        v, size = _heap_pop(key, ids, size)
        if done[v]:
            continue
        done[v] = True
        out[placed] = v
        placed += 1
        for e in range(start[v], start[v + 1]):
            w = front[e]
            indeg[w] -= 1
            if indeg[w] == 0 and not done[w]:
                size = _heap_push(key, ids, size, depth[w], w)
    return cycles


def drawing_pieces(layout: Layout) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Boxes to paint, back to front, so that no occlusion cycle is left.

    Returns ``(pieces, owner, order, split)``: piece boxes (m, 2, 3) in mm,
    the index in ``layout.bricks`` each piece draws, the painting order (a
    permutation of the pieces) and the number of bricks split.  A brick is
    one piece, unless it lies on an occlusion cycle (a strongly connected
    component of the "drawn before" graph); such bricks are split into their
    1 x 1-stud columns.  Columns alone never form a cycle (along a view ray
    the stud indices i and j never decrease, and within one column the ray
    only descends), and every cycle after the split would map to a cycle of
    bricks that were all split, so one round of splitting leaves an acyclic
    graph and the order is exact.
    """
    boxes = brick_boxes(layout)
    n = len(boxes)
    owner = np.arange(n, dtype=np.int64)
    if n == 0:
        return boxes, owner, np.zeros(0, np.int64), 0
    back, front = _front_pairs(boxes)
    graph = sparse.csr_matrix((np.ones(len(back), dtype=np.int8), (back, front)), shape=(n, n))
    _, label = connected_components(graph, directed=True, connection="strong")
    split = np.bincount(label)[label] > 1
    if split.any():
        cell = np.asarray(layout.grid.cell, dtype=float)
        pieces, owners = [boxes[~split]], [owner[~split]]
        for b in np.flatnonzero(split):
            brick = layout.bricks[b]
            i, j = np.meshgrid(np.arange(brick.size[0]), np.arange(brick.size[1]), indexing="ij")
            ij = np.stack([i.ravel(), j.ravel()], axis=1) + np.asarray(brick.cell[:2])
            lo = np.column_stack([ij * cell[:2], np.full(len(ij), boxes[b, 0, 2])])
            hi = np.column_stack([(ij + 1) * cell[:2], np.full(len(ij), boxes[b, 1, 2])])
            pieces.append(np.stack([lo, hi], axis=1))
            owners.append(np.full(len(ij), b, dtype=np.int64))
        boxes, owner = np.concatenate(pieces), np.concatenate(owners)
    order, _ = painter_order(boxes, None if split.any() else (back, front))
    return boxes, owner, order, int(split.sum())
