"""Build steps checked by forces: does each prefix of the build order stand, with its props?

:class:`BuildChecker` re-solves one model's program for subsets of its bodies, warm
started from the previous basis (consecutive prefixes differ by a few bricks).
"""

from __future__ import annotations

import math
import time

import numpy as np
from scipy import sparse
from scipy.sparse.csgraph import connected_components

from core.forces import joints, limits
from core.forces.analyse import _Model
from core.forces.joints import bending_capacity_nmm
from core.forces.limits import worst_of
from core.forces.solver import INTERIOR_POINT, run_highs, solver_work
from core.forces.verdict import GRAPH_ONLY, graph_only_why
from core.model import Layout
from core.request import parse_load


class _Warm:
    """The phase-1 program of one model, re-solved for subsets of its bodies by the primal
    simplex from the previous basis (consecutive build prefixes differ by a few bricks)."""

    def __init__(self, model: "_Model"):
        import highspy
        self.model = m = model
        prog, parts = m._program(detail=False)
        self.factor = parts["factor"]
        coo = prog.matrix().tocoo()
        eq_rows = (coo.row < 6 * m.nbody) & (coo.col != self.factor)
        # bodies each force column touches through the equilibrium rows (not the load factor)
        self.col_body = (coo.col[eq_rows], coo.row[eq_rows] // 6)
        self.row_lo, self.row_hi = prog.row_bounds()
        self.col_lo, self.col_hi = prog.col_bounds()
        self.section_rows = [(idx, rows) for idx, rows in parts["section_rows"]]
        self.table = parts.get("table")
        self.highs = prog.highs(simplex=True)
        self.present = np.ones(m.nbody, dtype=bool)
        self.basis = None
        #: the solves' work so far (:func:`solver_work`)
        self.work = 0
        self.nnz = prog.nnz
        self._ok = highspy.HighsModelStatus.kOptimal

    def factor_of(self, body_present: np.ndarray, propped: np.ndarray | None = None) -> float | None:
        """The largest load factor the bodies ``body_present`` carry (with the table points
        ``propped`` held up by props, :meth:`_Model.resting`); None when neither the
        warm start nor a cold solve found it (a degenerate set, e.g. a piece about to tip),
        with the last good basis put back."""
        m, h = self.model, self.highs
        self._apply(body_present)
        if self.table is not None and len(self.table["cols"]):
            if m.ground == "table":
                active, _ = m.resting(body_present, propped)
            else:                                 # on a baseplate only props press up
                active = np.zeros(len(m._table_points()[0]), dtype=bool) if propped is None \
                    else propped
            cols = self.table["cols"]
            hi = np.where(active[self.table["index"]] & body_present[m._table_points()[1][self.table["index"]]],
                          np.inf, 0.0)
            h.changeColsBounds(len(cols), cols.astype(np.int32), np.zeros(len(cols)), hi)
        if self.basis is None or not self._run(cold=False):
            self._run(cold=True)
        if h.getModelStatus() != self._ok:
            if self.basis is not None:
                h.setBasis(self.basis)
            else:
                h.clearSolver()
            return None
        self.basis = h.getBasis()
        return float(h.getSolution().col_value[self.factor])

    def _run(self, cold: bool) -> bool:
        """Solve from the current basis by the primal simplex, or (``cold``) afresh by the
        interior point with a crossover to a basis for the next warm start (faster than a
        cold primal simplex).  Whether it reached the optimum."""
        h = self.highs
        if cold:
            h.clearSolver()
            h.setOptionValue("solver", INTERIOR_POINT)
            h.setOptionValue("run_crossover", "on")
        run_highs(h)
        self.work += solver_work(h.getInfo(), self.nnz)
        if cold:
            h.setOptionValue("solver", "simplex")
            h.setOptionValue("run_crossover", "choose")
        return h.getModelStatus() == self._ok

    def _apply(self, body_present: np.ndarray) -> None:
        """Bounds for the bodies now present: absent bodies' rows free, their forces zero."""
        changed = body_present != self.present
        if not changed.any():
            return
        self.present = body_present.copy()
        m, h = self.model, self.highs
        cols, bodies = self.col_body
        touched = np.unique(cols[changed[bodies]])
        absent_col = np.zeros(len(self.col_lo), dtype=bool)
        absent_col[cols[~body_present[bodies]]] = True
        lo = np.where(absent_col[touched], 0.0, self.col_lo[touched])
        hi = np.where(absent_col[touched], 0.0, self.col_hi[touched])
        h.changeColsBounds(len(touched), touched.astype(np.int32), lo, hi)
        rows = [np.arange(6 * b, 6 * b + 6) for b in np.flatnonzero(changed)]
        rows += [r for idx, r in self.section_rows if changed[m.body_of[idx]]]
        if rows:
            rows = np.concatenate(rows).astype(np.int64)
            free = ~body_present[np.where(rows < 6 * m.nbody, rows // 6, 0)]
            for idx, r in self.section_rows:
                if changed[m.body_of[idx]]:
                    free[np.isin(rows, r)] = ~body_present[m.body_of[idx]]
            lo = np.where(free, -np.inf, self.row_lo[rows])
            hi = np.where(free, np.inf, self.row_hi[rows])
            for r, a, b in zip(rows.tolist(), lo.tolist(), hi.tolist()):
                h.changeRowBounds(r, a, b)


class BuildChecker:
    """Whether partial builds of one layout stand: every prefix of a build order.

    Built once for ``layout`` (the settings as :func:`analyse`; no ``loads``
    unless given: what the object carries goes on when it is built), it answers :meth:`stands`
    for any set of its bricks.  A set whose every cell rests on a cell of the
    set (or the ground) stands in pure compression and needs no program;
    otherwise a program is solved with the absent bodies' rows let go and
    every force touching them held at zero, warm-started from the previous
    answer (:class:`_Warm`).  Past :data:`limits.EXACT_BODIES` bodies that is the
    program of the layout's hanging part on its supports (as
    :meth:`_Model._by_parts`, uncut, with :data:`limits.BUILD_MARGIN_LEVELS` levels
    under it where they fit) while every present brick outside it
    rests on present cells: an upper bound of the worst utilisation, so a set
    it finds above :data:`limits.FRAGILE` is solved again with the whole program.
    Past :data:`limits.MAX_BODIES` bodies no program is solved: a set that would need
    one is checked by the brick graph only (:func:`graph_only_why`); so are the
    sets asked about once the programs have done more than ``budget`` units of work in
    all (:attr:`work`; None: :data:`limits.BUILD_BUDGET`; :attr:`why` then says so).  The work is
    counted in the solver's iterations, not in seconds, so the same build gets the same
    answers on a busy machine as on an idle one.

    A set that holds the last set found standing at most :data:`limits.FRAGILE` and adds to it
    only LEGO bricks borne on full columns (every cell under them filled by bricks of
    the set, down to the ground; :meth:`_borne`) needs no program either: the forces that
    held the smaller set still hold, and each new brick's weight goes straight down its
    columns in compression, through every body on the way at the same stud axis (no force
    or moment left over on them, nor any bending).  It gets the smaller set's utilisation,
    an upper bound of its own.
    """

    def __init__(self, layout: Layout, ground: str = "table", printed=(), clamp=None,
                 clutch_n: float = joints.CLUTCH_N, profile: dict[str, str] | None = None,
                 budget: int | None = None, loads=()):
        self.layout = layout
        self.model = _Model(layout, ground, [parse_load(x) for x in loads], printed, clamp,
                            float(clutch_n), profile)
        self.model.propping = True
        self.budget = limits.BUILD_BUDGET if budget is None else budget
        #: seconds the programs took in all (reported; the budget counts :attr:`work`)
        self.seconds = 0.0
        #: why sets that need a program are checked by the graph only (None: they are not)
        self.why: str | None = None if self.model.nbody <= limits.MAX_BODIES else graph_only_why(
            self.model.nbody)
        self._printed, self._clamp, self._profile = printed, clamp, profile
        # bricks on bricks (lower, upper; by position in layout.bricks), and bricks with a cell
        # above nothing (not on the ground): what a partial build's checks need, once
        lab = self.model.lab
        lower, upper = lab[:, :, :-1], lab[:, :, 1:]
        pairs = np.stack([lower.ravel(), upper.ravel()], 1)
        pairs = pairs[(pairs[:, 0] >= 0) & (pairs[:, 1] >= 0) & (pairs[:, 0] != pairs[:, 1])]
        self._pairs = np.unique(pairs, axis=0)
        self._hangs = np.zeros(len(layout.bricks), dtype=bool)
        self._hangs[np.unique(upper[(lower < 0) & (upper >= 0)])] = True
        self._grounded = np.zeros(len(layout.bricks), dtype=bool)
        self._grounded[np.unique(lab[:, :, 0][lab[:, :, 0] >= 0])] = True
        n = len(layout.bricks)
        by_upper = sparse.csr_matrix((np.ones(len(self._pairs)), (self._pairs[:, 1], self._pairs[:, 0])),
                                     shape=(n, n))
        by_lower = by_upper.T.tocsr()
        self._lowers = np.split(by_upper.indices, by_upper.indptr[1:-1])
        self._uppers = np.split(by_lower.indices, by_lower.indptr[1:-1])
        # the hanging part's bricks and its supports' (None: the whole program only)
        self._part = None
        self._outside = np.zeros(n, dtype=bool)
        self.programs = self.model.nbody <= limits.MAX_BODIES
        if self.programs and self.model.nbody > limits.EXACT_BODIES:
            low = self.model._lowest_layer()
            for margin in (limits.BUILD_MARGIN_LEVELS, limits.MARGIN_LEVELS):
                hanging, support, under = self.model._hanging_part(margin)
                if not np.any(low[hanging] == 0) and \
                        np.count_nonzero(hanging | support) <= limits.PART_SHARE * self.model.nbody:
                    self._part = (hanging, support, under)
                    self._outside = ~hanging[self.model.body_of]
                    break
        # the bricks of the last set asked about, and in it: pairs whose upper brick is in
        # and lower one out (all, and those whose upper brick is outside the hanging part),
        # and bricks with a cell above nothing (kept step by step)
        self._last = np.zeros(n, dtype=bool)
        self._missing = 0
        self._missing_outside = 0
        self._hanging = 0
        self.solves = 0
        self.fresh = 0
        self._fresh_work = 0
        self._whole: _Warm | None = None
        self._sub: tuple[_Warm, np.ndarray] | None = None
        # the last set found joined to the ground (the next is usually it and one step more)
        self._held_last = np.zeros(n, dtype=bool)
        # the last set found standing at most limits.FRAGILE without props, and its utilisation;
        # per brick, the bricks of its full columns (or None: it is not borne on them)
        self._proven: tuple[np.ndarray, float] | None = None
        self._columns: dict[int, np.ndarray | None] = {}

    def stands(self, present, props=None) -> tuple[bool, float]:
        """(stands, worst utilisation) of the bricks ``present`` (a bool per brick of the
        layout, in its order): inf when some present brick is joined to nothing on the ground;
        (True, NaN) when it is joined to the ground but would need a program past
        :data:`limits.MAX_BODIES` bodies, or past the budget, or its own program ran past
        :data:`limits.PROGRAM_WORK` (checked by the brick graph only).  ``props`` ((n, 3) cells
        i, j, k, or None): cells held up by a prop each, a column on the table (or the
        baseplate) under the cell that pushes up on its bottom (:meth:`_Model.resting`)."""
        m = self.model
        present = np.asarray(present, dtype=bool)
        propped = None
        if props is not None and len(props):
            propped = m.points_under(props)
        if self._supported(present):
            return True, 0.0                     # every present cell rests on a present cell
        if not self._held(present):
            return False, math.inf
        if self.programs and self.work > self.budget:
            self.programs = False
            self.why = (f"{m.nbody} bricks and printed parts: the programs of the partial builds "
                        f"ran {self.work:,} solver iterations in all, more than the "
                        f"{self.budget:,} they are given (about a minute); from here on "
                        + GRAPH_ONLY)
        if not self.programs:
            return True, math.nan
        if propped is None:
            bound = self._borne_bound(present)
            if bound is not None:
                self._proven = (present.copy(), bound)
                return True, bound
        start = time.perf_counter()
        try:
            ok, worst = self._programs(present, propped)
        finally:
            self.seconds += time.perf_counter() - start
        if propped is None and ok and worst <= limits.FRAGILE:
            self._proven = (present.copy(), worst)
        return ok, worst

    def _borne_bound(self, present: np.ndarray) -> float | None:
        """The last proven set's utilisation where ``present`` is it and bricks borne on full
        columns of ``present`` whose own weight bends them less (see the class); else None."""
        if self._proven is None:
            return None
        base, worst = self._proven
        if np.any(base & ~present):
            return None
        for b in np.flatnonzero(present & ~base).tolist():
            under = self._borne(b)
            if under is None or not present[under].all() or self._own_bending(b) > worst:
                return None
        return worst

    def _borne(self, b: int) -> np.ndarray | None:
        """The bricks (by position) under every cell of LEGO brick ``b`` down to the ground,
        if that column is full and ``b`` is a body of its own that carries nothing more than
        its weight; else None."""
        if b not in self._columns:
            m = self.model
            (x, y, z), (sx, sy, _) = m.corners[b], m.sizes[b]
            below = m.lab[x:x + sx, y:y + sy, :z]
            lone = np.count_nonzero(m.body_of == m.body_of[b]) == 1
            plain = (not m.printed_brick[b] and lone and b not in m.point_masses
                     and not np.any(m.extra[m.body_of[b]]))
            self._columns[b] = np.unique(below) if plain and np.all(below >= 0) else None
        return self._columns[b]

    def _own_bending(self, b: int) -> float:
        """An upper bound of brick ``b``'s bending utilisation under its own weight alone,
        borne at its studs: the weight at mid-span of its length, held at its ends."""
        m = self.model
        sx, sy, layers = (int(v) for v in m.sizes[b])
        if max(sx, sy) < 2:
            return 0.0
        span_mm = max(sx, sy) * float(m.layout.grid.cell[0])
        moment = m.mass_g[m.body_of[b]] * joints.G / 1000.0 * span_mm / 4.0
        return moment / bending_capacity_nmm(min(sx, sy), layers, m.layout.grid.cell)

    @property
    def work(self) -> int:
        """The programs' work so far (:func:`solver_work`): of every warm-started solve
        (:attr:`_Warm.work`) and of the sets solved by a program of their own."""
        warm = [w for w in (self._whole, self._sub and self._sub[0]) if w is not None]
        return sum(w.work for w in warm) + self._fresh_work

    def _programs(self, present: np.ndarray, propped: np.ndarray | None) -> tuple[bool, float]:
        """:meth:`stands` of a set joined to the ground that needs a program (with the table
        points ``propped`` held up, then always the whole program)."""
        m = self.model
        if propped is None and self._part is not None and self._missing_outside == 0:
            if self._sub is None:
                hanging, support, under = self._part
                model, members = m._sub_model(np.flatnonzero(hanging), support, under)
                self._sub = (_Warm(model), members)
            warm, members = self._sub
            worst = self._solve(warm, present[members])
            if worst <= limits.FRAGILE:
                return True, worst
        if self._whole is None:
            self._whole = _Warm(m)
        worst = self._solve(self._whole, present, propped)
        if math.isnan(worst):                    # its own program ran past its work: the graph's
            return True, worst
        return bool(worst <= joints.FAIL_ABOVE), worst

    def _supported(self, present: np.ndarray) -> bool:
        """Every brick of ``present`` rests on the ground or on bricks of ``present`` under
        every cell of it (it then stands in pure compression).  Kept up to date brick by
        brick from the last set asked about: consecutive build prefixes differ by a step,
        so all the prefixes of a build cost in all no more than its bricks.  Keeps the
        same count for the present bricks outside the hanging part."""
        last, outside = self._last, self._outside
        for b in np.flatnonzero(present != last).tolist():
            lowers, uppers = self._lowers[b], self._uppers[b]
            sign = 1 if present[b] else -1
            if present[b]:
                gaps = int(np.count_nonzero(~last[lowers]))
                last[b] = True
            else:
                last[b] = False
                gaps = int(np.count_nonzero(~last[lowers]))
            above = last[uppers]
            self._missing += sign * (gaps - int(np.count_nonzero(above)))
            self._missing_outside += sign * ((gaps if outside[b] else 0)
                                             - int(np.count_nonzero(above & outside[uppers])))
            self._hanging += sign * int(self._hangs[b])
        return self._missing == 0 and self._hanging == 0

    def _held(self, present: np.ndarray) -> bool:
        """Every present brick joined to the ground through present bricks (printed parts
        count as one piece through their joints: a part's bricks all go in together)."""
        grown = not np.any(self._held_last & ~present)
        if grown and self.model.nbody == len(present):
            held = self._reaches(present)
        else:
            held = self._held_all(present)
        if held:
            self._held_last = present.copy()
        return held

    def _reaches(self, present: np.ndarray) -> bool:
        """Whether every brick of ``present`` not in the last set found held reaches that set
        or the ground through such bricks (a layout without printed parts): a search over
        the new bricks only, so all the steps of a build cost in all no more than its bricks."""
        new = present & ~self._held_last
        todo = [b for b in np.flatnonzero(new).tolist()
                if self._grounded[b] or self._held_last[self._lowers[b]].any()
                or self._held_last[self._uppers[b]].any()]
        reached = self._held_last.copy()
        reached[todo] = True
        while todo:
            b = todo.pop()
            for nb in (self._lowers[b], self._uppers[b]):
                more = nb[new[nb] & ~reached[nb]]
                reached[more] = True
                todo.extend(more.tolist())
        return not np.any(new & ~reached)

    def _held_all(self, present: np.ndarray) -> bool:
        """:meth:`_held` from scratch: the components of the present bodies' graph."""
        m = self.model
        n = len(present)
        keep = present[self._pairs[:, 0]] & present[self._pairs[:, 1]]
        a, b = m.body_of[self._pairs[keep, 0]], m.body_of[self._pairs[keep, 1]]
        ground = np.unique(m.body_of[np.flatnonzero(present & self._grounded)])
        nb = m.nbody
        rows = np.concatenate([a, ground])
        cols = np.concatenate([b, np.full(len(ground), nb)])
        graph = sparse.coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(nb + 1, nb + 1))
        _, comp = connected_components(graph, directed=False)
        body_present = np.zeros(nb, dtype=bool)
        body_present[m.body_of[present]] = True
        return bool(np.all(comp[:nb][body_present] == comp[nb])) if n else True

    def _solve(self, warm: _Warm, present: np.ndarray, propped: np.ndarray | None = None) -> float:
        """The worst utilisation of the bricks ``present`` of ``warm``'s model (with the
        table points ``propped`` held up; inf when that program has no answer)."""
        model = warm.model
        body_present = np.zeros(model.nbody, dtype=bool)
        body_present[model.body_of[present]] = True
        self.solves += 1
        factor = warm.factor_of(body_present, propped)
        if factor is not None:
            return worst_of(factor)
        if propped is not None:
            return math.inf
        # answer from a program of its own
        self.fresh += 1
        idx = np.flatnonzero(present)
        own = model._model_of(idx, model.support[model.body_of[idx]] if model.on_supports else None)
        verdict = own.verdict(detail=False)
        self._fresh_work += verdict.work
        return verdict.max_utilisation
