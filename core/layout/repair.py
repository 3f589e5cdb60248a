"""The layout under construction and its repair (after Testuz et al. 2013).

:class:`State` holds the labels, the brick records and the union-find of one merge
(:func:`core.layout.merge_kernels.place` with :data:`WEIGHTS`), judges it as (components, weak
points, bricks) and repairs it: around every seam where two components of one region meet and
every weak brick, the bricks of a neighbourhood are split back into cells and merged again
with another variant (:data:`REPAIR_VARIANTS`, then shaken ones); a change is kept only when
it is :func:`_better`, and the attempts are bounded (:data:`MAX_REPAIR_ATTEMPTS`,
:data:`MAX_REPAIR_WORK`), so the result is deterministic.  :meth:`State.layout` gives the
finished :class:`~core.model.Layout`.
"""

from __future__ import annotations

import numpy as np

from core.catalog import Part
from core.connectivity import articulation_points, component_labels
from core.layout.merge_kernels import SLAB_TRIALS, label_graph, place, reset_union
from core.model import Brick, Grid, Layout


#: Score weights: area per cell, joining two components, resting on >= 2
#: bricks, per seam edge cell on a seam below/above, preferred direction,
#: seeded tie-break, per brick left hanging by one neighbour (a leaf), per part
#: (when comparing whole slabs), per free cell left without a free neighbour;
#: the last entry shifts the seeded tie-break (the repair varies it).
WEIGHTS = (1.0, 24.0, 0.5, 0.25, 0.5, 0.2, 8.0, 4.0, 2.0, 0.0)

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


class State:
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
        place(todo, self.filled, self.base, self.lab, self.rec, self.alive, self.count,
               self.parent, *self.plates, *self.bricks, np.array(weights, dtype=np.float64), self.noise, variant,
               np.array(box, dtype=np.int64), trials)

    def quality(self):
        """``(components, weak points, bricks)``, component per brick, articulation mask, graph."""
        n = int(self.count[0])
        indptr, indices = label_graph(self.lab, self.rec, self.alive, n)
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
        reset_union(*graph, self.alive, self.parent, n)
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
