"""Lower bounds on the bricks of layouts in one piece: the exact cover without what such a
layout cannot have.

:func:`leaf_free_bound` is the exact-cover program of :mod:`core.layout.bounds` without the
placements that would be islands or leaves there and, with ``connected``, solved again and
again with lazy cuts until its cover is in one piece per region (with no weak point, or at
most a number of thin ones).  Every cut holds for every such layout, so each round's answer is
still a lower bound, and a cover that passes is the fewest bricks any such layout has.  Large
programs solve their relaxation with the rows it breaks added round by round; relaxation
bounds are certified by weak duality.  :func:`core.layout.search.one_piece_bound` reports it,
and :func:`core.layout.search.improve` merges the layouts it found with it.
"""

from __future__ import annotations

import time
from typing import NamedTuple

import highspy
import numpy as np
from scipy import ndimage, sparse
from scipy.sparse.csgraph import connected_components

from core.catalog import CATALOG, Part
from core.connectivity import articulation_points
from core.layout.bounds import (_SIX, MAX_VARIABLES, _highs, _set_partitioning_lp, cover_matrix,
                                more_time)
from core.layout.quality import csr
from core.layout.window_program import contacts, covering, free_placements, numbered_shapes


def leaf_free_bound(grid, parts: tuple[Part, ...] = CATALOG, time_limit_s: float = 20.0,
                    no_weak_points: bool = False, connected: bool = False,
                    most_weak: int | None = None, placements: np.ndarray | None = None) -> dict:
    """A lower bound on the bricks of any layout that the improvement's targets accept: one
    component per region and no weak point but those holding a leaf on a one-cell-thin
    feature (:func:`~core.layout.quality.thin_weak_points`).

    The exact-cover program (:mod:`core.layout.bounds`) with what such a layout cannot have
    (:func:`_program`): a brick touching nothing above or below in a region it does not fill
    alone (it would be a component of its own), and, in regions of more than twice the cells
    of the largest of ``parts`` (which need three bricks or more), a brick that touches cells
    on one side only, at least two of them, all under (or over) one other brick (a leaf: that
    brick would be a weak point, and not a thin one).  Both are necessary conditions, so the
    answer is a lower bound, usually above the plain exact cover's, and the gap between them
    is what connection costs at least.  With ``no_weak_points`` it bounds the layouts with one
    component per region and no weak point at all (thin ones included): it also forbids every
    brick whose cells split its region (:func:`separating`), which such a layout cannot have.
    With ``connected`` the program is solved again and again with lazy cuts
    (:func:`_connection_cuts`) until its cover has one component per region (and, with
    ``no_weak_points``, no weak point) or ``time_limit_s`` runs out: each cut only removes
    covers that are not such layouts, so every round's bound is still one, and a cover that
    passes is the fewest bricks any such layout has; a cover that does not pass also gets the
    cuts of :func:`_degree_cuts` (two neighbours or more for every brick in a region of three
    bricks or more, but a leaf on a one-cell-thin feature where thin weak points are allowed).
    With ``connected`` and ``most_weak`` (and not ``no_weak_points``) it bounds the layouts
    that also have at most ``most_weak`` weak points: the weak-point cuts of
    :func:`_connection_cuts` hold for every brick but those the program marks as weak, at most
    ``most_weak`` of them.
    With ``placements`` ((n, 6) boxes ``x, y, z, sx, sy, sz`` on filled cells, e.g. the
    bricks of several layouts) the program has only those: ``bound`` then bounds only the
    covers made of them, and ``cover`` is such a layout with the fewest of them
    (:func:`~core.layout.search._merged`).
    Returns ``{"bound", "optimal", "objective", "status", "seconds", "variables", "rounds",
    "cuts", "cover"}`` as :func:`core.layout.bounds.brick_lower_bound`; ``bound`` is the larger of the
    relaxation's bound (interior point, certified by weak duality; :func:`_relaxation_bound`)
    and HiGHS's dual bounds, rounded up (0 when neither came in ``time_limit_s``; None past
    :data:`core.layout.bounds.MAX_VARIABLES` placements, ``status`` "too large"),
    ``objective`` the bricks of the best such cover found or None (with ``connected``, only a
    cover that passes the cuts), ``cover`` its placements as ``[x, y, z, sx, sy, sz]`` cell
    boxes (or None), ``rounds`` the programs solved and ``cuts`` the cuts added.
    """
    start = time.perf_counter()
    filled = np.ascontiguousarray(np.asarray(grid.filled, dtype=bool))
    shapes = numbered_shapes(parts)
    boxes = (free_placements(filled, None, shapes) if placements is None
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
    program = _program(filled, boxes, largest, no_weak_points)
    lp = _leaf_free_lp(sparse.vstack([program.cover, program.leaf]).tocsc(), m, program.island)
    relaxed = _relaxation_bound(program, lp, time_limit_s, start)
    if relaxed is None:
        return result(None, True, None, "infeasible")
    bound, degree_rows = relaxed
    weak_cuts = connected and (no_weak_points or most_weak is not None)
    h, marks_row = _integer_program(lp, bound, degree_rows,
                                    time_limit_s - (time.perf_counter() - start),
                                    most_weak if weak_cuts and not no_weak_points else None)
    by_placement = program.cover.T.tocsr()
    marks: dict[int, int] = {}        # placement -> the column of "it may be a weak point"
    while True:
        rounds += 1
        h.run()
        status = h.getModelStatus()
        if status == highspy.HighsModelStatus.kInfeasible:
            return result(None, True, None, "infeasible")
        objective, bound, solution = _round_answer(h, bound)
        added = []
        if solution is not None:
            chosen = np.flatnonzero(solution[:n] > 0.5)
            if connected:
                added = _broken_cuts(program, chosen, solution, by_placement, weak_cuts, marks)
            passed = None if added else boxes[chosen].tolist()
        if added:
            objective = None
        left = time_limit_s - (time.perf_counter() - start)
        if not added or status != highspy.HighsModelStatus.kOptimal or left <= 0:
            break
        _add_cuts(h, added, marks, marks_row)
        cuts += len(added)
        more_time(h, max(left, 0.05))
    optimal = objective is not None and (status == highspy.HighsModelStatus.kOptimal
                                         or bound >= objective)
    if optimal:
        bound = objective
    return result(bound, optimal, objective, "optimal" if optimal else "time limit")


class _Program(NamedTuple):
    """:func:`leaf_free_bound`'s exact cover and what its cuts read: the placements ``boxes``
    on the ``filled`` cells, the 6-connected regions ``labels`` (numbered from 1), the row
    ``cell_index`` of each filled cell (-1 elsewhere), the (cells, placements) 0/1 ``cover``,
    the ``leaf`` rows (at most 1 each), and per placement whether it is barred (``island``)
    and whether it has two neighbours or more in every layout the bound is of (``sociable``,
    :func:`_degree_cuts`)."""

    boxes: np.ndarray
    filled: np.ndarray
    labels: np.ndarray
    cell_index: np.ndarray
    cover: sparse.csr_matrix
    leaf: sparse.csr_matrix
    island: np.ndarray
    sociable: np.ndarray


def _program(filled: np.ndarray, boxes: np.ndarray, largest: int,
             no_weak_points: bool) -> _Program:
    """The program of :func:`leaf_free_bound` over the placements ``boxes`` on the ``filled``
    cells.  Barred: a placement touching nothing above or below in a region it does not fill
    alone, and with ``no_weak_points`` one whose cells split its region (:func:`separating`).
    A leaf row, per placement ``p`` in a region of more than twice ``largest`` cells (the
    largest part's; such a region needs three bricks or more) that touches two filled cells
    or more on one side only: ``p`` plus the placements ``q`` covering all those cells is at
    most 1 (with ``q`` chosen, ``p`` would be a leaf on it and ``q`` a weak point, not a thin
    one)."""
    m = int(filled.sum())
    n = len(boxes)
    labels = ndimage.label(filled, structure=_SIX)[0]
    region_cells = np.bincount(labels.ravel())
    cell_index = np.full(filled.shape, -1, dtype=np.int64)
    cell_index[filled] = np.arange(m)
    cover = cover_matrix(boxes, cell_index, m).tocsr()
    _, below, above, bbox, _ = contacts(boxes, filled, filled, np.full(filled.shape, -1, np.int64))
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
    t, q = covering(boxes, bbox[cand], cover.indptr.astype(np.int64),
                     cover.indices.astype(np.int64), cell_index)
    keep = cand[t] != q
    t, q = t[keep], q[keep]
    leaf = sparse.csr_matrix((np.ones(len(cand) + len(t)),
                              (np.concatenate([np.arange(len(cand)), t]),
                               np.concatenate([cand, q]))), shape=(len(cand), n))
    leaf.data[:] = 1.0
    return _Program(boxes, filled, labels, cell_index, cover, leaf, island, sociable)


def _relaxation_bound(program: _Program, lp: highspy.HighsLp, time_limit_s: float,
                      start: float) -> tuple[int, list] | None:
    """The bound the relaxation ``lp`` of ``program`` certifies (:func:`_certified`), and the
    degree cuts found on the way as (columns, values) of rows ``>= 0``; None when it is
    infeasible.  Solved by interior point (HiGHS's MIP root, by the dual simplex, is slow on
    such programs) in half of ``time_limit_s``.  One of more than :data:`LP_CUT_VARIABLES`
    placements has :data:`LP_CUT_SHARE` of it instead, starts without the leaf rows and gets
    those it breaks, and degree cuts, round by round (:func:`_relaxed_cuts`) until that share
    of ``time_limit_s`` after ``start`` (a ``time.perf_counter`` time) has passed."""
    n, m = len(program.boxes), program.cover.shape[0]
    large = n > LP_CUT_VARIABLES
    h = _highs((LP_CUT_SHARE if large else 0.5) * time_limit_s, random_seed=0, solver="ipm",
               run_crossover="off", presolve="off")
    h.passModel(_leaf_free_lp(program.cover.tocsc(), m, program.island) if large else lp)
    h.run()
    if h.getModelStatus() == highspy.HighsModelStatus.kInfeasible:
        return None
    bound = _certified(h)
    if not large:
        return bound, []
    found, degree_rows = _relaxed_cuts(h, program, start + LP_CUT_SHARE * time_limit_s)
    if h.getModelStatus() == highspy.HighsModelStatus.kInfeasible:
        return None
    return max(bound, found), degree_rows


def _integer_program(lp: highspy.HighsLp, bound: int, degree_rows: list, seconds: float,
                     most_weak: int | None) -> tuple[highspy.Highs, int | None]:
    """HiGHS holding ``lp`` in integers, with ``seconds`` (at least 0.05) to run, its bricks
    at least ``bound``, the ``degree_rows`` (columns, values) each ``>= 0``, and with
    ``most_weak`` a row of at most that many marked weak points (empty, its columns come with
    the cuts: :func:`_add_cuts`); and that row's index (None without ``most_weak``)."""
    n = lp.num_col_
    lp.integrality_ = [highspy.HighsVarType.kInteger] * n
    # a large program's presolve does not watch the clock
    h = _highs(max(seconds, 0.05), random_seed=0, mip_abs_gap=1.0 - 1e-3,
               presolve="off" if n > LP_CUT_VARIABLES else "choose")
    h.passModel(lp)
    h.addRow(float(bound), highspy.kHighsInf, n, np.arange(n, dtype=np.int32), np.ones(n))
    for columns, values in degree_rows:
        h.addRow(0.0, highspy.kHighsInf, len(columns), columns.astype(np.int32), values)
    if most_weak is None:
        return h, None
    h.addRow(-highspy.kHighsInf, float(most_weak), 0, np.empty(0, np.int32), np.empty(0))
    return h, h.getNumRow() - 1


def _round_answer(h: highspy.Highs, bound: int) -> tuple[int | None, int, np.ndarray | None]:
    """What the integer program ``h`` just solved gives: the bricks of its cover (None without
    one), ``bound`` raised to its dual bound rounded up, and its column values (None without
    a cover)."""
    info = h.getInfo()
    dual = info.mip_dual_bound
    if np.isfinite(dual):
        bound = max(bound, int(np.ceil(dual - 1e-6)))
    if info.primal_solution_status != highspy.SolutionStatus.kSolutionStatusFeasible:
        return None, bound, None
    return round(info.objective_function_value), bound, np.asarray(h.getSolution().col_value)


def _broken_cuts(program: _Program, chosen: np.ndarray, solution: np.ndarray,
                 by_placement: sparse.csr_matrix, weak_cuts: bool, marks: dict[int, int]) -> list:
    """The cuts of :func:`_connection_cuts` that the cover ``chosen`` (placement indices;
    ``solution`` the program's column values) breaks, less those on a weak point whose column
    in ``marks`` the program set, and then, if any are left, the cuts of :func:`_degree_cuts`
    too; empty when the cover passes."""
    chosen_boxes = program.boxes[chosen]
    added = _connection_cuts(chosen_boxes, chosen, program.filled, by_placement, program.labels,
                             weak_cuts)
    # a weak point the program marked as one breaks no cut
    added = [cut for cut in added if cut[3] not in marks or solution[marks[cut[3]]] < 0.5]
    if added:
        added += _degree_cuts(chosen_boxes, chosen, program.filled, program.cover,
                              program.cell_index, program.sociable)
    return added


def _add_cuts(h: highspy.Highs, added: list, marks: dict[int, int],
              marks_row: int | None) -> None:
    """Add the cuts ``added`` (``(columns, values, lower, p)`` rows) to the integer program
    ``h``.  With ``marks_row`` (:func:`_integer_program`'s row of marked weak points) a cut
    on the weak point ``p`` also takes ``p``'s mark column, a 0/1 variable in that row made
    the first time (``marks``, placement -> column): marked, ``p`` may be a weak point."""
    for columns, values, lower, p in added:
        if p >= 0 and marks_row is not None:
            if p not in marks:
                h.addCol(0.0, 0.0, 1.0, 1, np.array([marks_row], np.int32), np.ones(1))
                marks[p] = h.getNumCol() - 1
                h.changeColIntegrality(marks[p], highspy.HighsVarType.kInteger)
            columns, values = np.append(columns, marks[p]), np.append(values, 1.0)
        h.addRow(lower, highspy.kHighsInf, len(columns), columns.astype(np.int32), values)


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
    indptr, indices, _ = csr(lab, n)
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
    (:func:`~core.layout.quality.thin_weak_points`), so is a leaf touching one cell, but not one
    touching two cells or more: its neighbour would be a weak point that is not thin.  The bricks
    next to ``p`` are those covering a cell right above or below it, each counted once, so a cut
    holds for every such layout and removes every cover where ``p`` has fewer than two
    neighbours, whichever they are (a weak-point cut removes only covers with that one piece
    hanging on ``p``).  The placements ``q`` are those covering such a cell but none of
    ``p``'s.  ``cover`` is the (cells, placements) matrix, ``cell_index`` the row of each filled
    cell.
    """
    n = len(chosen_boxes)
    lab = np.full(filled.shape, -1, dtype=np.int64)
    for k, (x, y, z, sx, sy, sz) in enumerate(chosen_boxes):
        lab[x:x + sx, y:y + sy, z:z + sz] = k
    indptr, _, _ = csr(lab, n)
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


def _relaxed_cuts(h: highspy.Highs, program: _Program, deadline: float) -> tuple[int, list]:
    """Leaf rows and degree cuts (:func:`_degree_cuts`) for the relaxation ``h`` (solved) of
    ``program``: while its solution breaks some and ``deadline`` (a ``time.perf_counter``
    time) is ahead, the rows of ``program.leaf`` (one per row of the program, ``<= 1``) it
    breaks and the ``LP_CUTS`` most broken degree cuts are added to ``h`` and it is solved
    again.  Every row holds for every layout the bound is of, so every round's certified bound
    (:func:`_certified`) is one.  Returns the largest of those of the rounds it solved (0
    without any; the caller has ``h``'s own) and the degree cuts added, as (columns, values)
    of rows ``>= 0``, for the integer program (which has all the leaf rows)."""
    boxes, leaf, sociable = program.boxes, program.leaf, program.sociable
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
            q = _next_to(boxes[p], program.filled, program.cover, program.cell_index)
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
