"""Layout stage: merge the 1x1 plates of a grid into catalog plates and bricks.

:func:`lay_out` turns a :class:`~core.model.Grid` into a
:class:`~core.model.Layout` in three steps.

1. **Brick cells.**  A brick is three plate layers tall, so the cells are grouped into
   three-layer column pieces ("groups") where bricks will go, and plate cells elsewhere.
   Candidates: the three global phases (groups at layers ``p + 3t``) and a patch-wise
   choice (:func:`patch_groups`), so each part of the model gets its own phase.  In every
   candidate a group becomes plates again where neighbouring columns would otherwise touch
   only side by side, and in a second version also beside plate cells that could only hang
   by one stud.  ``relaxed`` (``best``'s second start) takes instead the brick layers of the
   exact cover's LP relaxation (:func:`relaxed_brick_groups`).
2. **Merging**, per candidate.  Bottom-up, per layer the brick slab and then the plate
   slab, a raster scan takes the first uncovered cell and chooses among the footprints of
   the allowed parts anchored there by a score (:data:`WEIGHTS`: area, joining components,
   seams over seams, leaves, orphaned cells, seeded ties).  Scan direction and axis
   alternate between layers; each slab is merged with four scans and the best kept.  The
   candidate with the fewest bricks plus weak points and extra components wins.
3. **Repair** (after Testuz et al. 2013).  Around every seam where two components of one
   region meet and every weak brick, the bricks of a neighbourhood are split back into
   cells and merged again with another variant (:data:`REPAIR_VARIANTS`); a change is kept
   only when (components, weak points, bricks) improves lexicographically, within
   :data:`BRICK_BUDGET`.  The attempts are bounded, so the result is deterministic.

All per-cell work runs in numba (the candidates of step 2 two at a time, in threads);
Python loops over candidates, repair attempts and the final bricks.  Randomness comes only
from ``seed``.
"""

from __future__ import annotations

import dataclasses
import heapq
from concurrent.futures import ThreadPoolExecutor
from typing import Callable

import numpy as np
from numba import njit
from scipy import ndimage

from core.catalog import BRICK_LAYERS, CATALOG, PLATE_LAYERS, Part
from core.connectivity import articulation_points, component_labels, regions
from core.errors import InputError
from core.layout.bounds import part_shapes, placement_count, relaxed_cover
from core.model import Brick, Grid, Layout

Progress = Callable[[float, str], None]

#: Score weights: area per cell, joining two components, resting on >= 2
#: bricks, per seam edge cell on a seam below/above, preferred direction,
#: seeded tie-break, per brick left hanging by one neighbour (a leaf), per part
#: (when comparing whole slabs), per free cell left without a free neighbour;
#: the last entry shifts the seeded tie-break (the repair varies it).
WEIGHTS = (1.0, 24.0, 0.5, 0.25, 0.5, 0.2, 8.0, 4.0, 2.0, 0.0)

#: Scan variant per layer (k mod 4): bit 0 flips x, bit 1 flips y, bit 2
#: scans columns instead of rows.  Consecutive layers start from other
#: corners along other axes, so seams do not line up.
LAYER_VARIANTS = (0, 7, 1, 6)

#: Scans tried per slab, as changes to the layer's scan variant.
SLAB_TRIALS = (0, 3, 4, 7)

#: Score weights of a plain merge: area only, no connectivity terms.
AREA_WEIGHTS = (1.0, 0.0, 0.0, 0.0, 0.0, 0.2, 0.0, 4.0, 0.0, 0.0)

#: Repair variants, tried in order at every site: (scan variant, radius of
#: the freed neighbourhood in studs, layers freed below and above, radius
#: around the site in which brick groups become plates (-1: none), weights).
REPAIR_VARIANTS = (
    (3, 2, 1, -1, WEIGHTS),
    (5, 2, 1, 0, WEIGHTS),
    (6, 3, 2, 1, WEIGHTS),
    (1, 2, 1, -1, AREA_WEIGHTS),
    (4, 1, 0, -1, WEIGHTS),
    (2, 3, 1, -1, WEIGHTS),
    (7, 2, 0, 1, WEIGHTS),
    (0, 4, 2, 8, WEIGHTS),
)

#: Variants tried at one site in one round of the repair, and the rounds
#: tried even without success: the fixed variants first, then shaken ones.
VARIANTS_PER_SITE = 4
MIN_REPAIR_ROUNDS = 6

#: Bound on the repair work: attempts (each re-merges one neighbourhood and
#: re-analyses the whole brick graph), and attempts times bricks.
MAX_REPAIR_ATTEMPTS = 2000
MAX_REPAIR_WORK = 8_000_000

#: Removing weak points may cost bricks up to this factor of the fewest
#: bricks any merge needed; joining components is never limited.
BRICK_BUDGET = 1.1

#: ``best`` also starts from a layout whose brick layers the exact cover's LP relaxation
#: chooses (:func:`relaxed_brick_groups`) where at most this many placements fit (beyond,
#: its interior point takes tens of seconds): the windows of the improvement cannot move a
#: wall's brick layers, so where the greedy's phases are poor its result stays poor.
RELAXED_PLACEMENTS = 50_000
#: Time limit of that relaxation, and the least value that makes a placement a brick group.
RELAXED_TIME_S = 20.0
RELAXED_TAKE = 0.3

#: Worth of a brick group flush with the end of its column's filled run,
#: in columns, when patches of brick groups are chosen.
ALIGN_BONUS = 0.5

#: Merge candidates laid out at once (threads: the merge kernel releases the GIL);
#: each holds its own labels and records, so memory grows with this too.
MERGE_THREADS = 2

#: Bricks a weak point and an extra component are worth when choosing
#: among merged layouts (the repair usually joins components cheaply).
WEAK_COST = 2.0
SPLIT_COST = 8.0


def _repair_variants(round_: int) -> list[tuple]:
    """The repair variants of a round: from :data:`REPAIR_VARIANTS`, then shaken.

    A shaken variant weighs the seeded tie-break like several cells of
    area, with a tie-break shifted per variant: a deterministic random
    local search.
    """
    fixed = len(REPAIR_VARIANTS) // VARIANTS_PER_SITE
    if round_ < fixed:
        return list(REPAIR_VARIANTS[round_ * VARIANTS_PER_SITE:(round_ + 1) * VARIANTS_PER_SITE])
    out = []
    for i in range(VARIANTS_PER_SITE):
        n = round_ * VARIANTS_PER_SITE + i
        weights = WEIGHTS[:5] + (3.0,) + WEIGHTS[6:9] + (float(n),)
        out.append((n % 8, 2 + n % 2, 1, 1 if n % 3 == 0 else -1, weights))
    return out


def lay_out(grid: Grid, parts: tuple[Part, ...] = CATALOG, seed: int = 0,
            progress: Progress | None = None, relaxed: bool = False) -> Layout:
    """Cover every filled cell of ``grid`` exactly once with parts from ``parts``.

    Promises: every brick is a part of ``parts`` in one of its orientations
    (size ``(w, d, layers)`` or ``(d, w, layers)``) and lies on filled cells
    only; together the bricks cover every filled cell once.  The same grid,
    parts and seed give the same layout.  With ``relaxed`` the brick cells are
    those of :func:`relaxed_brick_groups` (the candidates of step 1 where it has
    none).  ``progress(fraction, message)`` is
    called now and then.  Raises :class:`InputError` for a part set without
    the 1x1 plate 3024 or a seed that is not a whole number >= 0 (both the
    user's choice), TypeError for a grid that is not a 3-D boolean array.
    """
    report = progress or _silent
    filled = _check(grid, parts, seed)
    if not filled.any():
        return Layout(grid, [])
    parts = tuple(parts)
    plates = _orientations(parts, PLATE_LAYERS)
    bricks = _orientations(parts, BRICK_LAYERS)
    noise = np.random.default_rng(seed).random(filled.shape, dtype=np.float32)
    report(0.0, "layout: choosing brick layers")
    relaxed_groups = relaxed_brick_groups(filled, parts) if relaxed and bricks[0].size else None
    if relaxed_groups is not None:
        bases = [relaxed_groups]
    elif bricks[0].size:
        bases = brick_group_candidates(filled)
    else:
        bases = [np.where(filled, -1, -2).astype(np.int32)]
    region_count = regions(filled)[1]

    def merged(base):
        state = _State(filled, base.copy(), plates, bricks, noise, region_count)
        state.place_all()
        return state.quality()[0], state.snapshot()

    report(0.05, f"layout: merging plates, {len(bases)} ways")
    with ThreadPoolExecutor(max_workers=max(1, min(MERGE_THREADS, len(bases)))) as pool:
        results = list(pool.map(merged, bases))
    keys = [key for key, _ in results]
    budget = int(min(key[2] for key in keys) * BRICK_BUDGET)
    best = min(range(len(bases)), key=lambda n: (_rank(keys[n], budget, region_count), n))
    state = _State(filled, bases[best], plates, bricks, noise, region_count)
    state.restore(results[best][1])
    del results
    report(0.3, "layout: repairing weak points")
    state.repair(report, budget)
    report(1.0, "layout: done")
    return state.layout(grid, parts)


def _silent(fraction: float, message: str) -> None:
    """Progress sink that ignores everything."""


def _rank(key: tuple[int, int, int], budget: int, region_count: int) -> tuple[int, float]:
    """Order of merged layouts before repair: within the brick budget first, then
    bricks plus :data:`WEAK_COST` per weak point plus :data:`SPLIT_COST` per extra component."""
    return int(key[2] > budget), key[2] + WEAK_COST * key[1] + SPLIT_COST * (key[0] - region_count)


def _better(new: tuple[int, int, int], old: tuple[int, int, int], budget: int) -> bool:
    """Whether a repaired (components, weak points, bricks) beats ``old``.

    Lexicographic, except that removing weak points may not take the
    brick count above ``budget``.
    """
    if new[0] != old[0]:
        return new[0] < old[0]
    if new[1] != old[1]:
        return new[1] < old[1] and new[2] <= max(budget, old[2])
    return new[2] < old[2]


def _check(grid: Grid, parts: tuple[Part, ...], seed) -> np.ndarray:
    """The grid's occupancy as a C-contiguous bool array; TypeError for a grid that
    is not a 3-D boolean array, InputError for the user's brick set or seed."""
    filled = np.asarray(grid.filled)
    if filled.ndim != 3 or filled.dtype != np.bool_:
        raise TypeError(f"the grid must be a 3-D boolean array, not {filled.dtype} of shape {filled.shape}")
    if not any(p.footprint == (1, 1) and p.layers == PLATE_LAYERS for p in parts):
        raise InputError("the brick set must contain the 1x1 plate 3024, or some cells could not be covered")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise InputError(f"the seed must be a whole number >= 0, got {seed!r}")
    return np.ascontiguousarray(filled)


def _orientations(parts: tuple[Part, ...], layers: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Footprints (size x, size y, index into ``parts``) of the parts ``layers`` tall, largest first."""
    rows = sorted(((w * h, -i, w, h) for i, p in enumerate(parts) if p.layers == layers
                   for w, h in p.orientations()), reverse=True)
    return (np.array([r[2] for r in rows], dtype=np.int64),
            np.array([r[3] for r in rows], dtype=np.int64),
            np.array([-r[1] for r in rows], dtype=np.int64))


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


def relaxable(grid: Grid, parts: tuple[Part, ...]) -> bool:
    """Whether :func:`relaxed_brick_groups` is cheap on ``grid``: at most
    :data:`RELAXED_PLACEMENTS` placements of ``parts`` fit its filled cells."""
    return placement_count(grid, parts, stop_above=RELAXED_PLACEMENTS) <= RELAXED_PLACEMENTS


def relaxed_layout(grid: Grid, cells: np.ndarray | None, parts: tuple[Part, ...] = CATALOG,
                   seed: int = 0) -> Layout | None:
    """The layout of ``grid`` (around the marked ``cells`` as :func:`lay_out_around`, where
    any is marked) whose brick layers the exact cover's relaxation chooses
    (``relaxed``), or None where that is not cheap (:func:`relaxable`)."""
    if not relaxable(grid, parts):
        return None
    if cells is not None and np.asarray(cells, dtype=bool).any():
        return lay_out_around(grid, cells, parts, seed=seed, relaxed=True)
    return lay_out(grid, parts, seed=seed, relaxed=True)


def relaxed_brick_groups(filled: np.ndarray, parts: tuple[Part, ...]) -> np.ndarray | None:
    """Brick groups (as :func:`brick_group_candidates` gives them) read off the LP
    relaxation of the exact cover of ``filled`` by ``parts``
    (:func:`core.layout.bounds.relaxed_cover`), or None where it is not solved within
    :data:`RELAXED_TIME_S`.

    The brick placements (three layers tall) that the relaxation gives more than
    :data:`RELAXED_TAKE`, the largest value first (then the largest footprint, then the
    placements' order), each take their cells as a group where none of them is taken yet;
    the other cells are plate cells.  Where a cover with the fewest parts is found by the
    relaxation, so are its brick layers, each part of the model in its own phase.
    """
    found = relaxed_cover(filled, part_shapes(parts), RELAXED_TIME_S)
    if found is None:
        return None
    boxes, value = found
    base = np.where(filled, -1, -2).astype(np.int32)
    tall = np.flatnonzero((boxes[:, 5] == BRICK_LAYERS) & (value > RELAXED_TAKE))
    for x, y, z, sx, sy, sz in boxes[tall[np.lexsort((-boxes[tall, 3] * boxes[tall, 4],
                                                       -value[tall]))]]:
        group = base[x:x + sx, y:y + sy, z:z + sz]
        if (group == -1).all():
            group[...] = z
    return base


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


class _State:
    """The layout under construction: labels, brick records and the repair loop."""

    def __init__(self, filled, base, plates, bricks, noise, region_count):
        self.filled = filled
        self.base = base
        self.plates = plates
        self.bricks = bricks
        self.noise = noise
        self.lab = np.full(filled.shape, -1, dtype=np.int64)
        self.todo = np.zeros(filled.shape, dtype=bool)
        self.cells = int(np.count_nonzero(filled))
        cap = 2 * self.cells + 4096
        self.rec = np.zeros((cap, 7), dtype=np.int64)
        self.alive = np.zeros(cap, dtype=np.bool_)
        self.count = np.zeros(1, dtype=np.int64)
        self.parent = np.arange(cap, dtype=np.int64)
        self.region_count = region_count

    def snapshot(self) -> tuple:
        """The merged layout in few bytes (labels as int32, live records): :meth:`restore` it."""
        n = int(self.count[0])
        return (self.lab.astype(np.int32), self.base.copy(), self.rec[:n].copy(),
                self.alive[:n].copy())

    def restore(self, snap: tuple) -> None:
        """Take the layout of :meth:`snapshot` ``snap`` (union-find reset by the repair)."""
        lab, base, rec, alive = snap
        n = len(rec)
        self.lab[...] = lab
        self.base = base
        self.rec[:n] = rec
        self.alive[:] = False
        self.alive[:n] = alive
        self.count[0] = n

    def place_all(self):
        """Merge all filled cells."""
        nx, ny, nz = self.filled.shape
        self._place(self.filled, 0, (0, nx, 0, ny, 0, nz), len(SLAB_TRIALS), WEIGHTS)

    def _place(self, todo, variant, box, trials, weights):
        """Merge the uncovered ``todo`` cells inside ``box`` into parts (numba kernel)."""
        _place(todo, self.filled, self.base, self.lab, self.rec, self.alive, self.count,
               self.parent, *self.plates, *self.bricks, np.array(weights, dtype=np.float64), self.noise, variant,
               np.array(box, dtype=np.int64), trials)

    def quality(self):
        """``(components, weak points, bricks)``, component per brick, articulation mask, graph."""
        n = int(self.count[0])
        indptr, indices = _graph(self.lab, self.rec, self.alive, n)
        comp = component_labels(indptr, indices, n)
        art = articulation_points(indptr, indices, n)
        alive = int(np.count_nonzero(self.alive[:n]))
        components = int(comp.max(initial=-1)) + 1 - (n - alive)
        return (components, int(np.count_nonzero(art)), alive), comp, art, (indptr, indices)

    def repair(self, report, budget):
        """Re-merge the neighbourhoods of component seams and weak bricks while that helps.

        In each round every site is visited once (sites are recomputed
        after each success), trying :data:`VARIANTS_PER_SITE` variants of
        :data:`REPAIR_VARIANTS`, a different choice each round, until one
        is :func:`_better`.  Stops after a round without success or after
        :data:`MAX_REPAIR_ATTEMPTS` attempts (fewer for many bricks, see
        :data:`MAX_REPAIR_WORK`).
        """
        key, comp, art, graph = self.quality()
        limit = max(min(MAX_REPAIR_ATTEMPTS, MAX_REPAIR_WORK // max(key[2], 1)), 50)
        attempts = 0
        rounds = 0
        while attempts < limit and (key[0] > self.region_count or key[1] > 0):
            tried: set[tuple[int, int, int]] = set()
            variants = _repair_variants(rounds)
            progress_in_round = False
            searching = True
            while searching and attempts < limit:
                searching = False
                for site in self._sites(comp, art, graph):
                    if site in tried:
                        continue
                    tried.add(site)
                    for variant in variants:
                        if self.count[0] + self.cells > self.rec.shape[0]:
                            self._compact()
                            key, comp, art, graph = self.quality()
                        attempts += 1
                        saved = self._rework(site, variant, graph)
                        if saved is None:
                            continue
                        new, ncomp, nart, ngraph = self.quality()
                        if _better(new, key, budget):
                            key, comp, art, graph = new, ncomp, nart, ngraph
                            searching = progress_in_round = True
                            break
                        self._restore(saved)
                        if attempts >= limit:
                            break
                    if searching or attempts >= limit:
                        break
                extra = key[0] - self.region_count
                report(0.3 + 0.7 * attempts / limit,
                       f"layout: repairing, {extra} extra components, {key[1]} weak points")
            rounds += 1
            if not progress_in_round and rounds >= MIN_REPAIR_ROUNDS:
                break

    def _sites(self, comp, art, graph):
        """Repair sites as cells, in a fixed order.

        First one cell per layer and pair of components that meet side by
        side; then every brick hanging from a weak brick alone (a leaf),
        then the other weak bricks themselves.
        """
        live = comp[np.flatnonzero(self.alive[:len(comp)])]
        # components of different regions never meet side by side: no seam to look for
        seams = _seam_cells(self.lab, comp) if np.unique(live).size > self.region_count else ()
        sites = [tuple(int(v) for v in s) for s in seams]
        indptr, indices = graph
        degree = np.diff(indptr)
        weak = np.flatnonzero(art)
        leaves = np.flatnonzero(degree == 1)
        leaves = leaves[art[indices[indptr[leaves]]]]
        hung = np.zeros(art.size, dtype=bool)
        hung[indices[indptr[leaves]]] = True
        for b in list(leaves) + list(weak[~hung[weak]]):
            x, y, z, sx, sy, sz = self.rec[b, :6]
            sites.append((int(x + sx // 2), int(y + sy // 2), int(z + sz // 2)))
        return sites

    def _rework(self, site, variant, graph):
        """Split the bricks near ``site`` into cells and merge them again; returns the undo record.

        ``graph`` is the brick graph before the split.  Returns None (and
        changes nothing) when no brick lies near ``site``.
        """
        scan, radius, depth, demote, weights = variant
        nx, ny, nz = self.filled.shape
        x, y, z = site
        box = (slice(max(x - radius, 0), x + radius + 1), slice(max(y - radius, 0), y + radius + 1),
               slice(max(z - depth, 0), z + depth + 1))
        ids = self._ids(box)
        if ids.size == 0:
            return None
        r = self.rec[ids]
        lo = r[:, :3].min(axis=0)
        hi = (r[:, :3] + r[:, 3:6]).max(axis=0)
        sl = tuple(slice(int(a), int(b)) for a, b in zip(lo, hi))
        saved = (sl, self.lab[sl].copy(), self.base[sl].copy(), ids, int(self.count[0]))
        todo = self.todo[sl]
        todo[...] = np.isin(self.lab[sl], ids)
        self.lab[sl][todo] = -1
        self.alive[ids] = False
        if demote >= 0:
            i, j, k = np.nonzero(todo & (self.base[sl] >= 0))
            i, j = i + lo[0], j + lo[1]
            near = (np.abs(i - x) <= demote) & (np.abs(j - y) <= demote)
            i, j, k0 = i[near], j[near], self.base[i[near], j[near], k[near] + lo[2]]
            for dk in range(3):
                self.base[i, j, k0 + dk] = -1
        n = int(self.count[0])
        _reset_union(*graph, self.alive, self.parent, n)
        self._place(self.todo, scan, (lo[0], hi[0], lo[1], hi[1], lo[2], hi[2]), 1, weights)
        todo[...] = False
        return saved

    def _ids(self, box):
        """Ids of the bricks with a cell in ``box``."""
        ids = np.unique(self.lab[box])
        return ids[ids >= 0]

    def _restore(self, saved):
        """Undo :meth:`_rework`."""
        sl, lab, base, ids, count = saved
        self.alive[count:int(self.count[0])] = False
        self.count[0] = count
        self.lab[sl] = lab
        self.base[sl] = base
        self.alive[ids] = True

    def _compact(self):
        """Drop the records of freed bricks and renumber the labels (brick indices change)."""
        n = int(self.count[0])
        keep = np.flatnonzero(self.alive[:n])
        new = np.full(n + 1, -1, dtype=np.int64)
        new[keep] = np.arange(keep.size)
        self.lab = new[self.lab]
        self.rec[:keep.size] = self.rec[keep]
        self.alive[:] = False
        self.alive[:keep.size] = True
        self.count[0] = keep.size

    def layout(self, grid: Grid, parts: tuple[Part, ...]) -> Layout:
        """The finished :class:`Layout`, bricks ordered bottom-up (z, y, x), ids = positions."""
        n = int(self.count[0])
        r = self.rec[np.flatnonzero(self.alive[:n])]
        order = np.lexsort((r[:, 0], r[:, 1], r[:, 2]))
        bricks = []
        for idx, row in enumerate(r[order]):
            x, y, z, sx, sy, sz, p = (int(v) for v in row)
            bricks.append(Brick(id=idx, part=parts[p].number, size=(sx, sy, sz), cell=(x, y, z)))
        return Layout(grid, bricks)


def _seam_cells(lab: np.ndarray, comp: np.ndarray) -> np.ndarray:
    """Cells where two different components meet side by side, one per pair of components per layer."""
    cl = np.where(lab >= 0, comp[np.maximum(lab, 0)], -1)
    found = []
    for axis in (0, 1):
        lo = [slice(None)] * 3
        hi = [slice(None)] * 3
        lo[axis], hi[axis] = slice(None, -1), slice(1, None)
        a, b = cl[tuple(lo)], cl[tuple(hi)]
        seam = (a >= 0) & (b >= 0) & (a != b)
        if not seam.any():
            continue
        idx = np.argwhere(seam)
        ca, cb = a[seam], b[seam]
        key = np.stack([np.minimum(ca, cb), np.maximum(ca, cb), idx[:, 2]], axis=1)
        _, first = np.unique(key, axis=0, return_index=True)
        found.append(idx[np.sort(first)])
    if not found:
        return np.zeros((0, 3), dtype=np.int64)
    return np.concatenate(found)


@njit(cache=True)
def _graph(lab, rec, alive, n):
    """CSR ``(indptr, indices)`` of the brick graph over brick records ``0 .. n-1``.

    Looks only at the cells directly above each live brick, so the cost
    is the bricks' footprint area, not the grid's size.
    """
    nz = lab.shape[2]
    total = 0
    for b in range(n):
        if alive[b]:
            total += rec[b, 3] * rec[b, 4]
    lower = np.empty(total, dtype=np.int64)
    upper = np.empty(total, dtype=np.int64)
    stamp = np.full(n, -1, dtype=np.int64)
    m = 0
    for b in range(n):
        z = rec[b, 2] + rec[b, 5]
        if not alive[b] or z >= nz:
            continue
        for x in range(rec[b, 0], rec[b, 0] + rec[b, 3]):
            for y in range(rec[b, 1], rec[b, 1] + rec[b, 4]):
                a = lab[x, y, z]
                if a >= 0 and stamp[a] != b:
                    stamp[a] = b
                    lower[m] = b
                    upper[m] = a
                    m += 1
    indptr = np.zeros(n + 1, dtype=np.int64)
    for e in range(m):
        indptr[lower[e] + 1] += 1
        indptr[upper[e] + 1] += 1
    for v in range(n):
        indptr[v + 1] += indptr[v]
    fill = indptr[:-1].copy()
    indices = np.empty(2 * m, dtype=np.int64)
    for e in range(m):
        indices[fill[lower[e]]] = upper[e]
        fill[lower[e]] += 1
        indices[fill[upper[e]]] = lower[e]
        fill[upper[e]] += 1
    return indptr, indices


@njit(cache=True)
def _find(parent, a):
    """Union-find root of ``a`` with path halving."""
    while parent[a] != a:
        parent[a] = parent[parent[a]]
        a = parent[a]
    return a


@njit(cache=True)
def _reset_union(indptr, indices, alive, parent, n):
    """Set the union-find ``parent`` to the components of the live bricks of a CSR graph.

    Every live brick points straight at the first brick of its component
    found by a depth-first search; dead bricks stay alone.
    """
    seen = np.zeros(n, dtype=np.bool_)
    stack = np.empty(n, dtype=np.int64)
    for s in range(n):
        parent[s] = s
    for s in range(n):
        if seen[s] or not alive[s]:
            continue
        seen[s] = True
        top = 0
        stack[0] = s
        while top >= 0:
            v = stack[top]
            top -= 1
            parent[v] = s
            for e in range(indptr[v], indptr[v + 1]):
                w = indices[e]
                if alive[w] and not seen[w]:
                    seen[w] = True
                    top += 1
                    stack[top] = w


@njit(cache=True)
def _fits(x0, y0, w, h, k, want, todo, lab, base):
    """Whether the footprint lies on uncovered ``todo`` cells of layer k whose group is ``want``."""
    nx, ny = lab.shape[0], lab.shape[1]
    if x0 < 0 or y0 < 0 or x0 + w > nx or y0 + h > ny:
        return False
    for x in range(x0, x0 + w):
        for y in range(y0, y0 + h):
            if not todo[x, y, k] or lab[x, y, k] >= 0 or base[x, y, k] != want:
                return False
    return True


@njit(cache=True)
def _score(x0, y0, w, h, k, layers, want, todo, base, lab, filled, parent, rec, weights, nbr):
    """Score of a footprint at layer k, ``layers`` tall; its neighbour bricks go into ``nbr``.

    Returns ``(score, number of neighbours)``.  Neighbours are the bricks
    directly below and above.  The score adds area, joined components and
    resting on several bricks; it subtracts seam cells that continue a seam
    of the layer below or above, and a leaf penalty for every brick that
    this placement would leave with a single neighbour for good: the new
    brick itself (one neighbour and no uncovered filled cell above), or a
    brick below with nothing under it whose top this footprint covers alone;
    and an orphan penalty for every free cell of the slab next to the
    footprint that it would leave without a free neighbour (only a 1x1
    part could cover it; a leaf too if nothing is filled above or below it).
    """
    nx, ny, nz = lab.shape
    nd = 0
    aligned = 0
    below = 0
    future = False
    for side in range(2):
        layer = k - 1 if side == 0 else k + layers
        if layer < 0 or layer >= nz:
            continue
        for x in range(x0, x0 + w):
            for y in range(y0, y0 + h):
                b = lab[x, y, layer]
                if b < 0:
                    if side == 1 and filled[x, y, layer]:
                        future = True
                    continue
                new = True
                for q in range(nd):
                    if nbr[q] == b:
                        new = False
                        break
                if new:
                    nbr[nd] = b
                    nd += 1
        if side == 0:
            below = nd
        for y in range(y0, y0 + h):
            for x_in, x_out in ((x0, x0 - 1), (x0 + w - 1, x0 + w)):
                if 0 <= x_out < nx and filled[x_out, y, k]:
                    a = lab[x_in, y, layer]
                    b = lab[x_out, y, layer]
                    if a >= 0 and b >= 0 and a != b:
                        aligned += 1
        for x in range(x0, x0 + w):
            for y_in, y_out in ((y0, y0 - 1), (y0 + h - 1, y0 + h)):
                if 0 <= y_out < ny and filled[x, y_out, k]:
                    a = lab[x, y_in, layer]
                    b = lab[x, y_out, layer]
                    if a >= 0 and b >= 0 and a != b:
                        aligned += 1
    roots = 0
    for q in range(nd):
        r = _find(parent, nbr[q])
        first = True
        for p in range(q):
            if _find(parent, nbr[p]) == r:
                first = False
                break
        if first:
            roots += 1
    leaves = 0
    if nd <= 1 and not future:
        leaves += 2 - nd
    for q in range(below):
        if _hangs_from(rec[nbr[q]], x0, y0, w, h, k, lab, filled):
            leaves += 1
    orphans = 0
    for x in range(x0 - 1, x0 + w + 1):
        for y in range(y0 - 1, y0 + h + 1):
            edge_x = x == x0 - 1 or x == x0 + w
            edge_y = y == y0 - 1 or y == y0 + h
            if edge_x == edge_y or not _free(x, y, k, want, todo, lab, base):
                continue
            alone = True
            for dx, dy in ((1, 0), (-1, 0), (0, 1), (0, -1)):
                u = x + dx
                t = y + dy
                inside = x0 <= u < x0 + w and y0 <= t < y0 + h
                if not inside and _free(u, t, k, want, todo, lab, base):
                    alone = False
                    break
            if alone:
                orphans += 1
                if (k == 0 or not filled[x, y, k - 1]) or (k + layers >= nz or not filled[x, y, k + layers]):
                    leaves += 1
    score = weights[0] * w * h - weights[3] * aligned - weights[6] * leaves - weights[8] * orphans
    if roots > 1:
        score += weights[1] * (roots - 1)
    if nd >= 2:
        score += weights[2]
    return score, nd


@njit(cache=True)
def _free(x, y, k, want, todo, lab, base):
    """Whether cell (x, y, k) is inside the grid, uncovered, to do and of group ``want``."""
    if x < 0 or y < 0 or x >= lab.shape[0] or y >= lab.shape[1]:
        return False
    return todo[x, y, k] and lab[x, y, k] < 0 and base[x, y, k] == want


@njit(cache=True)
def _hangs_from(r, x0, y0, w, h, k, lab, filled):
    """Whether brick record ``r`` (just below layer k) would hang from this footprint alone.

    True when nothing lies under ``r`` and every filled cell on top of it
    is inside the footprint.
    """
    bx, by, bz, sx, sy = r[0], r[1], r[2], r[3], r[4]
    for x in range(bx, bx + sx):
        for y in range(by, by + sy):
            if bz > 0 and lab[x, y, bz - 1] >= 0:
                return False
            inside = x0 <= x < x0 + w and y0 <= y < y0 + h
            if not inside and filled[x, y, k]:
                return False
    return True


@njit(cache=True, nogil=True)
def _place(todo, filled, base, lab, rec, alive, count, parent,
           pw, ph, pp, bw, bh, bp, weights, noise, variant, box, trials):
    """Merge the uncovered ``todo`` cells in ``box`` into parts, bottom-up.

    Per layer first the brick cells whose group starts there (footprints
    ``bw x bh``, three layers), then the plate cells (``pw x ph``).  Each
    such slab is merged with the first ``trials`` scans of
    :data:`SLAB_TRIALS` (relative to the layer's own scan) and the one with
    the best total score, each part costing ``weights[7]``, is kept.  New bricks are appended to
    ``rec`` (x, y, z, sx, sy, sz, part), marked alive and joined in the
    union-find ``parent`` with their neighbours.
    """
    nz = lab.shape[2]
    saved = np.empty(parent.size if trials > 1 else 0, dtype=np.int64)
    demoted = np.empty((box[1] - box[0]) * (box[3] - box[2]) + 1, dtype=np.int64)
    for k in range(box[4], box[5]):
        v0 = variant ^ LAYER_VARIANTS[k % 4]
        prefer_x = ((k + variant) % 2) == 0
        for slab in range(2):
            if slab == 0:
                if bw.size == 0 or k + 3 > nz:
                    continue
                tw, th, tp, layers, want = bw, bh, bp, 3, k
            else:
                tw, th, tp, layers, want = pw, ph, pp, 1, -1
            start = count[0]
            best = -1e300
            best_t = 0
            for t in range(trials):
                if trials > 1:
                    saved[:start] = parent[:start]
                total, nd = _place_slab(k, v0 ^ SLAB_TRIALS[t], prefer_x, tw, th, tp, layers, want,
                                        todo, filled, base, lab, rec, alive, count, parent, weights,
                                        noise, box, demoted)
                if total > best:
                    best = total
                    best_t = t
                if t == trials - 1 and best_t == t:
                    break
                for b in range(start, count[0]):
                    alive[b] = False
                    for x in range(rec[b, 0], rec[b, 0] + rec[b, 3]):
                        for y in range(rec[b, 1], rec[b, 1] + rec[b, 4]):
                            for kk in range(k, k + layers):
                                lab[x, y, kk] = -1
                count[0] = start
                parent[:start] = saved[:start]
                for q in range(nd):
                    c = demoted[q]
                    x = c // lab.shape[1]
                    y = c % lab.shape[1]
                    for kk in range(k, k + 3):
                        base[x, y, kk] = k
                if t == trials - 1:
                    _place_slab(k, v0 ^ SLAB_TRIALS[best_t], prefer_x, tw, th, tp, layers, want, todo,
                                filled, base, lab, rec, alive, count, parent, weights, noise, box,
                                demoted)


@njit(cache=True)
def _place_slab(k, v, prefer_x, tw, th, tp, layers, want, todo, filled, base, lab, rec, alive,
                count, parent, weights, noise, box, demoted):
    """Merge the slab of layer k whose cells have group ``want``, scan variant ``v``.

    A raster scan takes the first uncovered cell and places the
    best-scoring footprint anchored there.  Returns ``(total score minus
    part costs, number of demoted columns)``; columns that no brick
    footprint fits become plate cells and are listed (as ``x * ny + y``) in
    ``demoted``.
    """
    x0, x1, y0, y1 = box[0], box[1], box[2], box[3]
    ny = lab.shape[1]
    fx = (v & 1) != 0
    fy = (v & 2) != 0
    by_column = (v & 4) != 0
    nbr = np.empty(64, dtype=np.int64)
    keep = np.empty(64, dtype=np.int64)
    total = 0.0
    n_demoted = 0
    n_out = (x1 - x0) if by_column else (y1 - y0)
    n_in = (y1 - y0) if by_column else (x1 - x0)
    for a in range(n_out):
        for c in range(n_in):
            if by_column:
                x = x1 - 1 - a if fx else x0 + a
                y = y1 - 1 - c if fy else y0 + c
            else:
                y = y1 - 1 - a if fy else y0 + a
                x = x1 - 1 - c if fx else x0 + c
            if not todo[x, y, k] or lab[x, y, k] >= 0 or base[x, y, k] != want:
                continue
            best = -1e300
            bo = -1
            bx = 0
            by = 0
            bn = 0
            for o in range(tw.size):
                w = tw[o]
                h = th[o]
                xs = x - w + 1 if fx else x
                ys = y - h + 1 if fy else y
                if not _fits(xs, ys, w, h, k, want, todo, lab, base):
                    continue
                s, nd = _score(xs, ys, w, h, k, layers, want, todo, base, lab, filled, parent, rec,
                               weights, nbr)
                if (w > h and prefer_x) or (h > w and not prefer_x):
                    s += weights[4]
                t = noise[x, y, k] + 0.6180339887 * o + 0.7548776662 * weights[9]
                s += weights[5] * (t - np.floor(t))
                if s > best:
                    best = s
                    bo = o
                    bx = xs
                    by = ys
                    bn = nd
                    for q in range(nd):
                        keep[q] = nbr[q]
            if bo < 0:
                for kk in range(k, k + 3):
                    base[x, y, kk] = -1
                demoted[n_demoted] = x * ny + y
                n_demoted += 1
                total -= 3 * weights[7]
                continue
            total += best - weights[7]
            _put(bx, by, k, tw[bo], th[bo], layers, tp[bo], keep, bn, lab, rec, alive, count, parent)
    return total, n_demoted


@njit(cache=True)
def _put(x0, y0, k, w, h, layers, part, nbr, nd, lab, rec, alive, count, parent):
    """Record a new brick, label its cells and join it with its ``nd`` neighbours ``nbr``."""
    b = count[0]
    count[0] = b + 1
    rec[b, 0] = x0
    rec[b, 1] = y0
    rec[b, 2] = k
    rec[b, 3] = w
    rec[b, 4] = h
    rec[b, 5] = layers
    rec[b, 6] = part
    alive[b] = True
    parent[b] = b
    for x in range(x0, x0 + w):
        for y in range(y0, y0 + h):
            for kk in range(k, k + layers):
                lab[x, y, kk] = b
    for q in range(nd):
        ra = _find(parent, nbr[q])
        rb = _find(parent, b)
        if ra != rb:
            parent[ra] = rb


def lay_out_around(grid: Grid, cells: np.ndarray, parts: tuple[Part, ...] = CATALOG,
                   seed: int = 0, progress: Progress | None = None,
                   relaxed: bool = False) -> Layout:
    """The layout of ``grid`` with no brick straddling the boundary of the marked ``cells``.

    The filled cells outside ``cells`` and those inside are laid out on
    their own (:func:`core.layout.greedy.lay_out`, same parts, seed and ``relaxed``), and the two
    brick lists joined (ids renumbered 0..n-1, the outside bricks first).
    So the bricks touching ``cells`` cover exactly the marked filled cells.
    ``progress`` hears of the outside's layout (the bulk of the work).
    """
    filled = np.asarray(grid.filled, dtype=bool)
    inside = filled & np.asarray(cells, dtype=bool)
    bricks = []
    for n, mask in enumerate((filled & ~inside, inside)):
        if mask.any():
            part = lay_out(dataclasses.replace(grid, filled=mask), parts, seed=seed,
                           progress=progress if n == 0 else None, relaxed=relaxed)
            bricks += part.bricks
    return Layout(grid, [dataclasses.replace(b, id=n) for n, b in enumerate(bricks)])


#: Most tries of one brick's split into owned parts (:func:`_split`), so it stays quick.
SPLIT_TRIES = 20_000


def fit_stock(layout: Layout, parts: tuple[Part, ...], stock, frozen=()) -> Layout:
    """``layout`` with no more LEGO bricks of a design than ``stock``
    (:class:`core.inventory.Stock`) owns, where owned parts of ``parts`` can take their place.

    Designs are fitted largest first: a brick beyond what is owned of its design is split
    into owned parts of ``parts`` (each smaller, so a fitted design stays fitted) that fill
    its box exactly.  Where buying is allowed, a brick is split only into at most
    ``1 + BUY_COST`` parts, and is bought otherwise; where not, a brick that owned parts
    cannot fill is an :class:`InputError` naming its cells and the parts that would do.
    Bricks whose id is in ``frozen`` and printed bricks stay.  The same input gives the
    same layout; without ``frozen`` the ids are renumbered 0..n-1.
    """
    from core.inventory import BUY_COST, used

    have = used(layout)
    left = {p.number: max(stock.owned.get(p.number, 0) - have.get(p.number, 0), 0) for p in parts}
    most = int(1 + BUY_COST) if stock.buy else None
    frozen = set(frozen)
    replaced: dict[int, list[Brick]] = {}
    lacking: list[Brick] = []
    by_size = sorted(parts, key=lambda p: (-p.cells, p.number))
    for part in by_size:
        excess = have.get(part.number, 0) - stock.owned.get(part.number, 0)
        for b in reversed(layout.bricks):
            if excess <= 0:
                break
            if b.part != part.number or b.kind != "lego" or b.id in frozen:
                continue
            pieces = _split(tuple(b.size), by_size, left, most)
            if pieces is None:
                lacking.append(b)
                continue
            for _, _, number in pieces:
                left[number] -= 1
            replaced[b.id] = [Brick(-1, number, size, tuple(int(c) + o for c, o in zip(b.cell, at)))
                              for at, size, number in pieces]
            excess -= 1
    if lacking and not stock.buy:
        raise InputError(_lacking_words(lacking))
    bricks: list[Brick] = []
    start = max((b.id for b in layout.bricks), default=-1) + 1
    for b in layout.bricks:
        for piece in replaced.get(b.id, [b]):
            if piece.id < 0:
                piece, start = dataclasses.replace(piece, id=start), start + 1
            bricks.append(dataclasses.replace(piece))
    if not frozen:
        bricks = [dataclasses.replace(b, id=n) for n, b in enumerate(bricks)]
    return Layout(layout.grid, bricks)


def _lacking_words(lacking: list[Brick]) -> str:
    """The one line of a layout that the owned parts cannot cover."""
    from core.catalog import BY_NUMBER

    cells = sum(int(np.prod(b.size)) for b in lacking)
    wanted: dict[str, int] = {}
    for b in lacking:
        wanted[b.part] = wanted.get(b.part, 0) + 1
    where = ", ".join(f"({b.cell[0]}, {b.cell[1]}, {b.cell[2]})" for b in lacking[:3])
    more = f" and {len(lacking) - 3} more bricks' cells" if len(lacking) > 3 else ""
    need = ", ".join(f"{n}x {p} {BY_NUMBER[p].name}" for p, n in sorted(wanted.items()))
    return (f"--inventory-only: the owned parts cannot cover {cells} cell(s), at cells {where}"
            f"{more}; {need} more would do (or leave out --inventory-only to buy them)")


def _split(box: tuple[int, int, int], parts: tuple[Part, ...], left: dict[str, int],
           most: int | None) -> list[tuple] | None:
    """Owned parts (``left``: design -> count still free) filling ``box`` (sx, sy, layers)
    exactly, as (offset, size, design number), at most ``most`` of them (None: any number);
    None where none is found within :data:`SPLIT_TRIES` tries.  Larger parts first, each
    placed in a corner of what is left (a guillotine cut)."""
    options = [((sx, sy, p.layers), p.number) for p in parts for sx, sy in p.orientations()]
    tries = [0]
    free = dict(left)

    def fill(lo, size, budget):
        if 0 in size:
            return []
        if budget is not None and budget <= 0:
            return None
        for (sx, sy, sz), number in options:
            if tries[0] >= SPLIT_TRIES:
                return None
            if free.get(number, 0) <= 0 or sx > size[0] or sy > size[1] or sz > size[2]:
                continue
            if size[2] % sz:
                continue
            tries[0] += 1
            free[number] -= 1
            rest = [((lo[0] + sx, lo[1], lo[2]), (size[0] - sx, size[1], sz)),
                    ((lo[0], lo[1] + sy, lo[2]), (sx, size[1] - sy, sz)),
                    ((lo[0], lo[1], lo[2] + sz), (size[0], size[1], size[2] - sz))]
            got = [(lo, (sx, sy, sz), number)]
            for at, part_size in rest:
                more = fill(at, part_size, None if budget is None else budget - len(got))
                if more is None:
                    break
                got += more
            else:
                if budget is None or len(got) <= budget:
                    return got
            for _, _, n in got:
                free[n] += 1
        return None

    found = fill((0, 0, 0), box, most)
    return found
