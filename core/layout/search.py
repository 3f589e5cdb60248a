"""Improvement stage: a large neighbourhood search over the greedy layout.

:func:`improve` takes a finished :class:`~core.model.Layout` (the greedy layout with its
repairs, :mod:`core.layout.greedy`) and makes it better window by window, after Kollsker &
Malaguti's MIP repair of a constructive layout:

1. **Choose a window.**  Sites are bricks, weak ones first (articulation points and leaves
   of the brick graph), then small ones, seeded ties.  A box at the site frees the movable
   bricks it touches, nearest first, up to a number of cells and placements, so the freed
   cells are whole bricks; the first box (:data:`NEAREST`) is so large that this limit
   shapes the window.
2. **Solve it exactly** (:func:`_solve_window`, HiGHS): one binary per placement of an
   allowed part wholly on freed cells (never across the boundary of the ``apart`` cells),
   every freed cell covered once; the objective is bricks plus penalties for leaves (fixed
   bricks around the window too), islands and seams over seams.  A placement with a filled
   cell above or below always touches a brick there; that the window's bricks do not form
   a separate group is checked on the whole layout.
3. **Keep it** only when the whole layout improves on :data:`SearchKey` (lexicographic);
   while compacting, an equal re-cover is kept too: the search moves along a plateau.
4. **Sweep the layers** at the end of each search (:meth:`_Search.sweep_layers`): each
   layer re-covered by parts of its own height, wide enough for long bricks to fit again.
5. **Mend weak points** (``normal``, :func:`_repair_weak`): more windows at weak bricks.

The search runs in two phases, a compaction whose key leaves weak points out, then the full
key, and goes back to the best layout it held on :func:`quality`; should that be worse than
the input, the full key is searched from the input instead, so the result is never worse.
``best`` runs ``normal``'s search from several seeds (:func:`best_starts`), goes on from the
best within a budget of simplex iterations (:attr:`Effort.work`) and merges the layouts found
(:func:`_merged`).  Work is counted in windows and simplex iterations, not seconds, so the
same input, effort and seed give the same result (HiGHS runs single-threaded).
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass
from typing import Callable, Iterable

import highspy
import numpy as np
from numba import njit
from scipy import ndimage, sparse
from scipy.sparse.csgraph import connected_components

from core.catalog import CATALOG, Part
from core.connectivity import articulation_points, component_labels, pairs_csr, regions
from core.errors import InputError
from core.inventory import BUY_COST, Stock, used as used_designs
from core.layout.bounds import (_SIX, MAX_VARIABLES, _highs, _set_partitioning_lp,
                                _summed_volume, cover_matrix, fitting_boxes, more_time)
from core.model import Brick, Layout
from core.request import EFFORTS

Progress = Callable[[float, str], None]


@dataclass(frozen=True)
class Effort:
    """How hard :func:`improve` works.

    ``windows_per_cell``: windows tried per filled cell (bounded by
    ``min_windows`` and ``max_windows``); ``max_window_cells``: the largest
    number of freed cells in one window; ``shapes``: the window boxes tried
    at a site, (studs along x, studs along y, plate layers); ``compact_share``:
    the share of the windows spent compacting (weak points not counted yet);
    ``max_columns``: the most placements (program columns) in one window;
    ``mip_columns``: the most placements of a window whose LP relaxation is
    fractional that still go to branch and bound (of a larger one, those its relaxation
    uses and the current bricks; where they are more, the window is shrunk);
    ``node_limit``: branch-and-bound nodes per window; ``time_limit_s``: the
    safety limit per window; ``layer_cells``: the most studs of one layer window of the
    closing sweep (:meth:`_Search.sweep_layers`; 0: no sweep), ``layer_sweeps``: how many
    times it sweeps the layers, each time grouping their bricks from another corner;
    ``weak_windows``: while weak points remain, the most windows (as ``best`` tries them)
    tried at the end (:func:`_repair_weak`); ``relaxed_start``: the search also runs from the
    layout whose brick layers the exact cover's relaxation chooses, where that is cheap
    (:func:`core.layout.greedy.relaxed_brick_groups`, the ``others`` of :func:`improve`);
    ``work``: the most simplex iterations (HiGHS's, over all window programs) the whole
    effort spends, ``normal``'s searches from several seeds included (0: no such limit;
    :func:`improve`).
    """

    windows_per_cell: float
    min_windows: int
    max_windows: int
    max_window_cells: int
    shapes: tuple[tuple[int, int, int], ...]
    compact_share: float
    max_columns: int
    mip_columns: int
    node_limit: int
    time_limit_s: float
    layer_cells: int
    layer_sweeps: int
    weak_windows: int = 0
    relaxed_start: bool = False
    work: int = 0


#: The first window box tried at every site: so large that the bricks nearest the site fill
#: the window up to its most freed cells, whatever the shape there.  On a wall one stud
#: thick it reaches along the wall, where the smaller boxes free a few bricks.
NEAREST = (16, 16, 9)

#: ``normal`` ends, while weak points remain, by trying up to this many windows as ``best``
#: tries them, the weak bricks first, until none is left.  Weak points on one-cell-thin
#: features are tried too.
WEAK_WINDOWS = 120

#: The window boxes tried at a site, in this order, by ``normal`` and ``best``.
SHAPES = (NEAREST, (6, 6, 3), (4, 4, 6), (8, 4, 4), (4, 8, 4), (8, 8, 4), (6, 6, 6))

#: The effort levels: ``fast`` is the greedy layout only; ``best`` continues from
#: ``normal``'s result with more windows (so it is never worse on the key).  ``normal``'s
#: windows are as large as ``best``'s (up to 300 cells, 2,500 placements, branch and bound
#: up to 700).  ``best``'s last search, from the best of its seeds, tries 1 window per cell
#: (up to 3,000, and :data:`MAX_WORK`): where a model is large its seeds are few, and the
#: windows still find fewer bricks long after ``normal``'s share.  ``best``'s ``work`` is
#: counted in simplex iterations, which take about the same time each, so it stands for a
#: time limit that gives the same result on every machine.
EFFORT_LEVELS = {
    "fast": Effort(0.0, 0, 0, 0, (), 0.0, 0, 0, 0, 0.0, 0, 0),
    "normal": Effort(0.12, 120, 1000, 300, SHAPES, 0.4, 2500, 700, 200, 10.0, 300, 4, WEAK_WINDOWS),
    "best": Effort(1.0, 150, 3000, 300, SHAPES, 0.4, 2500, 700, 200, 20.0, 300, 4,
                   relaxed_start=True, work=750_000),
}

#: ``best`` runs ``normal``'s search from several seeds (the seed, then the next ones) and
#: goes on from the best result on the key: the search's result varies with the seed by
#: several per cent in bricks.  (most cells of the layout, seeds), smallest first; larger
#: layouts one.  Where :func:`improve` gets another start (``others``: the relaxed layout),
#: the seeds are shared among the starts.
BEST_STARTS = ((1_000, 8), (5_000, 3), (30_000, 2))

#: The share of ``best``'s work (:attr:`Effort.work`) its searches from several seeds may
#: spend: a seed's search starts only while the seeds so far, one more time on average, stay
#: within it (the first always runs, and the seeds take turns between the starts).  Its last
#: search gets the rest, and never less than the remaining share.
SEED_WORK_SHARE = 0.6

#: Windows times bricks one improvement may spend (each window judges the whole layout).
MAX_WORK = 2_500_000

#: Layer windows times bricks that sweeping the layers may spend at the end of a search: it
#: starts another round only while the rounds so far, one more time, stay within it.
MAX_LAYER_WORK = 150_000

#: Objective weights of the window program: per brick, per leaf (a brick
#: hanging from one neighbour), per island (a brick touching nothing above
#: or below), per brick side cell on a seam of a fixed brick below or above.
BRICK_COST = 1.0
LEAF_COST = 3.0
#: The leaf penalty while compacting (weak points not in the key yet).
COMPACT_LEAF_COST = 1.0
ISLAND_COST = 6.0
SEAM_COST = 0.02
#: While weak points count: how often a window whose re-cover leaves the key as it was is
#: solved again, and the extra price each time of each of its new bricks that was a weak point
#: (the program prices leaves, not weak points; this shows it those its answer made).
WEAK_RETRIES = 2
WEAK_COST = 1.5

Key = tuple[int, int, int, int, int]
#: The key each window is kept on: (components, failing joints, weak points, weak points
#: that are not thin, bricks), none counted while compacting: all weak points before those
#: that are not thin, unlike :func:`quality`, whose order would close paths the search
#: takes through layouts with a weak point that is not thin.
SearchKey = tuple[int, int, int, int, int]

#: What the window program returns when its LP relaxation is fractional and it, and the
#: placements its relaxation uses with the current bricks, are more placements than
#: branch and bound may take: the window is shrunk and tried again.
TOO_LARGE = "too large"
FailingJoints = Callable[[Layout], int]


def check_effort(effort: str) -> str:
    """``effort`` if it is one of :data:`EFFORTS`; InputError naming it otherwise."""
    if effort not in EFFORT_LEVELS:
        raise InputError(f"--effort {effort!r} must be one of {', '.join(EFFORTS)}")
    return effort


def improve(layout: Layout, parts: tuple[Part, ...] = CATALOG, effort: str = "normal",
            seed: int = 0, progress: Progress | None = None, frozen: Iterable[int] | None = None,
            apart: np.ndarray | None = None, failing_joints: FailingJoints | None = None,
            next_id: int | None = None, others: tuple[Layout, ...] = (),
            bound: dict | None = None, stock: Stock | None = None) -> Layout:
    """A layout of the same cells that is at least as good as ``layout`` on :func:`quality`.

    Promises: the result covers exactly the filled cells of ``layout.grid``
    once; every brick is ``layout``'s own or a part of ``parts`` in one of
    its orientations; bricks whose id is in ``frozen`` stay as they are; no
    new brick straddles the boundary of the ``apart`` cells (a grid-shaped
    bool array, e.g. the cells to print); its :func:`quality` key is never
    worse than ``layout``'s.  Untouched bricks keep their ids; new bricks get
    ids from one more than the largest id of ``layout`` (or ``next_id``, if larger) on, and
    without ``frozen`` all ids are renumbered 0..n-1 in brick order.  The same
    input, effort and seed give the same layout; ``best`` starts from the best
    of what ``normal`` gives from :func:`best_starts` seeds (``seed`` first); with
    ``others`` (other layouts of the same cells, e.g. with other brick layers; used only
    where the effort's ``relaxed_start`` says so) those seeds are shared out, the same ones
    (``seed`` first) from ``layout`` and from each of ``others``, so it is
    never worse on the key.  ``failing_joints(layout)``
    counts the joints a force model finds failing (None: not counted).
    ``bound`` is :func:`early_bound` of ``layout``'s cells: a layout already at the best
    key there can be (:func:`at_best`) is returned as it is, as no window can better it.
    ``progress(fraction, message)`` is called after every window; an
    exception it raises (a cancel) propagates.  ``layout`` is not changed.
    With ``stock`` (:class:`core.inventory.Stock`, which ``layout`` keeps to where buying is not
    allowed) no window uses more of a design than is owned (plus, where buying is allowed, what
    is bought, each bought brick counting :data:`core.inventory.BUY_COST` more on the key's
    bricks); then ``others``, ``bound`` and the merge of the layouts found are not used.
    Raises InputError for an unknown ``effort``.
    """
    level = EFFORT_LEVELS[check_effort(effort)]
    report = progress or _silent
    frozen_ids = set(frozen or ())
    if level.max_windows == 0 or not layout.bricks or (
            stock is None and at_best(layout, bound, failing_joints)):
        return _copy(layout, renumber=False)
    extra = tuple(others) if level.relaxed_start and stock is None else ()
    starts = {name: _starts(name, effort, layout, 1 + len(extra))
              for name in EFFORTS[1:EFFORTS.index(effort) + 1]}
    planned = [count * (1 + (len(extra) if name == "normal" else 0))
               for name, count in starts.items()]
    total = sum(planned)
    done, spent = 0, 0
    current, seen = layout, []
    for index, (name, count) in enumerate(starts.items()):
        found = []
        # the seeds take turns between the starts; of equal results the first start's wins
        begins = [(j, begin, seed + k) for k in range(count)
                  for j, begin in enumerate((current,) + (extra if name == "normal" else ()))]
        last = name == effort
        for _, begin, begin_seed in begins:
            if (level.work and not last and found
                    and spent * (len(found) + 1) / len(found) > SEED_WORK_SHARE * level.work):
                break

            def share(fraction, message, done=done):
                report((done + fraction) / total, message)
            work = max(level.work - spent, int((1.0 - SEED_WORK_SHARE) * level.work)) \
                if level.work and last else None
            better, iterations = _stage(begin, parts, EFFORT_LEVELS[name], begin_seed, share,
                                        frozen_ids, apart, failing_joints, next_id, work, stock)
            found.append(better)
            spent += iterations
            done += 1
        done = sum(planned[:index + 1])
        keys = [(_judged(f, failing_joints, stock), j, k) for f, (j, _, k) in zip(found, begins)]
        current = found[keys.index(min(keys))]
        seen += found
        if len(seen) > 1 and stock is None:
            report(done / total, "improve: merging the layouts found")
            current = _merged(seen, current, layout, parts, failing_joints, next_id) or current
    report(1.0, "improve: done")
    return _copy(current, renumber=not frozen_ids)


#: Seconds :func:`_merged`'s program may take; where its fewest cover is not proven by
#: then, the merge is dropped rather than keeping a cover that a faster machine would have
#: bettered (merges usually take well under this, so the result rarely depends on the
#: machine).
MERGE_S = 30.0


def _merged(layouts: list[Layout], best: Layout, source: Layout, parts: tuple[Part, ...],
            failing_joints: FailingJoints | None, next_id: int | None) -> Layout | None:
    """A layout of the bricks that some of ``layouts`` (covers of one grid, ``best`` the
    best of them on :func:`quality`) have, with the fewest of them that is of ``best``'s
    kind: one component per region, and no weak point or, where ``best`` has only thin
    ones, at most as many (:func:`leaf_free_bound` over those placements, with its cuts).
    None where ``best`` is of neither kind, where that fewest is not proven within
    :data:`MERGE_S` or where it is not better than ``best`` on :func:`quality` (failing
    joints included).  Its bricks are ``source``'s (the layout the improvement started
    from) where they are the same, with their ids; the others get ids above every id of
    ``source`` and ``layouts`` (and from ``next_id``)."""
    def box(brick):
        return tuple(brick.cell) + tuple(brick.size)

    key = quality(best, failing_joints)
    if key[0] != regions(np.asarray(best.grid.filled, bool))[1] or key[2]:
        return None
    boxes = np.unique(np.array([box(b) for lay in layouts for b in lay.bricks],
                               dtype=np.int64), axis=0)
    found = leaf_free_bound(best.grid, parts, MERGE_S, no_weak_points=key[3] == 0,
                            connected=True, most_weak=key[3] or None, placements=boxes)
    if not found["optimal"] or found["cover"] is None:
        return None
    kept = {box(b): b for b in source.bricks}
    known = {box(b): b for lay in list(layouts) + [best] for b in lay.bricks}
    start = max([b.id + 1 for lay in [source] + list(layouts) for b in lay.bricks]
                + [next_id or 0])
    bricks = []
    for cover in map(tuple, found["cover"]):
        if cover in kept:
            bricks.append(dataclasses.replace(kept[cover]))
        else:
            bricks.append(dataclasses.replace(known[cover], id=start))
            start += 1
    merged = Layout(best.grid, bricks)
    return merged if quality(merged, failing_joints) < key else None


def _starts(name: str, effort: str, layout: Layout, begins: int = 1) -> int:
    """How many seeds the search of effort level ``name`` runs from, from each of ``begins``
    starting layouts, when ``effort`` was asked for: :func:`best_starts` shared out among
    them (rounded up, so that ``best`` takes about as long with more starts) for ``normal``'s
    within ``best``, else one."""
    if effort == "best" and name == "normal":
        return -(-best_starts(layout.grid.count) // begins)
    return 1


def best_starts(cells: int) -> int:
    """How many seeds ``best`` runs ``normal``'s search from on a layout of ``cells`` cells
    (:data:`BEST_STARTS`)."""
    return next((seeds for most, seeds in BEST_STARTS if cells <= most), 1)


def _stage(layout: Layout, parts, level: Effort, seed: int, report: Progress, frozen: set[int],
           apart, failing_joints, next_id, work: int | None = None,
           stock: Stock | None = None) -> tuple[Layout, int]:
    """One effort level's search from ``layout``: compaction, then the full key, back to
    the best layout on :func:`quality` it held; from ``layout`` again on the full key
    should none be better than ``layout`` (its progress goes on from where the first
    search's stopped); then the sweep of the layers and the weak points'
    windows, and back to the best again.  (So ``best``'s ``normal`` stages are ``normal``
    itself, and ``best`` is never worse than ``normal``.)  The windows stop at the level's
    number or once they have spent ``work`` simplex iterations (None: no such limit),
    compaction at its share of either.  Returns the layout and the simplex iterations
    spent."""
    budget = int(np.clip(round(level.windows_per_cell * layout.grid.count),
                         level.min_windows, level.max_windows))
    # every window re-judges the whole layout's graph: on big builds fewer windows, so that
    # the effort stays seconds
    budget = min(budget, max(1, int(MAX_WORK / max(len(layout.bricks), 1))))
    search = _Search(layout, parts, seed, frozen, apart, failing_joints, stock)
    start = search.strict
    search.count_weak(False)
    search.run(level, int(budget * level.compact_share), report, budget,
               work=None if work is None else int(work * level.compact_share))
    search.count_weak(True)
    search.run(level, budget, report, budget, work=work)
    search.restore_best()
    spent = 0
    if not search.strict < start:
        spent = search.iterations
        reached = min(search.windows / budget, 1.0)

        def again(fraction, message):
            report(reached + (1.0 - reached) * fraction, message)
        search = _Search(layout, parts, seed, frozen, apart, failing_joints, stock)
        search.run(level, budget - int(budget * level.compact_share), again, budget,
                   work=None if work is None else max(work - spent, 0))
    search.sweep_layers(level, report)
    _repair_weak(search, level, report)
    search.restore_best()
    return search.layout(next_id, renumber=False), spent + search.iterations


def _repair_weak(search: "_Search", level: Effort, report: Progress) -> None:
    """Up to ``level.weak_windows`` more windows, as ``best`` tries them (weak bricks first, as
    :meth:`_Search.sites` orders them), while ``search``'s layout has weak points, those on
    one-cell-thin features (:func:`thin_weak_points`) too; kept on the key.  Then, while
    some are left, up to as many again at the weak bricks (weak points and leaves) alone.

    The first round tries each window shape at every site before the next shape, so on a
    large layout it tries one or two shapes at the weak bricks and spends the rest on the
    others; the second tries them all at the weak bricks."""
    def none_weak() -> bool:
        return search.key[2] == 0

    if not level.weak_windows or none_weak():
        return

    def said(fraction, message):
        report(1.0, message.replace("improve: window", "improve: weak point window"))

    for weak_only in (False, True):
        if none_weak():
            return
        budget = search.windows + level.weak_windows
        search.run(EFFORT_LEVELS["best"], budget, said, budget, none_weak, weak_only=weak_only)


def _judged(layout: Layout, failing_joints: FailingJoints | None, stock: Stock | None) -> Key:
    """:func:`quality`, its bricks counted as ``stock`` prices them (:meth:`Stock.cost`)."""
    key = quality(layout, failing_joints)
    return key if stock is None else key[:4] + (stock.cost(used_designs(layout)),)


def quality(layout: Layout, failing_joints: FailingJoints | None = None) -> Key:
    """The lexicographic key the improvement lowers: (components of the brick graph,
    failing joints, weak points (articulation points) that are not thin, weak points,
    bricks).  A thin weak point (:func:`thin_weak_points`) holds leaf bricks on
    one-cell-thin features only, which the shape forces more often than not; so of two
    layouts, one that traded a thin weak point for one that is not, even for fewer bricks,
    is the worse.  (The search's windows are kept on :data:`SearchKey`, which counts all weak
    points before those that are not thin; :meth:`_Search.restore_best` judges on this one.)

    Bricks are joined where one sits on another with overlapping footprints
    (:func:`core.stability.brick_graph`).  ``failing_joints`` counts the
    joints a force model finds failing; None counts 0.
    """
    n = len(layout.bricks)
    comps, weak, thin, _, _ = _graph_key(layout.labels(), n, 0)
    return comps, int(failing_joints(layout)) if failing_joints else 0, weak - thin, weak, n


#: Time limit of the lower bound when it is asked for (``--lower-bound``).
LOWER_BOUND_S = 20.0

#: Placement variables up to which the lower bound counts as cheap: computed
#: by default, within the time the layout took.
CHEAP_VARIABLES = 10_000


#: Placement variables up to which :func:`early_bound` solves the lower bound before the
#: search (a few hundredths of a second), and the seconds it may take.
EARLY_VARIABLES = 3_000
EARLY_BOUND_S = 1.0


def early_bound(grid, parts: tuple[Part, ...] = CATALOG) -> dict | None:
    """:func:`core.layout.bounds.brick_lower_bound` of ``grid`` when its program is small
    (:data:`EARLY_VARIABLES`), within :data:`EARLY_BOUND_S`; None otherwise."""
    from core.layout import bounds as lb_stage

    if lb_stage.placement_count(grid, parts, stop_above=EARLY_VARIABLES) > EARLY_VARIABLES:
        return None
    return lb_stage.brick_lower_bound(grid, parts, time_limit_s=EARLY_BOUND_S)


def at_best(layout: Layout, bound: dict | None, failing_joints: FailingJoints | None = None) -> bool:
    """Whether ``layout`` has the best :func:`quality` key any layout of its cells can have:
    one component per region, no failing joint and no weak point, and as few bricks as
    ``bound`` (a lower bound proven optimal) says any cover has."""
    if bound is None or not bound.get("optimal") or bound.get("bound") is None:
        return False
    best = (regions(np.asarray(layout.grid.filled, bool))[1], 0, 0, 0, bound["bound"])
    return quality(layout, failing_joints) == best


def layout_quality(greedy: Layout, layout: Layout, parts: tuple[Part, ...] = CATALOG,
                   timings: dict | None = None, lower_bound: bool = False,
                   failing_joints: FailingJoints | None = None, bound: dict | None = None) -> dict:
    """The ``layout_quality`` block of report.json for the greedy and improved layouts.

    ``bricks``, ``regions``, ``components``, ``weak_points`` (articulation
    points), ``weak_points_thin`` (those :func:`thin_weak_points`: a leaf
    brick on a one-cell-thin feature hangs on them, and no other leaf; counted apart), ``greedy`` and
    ``improved`` (their :func:`quality` keys by name), ``seconds`` per phase
    (from ``timings``: layout, improve, and with ``best`` layout_relaxed, the layout from
    the relaxation's brick layers, where it was made; and the lower bound's) and
    ``lower_bound``: the exact-cover bound (:func:`core.layout.bounds.brick_lower_bound`)
    with its ``time_limit_s``, whether it is ``proven`` optimal and the
    ``ratio`` bricks / bound.  The bound is computed when ``lower_bound`` is
    asked for (:data:`LOWER_BOUND_S`), else only when the program is small
    (:data:`CHEAP_VARIABLES`) and then within the seconds the layout took;
    otherwise it is None with the reason.  A ``bound`` already proven optimal
    (:func:`early_bound`) is taken as it is.  When asked for, ``lower_bound.one_piece`` is
    :func:`one_piece_bound` too.
    """
    from core.layout import bounds as lb_stage

    timings = timings or {}
    before, after = quality(greedy, failing_joints), quality(layout, failing_joints)
    names = ("components", "failing_joints", "weak_points_not_thin", "weak_points", "bricks")
    spent = float(timings.get("layout", 0.0)) + float(timings.get("improve", 0.0))
    seconds = {"layout": timings.get("layout"), "improve": timings.get("improve")}
    if "layout_relaxed" in timings:
        seconds["layout_relaxed"] = timings["layout_relaxed"]
        spent += float(timings["layout_relaxed"])
    block = {
        "bricks": after[4], "regions": regions(np.asarray(layout.grid.filled, bool))[1],
        "components": after[0], "weak_points": after[3],
        "weak_points_thin": after[3] - after[2],
        "greedy": dict(zip(names, before)), "improved": dict(zip(names, after)),
        "failing_joints_counted": failing_joints is not None,
    }
    variables = lb_stage.placement_count(layout.grid, parts,
                                         stop_above=None if lower_bound else CHEAP_VARIABLES)
    if lower_bound or variables <= CHEAP_VARIABLES:
        if bound is not None and bound.get("optimal"):
            limit, found = EARLY_BOUND_S, bound
        else:
            limit = LOWER_BOUND_S if lower_bound else max(round(spent, 3), 0.05)
            found = lb_stage.brick_lower_bound(layout.grid, parts, time_limit_s=limit)
        bound = found["bound"]
        block["lower_bound"] = {
            "bound": bound, "time_limit_s": limit, "proven": bool(found["optimal"]),
            "status": found["status"], "variables": found["variables"],
            "ratio": round(after[4] / bound, 4) if bound else None,
            "greedy_ratio": round(before[4] / bound, 4) if bound else None}
        seconds["lower_bound"] = found["seconds"]
        if lower_bound:
            block["lower_bound"]["one_piece"] = one_piece_bound(
                layout, parts, block["components"] == block["regions"], after[3],
                block["weak_points_thin"], limit)
            seconds["one_piece_bound"] = block["lower_bound"]["one_piece"]["seconds"]
    else:
        block["lower_bound"] = {
            "bound": None, "variables": variables,
            "why": f"not computed: more than {CHEAP_VARIABLES:,} placements would cost more "
                   "than the layout; ask for it with --lower-bound"}
    block["seconds"] = seconds
    return block


def one_piece_bound(layout: Layout, parts: tuple[Part, ...], joined: bool, weak: int, thin: int,
                    time_limit_s: float) -> dict:
    """The fewest bricks that ``layout``'s kind of layout can have, as far as
    :func:`leaf_free_bound` with its cuts finds in ``time_limit_s``: layouts in one piece per
    region with no weak point when ``layout`` has none (``weak`` 0), else with none but
    thin ones (``weak`` == ``thin``, its weak points that :func:`thin_weak_points` finds)
    and at most ``weak`` of them (``most_weak``): those as good as ``layout`` on the first
    terms of :func:`quality` (failing joints aside).
    ``joined`` says whether ``layout`` has one component per region.  Returns ``{"bound",
    "proven", "status", "time_limit_s", "seconds", "layouts", "ratio"}`` (``layouts`` names
    the kind, ``ratio`` is bricks / bound); for a layout of neither kind, ``bound`` None
    and ``why``, as no such bound holds for it."""
    if not joined or weak > thin:
        return {"bound": None, "seconds": 0.0,
                "why": "the layout is not in one piece per region with no weak point but those "
                       "on one-cell-thin features, so no bound of such layouts holds for it"}
    found = leaf_free_bound(layout.grid, parts, time_limit_s, no_weak_points=weak == 0,
                            connected=True, most_weak=weak or None)
    bound = found["bound"]
    if found["status"] == "infeasible":
        # ``layout`` is of the kind, so the program cannot be infeasible: said, not hidden
        return {"bound": None, "seconds": found["seconds"],
                "why": "the program finds no layout of this kind, though this layout is one "
                       "(a bug), so no bound is given"}
    return {"bound": bound, "proven": bool(found["optimal"]), "status": found["status"],
            "time_limit_s": time_limit_s, "seconds": found["seconds"],
            "layouts": "in one piece per region, with no weak point" if weak == 0 else
                       f"in one piece per region, with at most {weak} weak point(s), each "
                       "holding a leaf brick on a one-cell-thin feature",
            "ratio": round(len(layout.bricks) / bound, 4) if bound else None}


def bound_words(quality: dict) -> str | None:
    """The lower bounds of a :func:`layout_quality` block asked for with ``lower_bound``
    (its ``lower_bound`` has ``one_piece``) in one line of words; None for a block made
    without asking."""
    bricks, bound = quality.get("bricks"), quality.get("lower_bound") or {}
    if "one_piece" not in bound:
        return None

    def proven(found):
        return "proven" if found.get("proven") else f"not proven in {found['time_limit_s']:g} s"

    words = (f"lower bound: any layout needs at least {bound['bound']} bricks ({proven(bound)})"
             if bound.get("bound") else "lower bound: none found in the time given")
    piece = bound["one_piece"]
    if piece.get("bound"):
        words += (f"; a layout {piece['layouts']} at least {piece['bound']} ({proven(piece)}): "
                  f"these {bricks} are {piece['ratio']:.3f} times that")
    elif piece.get("why"):
        words += f"; {piece['why']}"
    return words + " (report.json layout_quality.lower_bound)"


def leaf_free_bound(grid, parts: tuple[Part, ...] = CATALOG, time_limit_s: float = 20.0,
                    no_weak_points: bool = False, connected: bool = False,
                    most_weak: int | None = None, placements: np.ndarray | None = None) -> dict:
    """A lower bound on the bricks of any layout that the improvement's targets accept: one
    component per region and no weak point but those holding a leaf on a one-cell-thin
    feature (:func:`thin_weak_points`).

    The exact-cover program (:mod:`core.layout.bounds`) with what such a layout cannot have:
    a brick touching nothing above or below in a region it does not fill alone (it would
    be a component of its own), and, in regions of more than twice the cells of the largest
    of ``parts`` (which need three bricks or more), a brick that touches cells on one side only, at
    least two of them, all under (or over) one other brick (a leaf: that brick would be a
    weak point, and not a thin one).  Both are necessary conditions, so the answer is a
    lower bound, usually above the plain exact cover's, and the gap between them is what
    connection costs at least.  With ``no_weak_points`` it bounds the layouts with one
    component per region and no weak point at all (thin ones included): it also forbids
    every brick whose cells split its region (:func:`separating`), which such a layout
    cannot have.  With ``connected`` the program is solved again and again with lazy cuts
    (:func:`_connection_cuts`) until its cover has one component per region (and, with
    ``no_weak_points``, no weak point) or ``time_limit_s`` runs out: each cut only removes
    covers that are not such layouts, so every round's bound is still one, and a cover that
    passes is the fewest bricks any such layout has; a cover that does not pass also gets
    the cuts of :func:`_degree_cuts` (two neighbours or more for every brick in a region of
    three bricks or more, but a leaf on a one-cell-thin feature where thin weak points
    are allowed).  Programs of more than :data:`LP_CUT_VARIABLES` placements solve their
    relaxation with the leaf rows it breaks and degree cuts, added round by round
    (:func:`_relaxed_cuts`); the integer program keeps the degree cuts.  With ``connected``
    and ``most_weak`` (and not ``no_weak_points``) it bounds the layouts that also have at
    most ``most_weak`` weak points: the weak-point cuts of :func:`_connection_cuts` hold for
    every brick but those the program marks as weak, at most ``most_weak`` of them.
    With ``placements`` ((n, 6) boxes ``x, y, z, sx, sy, sz`` on filled cells, e.g. the
    bricks of several layouts) the program has only those: ``bound`` then bounds only the
    covers made of them, and ``cover`` is such a layout with the fewest of them
    (:func:`_merged`).
    Returns ``{"bound", "optimal", "objective", "status", "seconds", "variables", "rounds",
    "cuts", "cover"}`` as :func:`core.layout.bounds.brick_lower_bound`; ``bound`` is the larger of the
    relaxation's bound (interior point, certified by weak duality) and HiGHS's dual
    bounds, rounded up (0 when neither came in ``time_limit_s``; None past
    :data:`core.layout.bounds.MAX_VARIABLES` placements, ``status`` "too large"),
    ``objective`` the bricks of the best such cover found or None (with ``connected``, only a
    cover that passes the cuts), ``cover`` its placements as ``[x, y, z, sx, sy, sz]`` cell
    boxes (or None), ``rounds`` the programs solved and ``cuts`` the cuts added.
    """
    start = time.perf_counter()
    filled = np.ascontiguousarray(np.asarray(grid.filled, dtype=bool))
    shapes = _shapes(parts)
    boxes = (_placements(filled, None, shapes) if placements is None
             else np.asarray(placements, dtype=np.int64).reshape(-1, 6))
    n, m = len(boxes), int(filled.sum())
    largest = max((sx * sy * sz for (sx, sy, sz), _ in shapes), default=1)

    rounds, cuts, passed = 0, 0, None

    def result(bound, optimal, objective, status):
        return {"bound": bound, "optimal": optimal, "objective": objective, "status": status,
                "seconds": round(time.perf_counter() - start, 4), "variables": n,
                "rounds": rounds, "cuts": cuts, "cover": passed}

    if m == 0:
        return result(0, True, 0, "optimal")
    if n > MAX_VARIABLES:
        return result(None, False, None, "too large")
    labels = ndimage.label(filled, structure=_SIX)[0]
    region_cells = np.bincount(labels.ravel())
    cell_index = np.full(filled.shape, -1, dtype=np.int64)
    cell_index[filled] = np.arange(m)
    cover = cover_matrix(boxes, cell_index, m).tocsr()
    _, below, above, bbox, _ = _contacts(boxes, filled, filled, np.full(filled.shape, -1, np.int64))
    region = region_cells[labels[boxes[:, 0], boxes[:, 1], boxes[:, 2]]]
    island = (below == 0) & (above == 0) & (boxes[:, 3] * boxes[:, 4] * boxes[:, 5] < region)
    if no_weak_points:
        island |= separating(boxes, labels)
    # a region of more cells than two of the largest parts take needs three bricks or more
    crowded = region > 2 * largest
    # bricks that have two neighbours or more in every such layout (:func:`_degree_cuts`)
    sociable = crowded & ((below + above >= 2) | no_weak_points)
    cand = np.flatnonzero(crowded & (bbox[:, 4] >= 0)
                          & (below + above >= 2))
    t, q = _covering(boxes, bbox[cand], cover.indptr.astype(np.int64),
                     cover.indices.astype(np.int64), cell_index)
    keep = cand[t] != q
    t, q = t[keep], q[keep]
    leaf = sparse.csr_matrix((np.ones(len(cand) + len(t)),
                              (np.concatenate([np.arange(len(cand)), t]),
                               np.concatenate([cand, q]))), shape=(len(cand), n))
    leaf.data[:] = 1.0
    lp = _leaf_free_lp(sparse.vstack([cover, leaf]).tocsc(), m, island)
    # the relaxation by interior point first (HiGHS's MIP root, by the dual simplex, is slow
    # on such programs), its bound certified by weak duality; a large one without the leaf
    # rows, which it gets as they are broken (:func:`_relaxed_cuts`)
    large = n > LP_CUT_VARIABLES
    h = _highs((LP_CUT_SHARE if large else 0.5) * time_limit_s, random_seed=0, solver="ipm",
               run_crossover="off", presolve="off")
    h.passModel(_leaf_free_lp(cover.tocsc(), m, island) if large else lp)
    h.run()
    if h.getModelStatus() == highspy.HighsModelStatus.kInfeasible:
        return result(None, True, None, "infeasible")
    bound = _certified(h)
    degree_rows = []
    if large:
        found, degree_rows = _relaxed_cuts(h, leaf, boxes, filled, cover, cell_index,
                                           sociable, start + LP_CUT_SHARE * time_limit_s)
        if h.getModelStatus() == highspy.HighsModelStatus.kInfeasible:
            return result(None, True, None, "infeasible")
        bound = max(bound, found)
    lp.integrality_ = [highspy.HighsVarType.kInteger] * n
    # a large program's presolve does not watch the clock
    h = _highs(max(time_limit_s - (time.perf_counter() - start), 0.05), random_seed=0,
               mip_abs_gap=1.0 - 1e-3, presolve="off" if large else "choose")
    h.passModel(lp)
    h.addRow(float(bound), highspy.kHighsInf, n, np.arange(n, dtype=np.int32), np.ones(n))
    for columns, values in degree_rows:
        h.addRow(0.0, highspy.kHighsInf, len(columns), columns.astype(np.int32), values)
    by_placement = cover.T.tocsr()
    weak_cuts = connected and (no_weak_points or most_weak is not None)
    marks: dict[int, int] = {}        # placement -> the column of "it may be a weak point"
    if weak_cuts and not no_weak_points:
        h.addRow(-highspy.kHighsInf, float(most_weak), 0, np.empty(0, np.int32), np.empty(0))
        marks_row = h.getNumRow() - 1
    while True:
        rounds += 1
        h.run()
        status = h.getModelStatus()
        if status == highspy.HighsModelStatus.kInfeasible:
            return result(None, True, None, "infeasible")
        info = h.getInfo()
        found = info.primal_solution_status == highspy.SolutionStatus.kSolutionStatusFeasible
        objective = round(info.objective_function_value) if found else None
        dual = info.mip_dual_bound
        if np.isfinite(dual):
            bound = max(bound, int(np.ceil(dual - 1e-6)))
        added = []
        if found:
            solution = np.asarray(h.getSolution().col_value)
            chosen = np.flatnonzero(solution[:n] > 0.5)
            if connected:
                added = _connection_cuts(boxes[chosen], chosen, filled, by_placement, labels,
                                         weak_cuts)
                # a weak point the program marked as one breaks no cut
                added = [cut for cut in added if cut[3] not in marks
                         or solution[marks[cut[3]]] < 0.5]
                if added:
                    added += _degree_cuts(boxes[chosen], chosen, filled, cover, cell_index,
                                          sociable)
            passed = None if added else boxes[chosen].tolist()
        if added:
            objective = None
        left = time_limit_s - (time.perf_counter() - start)
        if not added or status != highspy.HighsModelStatus.kOptimal or left <= 0:
            break
        for columns, values, lower, p in added:
            if p >= 0 and not no_weak_points:
                if p not in marks:
                    h.addCol(0.0, 0.0, 1.0, 1, np.array([marks_row], np.int32), np.ones(1))
                    marks[p] = h.getNumCol() - 1
                    h.changeColIntegrality(marks[p], highspy.HighsVarType.kInteger)
                columns, values = np.append(columns, marks[p]), np.append(values, 1.0)
            h.addRow(lower, highspy.kHighsInf, len(columns), columns.astype(np.int32), values)
        cuts += len(added)
        more_time(h, max(left, 0.05))
    optimal = objective is not None and (status == highspy.HighsModelStatus.kOptimal
                                         or bound >= objective)
    if optimal:
        bound = objective
    return result(bound, optimal, objective, "optimal" if optimal else "time limit")


def _leaf_free_lp(a: sparse.csc_matrix, m: int, island: np.ndarray) -> highspy.HighsLp:
    """The relaxation of :func:`leaf_free_bound`'s program: fewest placements (columns of
    ``a``, a 0/1 matrix), its first ``m`` rows (the cells) covered exactly once, every
    further row (a leaf row) at most 1, no placement marked ``island`` chosen."""
    lp = _set_partitioning_lp(a.indptr, a.indices, a.shape[0])
    lp.col_upper_ = np.where(island, 0.0, 1.0)
    lp.row_lower_ = np.concatenate([np.ones(m), np.full(a.shape[0] - m, -highspy.kHighsInf)])
    return lp


def _connection_cuts(chosen_boxes: np.ndarray, chosen: np.ndarray, filled: np.ndarray,
                     by_placement: sparse.csr_matrix, labels: np.ndarray,
                     weak_cuts: bool) -> list:
    """Cuts that the cover ``chosen`` (placement indices, their ``chosen_boxes``) breaks
    and every layout with one component per region (and, with ``weak_cuts``, where the
    brick ``p`` of the cut is not a weak point) keeps, as ``(columns, values, lower, p)``
    rows ``values . x[columns] >= lower`` over the placements (``p`` -1 for a cut that
    holds whatever the weak points); empty when the cover is such a layout.

    Bricks join only where one is over another, so the cells ``S`` of a component in a
    region it does not fill have all their neighbours above and below in ``S``: in a
    layout with one component per region some brick must lie partly in ``S`` and partly
    outside it (sum of those >= 1).  Likewise the cells ``S`` of a piece that falls off
    when the brick ``p`` is taken away have their neighbours above and below in ``S`` or
    under ``p``: with ``p`` chosen and no weak point, some brick must lie partly in
    ``S`` and partly in the rest of the region, off ``p`` (sum of those >= x_p).
    ``by_placement`` is the (placements, cells) matrix of the cells each placement covers,
    ``labels`` the 6-connected regions.
    """
    n = len(chosen_boxes)
    lab = np.full(filled.shape, -1, dtype=np.int64)
    for k, (x, y, z, sx, sy, sz) in enumerate(chosen_boxes):
        lab[x:x + sx, y:y + sy, z:z + sz] = k
    cell_brick = lab[filled]                       # per cell (cover's row order): its brick
    region = labels[chosen_boxes[:, 0], chosen_boxes[:, 1], chosen_boxes[:, 2]]
    indptr, indices, _ = _csr(lab, n)
    graph = sparse.csr_matrix((np.ones(indices.size, dtype=np.int8), indices, indptr), shape=(n, n))
    ncomp, comp = connected_components(graph, directed=False)
    per_region = np.bincount(np.unique(np.stack([region, comp], 1), axis=0)[:, 0])
    sizes = np.diff(by_placement.indptr)
    out = []

    def inside(bricks: np.ndarray) -> np.ndarray:
        """Per placement: how many of its cells lie in the cells of ``bricks``."""
        return by_placement @ np.isin(cell_brick, bricks).astype(np.float64)

    for c in range(ncomp):
        members = np.flatnonzero(comp == c)
        if per_region[region[members[0]]] > 1:
            count = inside(members)
            cross = np.flatnonzero((count > 0) & (count < sizes))
            out.append((cross, np.ones(len(cross)), 1.0, -1))
    if not weak_cuts:
        return out
    for p in np.flatnonzero(articulation_points(indptr, indices, n)):
        keep = np.ones(n, dtype=bool)
        keep[p] = False
        rest = graph[keep][:, keep]
        pieces, piece = connected_components(rest, directed=False)
        others = np.flatnonzero(keep)
        on_p = inside(np.array([p]))
        sides = [others[piece == k] for k in range(pieces)]
        own = comp[p]
        sides = [side for side in sides if comp[side[0]] == own]
        for side in sides[:-1] if len(sides) == 2 else sides:
            count = inside(side)
            cross = np.flatnonzero((count > 0) & (count + on_p < sizes) & (on_p == 0))
            out.append((np.append(cross, chosen[p]),
                        np.append(np.ones(len(cross)), -1.0), 0.0, int(chosen[p])))
    return out


def _degree_cuts(chosen_boxes: np.ndarray, chosen: np.ndarray, filled: np.ndarray,
                 cover: sparse.csr_matrix, cell_index: np.ndarray, sociable: np.ndarray) -> list:
    """Cuts, as :func:`_connection_cuts` gives them, ``sum(x_q, q next to p) - 2 x_p >= 0``
    for each brick ``p`` of the cover ``chosen`` (placement indices, their ``chosen_boxes``)
    with fewer than two neighbours whose placement is ``sociable`` (per placement: its
    region needs three bricks or more, and, unless the layouts have no weak point at all,
    it touches two filled cells or more right above and below it, in all).

    In a layout with one component per region and no weak point, a brick in a region of
    three bricks or more has two neighbours or more: with none it is a component of its own,
    with one that neighbour is a weak point.  Where thin weak points are allowed
    (:func:`thin_weak_points`), so is a leaf touching one cell, but not one touching two
    cells or more: its neighbour would be a weak point that is not thin.  The bricks next
    to ``p`` are those covering a
    cell right above or below it, each counted once, so a cut holds for every such layout
    and removes every cover where ``p`` has fewer than two neighbours, whichever they are
    (a weak-point cut removes only covers with that one piece hanging on ``p``).  The
    placements ``q`` are those covering such a cell but none of ``p``'s.  ``cover`` is the
    (cells, placements) matrix, ``cell_index`` the row of each filled cell.
    """
    n = len(chosen_boxes)
    lab = np.full(filled.shape, -1, dtype=np.int64)
    for k, (x, y, z, sx, sy, sz) in enumerate(chosen_boxes):
        lab[x:x + sx, y:y + sy, z:z + sz] = k
    indptr, _, _ = _csr(lab, n)
    out = []
    for k in np.flatnonzero((np.diff(indptr) < 2) & sociable[chosen]):
        q = _next_to(chosen_boxes[k], filled, cover, cell_index)
        out.append((np.append(q, chosen[k]), np.append(np.ones(len(q)), -2.0), 0.0, -1))
    return out


def _next_to(box: np.ndarray, filled: np.ndarray, cover: sparse.csr_matrix,
             cell_index: np.ndarray) -> np.ndarray:
    """The placements (columns of ``cover``, the (cells, placements) matrix) that cover a
    filled cell right above or below ``box`` (x, y, z, sx, sy, sz) and none of its cells:
    the bricks that would be its neighbours; ``cell_index`` is the row of each filled cell."""
    x, y, z, sx, sy, sz = box
    near = []
    for layer in (z - 1, z + sz):
        if 0 <= layer < filled.shape[2]:
            cells = cell_index[x:x + sx, y:y + sy, layer]
            near.append(cells[cells >= 0])
    near = np.concatenate(near) if near else np.empty(0, np.int64)
    own = cell_index[x:x + sx, y:y + sy, z:z + sz].ravel()
    return np.setdiff1d(np.unique(cover[near].indices), np.unique(cover[own].indices))


def separating(boxes: np.ndarray, labels: np.ndarray) -> np.ndarray:
    """Per placement (``boxes``, (n, 6)): whether its region (``labels``, 6-connected
    regions numbered from 1) falls apart into two or more 6-connected pieces without the
    cells it covers.  Bricks join only through faces, so the bricks of one piece touch
    those of another only through that brick: in a layout with one component per region
    it is a weak point, whatever the other bricks are."""
    objects = ndimage.find_objects(labels)
    shape = np.array(labels.shape)
    out = np.zeros(len(boxes), dtype=bool)
    for i, (x, y, z, sx, sy, sz) in enumerate(boxes):
        region = labels[x, y, z]
        # the region's cells in a one-cell rim around the box: when they are one piece, a
        # path through the box can go round it, so the region stays whole
        lo = np.maximum((x - 1, y - 1, z - 1), 0)
        hi = np.minimum((x + sx + 1, y + sy + 1, z + sz + 1), shape)
        rim = labels[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]] == region
        rim[x - lo[0]:x + sx - lo[0], y - lo[1]:y + sy - lo[1], z - lo[2]:z + sz - lo[2]] = False
        if ndimage.label(rim, structure=_SIX)[1] <= 1:
            continue
        sl = objects[region - 1]
        rest = labels[sl] == region
        x0, y0, z0 = (s.start for s in sl)
        rest[x - x0:x - x0 + sx, y - y0:y - y0 + sy, z - z0:z - z0 + sz] = False
        out[i] = ndimage.label(rest, structure=_SIX)[1] >= 2
    return out


def _dual_bound(a: sparse.csc_matrix, y: np.ndarray, row_lower: np.ndarray,
                row_upper: np.ndarray, upper: np.ndarray) -> float:
    """A lower bound on ``min sum x`` subject to ``row_lower <= a x <= row_upper`` (each row
    an equation, or bounded on one side) and ``0 <= x <= upper``, from any row prices ``y``
    (weak duality: a row bounded above takes a price of at most 0, one bounded below of at
    least 0; an inexact interior-point answer still gives a valid bound)."""
    y = np.nan_to_num(np.asarray(y, dtype=np.float64), nan=0.0, posinf=0.0, neginf=0.0)
    low, high = np.isfinite(row_lower), np.isfinite(row_upper)
    y = np.where(high & ~low, np.minimum(y, 0.0), np.where(low & ~high, np.maximum(y, 0.0), y))
    rhs = np.where(low, row_lower, np.where(high, row_upper, 0.0))
    reduced = 1.0 - a.T @ y
    return float(y @ rhs + np.minimum(reduced, 0.0) @ upper)


def _certified(h: highspy.Highs) -> int:
    """The bricks that the relaxation ``h`` just solved (by interior point, maybe inexact)
    certifies by weak duality, rounded up; 0 without row prices."""
    lp = h.getLp()
    y = np.asarray(h.getSolution().row_dual)
    if len(y) != lp.num_row_:
        return 0
    stored = (np.asarray(lp.a_matrix_.value_), np.asarray(lp.a_matrix_.index_),
              np.asarray(lp.a_matrix_.start_))
    shape = (lp.num_row_, lp.num_col_)
    a = (sparse.csr_matrix(stored, shape=shape)
         if lp.a_matrix_.format_ == highspy.MatrixFormat.kRowwise
         else sparse.csc_matrix(stored, shape=shape))
    found = _dual_bound(a, y, np.asarray(lp.row_lower_), np.asarray(lp.row_upper_),
                        np.asarray(lp.col_upper_))
    return max(0, int(np.ceil(found - 1e-6)))


#: Programs of more placements than this solve their relaxation without the leaf rows of
#: :func:`leaf_free_bound` and get those it breaks, and degree cuts, a round at a time
#: (:func:`_relaxed_cuts`), until this share of the time limit, at most this many degree cuts
#: a round: their integer program's first round seldom ends in the time, so its lazy cuts
#: never come, and with all leaf rows the relaxation itself often does not end either.
#: Smaller programs skip these rounds: there the cuts would take the integer program's time.
LP_CUT_VARIABLES = 10_000
LP_CUT_SHARE = 0.8
LP_CUTS = 4000


def _relaxed_cuts(h: highspy.Highs, leaf: sparse.csr_matrix, boxes: np.ndarray,
                  filled: np.ndarray, cover: sparse.csr_matrix, cell_index: np.ndarray,
                  sociable: np.ndarray, deadline: float) -> tuple[int, list]:
    """Leaf rows and degree cuts (:func:`_degree_cuts`) for the relaxation ``h`` (solved):
    while its solution breaks some and ``deadline`` (a ``time.perf_counter`` time) is ahead,
    the rows of ``leaf`` (one per row of the program, ``<= 1``) it breaks and the ``LP_CUTS``
    most broken degree cuts are added to ``h`` and it is solved again.  Every row holds for
    every layout the bound is of, so every round's certified bound (:func:`_certified`) is
    one.  Returns the largest of those of the rounds it solved (0 without any; the caller
    has ``h``'s own) and the degree cuts added, as (columns, values) of rows ``>= 0``, for
    the integer program (which has all the leaf rows)."""
    best = 0
    taken = np.zeros(leaf.shape[0], dtype=bool)
    added = []
    while time.perf_counter() < deadline:
        x = np.asarray(h.getSolution().col_value)
        if len(x) != len(boxes):
            break
        rows = np.flatnonzero((leaf @ x > 1.0 + 1e-4) & ~taken)
        taken[rows] = True
        for r in rows:
            row = leaf.getrow(r)
            h.addRow(-highspy.kHighsInf, 1.0, row.nnz, row.indices.astype(np.int32), row.data)
        found = []
        for p in np.flatnonzero(sociable & (x > 1e-6)):
            q = _next_to(boxes[p], filled, cover, cell_index)
            short = 2.0 * x[p] - x[q].sum()
            if short > 1e-4:
                found.append((short, p, q))
        if not found and not len(rows):
            break
        found.sort(key=lambda cut: -cut[0])
        for _, p, q in found[:LP_CUTS]:
            columns, values = np.append(q, p), np.append(np.ones(len(q)), -2.0)
            h.addRow(0.0, highspy.kHighsInf, len(columns), columns.astype(np.int32), values)
            added.append((columns, values))
        more_time(h, deadline - time.perf_counter())
        h.run()
        if h.getModelStatus() == highspy.HighsModelStatus.kInfeasible:
            break
        best = max(best, _certified(h))
    return best, added


def thin_weak_points(layout: Layout) -> list[int]:
    """Ids of the weak points that hold a leaf brick on a one-cell-thin feature and no
    other leaf: a leaf (a brick with a single neighbour) that touches the rest of the model,
    above and below, through one cell only (a spike, pin or tip) hangs on it, and every
    leaf that hangs on it does so.  Such a point is often the shape's doing rather than the
    layout's, so report.json counts it apart, and :func:`quality` ranks it after one that
    is not; the search still removes one where covering the feature differently gives its
    leaf more neighbours.  A weak point that also holds a leaf touching two cells or more
    is the layout's doing, and not thin (the bound of :func:`one_piece_bound` forbids such
    leaves)."""
    n = len(layout.bricks)
    indptr, indices, touching = _csr(layout.labels(), n)
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


def _shapes(parts) -> list[tuple[tuple[int, int, int], str]]:
    """Each box a part of ``parts`` takes when placed, (cells x, y, z), with the part's
    number (the last part of a shape wins), sorted by box."""
    return sorted({(sx, sy, p.layers): p.number for p in parts for sx, sy in p.orientations()}.items())


def _silent(fraction: float, message: str) -> None:
    """Progress sink that ignores everything."""


def _copy(layout: Layout, renumber: bool) -> Layout:
    """A new Layout with copies of the bricks."""
    bricks = [dataclasses.replace(b) for b in layout.bricks]
    if renumber:
        bricks = [dataclasses.replace(b, id=n) for n, b in enumerate(bricks)]
    return Layout(layout.grid, bricks)


#: A pair of bricks' key in the brick graph: the lower index shifted by this, or the other.
_KEY_BITS = 32


def _vertical_pairs(lab: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(lower, upper) brick of every cell of a label grid (-1 empty) directly over a cell of
    another brick, once per such cell."""
    lower, upper = lab[:, :, :-1], lab[:, :, 1:]
    touch = (lower >= 0) & (upper >= 0) & (lower != upper)
    return lower[touch], upper[touch]


def _pair_keys(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return (np.minimum(a, b) << _KEY_BITS) | np.maximum(a, b)


def _contacts_of(lab: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The brick graph of a label grid: its pairs' keys (sorted), the cells each pair touches
    at, and each of the ``n`` bricks' cells that touch another brick above or below."""
    a, b = _vertical_pairs(lab)
    keys, counts = np.unique(_pair_keys(a, b), return_counts=True)
    return keys, counts.astype(np.int64), np.bincount(np.concatenate([a, b]), minlength=n)


def _changed_contacts(keys: np.ndarray, counts: np.ndarray, added: np.ndarray,
                      removed: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_contacts_of`'s keys and counts with the touching cells of pairs ``added`` (one
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


def _csr_of(keys: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """CSR (indptr, indices) of the undirected graph of pair ``keys`` on ``n`` vertices."""
    return pairs_csr(keys >> _KEY_BITS, keys & ((1 << _KEY_BITS) - 1), n)


def _csr(lab: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """CSR (indptr, indices) of the brick graph of a grid of brick indices (-1 empty), and
    each brick's cells that touch another brick directly above or below."""
    keys, _, touching = _contacts_of(lab, n)
    return (*_csr_of(keys, n), touching)


def _graph_key(lab: np.ndarray, n: int, dead: int):
    """(components, weak points, thin weak points (:func:`thin_weak_points`), degree per
    vertex, articulation mask) of the brick graph of ``lab`` with ``n`` vertices of which
    ``dead`` are unused (isolated, not counted)."""
    return _key_of_graph(*_csr(lab, n), n, dead)


def _key_of_graph(indptr: np.ndarray, indices: np.ndarray, touching: np.ndarray, n: int,
                  dead: int):
    """:func:`_graph_key` of the brick graph given as CSR, with its bricks' touching cells."""
    comps = (int(component_labels(indptr, indices, n).max()) + 1 if n else 0) - dead
    art = articulation_points(indptr, indices, n)
    thin = int(np.count_nonzero(_thin(indptr, indices, art, touching)))
    return int(comps), int(np.count_nonzero(art)), thin, np.diff(indptr), art


class _Search:
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
        self.shapes = _shapes(parts)
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
        self.keys, self.counts, self.touching = _contacts_of(self.lab, len(self.rec))
        self.key, self.strict, self.deg, self.art = self._evaluate(self.lab, len(self.rec), 0)
        self.best = (self.strict, np.flatnonzero(self.alive))
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
        """(the search's key, the :func:`quality` key, degrees, articulation mask) of the
        label grid ``lab`` of ``n`` records of which ``dead`` are removed, whose brick graph
        is ``graph`` (pair keys and touching cells; None: the search's own) and whose LEGO
        bricks of each design are ``used`` (None: the search's own; counted only with a
        stock, whose bought bricks cost more)."""
        keys, touching = (self.keys, self.touching) if graph is None else graph
        comps, weak, thin, deg, art = _key_of_graph(*_csr_of(keys, n), touching, n, dead)
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

    def _limits(self, ids: list[int]):
        """The window program's design rows when bricks ``ids`` are freed (None without a
        stock): (box size codes, sorted; each one's design row; the designs' owned counts
        left over by the fixed bricks; whether more may be bought)."""
        if self.stock is None:
            return None
        designs = sorted({p for _, p in self.shapes})
        row = {d: j for j, d in enumerate(designs)}
        codes = np.array([_size_code(*size) for size, _ in self.shapes], dtype=np.int64)
        order = np.argsort(codes)
        rows = np.array([row[p] for _, p in self.shapes], dtype=np.int64)[order]
        fixed = dict(self.used)
        for i in ids:
            fixed[self.part[i]] = fixed.get(self.part[i], 0) - 1
        left = np.array([self.stock.owned.get(d, 0) - fixed.get(d, 0) for d in designs], dtype=float)
        return codes[order], rows, left, self.stock.buy

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
        x, y, z, sx, sy, sz = self.rec[site]
        wx, wy, layers = shape
        if anchor == 0:
            lo = np.array([x + sx // 2 - wx // 2, y + sy // 2 - wy // 2, z + sz // 2 - layers // 2])
            lo += self.rng.integers(-1, 2, size=3)
        elif anchor == 1:
            lo = np.array([x, y, z])
        else:
            lo = np.array([x + sx - wx, y + sy - wy, z + sz - layers])
        lo = np.clip(lo, 0, np.maximum(np.array(self.grid.shape) - (wx, wy, layers), 0))
        hi = lo + (wx, wy, layers)
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
        ``level.mip_columns`` (:func:`_solve_window`).  While weak points count, a re-cover
        that does not improve the key is solved again (up to :data:`WEAK_RETRIES` times)
        with its new bricks that are weak points priced :data:`WEAK_COST` more."""
        shapes = self.shapes if shapes is None else shapes
        limit = level.max_columns
        while True:
            recs = np.array([self.rec[i] for i in ids], dtype=np.int64)
            lo = np.maximum(recs[:, :3].min(axis=0) - 1, 0)
            hi = np.minimum((recs[:, :3] + recs[:, 3:]).max(axis=0) + 1, self.grid.shape)
            sl = tuple(slice(a, b) for a, b in zip(lo, hi))
            free = np.zeros(tuple(hi - lo), dtype=bool)
            for x, y, z, sx, sy, sz in recs - np.concatenate([lo, np.zeros(3, np.int64)]):
                free[x:x + sx, y:y + sy, z:z + sz] = True
            boxes = _placements(free, None, shapes)
            if len(ids) > 2 and len(boxes) > limit:
                ids = ids[:max(2, (len(ids) * 4) // 5)]
                continue
            if self.apart is not None:
                boxes = _placements(free, self.apart[sl], shapes)
            current = [tuple(np.subtract(self.rec[i][:3], lo)) + self.rec[i][3:] for i in ids]
            window = (boxes, free, self.filled[sl], np.where(free, -1, self.lab[sl]),
                      current, self.rng, level, LEAF_COST if self.weak_on else COMPACT_LEAF_COST)
            limits = self._limits(ids)
            chosen, spent = _solve_window(*window, limits=limits)
            self.iterations += spent
            if chosen is not TOO_LARGE:
                break
            if len(ids) <= 2:
                return False
            limit = level.mip_columns
            ids = ids[:max(2, (len(ids) * 4) // 5)]
        penalty: dict[tuple, float] = {}
        for attempt in range(WEAK_RETRIES + 1):
            if chosen is None or sorted(chosen) == sorted(current):
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
            chosen, spent = _solve_window(*window, penalty, limits=limits)
            self.iterations += spent
            if chosen is TOO_LARGE:
                return False
        return False

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
        gone, come = _vertical_pairs(before), _vertical_pairs(self.lab[sl])
        keys, counts = _changed_contacts(self.keys, self.counts, _pair_keys(*come), _pair_keys(*gone))
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
        """Go back to the layout that is best on :func:`quality` of all the search has held
        (its start and every kept window), where that is better than the current one.

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
        self.keys, self.counts, self.touching = _contacts_of(self.lab, len(self.rec))
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


# -- the window program ------------------------------------------------------

def _placements(free, apart, shapes):
    """Every placement on the freed cells: (n, 6) boxes (x, y, z, sx, sy, sz), shape by
    shape in the order of ``shapes``, each shape's min corners in C order.

    With ``apart`` cells a placement lies wholly inside or wholly outside them.
    """
    masks = [free] if apart is None else [free & apart, free & ~apart]
    sizes = np.array([size for size, _ in shapes], dtype=np.int64).reshape(-1, 3)
    out = [fitting_boxes(_summed_volume(mask), sizes) for mask in masks if mask.any()]
    return np.concatenate(out) if out else np.empty((0, 6), dtype=np.int64)


@njit(cache=True)
def _contacts(boxes, free, filled, lab):
    """Per placement: distinct fixed bricks touching it above or below (capped at 2), freed
    cells it touches below and above, whether its freed contacts lie on one side only and
    their bounding box (x0, y0, x1, y1, layer), and its side cells on seams of fixed bricks
    directly below or above."""
    n = boxes.shape[0]
    nx, ny, nz = free.shape
    fixed = np.zeros(n, dtype=np.int64)
    wb = np.zeros(n, dtype=np.int64)
    wa = np.zeros(n, dtype=np.int64)
    bbox = np.zeros((n, 5), dtype=np.int64)
    seams = np.zeros(n, dtype=np.int64)
    for p in range(n):
        x0, y0, z0, sx, sy, sz = boxes[p]
        first = -1
        second = -1
        bx0, by0, bx1, by1, layer = nx, ny, -1, -1, -1
        for side in range(2):
            z = z0 - 1 if side == 0 else z0 + sz
            if z < 0 or z >= nz:
                continue
            for x in range(x0, x0 + sx):
                for y in range(y0, y0 + sy):
                    if not filled[x, y, z]:
                        continue
                    if free[x, y, z]:
                        if side == 0:
                            wb[p] += 1
                        else:
                            wa[p] += 1
                        bx0 = min(bx0, x)
                        by0 = min(by0, y)
                        bx1 = max(bx1, x)
                        by1 = max(by1, y)
                        layer = z
                    else:
                        b = lab[x, y, z]
                        if first < 0:
                            first = b
                        elif b != first and second < 0:
                            second = b
            # side cells of the placement whose fixed neighbour cells in layer z split there too
            for y in range(y0, y0 + sy):
                for xi, xo in ((x0, x0 - 1), (x0 + sx - 1, x0 + sx)):
                    if 0 <= xo < nx and not free[xi, y, z] and not free[xo, y, z]:
                        a = lab[xi, y, z]
                        c = lab[xo, y, z]
                        if a >= 0 and c >= 0 and a != c:
                            seams[p] += 1
            for x in range(x0, x0 + sx):
                for yi, yo in ((y0, y0 - 1), (y0 + sy - 1, y0 + sy)):
                    if 0 <= yo < ny and not free[x, yi, z] and not free[x, yo, z]:
                        a = lab[x, yi, z]
                        c = lab[x, yo, z]
                        if a >= 0 and c >= 0 and a != c:
                            seams[p] += 1
        fixed[p] = 0 if first < 0 else (1 if second < 0 else 2)
        bbox[p, 0] = bx0
        bbox[p, 1] = by0
        bbox[p, 2] = bx1
        bbox[p, 3] = by1
        bbox[p, 4] = layer if (wb[p] == 0) != (wa[p] == 0) else -1
    return fixed, wb, wa, bbox, seams


@njit(cache=True)
def _covering(boxes, targets, cell_ptr, cell_cols, cell_index):
    """Pairs (t, q): placement q covers the whole box ``targets[t]`` (x0, y0, x1, y1, layer)."""
    out_t = []
    out_q = []
    for t in range(targets.shape[0]):
        x0, y0, x1, y1, z = targets[t]
        c = cell_index[x0, y0, z]
        for e in range(cell_ptr[c], cell_ptr[c + 1]):
            q = cell_cols[e]
            qx, qy, qz, sx, sy, sz = boxes[q]
            if qx <= x0 and qy <= y0 and x1 < qx + sx and y1 < qy + sy and qz <= z < qz + sz:
                out_t.append(t)
                out_q.append(q)
    return np.array(out_t, dtype=np.int64), np.array(out_q, dtype=np.int64)


@njit(cache=True)
def _fixed_leaf_targets(free, filled, lab):
    """Boxes (x0, y0, x1, y1, layer) of the freed cells that a fixed brick touches, for the
    fixed bricks beside the window that touch no other fixed brick and touch freed cells
    on one side only: such a brick becomes a leaf if one placement covers that box.  The
    bricks are taken in the order of their labels, each as far as it lies in the grid."""
    nx, ny, nz = lab.shape
    flat = lab.ravel()
    ids = np.unique(flat[flat >= 0])
    lo = np.full((ids.size, 3), 1 << 30, dtype=np.int64)
    hi = np.full((ids.size, 3), -1, dtype=np.int64)
    for x in range(nx):
        for y in range(ny):
            for z in range(nz):
                if lab[x, y, z] >= 0:
                    j = np.searchsorted(ids, lab[x, y, z])
                    for axis, v in ((0, x), (1, y), (2, z)):
                        lo[j, axis] = min(lo[j, axis], v)
                        hi[j, axis] = max(hi[j, axis], v)
    out = np.empty((ids.size, 5), dtype=np.int64)
    count = 0
    for j in range(ids.size):
        touch, sides = False, 0
        for z in (lo[j, 2] - 1, hi[j, 2] + 1):
            if z < 0 or z >= nz:
                continue
            bx0, by0, bx1, by1 = 1 << 30, 1 << 30, -1, -1
            for x in range(lo[j, 0], hi[j, 0] + 1):
                for y in range(lo[j, 1], hi[j, 1] + 1):
                    if free[x, y, z]:
                        bx0, by0, bx1, by1 = min(bx0, x), min(by0, y), max(bx1, x), max(by1, y)
                    elif filled[x, y, z] and lab[x, y, z] >= 0 and lab[x, y, z] != ids[j]:
                        touch = True
            if bx1 >= 0:
                sides += 1
                out[count, 0], out[count, 1], out[count, 2] = bx0, by0, bx1
                out[count, 3], out[count, 4] = by1, z
        if not touch and sides == 1:
            count += 1
    return out[:count]


def _solve_window(boxes, free, filled, lab, current, rng, level: Effort, leaf_cost: float,
                  penalty: dict | None = None, limits=None):
    """The best re-cover of the ``free`` cells of a local box by the placements ``boxes``
    (:func:`_placements`), as a list of boxes, or None; with the simplex iterations HiGHS
    spent on it (a count of work that, unlike seconds, is the same on every run).

    ``lab`` holds the fixed bricks' indices (-1 on freed and empty cells);
    the box has a margin of one cell around the freed cells where the grid
    allows.  ``current`` (the freed bricks' boxes) is the starting solution.  Where the
    LP relaxation is fractional: branch and bound over ``boxes`` when they are at most
    ``level.mip_columns``, else over the placements the relaxation uses and ``current``
    when those are, else :data:`TOO_LARGE`.  ``limits`` (:meth:`_Search._limits`, None:
    none) add a row per design: its placements at most the owned count left, plus a bought
    count (at most 0 where buying is not allowed) priced :data:`core.inventory.BUY_COST`.
    """
    n = len(boxes)
    if n == 0:
        return None, 0
    cell_index = np.full(free.shape, -1, dtype=np.int64)
    cell_index[free] = np.arange(int(free.sum()))
    m = int(free.sum())
    cover = cover_matrix(boxes, cell_index, m)
    rows, cols = cover.row, cover.col
    by_cell = cover.tocsr()
    fixed, wb, wa, bbox, seams = _contacts(boxes, free, filled, lab)
    cost = BRICK_COST + SEAM_COST * seams + 1e-4 * rng.random(n)
    cost += ISLAND_COST * ((fixed == 0) & (wb == 0) & (wa == 0))
    cost += leaf_cost * ((fixed == 1) & (wb == 0) & (wa == 0))
    for box, extra in (penalty or {}).items():
        cost[np.flatnonzero((boxes == box).all(axis=1))] += extra
    # A placement p with no fixed neighbour that touches freed cells on one side only is
    # a leaf when one placement q covers all of those cells.  All such q cover the same
    # cell, so at most one is chosen: y_p >= x_p + sum_q x_q - 1 is exact (one row per p).
    # A fixed brick beside the window with no other fixed neighbour: y_F >= sum_q x_q.
    ptr, idx = by_cell.indptr.astype(np.int64), by_cell.indices.astype(np.int64)
    cand = np.flatnonzero((fixed == 0) & (bbox[:, 4] >= 0))
    t, q = _covering(boxes, bbox[cand], ptr, idx, cell_index)
    keep = cand[t] != q
    t, q = t[keep], q[keep]
    leaves, t = np.unique(t, return_inverse=True)
    targets = _fixed_leaf_targets(free, filled, lab)
    ft, fq = (_covering(boxes, targets, ptr, idx, cell_index) if len(targets)
              else (np.empty(0, np.int64), np.empty(0, np.int64)))
    n_leaf, n_fixed = leaves.size, len(targets)
    design, n_buy = None, 0
    if limits is not None:
        codes, design_rows, left, may_buy = limits
        design = design_rows[np.searchsorted(codes, _size_code(boxes[:, 3], boxes[:, 4], boxes[:, 5]))]
        n_buy = len(left)
    n_cols = n + n_leaf + n_fixed + n_buy
    n_rows = m + n_leaf + n_fixed + n_buy
    leaf_rows = m + np.arange(n_leaf)
    fixed_rows = m + n_leaf + np.arange(n_fixed)
    r_rows = [rows, leaf_rows, m + t, leaf_rows, fixed_rows[ft], fixed_rows]
    r_cols = [cols, cand[leaves], q, n + np.arange(n_leaf), fq, n + n_leaf + np.arange(n_fixed)]
    r_vals = [np.ones(rows.size), np.ones(n_leaf), np.ones(q.size), -np.ones(n_leaf),
              np.ones(fq.size), -np.ones(n_fixed)]
    if n_buy:
        buy_rows = m + n_leaf + n_fixed + np.arange(n_buy)
        r_rows += [buy_rows[design], buy_rows]
        r_cols += [np.arange(n), n + n_leaf + n_fixed + np.arange(n_buy)]
        r_vals += [np.ones(n), -np.ones(n_buy)]
    a = sparse.csc_matrix((np.concatenate(r_vals), (np.concatenate(r_rows).astype(np.int64),
                                                   np.concatenate(r_cols).astype(np.int64))),
                          shape=(n_rows, n_cols))
    a.sum_duplicates()
    lp = highspy.HighsLp()
    lp.num_col_ = n_cols
    lp.num_row_ = n_rows
    lp.col_cost_ = np.concatenate([cost, np.full(n_leaf + n_fixed, leaf_cost),
                                   np.full(n_buy, BUY_COST)])
    lp.col_lower_ = np.zeros(n_cols)
    lp.col_upper_ = np.concatenate([np.ones(n + n_leaf + n_fixed),
                                    np.full(n_buy, highspy.kHighsInf if n_buy and may_buy else 0.0)])
    lp.row_lower_ = np.concatenate([np.ones(m), np.full(n_leaf + n_fixed + n_buy,
                                                        -highspy.kHighsInf)])
    lp.row_upper_ = np.concatenate([np.ones(m), np.ones(n_leaf), np.zeros(n_fixed),
                                    left if n_buy else np.zeros(0)])
    lp.a_matrix_.format_ = highspy.MatrixFormat.kColwise
    lp.a_matrix_.num_col_ = n_cols
    lp.a_matrix_.num_row_ = n_rows
    lp.a_matrix_.start_ = a.indptr.astype(np.int32)
    lp.a_matrix_.index_ = a.indices.astype(np.int32)
    lp.a_matrix_.value_ = a.data.astype(np.float64)
    h = highspy.Highs()
    h.setOptionValue("output_flag", False)
    h.setOptionValue("threads", 1)
    h.setOptionValue("random_seed", 0)
    # no presolve: it would change which of equal re-covers is kept
    h.setOptionValue("presolve", "off")
    h.setOptionValue("time_limit", level.time_limit_s)
    h.setOptionValue("mip_max_nodes", level.node_limit)
    h.setOptionValue("mip_rel_gap", 1e-6)
    h.passModel(lp)
    # The LP relaxation first: most windows' are integral, and then it is the optimum.
    h.run()
    spent = max(h.getInfo().simplex_iteration_count, 0)
    x = np.asarray(h.getSolution().col_value)[:n]
    lp_done = (h.getModelStatus() == highspy.HighsModelStatus.kOptimal and len(x) == n
               and np.abs(x - np.round(x)).max(initial=0.0) < 1e-7)
    if not lp_done and n > level.mip_columns:
        keep = x > 1e-6
        keep[[i for i in _rows_of(boxes, current) if i is not None]] = True
        if np.count_nonzero(keep) > level.mip_columns:
            return TOO_LARGE, spent
        # the placements the relaxation uses and the current bricks: the same relaxation,
        # small enough for branch and bound
        chosen, more = _solve_window(boxes[keep], free, filled, lab, current, rng, level,
                                     leaf_cost, penalty, limits)
        return chosen, spent + more
    if not lp_done:
        h.changeColsIntegrality(n, np.arange(n, dtype=np.int32),
                                np.full(n, highspy.HighsVarType.kInteger))
        start = _start_solution(boxes, current, a, n, n_cols, m, lp.row_upper_[m:], n_buy)
        if start is not None:
            sol = highspy.HighsSolution()
            sol.col_value = list(start)
            sol.value_valid = True
            h.setSolution(sol)
        h.run()
        spent += max(h.getInfo().simplex_iteration_count, 0)
        if h.getInfo().primal_solution_status != highspy.SolutionStatus.kSolutionStatusFeasible:
            return None, spent
    x = np.asarray(h.getSolution().col_value)[:n]
    chosen = boxes[x > 0.5]
    if int((chosen[:, 3] * chosen[:, 4] * chosen[:, 5]).sum()) != m:
        return None, spent
    return [tuple(int(v) for v in b) for b in chosen], spent


def _start_solution(boxes, current, a, n, n_cols, m, upper, n_buy=0):
    """The column values of the current bricks (leaf variables and the last ``n_buy``, the
    bought counts, at their least), or None.

    ``upper`` are the right-hand sides of the leaf and design rows ``sum x - y <= upper``.
    """
    x = np.zeros(n_cols)
    for i in _rows_of(boxes, current):
        if i is None:
            return None
        x[i] = 1.0
    n_aux = n_cols - n - n_buy
    if n_aux:
        rows = a[m:m + n_aux].tocsr()
        need = rows[:, :n] @ x[:n] - upper[:n_aux]
        aux = rows[:, n:n + n_aux].tocoo()
        y = np.zeros(n_aux)
        np.maximum.at(y, aux.col, need[aux.row])
        x[n:n + n_aux] = np.clip(y, 0.0, 1.0)
    if n_buy:
        rows = a[m + n_aux:].tocsr()
        x[n + n_aux:] = np.maximum(rows[:, :n] @ x[:n] - upper[n_aux:], 0.0)
    return x


def _size_code(sx, sy, sz):
    """One number for a box size (cells x, y, z), for looking sizes up in bulk."""
    return (np.asarray(sx, dtype=np.int64) * 4096 + sy) * 64 + sz


def _rows_of(boxes: np.ndarray, current) -> list[int | None]:
    """The row of ``boxes`` of each box of ``current`` (None where it is not a placement)."""
    if len(current) == 0 or len(boxes) == 0:
        return [None] * len(current)
    boxes = np.asarray(boxes, dtype=np.int64).reshape(-1, 6)
    cur = np.asarray(current, dtype=np.int64).reshape(-1, 6)
    # each box as one number in the mixed radix of the boxes' and current bricks' ranges
    top = np.maximum(boxes.max(axis=0, initial=0), cur.max(axis=0)) + 1
    radix = np.concatenate([[1], np.cumprod(top[:-1])])
    keys, wanted = boxes @ radix, cur @ radix
    order = np.argsort(keys, kind="stable")
    pos = np.minimum(np.searchsorted(keys[order], wanted), len(keys) - 1)
    found = keys[order][pos] == wanted
    return [int(order[p]) if f else None for p, f in zip(pos.tolist(), found.tolist())]
