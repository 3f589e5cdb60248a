"""Reinforce stage: the layout re-merged around the joints the force check finds failing.

The layout stage (:mod:`core.layout.greedy`) makes bricks hold together as a graph;
:mod:`core.forces` says which joints cannot carry what hangs on them.  This
stage takes the failing and the most loaded bricks as sites and, around each,
frees a window (a few studs across, a brick's height above and below) and
merges its cells again (:func:`core.layout.greedy.lay_out` on the window, other
seeds): longer parts that span the old seams, overlaps further from the
tipping edge.  A change is kept when the whole layout gets better on
(components, stands, worst utilisation, weak points, bricks), compared in
that order, so the graph's connectivity is never traded for forces.  Cells
marked for printing (``frozen``) keep their bricks.  The number of attempts
is bounded and the seeds fixed, so the result is deterministic.  A build the
force check could only judge unchecked, or in height bands (a big solid one,
:meth:`core.forces.decompose.Decompositions._by_bands`: each brick has its band's worst, not its
own), is left as it is.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from core import forces as forces_stage, stability as stability_stage
from core.catalog import CATALOG, Part
from core.layout import greedy as layout_stage
from core.model import Layout

#: Sites tried per round (the worst first), and the seeds of a site's windows.
SITES = 4
SEEDS = (1, 2, 3)
#: Window around a site: studs beyond its footprint, plate layers below and above.
RADIUS = (2, 3)
#: Per effort level (:data:`core.request.EFFORTS`): the rounds, and the first how many
#: of :data:`RADIUS` and of :data:`SEEDS` are tried at each site.  Each try is a force check
#: of the whole build (seconds on hundreds of bricks), so ``fast``, which keeps the greedy
#: layout, tries each site once.
EFFORT_TRIES = {"fast": (1, 1, 1), "normal": (2, 2, 3), "best": (2, 2, 3)}
LAYERS = 3
#: A brick this loaded (utilisation) is a site even when the layout stands.
LOADED = 0.8


@dataclass
class Reinforced:
    """What :func:`reinforce` did: the layout, and before/after of the force check."""

    layout: Layout
    before: dict
    after: dict
    attempts: int
    kept: int
    forces: forces_stage.Forces | None = None

    def to_json(self) -> dict:
        return {"before": self.before, "after": self.after, "attempts": self.attempts,
                "windows_kept": self.kept}


def _summary(f: forces_stage.Forces, st: stability_stage.Stability, bricks: int) -> dict:
    worst = f.max_utilisation
    return {"stable": None if f.unchecked else f.stable,
            "max_utilisation": None if not math.isfinite(worst) else round(worst, 4),
            "components": st.components, "weak_points": len(st.weak_points), "bricks": bricks}


def reinforce(layout: Layout, parts: tuple[Part, ...] = CATALOG, ground: str = "table",
              loads=(), clutch_n: float = forces_stage.CLUTCH_N, frozen: np.ndarray | None = None,
              seed: int = 0, checked_again: bool = False, effort: str = "normal") -> Reinforced:
    """``layout`` re-merged around its failing and most loaded bricks (see the module).

    ``frozen`` (a grid-shaped bool array, e.g. the cells to print) keeps the
    bricks touching it.  Promises: the result covers the same cells exactly
    once with parts of ``parts``; it is never worse than ``layout`` on the
    key (components, not standing, worst utilisation, weak points, bricks);
    ``layout`` is not changed; the same input gives the same result.
    ``forces`` is the full force check of the result, except that with
    ``checked_again`` (the caller checks the final build anew, e.g. with printed
    parts in it) a layout that stands below :data:`LOADED` is judged on the
    verdict alone and comes back as it is with ``forces`` None.
    """
    def judge(check: forces_stage.Analysis, detail: bool = True):
        candidate = check.layout
        f = check.verdict(detail)
        st = stability_stage.analyse(candidate)
        worst = f.max_utilisation if math.isfinite(f.max_utilisation) else 1e9
        key = (st.components, not f.stable, round(worst, 6), len(st.weak_points), len(candidate.bricks))
        return key, f, st

    def analysis(candidate: Layout) -> forces_stage.Analysis:
        return forces_stage.Analysis(candidate, ground, loads, clutch_n=clutch_n)

    first = analysis(layout)
    key, f, st = judge(first, detail=not checked_again)
    before = _summary(f, st, len(layout.bricks))
    if f.unchecked or f.bands:
        # in height bands every brick has only its band's worst: no joint to work around,
        # and each judgement of a candidate would be another minute of bands (the same
        # verdict with or without the detail)
        return Reinforced(layout, before, before, 0, 0, f)
    if checked_again:
        if f.stable and f.max_utilisation <= LOADED:
            # no brick above the worst, so none is a site
            return Reinforced(layout, before, before, 0, 0, None)
        key, f, st = judge(first)
        before = _summary(f, st, len(layout.bricks))
    best = layout
    attempts = kept = 0
    frozen = np.zeros(layout.grid.shape, bool) if frozen is None else np.asarray(frozen, bool)
    rounds, radii, seeds = EFFORT_TRIES[effort]
    for round_ in range(rounds):
        sites = _sites(best, f, frozen)
        if not sites:
            break
        improved = False
        for site in sites[:SITES]:
            for radius in RADIUS[:radii]:
                for s in SEEDS[:seeds]:
                    candidate = _relaid(best, site, radius, parts, seed * 1009 + 31 * round_ + s, frozen)
                    if candidate is None:
                        continue
                    attempts += 1
                    # the verdict alone first: its key is never above the full one's (the
                    # same worst; a build that stands may yet tip in the detail), so a
                    # candidate it does not keep, the full check would not keep either
                    check = analysis(candidate)
                    if not judge(check, detail=False)[0] < key:
                        continue
                    new_key, new_f, new_st = judge(check)
                    if new_key < key:
                        key, f, st, best = new_key, new_f, new_st, candidate
                        kept += 1
                        improved = True
                        break
                if improved:
                    break
            if improved:
                break
        if not improved:
            break
    return Reinforced(best, before, _summary(f, st, len(best.bricks)), attempts, kept, f)


def _sites(layout: Layout, f: forces_stage.Forces, frozen: np.ndarray) -> list[int]:
    """Indices of the bricks to work around: failing by their joints or bending, then
    loaded above :data:`LOADED`, worst first (unsupported ones cannot be helped here)."""
    util = f.utilisation
    out = []
    for n, b in enumerate(layout.bricks):
        u = util.get(b.id, 0.0)
        if math.isfinite(u) and u > LOADED and not frozen[b.slices()].any():
            out.append((-u, n))
    return [n for _, n in sorted(out)]


def _relaid(layout: Layout, site: int, radius: int, parts, seed: int,
            frozen: np.ndarray) -> Layout | None:
    """The layout with the LEGO bricks near brick ``site`` merged again; None if nothing moved."""
    grid = layout.grid
    b = layout.bricks[site]
    lo = np.maximum(np.array(b.cell) - [radius, radius, LAYERS], 0)
    hi = np.minimum(np.array(b.cell) + np.array(b.size) + [radius, radius, LAYERS], grid.shape)
    keep, free_ids = [], []
    free = np.zeros(grid.shape, dtype=bool)
    for brick in layout.bricks:
        c0, c1 = np.array(brick.cell), np.array(brick.cell) + np.array(brick.size)
        inside = np.all(c0 >= lo) and np.all(c1 <= hi)
        if inside and brick.kind == "lego" and not frozen[brick.slices()].any():
            free[brick.slices()] = True
            free_ids.append(brick.id)
        else:
            keep.append(brick)
    if len(free_ids) < 2:
        return None
    new = layout_stage.lay_out(dataclasses.replace(grid, filled=free), parts, seed=seed).bricks
    start = max(x.id for x in layout.bricks) + 1
    new = [dataclasses.replace(x, id=start + n) for n, x in enumerate(new)]
    return Layout(grid, keep + new)
