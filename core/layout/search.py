"""Improvement stage: a large neighbourhood search over the greedy layout, and its measure.

:func:`improve` takes a finished :class:`~core.model.Layout` (the greedy layout with its
repairs, :mod:`core.layout.greedy`) and makes it better window by window, after Kollsker &
Malaguti's MIP repair of a constructive layout:

1. **Choose a window** (:class:`~core.layout.neighbourhood.Search`).  Sites are bricks, weak
   ones first, then small ones, seeded ties.  A box at the site frees the movable bricks it
   touches, nearest first, up to a number of cells and placements, so the freed cells are
   whole bricks; the first box (:data:`NEAREST`) is so large that this limit shapes it.
2. **Solve it exactly** (:func:`~core.layout.window_program.solve_window`, HiGHS): every
   freed cell covered once by placements of allowed parts, at the least bricks plus
   penalties for leaves, islands and seams over seams.
3. **Keep it** only when the whole layout improves on
   :data:`~core.layout.neighbourhood.SearchKey` (lexicographic); while compacting, an equal
   re-cover is kept too: the search moves along a plateau.
4. **Sweep the layers** at the end of each search: each layer re-covered by parts of its own
   height, wide enough for long bricks to fit again.
5. **Mend weak points** (``normal``, :func:`_repair_weak`): more windows at weak bricks.

The search runs in two phases, a compaction whose key leaves weak points out, then the full
key, and goes back to the best layout it held on :func:`~core.layout.quality.quality`; should
that be worse than the input, the full key is searched from the input instead, so the result
is never worse.  ``best`` runs ``normal``'s search from several seeds (:func:`best_starts`),
goes on from the best within a budget of simplex iterations and merges the layouts found
(:func:`_merged`).  Work is counted in windows and simplex iterations, not seconds, so the
same input, effort and seed give the same result (HiGHS runs single-threaded).
:func:`layout_quality` measures the result against the lower bounds for report.json.
"""

from __future__ import annotations

import dataclasses
from typing import Iterable

import numpy as np

from core.catalog import CATALOG, Part
from core.connectivity import regions
from core.errors import InputError
from core.inventory import Stock, used as used_designs
from core.layout.connected_bound import leaf_free_bound
from core.layout.neighbourhood import Progress, Search
from core.layout.quality import FailingJoints, Key, quality
from core.layout.window_program import Effort
from core.model import Layout
from core.request import EFFORTS


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

#: The share of ``best``'s work (:attr:`~core.layout.window_program.Effort.work`) its searches
#: from several seeds may spend: a seed's search starts only while the seeds so far, one more
#: time on average, stay within it (the first always runs, and the seeds take turns between the
#: starts).  Its last search gets the rest, and never less than the remaining share.
SEED_WORK_SHARE = 0.6

#: Windows times bricks one improvement may spend (each window judges the whole layout).
MAX_WORK = 2_500_000


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
    """A layout of the same cells that is at least as good as ``layout`` on
    :func:`~core.layout.quality.quality`.

    Promises: the result covers exactly the filled cells of ``layout.grid``
    once; every brick is ``layout``'s own or a part of ``parts`` in one of
    its orientations; bricks whose id is in ``frozen`` stay as they are; no
    new brick straddles the boundary of the ``apart`` cells (a grid-shaped
    bool array, e.g. the cells to print); its :func:`~core.layout.quality.quality` key is never
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
    best of them on :func:`~core.layout.quality.quality`) have, with the fewest of them that is
    of ``best``'s kind: one component per region, and no weak point or, where ``best`` has only
    thin ones, at most as many (:func:`~core.layout.connected_bound.leaf_free_bound` over those
    placements, with its cuts). None where ``best`` is of neither kind, where that fewest is not
    proven within :data:`MERGE_S` or where it is not better than ``best`` on
    :func:`~core.layout.quality.quality` (failing joints included).  Its bricks are ``source``'s
    (the layout the improvement started from) where they are the same, with their ids; the
    others get ids above every id of ``source`` and ``layouts`` (and from ``next_id``)."""
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
    the best layout on :func:`~core.layout.quality.quality` it held; from ``layout`` again on
    the full key should none be better than ``layout`` (its progress goes on from where the
    first search's stopped); then the sweep of the layers and the weak points' windows, and back
    to the best again.  (So ``best``'s ``normal`` stages are ``normal`` itself, and ``best`` is
    never worse than ``normal``.)  The windows stop at the level's number or once they have
    spent ``work`` simplex iterations (None: no such limit), compaction at its share of
    either.  Returns the layout and the simplex iterations spent."""
    budget = int(np.clip(round(level.windows_per_cell * layout.grid.count),
                         level.min_windows, level.max_windows))
    # every window re-judges the whole layout's graph: on big builds fewer windows, so that
    # the effort stays seconds
    budget = min(budget, max(1, int(MAX_WORK / max(len(layout.bricks), 1))))
    search = Search(layout, parts, seed, frozen, apart, failing_joints, stock)
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
        search = Search(layout, parts, seed, frozen, apart, failing_joints, stock)
        search.run(level, budget - int(budget * level.compact_share), again, budget,
                   work=None if work is None else max(work - spent, 0))
    search.sweep_layers(level, report)
    _repair_weak(search, level, report)
    search.restore_best()
    return search.layout(next_id, renumber=False), spent + search.iterations


def _repair_weak(search: "Search", level: Effort, report: Progress) -> None:
    """Up to ``level.weak_windows`` more windows, as ``best`` tries them (weak bricks first, as
    :meth:`~core.layout.neighbourhood.Search.sites` orders them), while ``search``'s layout has
    weak points, those on one-cell-thin features (:func:`~core.layout.quality.thin_weak_points`)
    too; kept on the key.  Then, while some are left, up to as many again at the weak bricks
    (weak points and leaves) alone.

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
    """:func:`~core.layout.quality.quality`, its bricks counted as ``stock`` prices them
    (:meth:`Stock.cost`)."""
    key = quality(layout, failing_joints)
    return key if stock is None else key[:4] + (stock.cost(used_designs(layout)),)


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
    """Whether ``layout`` has the best :func:`~core.layout.quality.quality` key any layout of
    its cells can have: one component per region, no failing joint and no weak point, and as few
    bricks as ``bound`` (a lower bound proven optimal) says any cover has."""
    if bound is None or not bound.get("optimal") or bound.get("bound") is None:
        return False
    best = (regions(np.asarray(layout.grid.filled, bool))[1], 0, 0, 0, bound["bound"])
    return quality(layout, failing_joints) == best


def layout_quality(greedy: Layout, layout: Layout, parts: tuple[Part, ...] = CATALOG,
                   timings: dict | None = None, lower_bound: bool = False,
                   failing_joints: FailingJoints | None = None, bound: dict | None = None) -> dict:
    """The ``layout_quality`` block of report.json for the greedy and improved layouts.

    ``bricks``, ``regions``, ``components``, ``weak_points`` (articulation
    points), ``weak_points_thin`` (those :func:`~core.layout.quality.thin_weak_points`: a leaf
    brick on a one-cell-thin feature hangs on them, and no other leaf; counted apart), ``greedy`` and
    ``improved`` (their :func:`~core.layout.quality.quality` keys by name), ``seconds`` per phase
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
    :func:`~core.layout.connected_bound.leaf_free_bound` with its cuts finds in
    ``time_limit_s``: layouts in one piece per region with no weak point when ``layout`` has
    none (``weak`` 0), else with none but thin ones (``weak`` == ``thin``, its weak points that
    :func:`~core.layout.quality.thin_weak_points` finds) and at most ``weak`` of them
    (``most_weak``): those as good as ``layout`` on the first terms of
    :func:`~core.layout.quality.quality` (failing joints aside). ``joined`` says whether
    ``layout`` has one component per region.  Returns ``{"bound", "proven", "status",
    "time_limit_s", "seconds", "layouts", "ratio"}`` (``layouts`` names the kind, ``ratio`` is
    bricks / bound); for a layout of neither kind, ``bound`` None and ``why``, as no such bound
    holds for it."""
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


def _silent(fraction: float, message: str) -> None:
    """Progress sink that ignores everything."""


def _copy(layout: Layout, renumber: bool) -> Layout:
    """A new Layout with copies of the bricks."""
    bricks = [dataclasses.replace(b) for b in layout.bricks]
    if renumber:
        bricks = [dataclasses.replace(b, id=n) for n, b in enumerate(bricks)]
    return Layout(layout.grid, bricks)
