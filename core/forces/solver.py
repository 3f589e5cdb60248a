"""Linear programs in HiGHS's terms (:class:`Program`), solved with a work limit that counts
iterations, not seconds, so that a verdict does not depend on the machine's load.
"""

from __future__ import annotations

import signal
import threading
from dataclasses import dataclass, field

import numpy as np
from scipy import sparse

from core.forces import limits

#: HiGHS's interior point where its answer itself is used, not only its bound: the force
#: model's programs (whose work limits count its iterations) and the relaxation whose
#: values choose the relaxed start's brick layers (:func:`core.layout.bounds.relaxed_cover`).
#: HiGHS 1.15's default interior point (HiPO) stopped with status "Unknown" on the force
#: programs; the bounds use it (``"ipm"``: faster on the large exact-cover relaxations).
INTERIOR_POINT = "ipx"


class SolverTrouble(RuntimeError):
    """HiGHS ended a force program without an answer (a numerical failure, not the input's)."""


@dataclass
class Program:
    """A linear program in HiGHS's terms, built block by block."""

    cost: list = field(default_factory=list)
    lower: list = field(default_factory=list)
    upper: list = field(default_factory=list)
    rows: list = field(default_factory=list)
    cols: list = field(default_factory=list)
    vals: list = field(default_factory=list)
    ncol: int = 0
    nrow: int = 0
    row_lo: list = field(default_factory=list)
    row_hi: list = field(default_factory=list)
    #: the work (:func:`solver_work`) of the last :meth:`solve`, and the coefficients of
    #: the last program :meth:`highs` built
    spent: int = 0
    nnz: int = 0

    def columns(self, n: int, lo, hi, cost: float = 0.0) -> np.ndarray:
        """``n`` new columns with bounds ``lo``..``hi`` (scalars or arrays); their indices."""
        idx = np.arange(self.ncol, self.ncol + n)
        self.ncol += n
        self.cost.append(np.full(n, float(cost)))
        self.lower.append(np.broadcast_to(np.asarray(lo, float), (n,)).copy())
        self.upper.append(np.broadcast_to(np.asarray(hi, float), (n,)).copy())
        return idx

    def new_rows(self, n: int, lo, hi) -> np.ndarray:
        """``n`` new rows with bounds ``lo``..``hi``; their indices."""
        idx = np.arange(self.nrow, self.nrow + n)
        self.nrow += n
        self.row_lo.append(np.broadcast_to(np.asarray(lo, float), (n,)).copy())
        self.row_hi.append(np.broadcast_to(np.asarray(hi, float), (n,)).copy())
        return idx

    def put(self, row, col, val) -> None:
        """Add coefficients ``val`` at (``row``, ``col``), broadcast; duplicates add up."""
        row, col, val = np.broadcast_arrays(np.asarray(row), np.asarray(col), np.asarray(val, float))
        keep = np.abs(val) > 1e-12
        self.rows.append(row[keep].ravel())
        self.cols.append(col[keep].ravel())
        self.vals.append(val[keep].ravel())

    def matrix(self) -> sparse.csc_matrix:
        """The constraint matrix (duplicates summed)."""
        mat = sparse.csc_matrix((np.concatenate(self.vals), (np.concatenate(self.rows),
                                                             np.concatenate(self.cols))),
                                shape=(self.nrow, self.ncol))
        mat.sum_duplicates()
        return mat

    def row_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return np.concatenate(self.row_lo), np.concatenate(self.row_hi)

    def col_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return np.concatenate(self.lower), np.concatenate(self.upper)

    def highs(self, simplex: bool = False):
        """A HiGHS object holding this program: interior point (one-off solves) or the
        primal simplex (re-solved after bound changes from the previous basis, where it is
        much faster than the dual)."""
        import highspy

        h = highspy.Highs()
        h.setOptionValue("output_flag", False)
        h.setOptionValue("threads", 1)
        h.setOptionValue("solver", "simplex" if simplex else INTERIOR_POINT)
        # the interior point's own answer is enough (a vertex is not needed, and crossover
        # to one is costly)
        h.setOptionValue("run_crossover", "choose")
        if simplex:
            h.setOptionValue("simplex_strategy", 4)         # primal: warm starts after bound changes
        lp = highspy.HighsLp()
        lp.num_col_ = self.ncol
        lp.num_row_ = self.nrow
        lp.col_cost_ = np.concatenate(self.cost)
        lp.col_lower_, lp.col_upper_ = self.col_bounds()
        lp.row_lower_, lp.row_upper_ = self.row_bounds()
        mat = self.matrix()
        self.nnz = mat.nnz
        lp.a_matrix_.format_ = highspy.MatrixFormat.kColwise
        lp.a_matrix_.start_ = mat.indptr
        lp.a_matrix_.index_ = mat.indices
        lp.a_matrix_.value_ = mat.data
        h.passModel(lp)
        return h

    def solve(self, work: int | None = None, seconds: float | None = None
              ) -> tuple[str, np.ndarray | None]:
        """('optimal', column values), ('infeasible', None), ('unbounded', None), or
        ('limit', None) when the solver stopped first at ``work`` units of
        :func:`solver_work` (as iteration limits: the interior point's scaled by this
        program's size, and the simplex's) or at ``seconds`` (None: no such limit).
        :attr:`spent` is then the work this solve did."""
        import highspy
        h = self.highs()
        nnz = self.nnz
        if work is not None:
            h.setOptionValue("ipm_iteration_limit", max(1, int(work // ipm_iteration_work(nnz))))
            h.setOptionValue("simplex_iteration_limit", max(1, int(work)))
        if seconds is not None:
            h.setOptionValue("time_limit", float(seconds))
        run_highs(h)
        self.spent = solver_work(h.getInfo(), nnz)
        status = h.getModelStatus()
        if status == highspy.HighsModelStatus.kOptimal:
            return "optimal", np.asarray(h.getSolution().col_value)
        if status in (highspy.HighsModelStatus.kTimeLimit, highspy.HighsModelStatus.kIterationLimit):
            return "limit", None
        if status == highspy.HighsModelStatus.kInfeasible:
            return "infeasible", None
        if status in (highspy.HighsModelStatus.kUnbounded,
                      highspy.HighsModelStatus.kUnboundedOrInfeasible):
            return "unbounded", None
        raise SolverTrouble(f"the force program ended with HiGHS status {h.modelStatusToString(status)}")


def ipm_iteration_work(nnz: int) -> int:
    """The work of one interior-point iteration on a program of ``nnz`` coefficients, in
    simplex iterations (each about a millisecond on the big force programs): about a
    millisecond per unit too, growing with the square of the program.  Fitted to the
    interior point's milliseconds per iteration on big force programs (a slab over a box,
    the bands of scaled-up connecting rods and HMD shells, 56,000 to 631,000
    coefficients)."""
    return max(1, round((nnz / 1000.0) ** 2 / 350.0))


def solver_work(info, nnz: int) -> int:
    """The work of one HiGHS run whose info is ``info`` on a program of ``nnz`` coefficients,
    in simplex iterations: its simplex and crossover iterations, and its interior-point
    iterations at :func:`ipm_iteration_work` each.  The same program gets the same count
    on a busy machine as on an idle one (one thread)."""
    return (max(info.simplex_iteration_count, 0) + max(info.crossover_iteration_count, 0)
            + ipm_iteration_work(nnz) * max(info.ipm_iteration_count, 0))


def work_words(subject: str) -> str:
    """:data:`limits.PROGRAM_WORK` in words: "the N solver iterations <subject> given (...)"."""
    return f"the {limits.PROGRAM_WORK:,} solver iterations {subject} given (about two minutes)"


#: Seconds a stopped run waits for the solver to stop (:func:`run_highs`).
STOP_WAIT_S = 0.2


def run_highs(h) -> None:
    """Run the HiGHS object ``h``.  Where a stop signal has a Python handler (the command
    line's SIGTERM, in its main thread), in a worker thread while this one waits in Python,
    so that the signal raises here at once and the solver is told to stop (HiGHS's user
    interrupt) instead of finishing a program that may run for minutes; the solver gets
    :data:`STOP_WAIT_S` to stop (it looks at the interrupt between iterations only, and a
    phase of its may take seconds), and is left running
    after that, as the command line ends its process without waiting for threads
    (:mod:`core.__main__`).  Elsewhere (inside FreeCAD, where a Qt event loop owns the main
    thread, or in a worker) in this thread."""
    if (threading.current_thread() is not threading.main_thread()
            or not callable(signal.getsignal(signal.SIGTERM))):
        h.run()
        return
    h.HandleUserInterrupt = True
    worker = h.startSolve()
    try:
        while worker.is_alive():
            worker.join(0.05)
    except BaseException:
        h.cancelSolve()
        worker.join(STOP_WAIT_S)
        raise
