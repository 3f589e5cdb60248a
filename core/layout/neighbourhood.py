"""One large neighbourhood search over a layout: its state, its windows and what it keeps.

:class:`Search` holds the layout as a grid of brick labels and brick records, with its brick
graph kept up to date window by window.  It orders the sites (weak bricks first, then small
ones, seeded ties), frees the movable bricks a box at a site touches (nearest first, up to a
number of cells), re-covers them exactly (:func:`core.layout.window_program.solve_window`) and
keeps a re-cover only when the whole layout improves on :data:`SearchKey` (while compacting,
an equal one too).  It sweeps the layers, each re-covered by parts of its own height, and goes
back to the best layout on :func:`core.layout.quality.quality` it has held.  Frozen bricks and
bricks that are not LEGO never move; the same layout and seed give the same search.
"""

from __future__ import annotations

import dataclasses
from typing import Callable

import numpy as np

from core.connectivity import regions
from core.inventory import BUY_COST, Stock, used as used_designs
from core.layout.bounds import MAX_VARIABLES
from core.layout.quality import (FailingJoints, Key, changed_contacts, contacts_of, csr_of,
                                 key_of_graph, pair_keys, vertical_pairs)
from core.layout.window_program import (COMPACT_LEAF_COST, LEAF_COST, TOO_LARGE, Effort,
                                        free_placements, numbered_shapes, size_code, solve_window)
from core.model import Brick, Layout


Progress = Callable[[float, str], None]

#: Layer windows times bricks that sweeping the layers may spend at the end of a search: it
#: starts another round only while the rounds so far, one more time, stay within it.
MAX_LAYER_WORK = 150_000

#: While weak points count: how often a window whose re-cover leaves the key as it was is
#: solved again, and the extra price each time of each of its new bricks that was a weak point
#: (the program prices leaves, not weak points; this shows it those its answer made).
WEAK_RETRIES = 2
WEAK_COST = 1.5

#: The key each window is kept on: (components, failing joints, weak points, weak points
#: that are not thin, bricks), none counted while compacting: all weak points before those
#: that are not thin, unlike :func:`~core.layout.quality.quality`, whose order would close paths
#: the search takes through layouts with a weak point that is not thin.
SearchKey = tuple[int, int, int, int, int]


class Search:
    """The state of one improvement: the cells' brick labels and the brick records.

    Brick records are rows ``(x, y, z, sx, sy, sz)`` with their part number,
    original id (None for new bricks) and whether they are frozen; removed
    bricks stay as dead rows, so indices never move.
    """

    def __init__(self, layout: Layout, parts, seed: int, frozen: set[int], apart,
                 failing: FailingJoints | None, stock: Stock | None = None):
        self.grid = layout.grid
        self.filled = np.ascontiguousarray(np.asarray(layout.grid.filled, dtype=bool))
        self.apart = None if apart is None else np.asarray(apart, dtype=bool) & self.filled
        self.shapes = numbered_shapes(parts)
        self.rng = np.random.default_rng(seed)
        self.failing = failing
        self.source = layout
        self.stock = stock
        # LEGO bricks of each design, kept up to date where a stock limits them
        self.used = used_designs(layout) if stock is not None else {}
        self.rec: list[tuple[int, int, int, int, int, int]] = []
        self.part: list[str] = []
        self.orig: list[Brick | None] = []
        self.fixed: list[bool] = []
        self.alive: list[bool] = []
        self.lab = np.full(self.grid.shape, -1, dtype=np.int64)
        self._pending: dict[int, tuple] = {}
        self._pending_part: dict[int, str] = {}
        for b in layout.bricks:
            self._add(tuple(b.cell) + tuple(b.size), b.part, b, b.id in frozen or b.kind != "lego")
        self.dead = 0
        self.weak_on = True
        # the brick graph, kept up to date window by window (:meth:`_try`)
        self.keys, self.counts, self.touching = contacts_of(self.lab, len(self.rec))
        self.key, self.strict, self.deg, self.art = self._evaluate(self.lab, len(self.rec), 0)
        self.best = (self.strict, np.flatnonzero(self.alive))
        # the fewest components any cover of these cells has: their regions
        self.fewest_components = regions(self.filled)[1]
        self.windows = 0
        self.accepted = 0
        self.iterations = 0

    def _add(self, box, part, orig, fixed) -> int:
        i = len(self.rec)
        self.rec.append(tuple(int(v) for v in box))
        self.part.append(part)
        self.orig.append(orig)
        self.fixed.append(fixed)
        self.alive.append(True)
        x, y, z, sx, sy, sz = box
        self.lab[x:x + sx, y:y + sy, z:z + sz] = i
        return i

    def count_weak(self, on: bool) -> None:
        """Count weak points in the key (the lexicographic search) or not (compaction)."""
        self.weak_on = on
        self.key, self.strict, self.deg, self.art = self._evaluate(self.lab, len(self.rec),
                                                                    self.dead)

    def _evaluate(self, lab, n, dead, graph=None, used=None) -> tuple[SearchKey, Key, np.ndarray,
                                                                      np.ndarray]:
        """(the search's key, the :func:`~core.layout.quality.quality` key, degrees,
        articulation mask) of the label grid ``lab`` of ``n`` records of which ``dead`` are
        removed, whose brick graph is ``graph`` (pair keys and touching cells; None: the
        search's own) and whose LEGO bricks of each design are ``used`` (None: the search's own;
        counted only with a stock, whose bought bricks cost more)."""
        keys, touching = (self.keys, self.touching) if graph is None else graph
        comps, weak, thin, deg, art = key_of_graph(*csr_of(keys, n), touching, n, dead)
        failing = 0
        if self.failing is not None:
            failing = int(self.failing(self._layout_of(lab)))
        bricks = n - dead
        if self.stock is not None:
            bricks += BUY_COST * self.stock.bought(self.used if used is None else used)
        strict = (comps, failing, weak - thin, weak, bricks)
        if not self.weak_on:
            weak = thin = 0
        return (comps, failing, weak, weak - thin, bricks), strict, deg, art

    def _layout_of(self, lab) -> Layout:
        """The layout of a label grid (for a force model): bricks in index order; indices
        past the records are the candidate bricks of the window being tried (``_pending``)."""
        used = np.unique(lab[lab >= 0])
        bricks = []
        for i in used:
            x, y, z, sx, sy, sz = self.rec[i] if i < len(self.rec) else self._pending[i]
            bricks.append(Brick(len(bricks), self._part_of(i), (sx, sy, sz), (x, y, z)))
        return Layout(self.grid, bricks)

    @property
    def bricks(self) -> int:
        """The number of bricks now."""
        return len(self.rec) - self.dead

    def _part_of(self, i):
        return self.part[i] if i < len(self.part) else self._pending_part[i]

    # -- sites and windows ---------------------------------------------------

    def sites(self, weak_only: bool = False) -> list[int]:
        """Live, movable bricks ordered by promise: weak (weak points and leaves), then
        small, seeded ties; with ``weak_only`` the weak ones alone."""
        idx = np.array([i for i, a in enumerate(self.alive) if a and not self.fixed[i]], dtype=np.int64)
        if idx.size == 0:
            return []
        rec = np.array([self.rec[i] for i in idx], dtype=np.int64)
        area = rec[:, 3] * rec[:, 4]
        deg = self.deg[idx]
        weak = self.art[idx] | (deg <= 1)
        score = 4.0 * weak + 2.0 * (1.0 - np.minimum(area, 16) / 16.0) + 0.5 * (deg == 2)
        score += 0.3 * self.rng.random(idx.size)
        order = np.argsort(-score, kind="stable")
        if weak_only:
            order = order[weak[order]]
        return [int(i) for i in idx[order]]

    def window(self, site: int, shape: tuple[int, int, int], anchor: int, max_cells: int):
        """The bricks to free for the window of ``shape`` (studs x, studs y, layers) at brick
        ``site``, or None when fewer than two.

        The box is centred on the site, shifted by up to one stud and one layer
        (seeded; ``anchor`` 0), or starts (1) or ends (2) where the site does,
        moved inside the grid; the freed bricks are the movable ones it touches, the
        nearest to the site first up to ``max_cells`` freed cells.
        """
        x, y, z = self.rec[site][:3]
        lo, hi = _window_box(self.rec[site], shape, anchor, self.grid.shape, self.rng)
        box = self.lab[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]]
        ids = []
        cells = 0
        for i in np.unique(box[box >= 0]):
            i = int(i)
            bx, by, bz, bsx, bsy, bsz = self.rec[i]
            if self.fixed[i]:
                continue
            ids.append(i)
            cells += bsx * bsy * bsz
        ids.sort(key=lambda i: (abs(self.rec[i][0] - x) + abs(self.rec[i][1] - y)
                                + abs(self.rec[i][2] - z), i))
        if cells > max_cells:
            kept, cells = [], 0
            for i in ids:
                size = self.rec[i][3] * self.rec[i][4] * self.rec[i][5]
                if cells + size <= max_cells:
                    kept.append(i)
                    cells += size
            ids = kept
        return ids if len(ids) >= 2 else None

    # -- the search ----------------------------------------------------------

    def run(self, level: Effort, budget: int, report: Progress, total: int,
            enough: Callable[[], bool] | None = None, work: int | None = None,
            weak_only: bool = False) -> None:
        """Try windows, shape by shape, sites in order of promise, until ``budget`` windows
        have been tried in all, or the windows' simplex iterations (:attr:`iterations`) have
        reached ``work`` (None: no such limit), or, after a window is kept, ``enough()`` says
        so; progress is reported as a share of the ``total`` windows of the whole stage."""
        tried: set[tuple] = set()
        report(min(self.windows / total, 1.0), "improve: windows")

        def spent() -> bool:
            return self.windows >= budget or (work is not None and self.iterations >= work)

        while not spent():
            progressed = False
            for shape, anchor in ((s, a) for s in level.shapes for a in (1, 2, 0)):
                for site in self.sites(weak_only):
                    if spent():
                        return
                    if not self.alive[site]:
                        continue
                    ids = self.window(site, shape, anchor, level.max_window_cells)
                    if ids is None:
                        continue
                    sig = tuple(sorted(self.rec[i] for i in ids))
                    if sig in tried:
                        continue
                    tried.add(sig)
                    progressed = True
                    self.windows += 1
                    if self.solve(ids, level):
                        self.accepted += 1
                        if enough is not None and enough():
                            return
                    report(min(self.windows / total, 1.0),
                           f"improve: window {self.windows}/{total}, {self.bricks} bricks, "
                           + (f"{self.key[2]} weak points" if self.weak_on else "compacting"))
            if not progressed:
                return

    def solve(self, ids: list[int], level: Effort, shapes=None) -> bool:
        """Re-cover the cells of bricks ``ids`` (nearest the site first) optimally with
        ``shapes`` (default: every allowed part); keep it
        if the key improves.  The farthest bricks stay fixed while the window has more than
        ``level.max_columns`` placements, and while its LP relaxation is fractional
        and the placements it uses, with the current bricks, are more than
        ``level.mip_columns`` (:func:`~core.layout.window_program.solve_window`).  While weak
        points count, a re-cover that does not improve the key is solved again (up to
        :data:`WEAK_RETRIES` times) with its new bricks that are weak points priced
        :data:`WEAK_COST` more."""
        shapes = self.shapes if shapes is None else shapes
        limit = level.max_columns
        while True:
            lo, sl, free = _freed_box(np.array([self.rec[i] for i in ids], dtype=np.int64),
                                      self.grid.shape)
            boxes = free_placements(free, None, shapes)
            if len(ids) > 2 and len(boxes) > limit:
                ids = ids[:max(2, (len(ids) * 4) // 5)]
                continue
            if self.apart is not None:
                boxes = free_placements(free, self.apart[sl], shapes)
            current = [tuple(np.subtract(self.rec[i][:3], lo)) + self.rec[i][3:] for i in ids]
            window = (boxes, free, self.filled[sl], np.where(free, -1, self.lab[sl]),
                      current, self.rng, level, LEAF_COST if self.weak_on else COMPACT_LEAF_COST)
            limits = _design_limits(self.shapes, self.used, [self.part[i] for i in ids], self.stock)
            chosen, spent = solve_window(*window, limits=limits)
            self.iterations += spent
            if chosen is not TOO_LARGE:
                break
            if len(ids) <= 2:
                return False
            limit = level.mip_columns
            ids = ids[:max(2, (len(ids) * 4) // 5)]
        penalty: dict[tuple, float] = {}
        for attempt in range(WEAK_RETRIES + 1):
            if chosen is None or sorted(chosen) == sorted(current) or self._settled(len(chosen) - len(ids)):
                return False
            n = len(self.rec)
            kept, art = self._try(ids, chosen, lo)
            if kept:
                return True
            weak = [box for j, box in enumerate(chosen) if art[n + j]]
            if not self.weak_on or not weak or attempt == WEAK_RETRIES:
                return False
            for box in weak:
                penalty[box] = penalty.get(box, 0.0) + WEAK_COST
            chosen, spent = solve_window(*window, penalty, limits=limits)
            self.iterations += spent
            if chosen is TOO_LARGE:
                return False
        return False

    def _settled(self, more: int) -> bool:
        """Whether no re-cover with ``more`` bricks than the bricks it replaces can be kept,
        whatever its graph: the key has the fewest components the cells allow, no failing
        joint and no weak point, and no stock prices the designs, so such a re-cover's key is
        never lower, nor equal where more is 0 and weak points count (:meth:`_try`)."""
        return (more >= 0 and (more > 0 or self.weak_on) and self.stock is None
                and self.key[0] == self.fewest_components and self.key[1:4] == (0, 0, 0))

    def sweep_layers(self, level: Effort, report: Progress) -> None:
        """Re-cover each layer of bricks in turn, a few hundred studs at a time.

        A layer is the movable bricks of one height that start on one plate layer.  Its
        bricks are grouped nearest first, from the one nearest a corner of the grid, up to
        ``level.layer_cells`` studs a group; each group is re-covered by parts of the same
        height only, which makes the program two-dimensional and so large groups cheap.
        The search's windows free a few hundred cells of a thick slab in all three
        directions; a layer window frees one layer across hundreds of studs, where long
        bricks fit again.  The layers are swept ``level.layer_sweeps`` times, grouping
        from another corner each time, so a seam between two groups is inside a group
        the next time (while the work stays within :data:`MAX_LAYER_WORK`).  A re-cover is
        kept only when the key improves.
        """
        if level.layer_cells <= 0:
            return
        wide = dataclasses.replace(level, max_columns=MAX_VARIABLES)
        corners = ((1, 1), (-1, -1), (1, -1), (-1, 1))
        done = 0
        for sweep in range(level.layer_sweeps):
            if sweep and done * (sweep + 1) / sweep * (len(self.rec) - self.dead) > MAX_LAYER_WORK:
                return
            sign = np.array(corners[sweep % len(corners)])
            # a layer's re-cover only replaces bricks of that layer by bricks of that layer,
            # so the layers can be listed once a round
            layers: dict[tuple[int, int], list[int]] = {}
            for i, (r, a, f) in enumerate(zip(self.rec, self.alive, self.fixed)):
                if a and not f:
                    layers.setdefault((r[2], r[5]), []).append(i)
            for (_, height), ids in sorted(layers.items()):
                shapes = [s for s in self.shapes if s[0][2] == height]
                for group in _nearest_groups(np.array([self.rec[i] for i in ids]), sign,
                                             level.layer_cells):
                    if len(group) < 2:
                        continue
                    self.solve([ids[g] for g in group], wide, shapes)
                    done += 1
                    report(1.0, f"improve: layer window {done}, {self.bricks} bricks")

    def _try(self, ids: list[int], chosen: list[tuple], lo) -> tuple[bool, np.ndarray]:
        """Replace bricks ``ids`` by the boxes ``chosen`` (window coordinates from ``lo``)
        if that improves the key, or while compacting leaves it as it is (a sideways move:
        :meth:`solve` passes only boxes other than the current ones): (whether it did, the
        trial's articulation mask, whose rows from the current number of records on are the
        boxes of ``chosen``)."""
        n = len(self.rec)
        freed = np.array([self.rec[i] for i in ids], dtype=np.int64)
        lo_z = max(int(freed[:, 2].min()) - 1, 0)
        hi_z = min(int((freed[:, 2] + freed[:, 5]).max()) + 1, self.lab.shape[2])
        # the cells whose vertical contacts the change can touch: the freed ones and a
        # layer above and below
        sl = (slice(int(freed[:, 0].min()), int((freed[:, 0] + freed[:, 3]).max())),
              slice(int(freed[:, 1].min()), int((freed[:, 1] + freed[:, 4]).max())),
              slice(lo_z, hi_z))
        before = self.lab[sl].copy()
        self._pending = {}
        self._pending_part = {}
        part_of = dict((s, p) for s, p in self.shapes)
        for j, (x, y, z, sx, sy, sz) in enumerate(chosen):
            i = n + j
            gx, gy, gz = x + lo[0], y + lo[1], z + lo[2]
            self.lab[gx:gx + sx, gy:gy + sy, gz:gz + sz] = i
            self._pending[i] = (int(gx), int(gy), int(gz), sx, sy, sz)
            self._pending_part[i] = part_of[(sx, sy, sz)]
        gone, come = vertical_pairs(before), vertical_pairs(self.lab[sl])
        keys, counts = changed_contacts(self.keys, self.counts, pair_keys(*come), pair_keys(*gone))
        touching = np.concatenate([self.touching, np.zeros(len(chosen), dtype=np.int64)])
        np.add.at(touching, np.concatenate(come), 1)
        np.subtract.at(touching, np.concatenate(gone), 1)
        dead = self.dead + len(ids)
        used = None
        if self.stock is not None:
            used = dict(self.used)
            for i in ids:
                used[self.part[i]] -= 1
            for p in self._pending_part.values():
                used[p] = used.get(p, 0) + 1
        key, strict, deg, art = self._evaluate(self.lab, n + len(chosen), dead, (keys, touching),
                                               used)
        if key > self.key or (key == self.key and self.weak_on):
            self.lab[sl] = before
            return False, art
        for i in ids:
            self.alive[i] = False
        for i in sorted(self._pending):
            self._add(self._pending[i], self._pending_part[i], None, False)
        self.keys, self.counts, self.touching = keys, counts, touching
        self.dead, self.key, self.strict, self.deg, self.art = dead, key, strict, deg, art
        if used is not None:
            self.used = used
        if strict < self.best[0]:
            self.best = (strict, np.flatnonzero(self.alive))
        return True, art

    def restore_best(self) -> None:
        """Go back to the layout that is best on :func:`~core.layout.quality.quality` of all the
        search has held (its start and every kept window), where that is better than the current
        one.

        Windows are kept on the search's key, which counts weak points together: a path
        through a layout with a weak point that is not thin often leads to fewer bricks, but
        it can also end there, having traded a thin weak point for one that is not."""
        strict, alive = self.best
        if not strict < self.strict:
            return
        keep = np.zeros(len(self.rec), dtype=bool)
        keep[alive] = True
        self.alive = keep.tolist()
        self.lab.fill(-1)
        for i in alive:
            x, y, z, sx, sy, sz = self.rec[i]
            self.lab[x:x + sx, y:y + sy, z:z + sz] = i
        self.dead = len(self.rec) - len(alive)
        if self.stock is not None:
            self.used = {}
            for i in alive:
                if self.orig[i] is None or self.orig[i].kind == "lego":
                    self.used[self.part[i]] = self.used.get(self.part[i], 0) + 1
        self.keys, self.counts, self.touching = contacts_of(self.lab, len(self.rec))
        self.key, self.strict, self.deg, self.art = self._evaluate(self.lab, len(self.rec),
                                                                    self.dead)

    def layout(self, next_id: int | None, renumber: bool) -> Layout:
        """The current bricks as a Layout: kept bricks first (in their order), then new ones."""
        old_ids = [b.id for b in self.source.bricks]
        start = max(max(old_ids, default=-1) + 1, next_id or 0)
        bricks = []
        for i, alive in enumerate(self.alive):
            if not alive:
                continue
            if self.orig[i] is not None:
                bricks.append(dataclasses.replace(self.orig[i]))
            else:
                x, y, z, sx, sy, sz = self.rec[i]
                bricks.append(Brick(start, self.part[i], (sx, sy, sz), (x, y, z)))
                start += 1
        if renumber:
            bricks = [dataclasses.replace(b, id=n) for n, b in enumerate(bricks)]
        return Layout(self.grid, bricks)


def _nearest_groups(rec: np.ndarray, sign: np.ndarray, cells: int) -> list[list[int]]:
    """Rows of ``rec`` (bricks ``(x, y, z, sx, sy, sz)`` of one layer) in groups of at most
    ``cells`` studs (a brick larger than that alone): each group starts at the brick
    first toward the corner ``sign`` (its x and y times sign, summed, least) and takes the
    bricks nearest it (centres, city-block distance) while they fit."""
    left = np.arange(len(rec))
    centre = rec[:, :2] + rec[:, 3:5] / 2.0
    area = rec[:, 3] * rec[:, 4]
    groups = []
    while left.size:
        first = left[int(np.argmin(rec[left, :2] @ sign))]
        dist = np.abs(centre[left] - centre[first]).sum(axis=1)
        order = left[np.argsort(dist, kind="stable")]
        fits = np.cumsum(area[order]) <= cells
        fits[0] = True
        taken = order[:int(np.argmin(fits)) if not fits.all() else len(order)]
        groups.append(taken.tolist())
        left = np.setdiff1d(left, taken)
    return groups


def _window_box(site: tuple, shape: tuple[int, int, int], anchor: int, grid_shape,
                rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """The low and high corners of the window box of ``shape`` (studs x, studs y, layers) at
    the brick ``site`` (x, y, z, sx, sy, sz), inside the grid of ``grid_shape`` where it fits:
    centred on the site and shifted by up to one stud and one layer (one draw of ``rng``;
    ``anchor`` 0), or starting (1) or ending (2) where the site does."""
    x, y, z, sx, sy, sz = site
    wx, wy, layers = shape
    if anchor == 0:
        lo = np.array([x + sx // 2 - wx // 2, y + sy // 2 - wy // 2, z + sz // 2 - layers // 2])
        lo += rng.integers(-1, 2, size=3)
    elif anchor == 1:
        lo = np.array([x, y, z])
    else:
        lo = np.array([x + sx - wx, y + sy - wy, z + sz - layers])
    lo = np.clip(lo, 0, np.maximum(np.array(grid_shape) - (wx, wy, layers), 0))
    return lo, lo + (wx, wy, layers)


def _freed_box(recs: np.ndarray, grid_shape) -> tuple[np.ndarray, tuple, np.ndarray]:
    """The local box of a window program around the bricks ``recs`` ((k, 6) boxes), with a
    margin of one cell where the grid of ``grid_shape`` allows: its low corner, its slices of
    the grid, and, over the box, the cells the bricks cover (the freed cells)."""
    lo = np.maximum(recs[:, :3].min(axis=0) - 1, 0)
    hi = np.minimum((recs[:, :3] + recs[:, 3:]).max(axis=0) + 1, grid_shape)
    sl = tuple(slice(a, b) for a, b in zip(lo, hi))
    free = np.zeros(tuple(hi - lo), dtype=bool)
    for x, y, z, sx, sy, sz in recs - np.concatenate([lo, np.zeros(3, np.int64)]):
        free[x:x + sx, y:y + sy, z:z + sz] = True
    return lo, sl, free


def _design_limits(shapes, used: dict[str, int], freed: list[str], stock: Stock | None):
    """The window program's design rows (the ``limits`` of
    :func:`~core.layout.window_program.solve_window`) over the placements of ``shapes`` when
    bricks of the parts ``freed`` leave a layout whose LEGO bricks of each design are
    ``used`` (None without a ``stock``): (box size codes, sorted; each one's design row; the
    designs' owned counts left over by the fixed bricks; whether more may be bought)."""
    if stock is None:
        return None
    designs = sorted({p for _, p in shapes})
    row = {d: j for j, d in enumerate(designs)}
    codes = np.array([size_code(*size) for size, _ in shapes], dtype=np.int64)
    order = np.argsort(codes)
    rows = np.array([row[p] for _, p in shapes], dtype=np.int64)[order]
    fixed = dict(used)
    for part in freed:
        fixed[part] = fixed.get(part, 0) - 1
    left = np.array([stock.owned.get(d, 0) - fixed.get(d, 0) for d in designs], dtype=float)
    return codes[order], rows, left, stock.buy
