"""Brick cells: where the layout's bricks (three plate layers tall) may go.

A choice of brick cells is a grid-shaped int32 array: per cell the bottom layer of its brick
group (three filled layers of one column that bricks will cover), -1 for a plate cell, -2 for
an empty cell.  :func:`brick_group_candidates` gives the distinct choices
:func:`core.layout.greedy.lay_out` merges: the three global phases (:func:`phase_groups`) and
a choice patch by patch (:func:`patch_groups`), each after :func:`split_side_contacts` (groups
become plates where neighbouring columns would otherwise touch only side by side) and again
after :func:`split_lone_plates` (also beside plate cells that could only hang by one stud).
Groups only ever become plates, so every step ends; nothing here is random.
"""

from __future__ import annotations

import heapq

import numpy as np
from scipy import ndimage


#: Worth of a brick group flush with the end of its column's filled run,
#: in columns, when patches of brick groups are chosen.
ALIGN_BONUS = 0.5


def brick_group_candidates(filled: np.ndarray) -> list[np.ndarray]:
    """Distinct choices of brick cells, each a grid-shaped int32 array.

    A value is the bottom layer of the cell's brick group (three filled
    layers of one column that bricks will cover), -1 for a plate cell, -2
    for an empty cell.  The candidates are :func:`patch_groups` and the
    three global phases of :func:`phase_groups`, each after
    :func:`split_side_contacts`, and each of those again after
    :func:`split_lone_plates`.
    """
    out: list[np.ndarray] = []
    for base in [patch_groups(filled)] + [phase_groups(filled, p) for p in range(3)]:
        split_side_contacts(filled, base)
        lone = base.copy()
        split_lone_plates(filled, lone)
        for b in (base, lone):
            if not any(np.array_equal(b, other) for other in out):
                out.append(b)
    return out


def phase_groups(filled: np.ndarray, phase: int) -> np.ndarray:
    """Brick groups at layers ``phase + 3t`` wherever a column fills all three layers."""
    nz = filled.shape[2]
    base = np.where(filled, -1, -2).astype(np.int32)
    for k0 in range(phase, nz - 2, 3):
        column = filled[:, :, k0] & filled[:, :, k0 + 1] & filled[:, :, k0 + 2]
        base[:, :, k0:k0 + 3][column] = k0
    return base


def patch_groups(filled: np.ndarray) -> np.ndarray:
    """Brick groups chosen patch by patch, the best first.

    A patch is a connected set (4-connectivity in x, y) of columns that
    fill layers ``k0 .. k0+2``, for any ``k0``.  Its worth is its number of
    columns plus :data:`ALIGN_BONUS` for every end of a column's group that
    meets the end of the column's run of filled cells (a group flush with
    the part's surface leaves no odd plate there).  The best patch takes
    its cells; patches that lose cells to it shrink (and may fall apart)
    and go back into the queue.  So every part of the model gets its own
    phase, and a connected wall keeps one.  Ties go to the lower ``k0``.
    """
    nx, ny, nz = filled.shape
    base = np.where(filled, -1, -2).astype(np.int32)
    if nz < 3:
        return base
    able = filled[:, :, :-2] & filled[:, :, 1:-1] & filled[:, :, 2:]
    flush = np.zeros(able.shape, dtype=np.float64)
    flush[:, :, 0] += 1
    flush[:, :, 1:] += ~filled[:, :, :-3]
    flush[:, :, -1] += 1
    flush[:, :, :-1] += ~filled[:, :, 3:]
    flush = flush.reshape(nx * ny, nz - 2)
    heap: list[tuple[float, int, int, np.ndarray]] = []
    order = 0

    def push(cols, k0):
        nonlocal order
        worth = cols.size + ALIGN_BONUS * flush[cols, k0].sum()
        heapq.heappush(heap, (-worth, k0, order, cols))
        order += 1

    for k0 in range(nz - 2):
        for cols in _patches(able[:, :, k0].ravel(), (nx, ny)):
            push(cols, k0)
    taken = np.zeros((nx * ny, nz), dtype=bool)
    flat = base.reshape(nx * ny, nz)
    while heap:
        _, k0, _, cols = heapq.heappop(heap)
        free = ~taken[cols, k0:k0 + 3].any(axis=1)
        if free.all():
            taken[cols, k0:k0 + 3] = True
            flat[cols, k0:k0 + 3] = k0
            continue
        for part in _patches_of(cols[free], ny):
            push(part, k0)
    return base


def _patches_of(cols: np.ndarray, ny: int) -> list[np.ndarray]:
    """:func:`_patches` of the mask of the flat column indices ``cols`` (rows of ``ny``
    columns), labelled within their bounding box only: the same patches in the same order."""
    if cols.size == 0:
        return []
    i, j = np.divmod(cols, ny)
    i0, j0 = int(i.min()), int(j.min())
    h, w = int(i.max()) - i0 + 1, int(j.max()) - j0 + 1
    mask = np.zeros(h * w, dtype=bool)
    mask[(i - i0) * w + (j - j0)] = True
    return [(a // w + i0) * ny + (a % w + j0) for a in _patches(mask, (h, w))]


def _patches(mask: np.ndarray, shape: tuple[int, int]) -> list[np.ndarray]:
    """Flat indices of the 4-connected components of a flattened 2-D mask."""
    lab, n = ndimage.label(mask.reshape(shape))
    if n == 0:
        return []
    flat = lab.ravel()
    order = np.argsort(flat, kind="stable")
    ends = np.cumsum(np.bincount(flat, minlength=n + 1))
    return [order[ends[p - 1]:ends[p]] for p in range(1, n + 1)]


def split_side_contacts(filled: np.ndarray, base: np.ndarray) -> None:
    """Turn brick groups into plates until neighbouring columns can hold each other.

    For every pair of x- or y-neighbouring columns and every run of layers
    in which both are filled, some layer must be a plate in both or a brick
    of the same group in both; otherwise no part can join the two columns
    there (a thin floor beside a wall, a staircase of short runs, two
    patches of different phase).  For each run without such a layer one
    group becomes three plate cells: preferably the brick at the lowest
    layer where the other column has a plate.  Repeats until every run is
    held (groups only ever become plates, so this ends).
    """
    nz = filled.shape[2]
    for _ in range(filled.size + 1):
        mark = np.zeros(filled.shape, dtype=bool)
        for axis in (0, 1):
            lo = [slice(None)] * 3
            hi = [slice(None)] * 3
            lo[axis], hi[axis] = slice(None, -1), slice(1, None)
            lo, hi = tuple(lo), tuple(hi)
            both = filled[lo] & filled[hi]
            ba, bb = base[lo], base[hi]
            shared = both & (((ba == -1) & (bb == -1)) | ((ba == bb) & (ba >= 0)))
            start = both.copy()
            start[:, :, 1:] &= ~both[:, :, :-1]
            run = np.cumsum(start.ravel()).reshape(both.shape)
            held = np.zeros(int(run.max(initial=0)) + 1, dtype=bool)
            held[run[shared]] = True
            loose = both & ~held[run]
            if not loose.any():
                continue
            layer = np.broadcast_to(np.arange(nz), both.shape)
            mixed = loose & ((ba == -1) | (bb == -1))
            key = np.where(mixed, layer, layer + nz)
            first = np.full(held.size, 2 * nz)
            np.minimum.at(first, run[loose], key[loose])
            pick = loose & (key == first[run])
            mark[lo] |= pick & (ba >= 0)
            mark[hi] |= pick & (bb >= 0) & (ba < 0)
        if not mark.any():
            return
        group = np.zeros(filled.shape, dtype=bool)
        i, j, k = np.nonzero(mark)
        group[i, j, base[i, j, k]] = True
        i, j, k = np.nonzero(base >= 0)
        undo = group[i, j, base[i, j, k]]
        base[i[undo], j[undo], k[undo]] = -1


#: The four neighbours of a column in x, y.
_SIDES = ((1, 0), (-1, 0), (0, 1), (0, -1))


def split_lone_plates(filled: np.ndarray, base: np.ndarray, rounds: int = 16) -> None:
    """Turn brick groups into plates next to plate cells that would hang by one stud.

    A lone plate cell has no plate cell beside it in its layer and nothing
    filled above it or nothing below: whatever covers it is a 1x1 plate
    with a single neighbour, which makes that neighbour a weak point.  The
    brick group of its first neighbouring column (+x, -x, +y, -y) that is
    a brick at that layer becomes plates, so a larger plate can reach
    across; then :func:`split_side_contacts` again.  At most ``rounds``
    passes (each pass only turns bricks into plates).
    """
    nx, ny, nz = filled.shape
    for _ in range(rounds):
        plate = base == -1
        beside = np.zeros(filled.shape, dtype=bool)
        side = np.full(filled.shape, -1, dtype=np.int8)
        for d, (dx, dy) in enumerate(_SIDES):
            there = np.zeros(filled.shape, dtype=bool)
            brick = np.zeros(filled.shape, dtype=bool)
            dst = (slice(max(-dx, 0), nx - max(dx, 0)), slice(max(-dy, 0), ny - max(dy, 0)))
            src = (slice(max(dx, 0), nx - max(-dx, 0)), slice(max(dy, 0), ny - max(-dy, 0)))
            there[dst] = plate[src]
            brick[dst] = base[src] >= 0
            beside |= there
            side[(side < 0) & brick] = d
        open_above = np.ones(filled.shape, dtype=bool)
        open_above[:, :, :-1] = ~filled[:, :, 1:]
        open_below = np.ones(filled.shape, dtype=bool)
        open_below[:, :, 1:] = ~filled[:, :, :-1]
        lone = plate & ~beside & (open_above | open_below) & (side >= 0)
        if not lone.any():
            return
        i, j, k = np.nonzero(lone)
        d = side[i, j, k]
        i = i + np.array([s[0] for s in _SIDES])[d]
        j = j + np.array([s[1] for s in _SIDES])[d]
        k0 = base[i, j, k]
        for dk in range(3):
            base[i, j, k0 + dk] = -1
        split_side_contacts(filled, base)
