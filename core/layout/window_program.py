"""The window program: the exact re-cover of one window's freed cells (HiGHS).

:func:`solve_window` takes the placements of the allowed parts wholly on the freed cells
(:func:`free_placements`, never across the boundary of the ``apart`` cells) and chooses those
that cover every freed cell once at the least cost: bricks, plus penalties for leaves (the
fixed bricks around the window too), islands and seams over seams (:data:`BRICK_COST` and the
weights after it).  The LP relaxation comes first; where it is fractional, branch and bound
over the placements, or over those the relaxation uses with the current bricks where they are
too many, else :data:`TOO_LARGE` and the caller shrinks the window.  With a stock, a row per
design keeps the re-cover to what is owned or bought.  Work is counted in simplex iterations,
the same on every run (HiGHS single-threaded, no presolve).  :class:`Effort` holds the limits
of a search and of its window programs.
"""

from __future__ import annotations

from dataclasses import dataclass

import highspy
import numpy as np
from numba import njit
from scipy import sparse

from core.inventory import BUY_COST
from core.layout.bounds import _summed_volume, cover_matrix, fitting_boxes


@dataclass(frozen=True)
class Effort:
    """How hard :func:`~core.layout.search.improve` works.

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
    closing sweep (:meth:`~core.layout.neighbourhood.Search.sweep_layers`; 0: no sweep),
    ``layer_sweeps``: how many times it sweeps the layers, each time grouping their bricks from
    another corner; ``weak_windows``: while weak points remain, the most windows (as ``best``
    tries them) tried at the end (:func:`~core.layout.search._repair_weak`); ``relaxed_start``:
    the search also runs from the layout whose brick layers the exact cover's relaxation
    chooses, where that is cheap (:func:`core.layout.greedy.relaxed_brick_groups`, the
    ``others`` of :func:`~core.layout.search.improve`); ``work``: the most simplex iterations
    (HiGHS's, over all window programs) the whole effort spends, ``normal``'s searches from
    several seeds included (0: no such limit; :func:`~core.layout.search.improve`).
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


#: Objective weights of the window program: per brick, per leaf (a brick
#: hanging from one neighbour), per island (a brick touching nothing above
#: or below), per brick side cell on a seam of a fixed brick below or above.
BRICK_COST = 1.0
LEAF_COST = 3.0
#: The leaf penalty while compacting (weak points not in the key yet).
COMPACT_LEAF_COST = 1.0
ISLAND_COST = 6.0
SEAM_COST = 0.02

#: What the window program returns when its LP relaxation is fractional and it, and the
#: placements its relaxation uses with the current bricks, are more placements than
#: branch and bound may take: the window is shrunk and tried again.
TOO_LARGE = "too large"


def numbered_shapes(parts) -> list[tuple[tuple[int, int, int], str]]:
    """Each box a part of ``parts`` takes when placed, (cells x, y, z), with the part's
    number (the last part of a shape wins), sorted by box."""
    return sorted({(sx, sy, p.layers): p.number for p in parts for sx, sy in p.orientations()}.items())


def free_placements(free, apart, shapes):
    """Every placement on the freed cells: (n, 6) boxes (x, y, z, sx, sy, sz), shape by
    shape in the order of ``shapes``, each shape's min corners in C order.

    With ``apart`` cells a placement lies wholly inside or wholly outside them.
    """
    masks = [free] if apart is None else [free & apart, free & ~apart]
    sizes = np.array([size for size, _ in shapes], dtype=np.int64).reshape(-1, 3)
    out = [fitting_boxes(_summed_volume(mask), sizes, np.argwhere(mask)) for mask in masks if mask.any()]
    return np.concatenate(out) if out else np.empty((0, 6), dtype=np.int64)


@njit(cache=True)
def contacts(boxes, free, filled, lab):
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
def covering(boxes, targets, cell_ptr, cell_cols, cell_index):
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


def solve_window(boxes, free, filled, lab, current, rng, level: Effort, leaf_cost: float,
                  penalty: dict | None = None, limits=None):
    """The best re-cover of the ``free`` cells of a local box by the placements ``boxes``
    (:func:`free_placements`), as a list of boxes, or None; with the simplex iterations HiGHS
    spent on it (a count of work that, unlike seconds, is the same on every run).

    ``lab`` holds the fixed bricks' indices (-1 on freed and empty cells);
    the box has a margin of one cell around the freed cells where the grid
    allows.  ``current`` (the freed bricks' boxes) is the starting solution.  Where the
    LP relaxation is fractional: branch and bound over ``boxes`` when they are at most
    ``level.mip_columns``, else over the placements the relaxation uses and ``current``
    when those are, else :data:`TOO_LARGE`.  ``limits``
    (:func:`~core.layout.neighbourhood._design_limits`, None: none) add a row per design: its
    placements at most the owned count left, plus a bought count (at most 0 where buying is not
    allowed) priced :data:`core.inventory.BUY_COST`.
    """
    n = len(boxes)
    if n == 0:
        return None, 0
    m = int(free.sum())
    a, lp, n_buy = _window_lp(boxes, free, filled, lab, rng, leaf_cost, penalty, limits)
    h = _window_highs(lp, level)
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
        chosen, more = solve_window(boxes[keep], free, filled, lab, current, rng, level,
                                     leaf_cost, penalty, limits)
        return chosen, spent + more
    if not lp_done:
        more, found = _branch_and_bound(h, boxes, current, a, lp, m, n_buy)
        spent += more
        if not found:
            return None, spent
    x = np.asarray(h.getSolution().col_value)[:n]
    chosen = boxes[x > 0.5]
    if int((chosen[:, 3] * chosen[:, 4] * chosen[:, 5]).sum()) != m:
        return None, spent
    return [tuple(int(v) for v in b) for b in chosen], spent


def _window_lp(boxes, free, filled, lab, rng, leaf_cost: float, penalty: dict | None, limits):
    """The program of :func:`solve_window` (its arguments of the same names): its matrix
    (CSC), the :class:`_Lp` and the number of its bought-count columns.

    Columns: the placements (:func:`_placement_costs`), the leaf variables
    (:func:`_leaf_entries`) at ``leaf_cost`` each, and with ``limits`` a bought count per
    design at :data:`core.inventory.BUY_COST`.  Rows: each freed cell covered once, each leaf
    row, and with ``limits`` a row per design: its placements less its bought count at most
    the owned count left."""
    n = len(boxes)
    cell_index = np.full(free.shape, -1, dtype=np.int64)
    cell_index[free] = np.arange(int(free.sum()))
    m = int(free.sum())
    cover = cover_matrix(boxes, cell_index, m)
    fixed, wb, wa, bbox, seams = contacts(boxes, free, filled, lab)
    cost = _placement_costs(boxes, fixed, wb, wa, seams, rng, leaf_cost, penalty)
    rows, cols, vals, n_leaf, n_fixed = _leaf_entries(boxes, free, filled, lab, cover,
                                                      cell_index, fixed, bbox)
    r_rows, r_cols = [cover.row, *rows], [cover.col, *cols]
    r_vals = [np.ones(cover.row.size), *vals]
    design, n_buy = None, 0
    if limits is not None:
        codes, design_rows, left, may_buy = limits
        design = design_rows[np.searchsorted(codes, size_code(boxes[:, 3], boxes[:, 4], boxes[:, 5]))]
        n_buy = len(left)
    n_cols = n + n_leaf + n_fixed + n_buy
    n_rows = m + n_leaf + n_fixed + n_buy
    if n_buy:
        buy_rows = m + n_leaf + n_fixed + np.arange(n_buy)
        r_rows += [buy_rows[design], buy_rows]
        r_cols += [np.arange(n), n + n_leaf + n_fixed + np.arange(n_buy)]
        r_vals += [np.ones(n), -np.ones(n_buy)]
    a = sparse.csc_matrix((np.concatenate(r_vals), (np.concatenate(r_rows).astype(np.int64),
                                                   np.concatenate(r_cols).astype(np.int64))),
                          shape=(n_rows, n_cols))
    a.sum_duplicates()
    col_cost = np.concatenate([cost, np.full(n_leaf + n_fixed, leaf_cost),
                               np.full(n_buy, BUY_COST)])
    col_upper = np.concatenate([np.ones(n + n_leaf + n_fixed),
                                np.full(n_buy, highspy.kHighsInf if n_buy and may_buy else 0.0)])
    row_lower = np.concatenate([np.ones(m), np.full(n_leaf + n_fixed + n_buy, -highspy.kHighsInf)])
    row_upper = np.concatenate([np.ones(m), np.ones(n_leaf), np.zeros(n_fixed),
                                left if n_buy else np.zeros(0)])
    return a, _Lp(a, col_cost, col_upper, row_lower, row_upper), n_buy


def _placement_costs(boxes, fixed, wb, wa, seams, rng, leaf_cost: float,
                     penalty: dict | None) -> np.ndarray:
    """Per placement (``boxes``, with :func:`contacts`' ``fixed``, ``wb``, ``wa`` and
    ``seams``): its objective weight, :data:`BRICK_COST` plus :data:`SEAM_COST` per seam cell,
    :data:`ISLAND_COST` where it touches nothing above or below, ``leaf_cost`` where it
    touches one fixed brick there and nothing else, a seeded tie-breaker below 1e-4 (one draw
    of ``rng`` per placement) and its extra price in ``penalty`` (box -> price)."""
    n = len(boxes)
    cost = BRICK_COST + SEAM_COST * seams + 1e-4 * rng.random(n)
    cost += ISLAND_COST * ((fixed == 0) & (wb == 0) & (wa == 0))
    cost += leaf_cost * ((fixed == 1) & (wb == 0) & (wa == 0))
    for box, extra in (penalty or {}).items():
        cost[np.flatnonzero((boxes == box).all(axis=1))] += extra
    return cost


def _leaf_entries(boxes, free, filled, lab, cover: sparse.coo_matrix, cell_index, fixed,
                  bbox) -> tuple[list, list, list, int, int]:
    """The entries of the window program's leaf rows, after the rows of ``cover`` (the
    (cells, placements) matrix), as lists of rows, of columns and of values arrays, and the
    numbers of leaf rows of placements and of fixed bricks; one leaf variable per leaf row,
    in the columns after the placements.

    A placement p with no fixed neighbour that touches freed cells on one side only is a
    leaf when one placement q covers all of those cells.  All such q cover the same cell, so
    at most one is chosen: y_p >= x_p + sum_q x_q - 1 is exact (one row per p).  A fixed
    brick beside the window with no other fixed neighbour (:func:`_fixed_leaf_targets`):
    y_F >= sum_q x_q."""
    n, m = len(boxes), cover.shape[0]
    by_cell = cover.tocsr()
    ptr, idx = by_cell.indptr.astype(np.int64), by_cell.indices.astype(np.int64)
    cand = np.flatnonzero((fixed == 0) & (bbox[:, 4] >= 0))
    t, q = covering(boxes, bbox[cand], ptr, idx, cell_index)
    keep = cand[t] != q
    t, q = t[keep], q[keep]
    leaves, t = np.unique(t, return_inverse=True)
    targets = _fixed_leaf_targets(free, filled, lab)
    ft, fq = (covering(boxes, targets, ptr, idx, cell_index) if len(targets)
              else (np.empty(0, np.int64), np.empty(0, np.int64)))
    n_leaf, n_fixed = leaves.size, len(targets)
    leaf_rows = m + np.arange(n_leaf)
    fixed_rows = m + n_leaf + np.arange(n_fixed)
    rows = [leaf_rows, m + t, leaf_rows, fixed_rows[ft], fixed_rows]
    cols = [cand[leaves], q, n + np.arange(n_leaf), fq, n + n_leaf + np.arange(n_fixed)]
    vals = [np.ones(n_leaf), np.ones(q.size), -np.ones(n_leaf), np.ones(fq.size),
            -np.ones(n_fixed)]
    return rows, cols, vals, n_leaf, n_fixed


@dataclass(frozen=True)
class _Lp:
    """The LP ``min col_cost . x`` subject to ``row_lower <= a x <= row_upper`` and
    ``0 <= x <= col_upper``, its matrix ``a`` column-wise."""

    a: sparse.csc_matrix
    col_cost: np.ndarray
    col_upper: np.ndarray
    row_lower: np.ndarray
    row_upper: np.ndarray

    @property
    def num_col(self) -> int:
        return self.a.shape[1]


def _window_highs(lp: _Lp, level: Effort) -> highspy.Highs:
    """A silent single-threaded HiGHS holding ``lp``, with ``level``'s time and node limits."""
    h = highspy.Highs()
    h.setOptionValue("output_flag", False)
    h.setOptionValue("threads", 1)
    h.setOptionValue("random_seed", 0)
    # no presolve: it would change which of equal re-covers is kept
    h.setOptionValue("presolve", "off")
    h.setOptionValue("time_limit", level.time_limit_s)
    h.setOptionValue("mip_max_nodes", level.node_limit)
    h.setOptionValue("mip_rel_gap", 1e-6)
    a = lp.a
    # the arrays themselves: a HighsLp's members convert each array anew, element by element
    h.passModel(a.shape[1], a.shape[0], a.nnz, int(highspy.MatrixFormat.kColwise),
                int(highspy.ObjSense.kMinimize), 0.0, lp.col_cost, np.zeros(a.shape[1]),
                lp.col_upper, lp.row_lower, lp.row_upper, a.indptr.astype(np.int32),
                a.indices.astype(np.int32), a.data.astype(np.float64),
                np.zeros(a.shape[1], np.int32))          # every column continuous
    return h


def _branch_and_bound(h: highspy.Highs, boxes, current, a, lp: _Lp, m: int,
                      n_buy: int) -> tuple[int, bool]:
    """Solve the window program ``h`` (``lp``, matrix ``a``, ``m`` cell rows, ``n_buy``
    bought counts last) with its placements ``boxes`` in integers, from the ``current``
    bricks where they are all placements: (the simplex iterations spent, whether it found a
    cover)."""
    n = len(boxes)
    h.changeColsIntegrality(n, np.arange(n, dtype=np.int32),
                            np.full(n, highspy.HighsVarType.kInteger))
    start = _start_solution(boxes, current, a, n, lp.num_col, m, lp.row_upper[m:], n_buy)
    if start is not None:
        sol = highspy.HighsSolution()
        sol.col_value = list(start)
        sol.value_valid = True
        h.setSolution(sol)
    h.run()
    spent = max(h.getInfo().simplex_iteration_count, 0)
    found = h.getInfo().primal_solution_status == highspy.SolutionStatus.kSolutionStatusFeasible
    return spent, found


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


def size_code(sx, sy, sz):
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
