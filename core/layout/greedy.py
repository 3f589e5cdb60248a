"""Layout stage: merge the 1x1 plates of a grid into catalog plates and bricks.

:func:`lay_out` turns a :class:`~core.model.Grid` into a
:class:`~core.model.Layout` in three steps.

1. **Brick cells** (:mod:`core.layout.brick_cells`).  A brick is three plate layers tall, so
   the cells are grouped into three-layer column pieces ("groups") where bricks will go, and
   plate cells elsewhere: the three global phases and a patch-wise choice, each part of the
   model in its own phase.  ``relaxed`` (``best``'s second start) takes instead the brick
   layers of the exact cover's LP relaxation (:func:`relaxed_brick_groups`).
2. **Merging**, per candidate (:mod:`core.layout.merge_kernels`).  Bottom-up, per layer the
   brick slab and then the plate slab, a raster scan takes the first uncovered cell and
   chooses among the footprints of the allowed parts anchored there by a score
   (:data:`core.layout.repair.WEIGHTS`).  The candidate with the fewest bricks plus weak
   points and extra components wins.
3. **Repair** (:mod:`core.layout.repair`, after Testuz et al. 2013).  The neighbourhoods of
   seams between components and of weak bricks are merged again with other variants; a
   change is kept only when (components, weak points, bricks) improves lexicographically,
   within :data:`BRICK_BUDGET`.  The attempts are bounded, so the result is deterministic.

:func:`lay_out_around` keeps bricks off the boundary of marked cells; :func:`fit_stock` keeps
a layout to the maker's owned bricks.  All per-cell work runs in numba (the candidates of
step 2 two at a time, in threads).  Randomness comes only from ``seed``.
"""

from __future__ import annotations

import dataclasses
from concurrent.futures import ThreadPoolExecutor
from typing import Callable

import numpy as np

from core.catalog import BRICK_LAYERS, CATALOG, PLATE_LAYERS, Part
from core.connectivity import regions
from core.errors import InputError
from core.layout.bounds import part_shapes, placement_count, relaxed_cover
from core.layout.brick_cells import brick_group_candidates
from core.layout.repair import State
from core.model import Brick, Grid, Layout

Progress = Callable[[float, str], None]

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

#: Merge candidates laid out at once (threads: the merge kernel releases the GIL);
#: each holds its own labels and records, so memory grows with this too.
MERGE_THREADS = 2

#: Bricks a weak point and an extra component are worth when choosing
#: among merged layouts (the repair usually joins components cheaply).
WEAK_COST = 2.0
SPLIT_COST = 8.0


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
        state = State(filled, base.copy(), plates, bricks, noise, region_count)
        state.place_all()
        return state.quality()[0], state.snapshot()

    report(0.05, f"layout: merging plates, {len(bases)} ways")
    with ThreadPoolExecutor(max_workers=max(1, min(MERGE_THREADS, len(bases)))) as pool:
        results = list(pool.map(merged, bases))
    keys = [key for key, _ in results]
    budget = int(min(key[2] for key in keys) * BRICK_BUDGET)
    best = min(range(len(bases)), key=lambda n: (_rank(keys[n], budget, region_count), n))
    state = State(filled, bases[best], plates, bricks, noise, region_count)
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
    """Brick groups (as :func:`~core.layout.brick_cells.brick_group_candidates` gives them) read
    off the LP relaxation of the exact cover of ``filled`` by ``parts``
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
