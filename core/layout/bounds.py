"""The exact fewest-parts cover of a grid: a yardstick for the layouter.

The question: how few catalog parts can cover exactly the filled cells of a
:class:`~core.model.Grid` (every filled cell once, no empty cell), if a part
may sit at any cell, plates take one layer and bricks three, and footprints
turn by 0° or 90°?  Stability and connection are ignored, so the answer is a
lower bound for any layout the layouter makes.

It is the set-partitioning integer program

    minimise  sum_p x_p   subject to   sum_{p covers c} x_p = 1 for each
    filled cell c,   x_p in {0, 1},

with one variable per placement that fits inside the filled cells.  Placements
are found per part orientation with a summed-volume table (a box fits where
its window sum equals its volume), and the constraint matrix is assembled
column-wise with index arithmetic, all vectorised over positions.  A box of
cells is 6-connected, so no placement spans two 6-connected regions and the
program splits into one independent program per region; HiGHS solves each.

Per region, the LP relaxation comes first (interior point, then PDLP: much
faster than simplex on these degenerate programs).  Its row duals ``y``,
exact or not, give a certified bound by weak duality
(:func:`certified_bound`).  When the LP is solved in time, the MIP follows
with the cut ``sum x >= ceil(LP bound)``, which lets HiGHS stop as soon as
a cover of that size is found.  So under a time limit the result stays a
*valid* lower bound: the largest of the ceilings of the certified LP bound
and of HiGHS's MIP dual bound, and of cells / largest part; never the
incumbent unless it is proven optimal.
"""

from __future__ import annotations

import math
import time

import highspy
import numpy as np
from numba import njit
from scipy import ndimage, sparse

from core.catalog import CATALOG, Part
from core.errors import InputError
from core.forces.solver import INTERIOR_POINT
from core.model import Grid

#: Above this many placement variables the program is not built at all.
MAX_VARIABLES = 2_000_000

#: Slack when rounding a floating-point dual bound up to an integer.
_ROUND_EPS = 1e-6

#: 6-connectivity structure for :func:`scipy.ndimage.label`.
_SIX = ndimage.generate_binary_structure(3, 1)


def part_shapes(parts: tuple[Part, ...]) -> list[tuple[int, int, int]]:
    """The distinct box sizes (x, y, z in cells) the parts take when placed."""
    shapes = {(sx, sy, p.layers) for p in parts for sx, sy in p.orientations()}
    return sorted(shapes)


def _summed_volume(filled: np.ndarray) -> np.ndarray:
    """Zero-padded 3-D prefix sums: ``S[i, j, k]`` = filled cells in ``[:i, :j, :k]``."""
    s = np.zeros(tuple(n + 1 for n in filled.shape), dtype=np.int64)
    s[1:, 1:, 1:] = filled.astype(np.int64).cumsum(0).cumsum(1).cumsum(2)
    return s


def fitting_positions(table: np.ndarray, shape: tuple[int, int, int],
                      corners: np.ndarray | None = None) -> np.ndarray:
    """Min corners (n, 3) of every box of size ``shape`` made only of filled cells, in C
    order.

    ``table`` is the summed-volume table of the grid (:func:`_summed_volume`), ``corners``
    as :func:`fitting_boxes`.
    """
    return fitting_boxes(table, np.array([shape], dtype=np.int64), corners)[:, :3]


def fitting_boxes(table: np.ndarray, sizes: np.ndarray, corners: np.ndarray | None = None) -> np.ndarray:
    """The boxes (n, 6) of every size of ``sizes`` (k, 3) made only of filled cells, size by
    size, min corners in C order; ``table`` is the grid's summed-volume table
    (:func:`_summed_volume`), ``corners`` its filled cells in C order (None: read from
    ``table``).  Only filled cells are tried as corners, so a sparse box costs its cells, not
    its volume."""
    if corners is None:
        corners = np.argwhere(_filled_of(table))
    return _boxes_at(table, np.asarray(sizes, dtype=np.int64), np.asarray(corners, dtype=np.int64))


def _filled_of(table: np.ndarray) -> np.ndarray:
    """The filled cells whose summed-volume table is ``table``."""
    t = table
    return (t[1:, 1:, 1:] - t[:-1, 1:, 1:] - t[1:, :-1, 1:] - t[1:, 1:, :-1] + t[:-1, :-1, 1:]
            + t[:-1, 1:, :-1] + t[1:, :-1, :-1] - t[:-1, :-1, :-1]) > 0


@njit(cache=True)
def _boxes_at(table, sizes, corners):
    nx, ny, nz = table.shape[0] - 1, table.shape[1] - 1, table.shape[2] - 1
    out = np.empty((0, 6), dtype=np.int64)
    count = 0
    for fill in (False, True):
        if fill:
            out = np.empty((count, 6), dtype=np.int64)
            count = 0
        for k in range(sizes.shape[0]):
            sx, sy, sz = sizes[k, 0], sizes[k, 1], sizes[k, 2]
            for c in range(corners.shape[0]):
                x, y, z = corners[c, 0], corners[c, 1], corners[c, 2]
                if x + sx > nx or y + sy > ny or z + sz > nz:
                    continue
                inside = (table[x + sx, y + sy, z + sz] - table[x, y + sy, z + sz]
                          - table[x + sx, y, z + sz] - table[x + sx, y + sy, z]
                          + table[x, y, z + sz] + table[x, y + sy, z]
                          + table[x + sx, y, z] - table[x, y, z])
                if inside == sx * sy * sz:
                    if fill:
                        out[count, 0], out[count, 1], out[count, 2] = x, y, z
                        out[count, 3], out[count, 4], out[count, 5] = sx, sy, sz
                    count += 1
    return out


def fitting_count(table: np.ndarray, shape: tuple[int, int, int]) -> int:
    """How many boxes of size ``shape`` are made only of filled cells (as
    :func:`fitting_positions`, without listing them)."""
    fits = _fits(table, shape)
    return 0 if fits is None else int(np.count_nonzero(fits))


def _fits(table: np.ndarray, shape: tuple[int, int, int]) -> np.ndarray | None:
    """Per min corner: the box of size ``shape`` there is all filled (None: it fits nowhere)."""
    nx, ny, nz = (n - 1 for n in table.shape)
    sx, sy, sz = shape
    if sx > nx or sy > ny or sz > nz:
        return None
    mx, my, mz = nx - sx + 1, ny - sy + 1, nz - sz + 1

    def corner(a: int, b: int, c: int) -> np.ndarray:
        return table[a:a + mx, b:b + my, c:c + mz]

    window = (corner(sx, sy, sz) - corner(0, sy, sz) - corner(sx, 0, sz) - corner(sx, sy, 0)
              + corner(0, 0, sz) + corner(0, sy, 0) + corner(sx, 0, 0) - corner(0, 0, 0))
    return window == sx * sy * sz


def cover_matrix(boxes: np.ndarray, cell_index: np.ndarray, m: int) -> sparse.coo_matrix:
    """The (cells x placements) 0/1 matrix of which placement covers which cell: ``boxes``
    (n, 6) placements, ``cell_index`` each covered cell's row (all ``m`` of them).  Its
    entries come column by column, each column's cells in x, y, z order."""
    boxes = np.ascontiguousarray(boxes, dtype=np.int64)
    rows, cols = _cover_entries(boxes, np.ascontiguousarray(cell_index, dtype=np.int64))
    return sparse.coo_matrix((np.ones(cols.size), (rows, cols)), shape=(m, len(boxes)))


@njit(cache=True)
def _cover_entries(boxes: np.ndarray, cell_index: np.ndarray):
    """The (row, column) pairs of :func:`cover_matrix`."""
    total = 0
    for p in range(boxes.shape[0]):
        total += boxes[p, 3] * boxes[p, 4] * boxes[p, 5]
    rows = np.empty(total, np.int64)
    cols = np.empty(total, np.int64)
    k = 0
    for p in range(boxes.shape[0]):
        x, y, z, sx, sy, sz = boxes[p]
        for i in range(x, x + sx):
            for j in range(y, y + sy):
                for c in range(z, z + sz):
                    rows[k] = cell_index[i, j, c]
                    cols[k] = p
                    k += 1
    return rows, cols


def relaxed_cover(filled: np.ndarray, shapes: list[tuple[int, int, int]],
                  time_limit_s: float) -> tuple[np.ndarray, np.ndarray] | None:
    """Every placement of a box of ``shapes`` on the filled cells, (n, 6) boxes
    ``(x, y, z, sx, sy, sz)``, and its value in an optimum of the exact cover's LP relaxation
    (fewest boxes, each filled cell covered once, values in 0..1), solved by interior point
    without crossover (so where optima tie the values are spread among them; where it
    cannot confirm its tolerances, its last point, e.g. 161.52 for an optimum of 161.5);
    None when it runs out of time (``time_limit_s``) or stops otherwise, or no placement
    fits."""
    filled = np.ascontiguousarray(filled, dtype=bool)
    boxes = fitting_boxes(_summed_volume(filled), np.array(shapes, dtype=np.int64).reshape(-1, 3),
                         np.argwhere(filled))
    m = int(filled.sum())
    if len(boxes) == 0 or m == 0:
        return None
    cell_index = np.full(filled.shape, -1, dtype=np.int64)
    cell_index[filled] = np.arange(m)
    a = cover_matrix(boxes, cell_index, m).tocsc()
    lp = _set_partitioning_lp(a.indptr, a.indices, m)
    h = _highs(time_limit_s, solver=INTERIOR_POINT, run_crossover="off", presolve="off")
    h.passModel(lp)
    h.run()
    values = np.asarray(h.getSolution().col_value)
    if (h.getModelStatus() not in (highspy.HighsModelStatus.kOptimal,
                                   highspy.HighsModelStatus.kUnknown)
            or len(values) != len(boxes)):
        return None
    return boxes, np.clip(values, 0.0, 1.0)


def _placements(filled: np.ndarray, shapes: list[tuple[int, int, int]]):
    """All fitting placements: (positions per shape, total count)."""
    table, corners = _summed_volume(filled), np.argwhere(filled)
    found = [fitting_positions(table, s, corners) for s in shapes]
    return found, int(sum(len(f) for f in found))


def _columns(filled, labels, shapes, found):
    """Constraint columns of every placement, grouped by region.

    Returns ``(col_region, indptr, rows, n_rows)``: columns sorted by region
    (stably), CSC ``indptr`` and row ``rows`` (row = rank of the cell among
    its region's filled cells, in flat index order, so each column's rows are
    ascending), and the number of rows per region (index = region label).
    """
    nx, ny, nz = filled.shape
    flat = np.flatnonzero(filled)
    lab = labels.ravel()[flat]
    n_regions = int(labels.max())
    n_rows = np.bincount(lab, minlength=n_regions + 1)
    first = np.concatenate(([0], np.cumsum(n_rows)))[:-1]
    order = np.argsort(lab, kind="stable")
    rowid = np.full(filled.size, -1, dtype=np.int32)
    rowid[flat[order]] = np.arange(flat.size) - first[lab[order]]

    regions, lengths, entries = [], [], []
    for (sx, sy, sz), pos in zip(shapes, found):
        if len(pos) == 0:
            continue
        base = (pos[:, 0] * ny + pos[:, 1]) * nz + pos[:, 2]
        di, dj, dk = np.meshgrid(np.arange(sx), np.arange(sy), np.arange(sz), indexing="ij")
        offset = ((di * ny + dj) * nz + dk).ravel()
        cells = base[:, None] + offset[None, :]
        regions.append(labels.ravel()[base])
        lengths.append(np.full(len(pos), offset.size, dtype=np.int64))
        entries.append(rowid[cells].ravel())
    if not regions:
        empty = np.empty(0, dtype=np.int64)
        return empty, np.zeros(1, dtype=np.int64), empty, n_rows
    region = np.concatenate(regions)
    length = np.concatenate(lengths)
    entry = np.concatenate(entries)
    if np.all(region[1:] >= region[:-1]):
        return region, np.concatenate(([0], np.cumsum(length))), entry, n_rows
    start = np.concatenate(([0], np.cumsum(length)))[:-1]
    perm = np.argsort(region, kind="stable")
    new_len = length[perm]
    indptr = np.concatenate(([0], np.cumsum(new_len)))
    gather = np.repeat(start[perm] - indptr[:-1], new_len) + np.arange(indptr[-1])
    return region[perm], indptr, entry[gather], n_rows


def _set_partitioning_lp(indptr, rows, n_rows: int) -> highspy.HighsLp:
    """The LP: minimise the number of columns with every row covered exactly once, 0 <= x <= 1."""
    n_cols = len(indptr) - 1
    lp = highspy.HighsLp()
    lp.num_col_ = n_cols
    lp.num_row_ = n_rows
    lp.col_cost_ = np.ones(n_cols)
    lp.col_lower_ = np.zeros(n_cols)
    lp.col_upper_ = np.ones(n_cols)
    lp.row_lower_ = np.ones(n_rows)
    lp.row_upper_ = np.ones(n_rows)
    lp.a_matrix_.format_ = highspy.MatrixFormat.kColwise
    lp.a_matrix_.num_col_ = n_cols
    lp.a_matrix_.num_row_ = n_rows
    lp.a_matrix_.start_ = indptr.astype(np.int32)
    lp.a_matrix_.index_ = rows.astype(np.int32)
    lp.a_matrix_.value_ = np.ones(len(rows))
    return lp


def _highs(time_limit_s: float, **options) -> highspy.Highs:
    """A silent single-threaded HiGHS instance with a time limit."""
    h = highspy.Highs()
    h.setOptionValue("output_flag", False)
    h.setOptionValue("threads", 1)
    h.setOptionValue("time_limit", max(float(time_limit_s), 0.01))
    for key, value in options.items():
        h.setOptionValue(key, value)
    return h


def more_time(h: highspy.Highs, seconds: float) -> None:
    """Let ``h`` run for ``seconds`` more from now: HiGHS holds its time limit against its
    run time summed over all its runs, so a limit of ``seconds`` alone would stop a solve
    again at once after a first one took that long."""
    h.setOptionValue("time_limit", h.getRunTime() + max(float(seconds), 0.01))


def certified_bound(indptr, rows, y: np.ndarray) -> float:
    """A lower bound on the LP (hence on the cover) from any row prices ``y``.

    By weak duality for ``min 1.x, Ax = 1, 0 <= x <= 1``, every ``y`` gives
    ``sum(y) - sum_j max(0, (A^T y)_j - 1) <= LP optimum``; so an inexact dual
    (interior point, PDLP, a solver stopped early) still yields a valid bound.
    """
    y = np.nan_to_num(np.asarray(y, dtype=np.float64), nan=0.0, posinf=0.0, neginf=0.0)
    col_sum = np.add.reduceat(y[rows], indptr[:-1]) if len(rows) else np.zeros(0)
    return float(y.sum() - np.maximum(col_sum - 1.0, 0.0).sum())


def _lp_bound(lp, indptr, rows, deadline: float) -> tuple[int, str]:
    """Ceiling of a certified LP-relaxation bound, and "optimal", "infeasible",
    "time limit" (the LP solvers ran out of time) or "inexact" (they stopped
    for another reason, e.g. an interior point method that cannot reach its
    tolerances without crossover).

    Interior point first, then PDLP with most of what is left if it timed
    out; both
    without presolve, which does not watch the clock on large programs.
    Their claims of infeasibility are not final (a stopped interior point
    method can make them wrongly): the MIP must confirm them.
    """
    best, status = -math.inf, "time limit"
    for solver, fraction in (("ipm", 0.5), ("pdlp", 0.8)):
        left = deadline - time.perf_counter()
        if left <= 0.01:
            break
        h = _highs(left * fraction, solver=solver, run_crossover="off", presolve="off")
        h.passModel(lp)
        h.run()
        model_status = h.getModelStatus()
        if model_status == highspy.HighsModelStatus.kInfeasible:
            status = "infeasible"
            break
        y = np.asarray(h.getSolution().row_dual)
        if len(y) == lp.num_row_:
            best = max(best, certified_bound(indptr, rows, y))
        if model_status == highspy.HighsModelStatus.kOptimal:
            status = "optimal"
            break
        if model_status != highspy.HighsModelStatus.kTimeLimit:
            status = "inexact"
            break
    return (math.ceil(best - _ROUND_EPS) if math.isfinite(best) else 0), status


def _solve_region(indptr, rows, n_rows: int, deadline: float):
    """Solve one region's set-partitioning program with HiGHS by ``deadline``.

    A cell that no placement covers means no cover.  Otherwise the LP
    relaxation is solved first (:func:`_lp_bound`).  Unless that ran out of
    time, its certified bound is added as the cut ``sum x >= bound`` and the
    MIP gets the rest of the time (a MIP whose LP cannot be solved in time
    would only spend it on its own root LP); the MIP alone decides that no
    cover exists.
    Returns ``(bound, incumbent, optimal)``: ``bound`` a valid lower bound
    (None if no exact cover exists), ``incumbent`` the best cover size
    found or None.
    """
    if not np.all(np.bincount(rows, minlength=n_rows)):
        return None, None, True
    lp = _set_partitioning_lp(indptr, rows, n_rows)
    lp_bound, lp_status = _lp_bound(lp, indptr, rows, deadline)
    if lp_status == "time limit":
        return lp_bound, None, False
    h = _highs(deadline - time.perf_counter(), mip_rel_gap=0.0, mip_abs_gap=1.0 - 1e-3)
    h.passModel(lp)
    h.changeColsIntegrality(lp.num_col_, np.arange(lp.num_col_, dtype=np.int32),
                            np.full(lp.num_col_, highspy.HighsVarType.kInteger))
    h.addRow(float(lp_bound), highspy.kHighsInf, lp.num_col_,
             np.arange(lp.num_col_, dtype=np.int32), np.ones(lp.num_col_))
    h.run()
    status = h.getModelStatus()
    if status == highspy.HighsModelStatus.kInfeasible:
        return None, None, True
    info = h.getInfo()
    has_solution = info.primal_solution_status == highspy.SolutionStatus.kSolutionStatusFeasible
    incumbent = round(info.objective_function_value) if has_solution else None
    dual = info.mip_dual_bound
    bound = max(lp_bound, math.ceil(dual - _ROUND_EPS) if math.isfinite(dual) else 0)
    if incumbent is not None and (status == highspy.HighsModelStatus.kOptimal or bound >= incumbent):
        return incumbent, incumbent, True
    return bound, incumbent, False


def placement_count(grid: Grid, parts: tuple[Part, ...] = CATALOG, stop_above: int | None = None) -> int:
    """The number of variables of the lower bound's program (placements that fit); once
    the count passes ``stop_above`` it stops and returns what it has counted so far (more
    than ``stop_above``): a 1 m cube's 5 million cells fit millions of placements a shape."""
    table = _summed_volume(np.asarray(grid.filled, dtype=bool))
    count = 0
    for shape in part_shapes(parts):
        count += fitting_count(table, shape)
        if stop_above is not None and count > stop_above:
            break
    return count


def brick_lower_bound(grid: Grid, parts: tuple[Part, ...] = CATALOG,
                      time_limit_s: float = 20.0) -> dict:
    """The fewest ``parts`` that cover exactly the filled cells of ``grid``.

    Returns ``{"bound", "optimal", "objective", "status", "seconds",
    "variables"}``.  ``bound`` is a valid lower bound on the number of parts
    of any exact cover (equal to the minimum when ``optimal``), or None when
    no cover exists (``status`` "infeasible", e.g. without the 1x1 plate) or
    the program has more than :data:`MAX_VARIABLES` placements (``status``
    "too large").  ``objective`` is the size of the best cover found, or None
    if some region has none yet.  ``status`` is "optimal" when every region
    was solved to optimality, else "time limit".  ``variables`` counts the
    placements.  ``time_limit_s`` bounds the total solver time (HiGHS checks
    its clock now and then, so it may run over by a few seconds on programs
    near the size limit); it is shared among the 6-connected regions, fewest
    placements first, each getting a share of what is left proportional to
    its number of placements.  An empty grid needs 0 parts.  Raises
    InputError for an empty brick set, ValueError for a time limit that is
    not positive.
    """
    start = time.perf_counter()
    if not parts:
        raise InputError("the brick set for the lower bound is empty")
    if not time_limit_s > 0:
        raise ValueError(f"the time limit for the lower bound must be positive, not {time_limit_s}")
    filled = np.asarray(grid.filled, dtype=bool)
    shapes = part_shapes(parts)
    found, n_vars = _placements(filled, shapes)

    def result(bound, optimal, objective, status):
        return {"bound": bound, "optimal": optimal, "objective": objective, "status": status,
                "seconds": round(time.perf_counter() - start, 4), "variables": n_vars}

    if not filled.any():
        return result(0, True, 0, "optimal")
    if n_vars > MAX_VARIABLES:
        return result(None, False, None, "too large")

    labels, n_regions = ndimage.label(filled, structure=_SIX)
    col_region, indptr, rows, n_rows = _columns(filled, labels, shapes, found)
    col_first = np.searchsorted(col_region, np.arange(1, n_regions + 2))
    n_cols = np.diff(col_first)
    largest = max(p.cells for p in parts)

    total_bound, total_obj, all_optimal = 0, 0, True
    weight = n_cols.astype(float)
    remaining_weight = weight.sum()
    deadline = start + time_limit_s
    for r in np.argsort(n_cols, kind="stable"):
        cells = int(n_rows[r + 1])
        trivial = -(-cells // largest)
        if n_cols[r] == 0:
            return result(None, True, None, "infeasible")
        if cells == 1:
            total_bound += 1
            total_obj = None if total_obj is None else total_obj + 1
            remaining_weight -= weight[r]
            continue
        lo, hi = col_first[r], col_first[r + 1]
        now = time.perf_counter()
        share = (deadline - now) * weight[r] / remaining_weight
        remaining_weight -= weight[r]
        sub_ptr = indptr[lo:hi + 1] - indptr[lo]
        sub_rows = rows[indptr[lo]:indptr[hi]]
        bound, obj, optimal = _solve_region(sub_ptr, sub_rows, cells, now + share)
        if bound is None:
            return result(None, True, None, "infeasible")
        total_bound += max(bound, trivial)
        all_optimal &= optimal
        total_obj = None if obj is None or total_obj is None else total_obj + obj
    return result(total_bound, all_optimal, total_obj,
                  "optimal" if all_optimal else "time limit")
