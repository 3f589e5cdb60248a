"""Force stage: does the layout stand, with what it carries?

The graph test of :mod:`core.stability` says which bricks hold together; this stage says
whether they *hold*: a static equilibrium of rigid bodies (every LEGO brick, every printed
part) whose joints have the strength of real LEGO, solved as linear programs with HiGHS
(after StableLego, Liu et al. 2024, and Luo et al. 2015).  Gravity acts at each body's
centre of mass (:data:`core.catalog.MASS_G`, :func:`printed_mass_g`); a brick's ``load_g``
(layout.json) and :class:`Load` boxes (``--load``) add masses.

**Joints.**  Where a cell of one body lies directly under a cell of another, the lower one's
stud is gripped at contact points (:func:`contact_directions`, :data:`CONTACT_RADIUS` from
its axis), each taking compression without limit and tension (the clutch) up to
``clutch_n`` where both stud and socket are whole (a printed part's incomplete one presses
but does not hold); each stud also takes shear.  Bodies side by side do not push on each
other (on the safe side).  The bottom layer rests on a ``table`` (compression, friction
:data:`TABLE_FRICTION`) or a ``baseplate`` (its studs grip).  A LEGO brick is also a beam:
its bending moment between studs stays within :func:`bending_capacity_nmm` (ABS).

**Program.**  Forces that put every body in equilibrium and minimise the worst
*utilisation* ``u``: tension / clutch, bending moment / strength.  A second pass keeps that
worst and minimises the sum of every joint's (all studs between two bodies) own worst, so
that each joint carries only what it must.  The layout stands when ``u <= 1``; a body that
no equilibrium holds (it floats, or tips whatever the joints do) is *unsupported*, ``u``
infinite.

**Big builds.**  Past :data:`EXACT_BODIES` bodies the parts that hang are solved first, on
supports that only press (:meth:`_Model._by_parts`); where one does not stand, the whole
program decides, up to :data:`MAX_BODIES`; past it, height bands top down
(:meth:`_Model._by_bands`).  Their forces balance every body, so when all stand the build
stands, with at most their worst (an upper bound); a band that does not leaves it unchecked.
"""

from __future__ import annotations

import dataclasses
import math
import signal
import threading
import time
from dataclasses import dataclass, field

import numpy as np
from scipy import sparse
from scipy.sparse.csgraph import connected_components

from core.catalog import BY_NUMBER, MASS_G
from core.errors import InputError
from core.model import Grid, Layout, Load
from core.request import parse_load

#: Acceleration of gravity, m/s^2.
G = 9.81
#: Default clutch: the tension one stud contact point holds, N (StableLego's T = 100 g).
CLUTCH_N = 0.98
#: Distance of a stud's contact points from its axis, in studs (8 mm), the one fitted
#: constant: with :data:`CLUTCH_N`, the catalog weights and a baseplate, StableLego's 2x4
#: staircase offset by two studs (stands at 19 levels, falls at 20) puts it below 0.2305, and
#: its 47-stud stick of 1-wide bricks (three 1x4 at the tip, a 1x2 propping its second
#: brick) above 0.2025; tests/core/test_stablelego.py checks every photographed build.
CONTACT_RADIUS = 0.215
#: Friction coefficient of ABS on a table top.
TABLE_FRICTION = 0.4
#: A build stands on a table only in the pose it was built in: one that would settle
#: leaning onto lower points (more than this, degrees: rounding) tips over.
MAX_TILT_DEG = 0.5
#: ABS tensile strength used for a part's bending strength, N/mm^2 (MPa).
ABS_STRENGTH_MPA = 40.0
#: LEGO wall and top thickness, mm (DESIGN.md dimensions: walls 1.2-1.5, top 1.0).
WALL_MM = 1.2
TOP_MM = 1.0
#: Grounds a layout can stand on.
GROUNDS = ("table", "baseplate")
#: Utilisation above which a joint counts as failing (numerical slack of the LP).
FAIL_ABOVE = 1.0 + 1e-6

_DIAG = math.sqrt(0.5)


@dataclass
class Forces:
    """What :func:`analyse` found.

    ``stable``: every body is held and every utilisation is at most 1.
    ``max_utilisation``: the worst utilisation (inf when some body is
    unsupported).  ``utilisation``: brick id -> the utilisation of what
    holds that brick (the joints under it, or above it for a brick that
    hangs; its own bending), inf for unsupported bricks; a build standing below
    :data:`DARK_BELOW` (past :data:`EXACT_BODIES` bodies, :data:`DETAIL_ABOVE`) gives each
    brick the worst, an upper bound.  ``failing_bricks``:
    ids whose utilisation is above 1, sorted; ``unsupported``: those no
    equilibrium holds.  ``failures``: one dict per failing brick with
    ``brick``, ``layer`` (from 1), ``cell``, ``utilisation`` (None when
    unsupported), ``mode`` ("clutch", "bending", "floats", "tips") and
    ``why``, a sentence.  ``mass_g``: the total mass, loads included.
    """

    stable: bool
    ground: str
    max_utilisation: float
    utilisation: dict[int, float] = field(default_factory=dict)
    failing_bricks: list[int] = field(default_factory=list)
    unsupported: list[int] = field(default_factory=list)
    failures: list[dict] = field(default_factory=list)
    mass_g: float = 0.0
    clutch_n: float = CLUTCH_N
    loads: list[dict] = field(default_factory=list)
    seconds: float = 0.0
    tilt_deg: float = 0.0
    topples: list[dict] = field(default_factory=list)
    unchecked: str | None = None
    sub_structures: int = 0
    bands: int = 0
    bodies: int = 0
    #: the work of the programs solved for it (:func:`solver_work`): the same on any machine
    work: int = 0

    def to_json(self) -> dict:
        """The ``stability.force`` block of report.json (inf written as null)."""
        def num(v: float):
            return None if not math.isfinite(v) else round(float(v), 4)
        return {"stable": None if self.unchecked else bool(self.stable), "ground": self.ground,
                "checked": self.unchecked is None, "unchecked_why": self.unchecked,
                "max_utilisation": num(self.max_utilisation),
                "failing_bricks": list(self.failing_bricks),
                "unsupported_bricks": list(self.unsupported),
                "failures": list(self.failures),
                "utilisation": {str(k): num(v) for k, v in sorted(self.utilisation.items())},
                "mass_g": round(self.mass_g, 2), "clutch_n": self.clutch_n,
                "loads": list(self.loads), "seconds": round(self.seconds, 3),
                "rests_tilted_deg": round(self.tilt_deg, 2),
                "topples": list(self.topples),
                "sub_structures": self.sub_structures, "bands": self.bands,
                "method": (BAND_MEANS if self.bands else SUB_MEANS if self.sub_structures
                           else WHOLE_MEANS),
                "explain": FORCE_MEANS}


#: What the utilisation means, in a builder's words.
FORCE_MEANS = ("Utilisation is how hard the hardest-working joint holding a brick works: the pull on "
               "its studs against the clutch they hold (about 100 g per contact point), or the bending "
               "of the brick against what it takes. Up to 1 the brick holds; above 1 it comes off or "
               "breaks. 'Unsupported' bricks float or tip over whatever their studs do.")


def worst_words(force: dict, digits: int = 2) -> str:
    """The worst utilisation of a ``stability.force`` document in words: "infinite" when
    something floats or tips, "at most X (checked by its N hanging part(s))" when the build
    was checked by its hanging parts, "at most X (checked in N height bands)" when in bands
    (upper bounds both), else the figure."""
    if force["max_utilisation"] is None:
        return "infinite (something floats or tips)"
    worst = f"{force['max_utilisation']:.{digits}f}"
    if force.get("bands"):
        return f"at most {worst} (checked in {force['bands']} height bands)"
    if force.get("sub_structures"):
        return f"at most {worst} (checked by its {force['sub_structures']} hanging part(s))"
    return worst


def verdict_words(force: dict) -> str:
    """A checked ``stability.force`` document's verdict in one clause: "stands on a table with
    120 g: worst joint utilisation 0.31" (what the CLI prints and FreeCAD's Forces holds)."""
    return (f"{'stands' if force['stable'] else 'does not stand'} on a {force['ground']} with "
            f"{force['mass_g']:.0f} g: worst joint utilisation {worst_words(force)}")


#: How the verdict was found: one program of the whole build (or :data:`SUB_MEANS`).
WHOLE_MEANS = "one program of the whole build: the worst utilisation is the least any forces reach"


def contact_directions(size_x: np.ndarray, size_y: np.ndarray, a: np.ndarray, b: np.ndarray,
                       printed: np.ndarray) -> np.ndarray:
    """Unit directions (n, 4, 2) from each stud's axis to its contact points, NaN where unused.

    The stud is at local position (``a``, ``b``) under a part of footprint
    (``size_x``, ``size_y``) studs.  A 1-wide part or a printed socket grips
    it all round (+x, -x, +y, -y); a 2-wide part by the outer wall across
    the part, and along it by the end wall at an end or the tube between it
    and the next stud (diagonally, towards the part's centre line).
    """
    n = len(a)
    out = np.full((n, 4, 2), np.nan)
    ring = np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]])
    round_ = printed | (np.minimum(size_x, size_y) < 2)
    out[round_] = ring
    for long_x in (True, False):
        sel = ~round_ & ((size_x >= size_y) == long_x)
        if not sel.any():
            continue
        along, across = (a[sel], b[sel]) if long_x else (b[sel], a[sel])
        length = size_x[sel] if long_x else size_y[sel]
        side = np.where(across == 0, -1.0, 1.0)      # the outer wall beside the stud
        inward = -side                                # towards the centre line (tubes)
        d = np.zeros((sel.sum(), 4, 2))
        d[:, 3] = np.nan
        # (along, across) components, then swapped into (x, y) for a part long in y
        d[:, 0] = np.stack([np.zeros_like(side), side], axis=1)
        minus_end = along == 0
        d[:, 1] = np.where(minus_end[:, None], [[-1.0, 0.0]],
                           np.stack([np.full_like(side, -_DIAG), _DIAG * inward], axis=1))
        plus_end = along == length - 1
        d[:, 2] = np.where(plus_end[:, None], [[1.0, 0.0]],
                           np.stack([np.full_like(side, _DIAG), _DIAG * inward], axis=1))
        if not long_x:
            d = d[:, :, ::-1]
        out[sel] = d
    return out


def section_modulus_mm3(width_mm: float, height_mm: float) -> float:
    """Elastic section modulus (mm^3) of a LEGO part's cross-section: a top of
    :data:`TOP_MM` over two side walls of :data:`WALL_MM`, ``width_mm`` wide and
    ``height_mm`` tall (the hollow underside's tubes ignored: on the safe side)."""
    top_a = width_mm * TOP_MM
    wall_h = height_mm - TOP_MM
    wall_a = 2 * WALL_MM * wall_h
    top_y, wall_y = height_mm - TOP_MM / 2, wall_h / 2
    area = top_a + wall_a
    ybar = (top_a * top_y + wall_a * wall_y) / area
    inertia = (width_mm * TOP_MM ** 3 / 12 + top_a * (top_y - ybar) ** 2
               + 2 * WALL_MM * wall_h ** 3 / 12 + wall_a * (wall_y - ybar) ** 2)
    return inertia / max(ybar, height_mm - ybar)


def bending_capacity_nmm(across_studs: int, layers: int, cell=(8.0, 8.0, 3.2)) -> float:
    """Bending moment (N mm) a LEGO part ``across_studs`` wide and ``layers`` plates tall
    takes across a section: :data:`ABS_STRENGTH_MPA` times :func:`section_modulus_mm3`."""
    return ABS_STRENGTH_MPA * section_modulus_mm3(across_studs * cell[0] - 0.2, layers * cell[2])


def printed_mass_g(volume_mm3: float, area_mm2: float, profile: dict[str, str] | None = None) -> float:
    """Mass (g) of a printed part of ``volume_mm3`` and surface ``area_mm2`` as the slicer
    prints it: a shell of the profile's perimeters times their extrusion width all round,
    the rest filled at the profile's ``fill_density``, in its ``filament_density``
    (PLA 1.24 g/cm^3, 2 perimeters of 0.45 mm, 15 % infill without a profile)."""
    cfg = profile or {}

    def number(key: str, default: float) -> float:
        try:
            return float(str(cfg.get(key, default)).rstrip("%").split(",")[0])
        except ValueError:
            return default
    density = number("filament_density", 1.24)
    fill = number("fill_density", 15.0) / 100.0
    shell_mm = number("perimeters", 2) * number("perimeter_extrusion_width", 0.45)
    shell = min(volume_mm3, area_mm2 * shell_mm)
    return density * (shell + fill * (volume_mm3 - shell)) / 1000.0


class SolverTrouble(RuntimeError):
    """HiGHS ended a force program without an answer (a numerical failure, not the input's)."""


@dataclass
class _Program:
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

        from core.lower_bound import INTERIOR_POINT
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
        _run(h)
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


def _work_words(subject: str) -> str:
    """:data:`PROGRAM_WORK` in words: "the N solver iterations <subject> given (...)"."""
    return f"the {PROGRAM_WORK:,} solver iterations {subject} given (about two minutes)"


#: Seconds a stopped run waits for the solver to stop (:func:`_run`).
STOP_WAIT_S = 0.2


def _run(h) -> None:
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


def analyse(layout: Layout, ground: str = "table", loads=(), printed=(), clamp=None,
            clutch_n: float = CLUTCH_N, profile: dict[str, str] | None = None,
            detail: bool = True, seconds: float | None = None) -> Forces:
    """The force verdict of ``layout`` standing on ``ground`` ("table" or "baseplate").

    ``loads`` are :class:`Load` (or "X0,Y0,Z0,X1,Y1,Z1:GRAMS" strings),
    ``printed`` the :class:`core.printed.PrintedPart` list (their masses;
    without it a printed part weighs as if solid PLA), ``clamp`` the
    (studs_ok, bottom_ok) masks of :func:`core.printed.clamp_masks` (None:
    every stud and socket whole), ``clutch_n`` the tension of one contact
    point in N, ``profile`` the slicer settings printed masses follow.
    ``detail`` False gives the verdict and the worst utilisation only (one
    small program), with ``utilisation`` and ``failures`` left empty.
    ``seconds`` (None: :data:`PROGRAM_WORK` per program, and past :data:`MAX_BODIES`
    bodies no whole program) is what the whole build's programs may take; given,
    a build past :data:`MAX_BODIES` that its parts and bands do not settle is
    solved as one program too (minutes for thousands of bricks).

    Promises: ``stable`` is True exactly when every body is held and the
    worst utilisation is at most 1; with ``detail`` every brick has a
    utilisation and ``failing_bricks`` are those above 1; ``layout`` is
    not changed.  Raises :class:`InputError` for an unknown ground, a
    clutch not > 0, a load that touches no brick, or ``seconds`` not > 0.
    """
    start = time.perf_counter()
    if seconds is not None and not (isinstance(seconds, (int, float)) and not isinstance(seconds, bool)
                                    and math.isfinite(seconds) and seconds > 0):
        raise InputError(f"--seconds {seconds!r} must be a number of seconds above 0")
    if ground not in GROUNDS:
        raise InputError(f"--ground {ground!r}: choose table or baseplate")
    if isinstance(clutch_n, bool) or not (isinstance(clutch_n, (int, float))
                                          and math.isfinite(clutch_n) and clutch_n > 0):
        raise InputError(f"--clutch {clutch_n!r} must be a force in N above 0")
    loads = [parse_load(x) for x in loads]
    if not layout.bricks:
        return Forces(True, ground, 0.0, clutch_n=float(clutch_n),
                      loads=[x.to_json() for x in loads], seconds=time.perf_counter() - start)
    model = _Model(layout, ground, loads, printed, clamp, float(clutch_n), profile)
    model.whole_seconds = seconds
    forces = model.verdict(detail)
    forces.seconds = time.perf_counter() - start
    return forces


def build_unchecked(verdict: Forces) -> str | None:
    """Why the partial builds of a layout whose verdict is ``verdict`` are not force-checked
    step by step, or None when they are (by :class:`BuildChecker`)."""
    if verdict.unchecked:
        return "the force check of the whole build was skipped, so was each step's"
    return None


def graph_only_why(bodies: int) -> str:
    """Why a build of ``bodies`` bricks and printed parts has steps checked by the brick graph
    only (:meth:`BuildChecker.stands` gave them NaN) when it has too many bodies for the
    programs (:attr:`BuildChecker.why` says it when the time budget ran out instead)."""
    return (f"{bodies} bricks and printed parts: a step that hangs would need a program of the "
            f"partial build, and more than {MAX_BODIES} take minutes each; " + _GRAPH_ONLY)


_GRAPH_ONLY = ("the steps that need one were checked by the brick graph only (joined to the "
               "ground), the others stand in pure compression")


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
        from core.lower_bound import INTERIOR_POINT
        h = self.highs
        if cold:
            h.clearSolver()
            h.setOptionValue("solver", INTERIOR_POINT)
            h.setOptionValue("run_crossover", "on")
        _run(h)
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
    answer (:class:`_Warm`).  Past :data:`EXACT_BODIES` bodies that is the
    program of the layout's hanging part on its supports (as
    :meth:`_Model._by_parts`, uncut, with :data:`BUILD_MARGIN_LEVELS` levels
    under it where they fit) while every present brick outside it
    rests on present cells: an upper bound of the worst utilisation, so a set
    it finds above :data:`FRAGILE` is solved again with the whole program.
    Past :data:`MAX_BODIES` bodies no program is solved: a set that would need
    one is checked by the brick graph only (:func:`graph_only_why`); so are the
    sets asked about once the programs have done more than ``budget`` units of work in
    all (:attr:`work`; None: :data:`BUILD_BUDGET`; :attr:`why` then says so).  The work is
    counted in the solver's iterations, not in seconds, so the same build gets the same
    answers on a busy machine as on an idle one.

    A set that holds the last set found standing at most :data:`FRAGILE` and adds to it
    only LEGO bricks borne on full columns (every cell under them filled by bricks of
    the set, down to the ground; :meth:`_borne`) needs no program either: the forces that
    held the smaller set still hold, and each new brick's weight goes straight down its
    columns in compression, through every body on the way at the same stud axis (no force
    or moment left over on them, nor any bending).  It gets the smaller set's utilisation,
    an upper bound of its own.
    """

    def __init__(self, layout: Layout, ground: str = "table", printed=(), clamp=None,
                 clutch_n: float = CLUTCH_N, profile: dict[str, str] | None = None,
                 budget: int | None = None, loads=()):
        self.layout = layout
        self.model = _Model(layout, ground, [parse_load(x) for x in loads], printed, clamp,
                            float(clutch_n), profile)
        self.model.propping = True
        self.budget = BUILD_BUDGET if budget is None else budget
        #: seconds the programs took in all (reported; the budget counts :attr:`work`)
        self.seconds = 0.0
        #: why sets that need a program are checked by the graph only (None: they are not)
        self.why: str | None = None if self.model.nbody <= MAX_BODIES else graph_only_why(
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
        self.programs = self.model.nbody <= MAX_BODIES
        if self.programs and self.model.nbody > EXACT_BODIES:
            low = self.model._lowest_layer()
            for margin in (BUILD_MARGIN_LEVELS, MARGIN_LEVELS):
                hanging, support, under = self.model._hanging_part(margin)
                if not np.any(low[hanging] == 0) and \
                        np.count_nonzero(hanging | support) <= PART_SHARE * self.model.nbody:
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
        # the last set found standing at most FRAGILE without props, and its utilisation;
        # per brick, the bricks of its full columns (or None: it is not borne on them)
        self._proven: tuple[np.ndarray, float] | None = None
        self._columns: dict[int, np.ndarray | None] = {}

    def stands(self, present, props=None) -> tuple[bool, float]:
        """(stands, worst utilisation) of the bricks ``present`` (a bool per brick of the
        layout, in its order): inf when some present brick is joined to nothing on the ground;
        (True, NaN) when it is joined to the ground but would need a program past
        :data:`MAX_BODIES` bodies, or past the budget, or its own program ran past
        :data:`PROGRAM_WORK` (checked by the brick graph only).  ``props`` ((n, 3) cells
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
                        + _GRAPH_ONLY)
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
        if propped is None and ok and worst <= FRAGILE:
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
        moment = m.mass_g[m.body_of[b]] * G / 1000.0 * span_mm / 4.0
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
            if worst <= FRAGILE:
                return True, worst
        if self._whole is None:
            self._whole = _Warm(m)
        worst = self._solve(self._whole, present, propped)
        if math.isnan(worst):                    # its own program ran past its work: the graph's
            return True, worst
        return bool(worst <= FAIL_ABOVE), worst

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
            return _worst(factor)
        if propped is not None:
            return math.inf
        # answer from a program of its own
        self.fresh += 1
        idx = np.flatnonzero(present)
        own = model._model_of(idx, model.support[model.body_of[idx]] if model.on_supports else None)
        verdict = own.verdict(detail=False)
        self._fresh_work += verdict.work
        return verdict.max_utilisation

def _worst(factor: float) -> float:
    """The worst utilisation of a largest load factor: its inverse; 0 for a structure that
    needs no clutch at all (the factor reached :data:`LOAD_FACTOR_CAP`), inf when it cannot
    carry even 1 / LOAD_FACTOR_CAP of its weight (it tips or floats)."""
    if factor >= LOAD_FACTOR_CAP * (1 - 1e-9):
        return 0.0
    return 1.0 / factor if factor > 1.0 / LOAD_FACTOR_CAP else math.inf


def _facet_under(points: np.ndarray, xy: np.ndarray, hull_of, hull_error):
    """(unit normal, offset) of the face of the lower convex hull of ``points`` (n, 3) under
    ``xy``, the plane ``normal . p + offset = 0``; None when ``xy`` lies outside the hull's
    plan (the structure tips).  Flat point sets are their own face."""
    pts = np.unique(np.round(points, 9), axis=0)
    if np.ptp(pts[:, 2]) <= 1e-9:
        try:
            plan = hull_of(pts[:, :2])
        except hull_error:
            return None
        if np.all(plan.equations[:, :2] @ xy + plan.equations[:, 2] <= 1e-9):
            return np.array([0.0, 0.0, -1.0]), float(pts[0, 2])
        return None
    try:
        hull = hull_of(pts)
    except hull_error:
        return None
    for eqn, simplex in zip(hull.equations, hull.simplices):
        if eqn[2] >= -1e-9:
            continue
        tri = pts[simplex][:, :2]
        m = np.array([tri[1] - tri[0], tri[2] - tri[0]]).T
        try:
            u, v = np.linalg.solve(m, xy - tri[0])
        except np.linalg.LinAlgError:
            continue
        if u >= -1e-9 and v >= -1e-9 and u + v <= 1 + 1e-9:
            return eqn[:3], float(eqn[3])
    return None


def _cut_margins(cuts: np.ndarray, axis: int, xy: np.ndarray, mass: np.ndarray,
                 rests: np.ndarray, resting: np.ndarray) -> np.ndarray:
    """Per cut ``c`` across ``axis`` (between cells ``c`` and ``c + 1``): how deep, in
    cells, each half's centre of mass lies inside the box of the support contacts under
    it, in x and in y, the least of the two halves' (negative: outside, so it tips; -inf:
    a half rests on nothing).  ``xy`` and ``mass`` are the bodies' centres in plan (cells)
    and masses; ``rests`` the support contacts' cells (n, 2) and ``resting`` the centre
    along ``axis`` of the body each holds (a contact goes with its body's half)."""
    out = np.full(len(cuts), -np.inf)
    for n, c in enumerate(cuts):
        line = c + 0.5
        worst = np.inf
        for body_side, rest_side in ((xy[:, axis] < line, resting < line),
                                     (xy[:, axis] >= line, resting >= line)):
            on = rests[rest_side]
            weight = mass[body_side].sum()
            if not len(on) or weight <= 0:
                worst = -np.inf
                break
            com = (mass[body_side, None] * xy[body_side]).sum(axis=0) / weight
            worst = min(worst, float(np.min(com - (on.min(axis=0) - 0.5))),
                        float(np.min(on.max(axis=0) + 0.5 - com)))
        out[n] = worst
    return out


def _reach(graph: sparse.csr_matrix, start: np.ndarray) -> np.ndarray:
    """The nodes ``start`` (bool) and every node reached from them along ``graph``'s edges."""
    seen = np.asarray(start, dtype=bool).copy()
    frontier = np.flatnonzero(seen)
    while len(frontier):
        nxt = np.unique(graph[frontier].indices)
        frontier = nxt[~seen[nxt]]
        seen[frontier] = True
    return seen


def _supported_below(lab: np.ndarray) -> bool:
    """Every filled cell of ``lab`` (bool grid) is in the bottom layer or on a filled cell."""
    return not np.any(lab[:, :, 1:] & ~lab[:, :, :-1])


#: Most bodies the force programs are solved for (beyond, a build that needs any pull and
#: that its hanging parts and height bands do not settle is reported unchecked): a
#: program's time grows faster than its build.
MAX_BODIES = 2500


#: A build of more bodies than this, some of them hanging, is checked by its hanging parts
#: (:meth:`_Model._by_parts`) before the whole program is solved.
EXACT_BODIES = 300
#: Up to MAX_BODIES, the hanging part is solved on its own only when it and its supports
#: are at most this share of the bodies (a build that hangs almost whole: the whole program).
PART_SHARE = 0.7
#: Most hanging bodies checked in parts.  A hanging piece that no cut splits is solved whole
#: only up to MERGED_BODIES: beyond, its one program takes many minutes.
MAX_HANGING = 20000
#: Work (:func:`solver_work`) one program of a whole build (or of a hanging part) may do
#: before the build is reported unchecked, and the height bands of one build in all
#: (:meth:`_Model._by_bands`).  Counted in iterations, not seconds, so that the verdict does
#: not depend on the machine's load; about two minutes on a 2-core machine.  The interior
#: point needs minutes on solid, overhanging builds of thousands of bricks.
PROGRAM_WORK = 120_000
#: Solver iterations the programs of one build's partial builds may run in all
#: (:class:`BuildChecker`); past them the steps that need one are checked by the brick graph
#: only (without a bound, the steps of a solid, overhanging build of thousands of bricks
#: would each solve a whole program).  Counted in iterations, not seconds, so that the
#: answer does not depend on the machine's load: about a minute of warm-started iterations
#: on a 2-core machine.
BUILD_BUDGET = 100_000
#: Levels of bricks under a hanging part that its program takes in (they may pull).
MARGIN_LEVELS = 2
#: Levels of bricks under the hanging part that the build steps' program of it takes in
#: (:class:`BuildChecker`; :data:`MARGIN_LEVELS` where that makes it too big a share): on
#: its supports, which only press, a slab being built on a wall two studs thick tips with
#: 2 levels, and each such step then needs the whole program.
BUILD_MARGIN_LEVELS = 4
#: Most bodies in one program of a hanging part (bigger ones are cut in plan)...
WINDOW_BODIES = 250
#: ...and of a group solved again with its neighbours when it does not stand alone...
MERGED_BODIES = 1200
#: Bodies in one height band of a build past MAX_BODIES that its hanging parts do not settle
#: (:meth:`_Model._by_bands`)...
BAND_BODIES = 400
#: ...up to this many bodies in all.
MAX_BANDED = 20000
#: ...while the bodies of all the groups solved stay within this many times the hanging ones
#: (cut too small, a roof's groups would be merged over and over).
EFFORT = 4
#: Levels of seated bodies a group that does not stand on its supports takes in, step by
#: step (:meth:`_Model._deepened`).
DEEPER_LEVELS = (4, 12, 32)
#: Below this worst utilisation a hanging part's bricks (and past EXACT_BODIES, a whole
#: build's) are each given its worst (an upper bound; their own utilisations would cost a
#: second program and stay in the dark range).
DETAIL_ABOVE = 0.25
#: Below this worst utilisation every brick of a build of any size is given the worst (an
#: upper bound): on the stress picture's scale, dark 0 to red 1, each is dark either way.
DARK_BELOW = 0.05

#: How the verdict of a big build with hanging parts was found (:meth:`_Model._by_parts`).
SUB_MEANS = ("the parts that hang (bricks with a cell over air, what rests on them and the "
             f"{MARGIN_LEVELS} levels of bricks under them) in programs of about {WINDOW_BODIES} "
             "bricks each, standing on the bricks under them, which only press, with no pull "
             "between two such parts; the rest of the build stands in pure compression. Those "
             "forces balance the whole build, so it stands; the worst utilisation is what they "
             "reach, at least the least possible. In a part whose worst is below "
             f"{DETAIL_ABOVE}, every brick is given that worst")


#: How the verdict of a big build that its hanging parts do not settle was found
#: (:meth:`_Model._by_bands`).
BAND_MEANS = ("height bands of about {BAND_BODIES} bricks, top down: each band one program standing "
              "on the bricks under it, whose studs hold, with the forces the bands above put on "
              "its bricks fixed. Those forces balance the whole build, so it stands; the worst "
              "utilisation is what they reach, at least the least possible. Every brick is given "
              "the worst of its band").replace("{BAND_BODIES}", str(BAND_BODIES))


#: A build prefix the hanging part's program finds above this is checked by the whole program
#: (build steps above it are fragile: the instructions warn).
FRAGILE = 0.8

#: Phase 2 bounds every joint's utilisation by phase 1's worst times 1 + this: held exactly
#: there the program has almost no interior, and HiGHS's interior point slows down many
#: times.  The utilisations it reports are then cut at the worst.
CAP_SLACK = 1e-4

#: Largest load factor the verdict looks for: a structure that carries this many times its
#: weight needs no clutch at all (worst utilisation 0).
LOAD_FACTOR_CAP = 1e5


class _Model:
    """Bodies, contacts and the programs of one :func:`analyse` call.

    Inside the programs lengths are in studs (8 mm) and forces in grams-force,
    so that the coefficients stay near 1."""

    def __init__(self, layout: Layout, ground: str, loads: list[Load], printed, clamp,
                 clutch_n: float, profile, support: np.ndarray | None = None, masses=None,
                 holding: np.ndarray | None = None, extra: np.ndarray | None = None):
        self.layout, self.ground, self.loads = layout, ground, loads
        self.clutch_n = clutch_n
        self.clutch = clutch_n / (G / 1000.0)                 # grams-force
        grid = layout.grid
        self.unit = float(grid.cell[0])
        self.cell = np.asarray(grid.cell, dtype=float) / self.unit
        self.origin = np.asarray(grid.origin, dtype=float) / self.unit
        bricks = layout.bricks
        n = len(bricks)
        self.lab = layout.labels()
        body_of = np.empty(n, dtype=np.int64)
        names: dict[str, int] = {}
        count = 0
        for idx, b in enumerate(bricks):
            if b.kind == "printed" and b.printed_part is not None:
                if b.printed_part not in names:
                    names[b.printed_part] = count
                    count += 1
                body_of[idx] = names[b.printed_part]
            else:
                body_of[idx] = count
                count += 1
        self.body_of, self.nbody, self.part_body = body_of, count, names
        self.blab = np.where(self.lab >= 0, body_of[np.maximum(self.lab, 0)], -1)
        self.sizes = np.array([b.size for b in bricks], dtype=np.int64).reshape(-1, 3)
        self.corners = np.array([b.cell for b in bricks], dtype=np.int64).reshape(-1, 3)
        self.printed_brick = np.array([b.kind == "printed" for b in bricks], dtype=bool)
        self.studs_ok, self.bottom_ok = (None, None) if clamp is None else (
            np.asarray(clamp[0], bool), np.asarray(clamp[1], bool))
        # a sub-structure (:meth:`_by_parts`) stands on bodies taken as rigid, which only
        # push up: no ground, and what they weigh and what rests on them is not asked
        self.on_supports = support is not None
        self.support = np.zeros(count, dtype=bool)
        if support is not None:
            self.support[body_of[np.asarray(support, dtype=bool)]] = True
        # supports whose studs also pull (the band under a band, :meth:`_by_bands`); the
        # others only press
        self.holds = np.zeros(count, dtype=bool)
        if holding is not None:
            self.holds[body_of[np.asarray(holding, dtype=bool)]] = True
        self.holds &= self.support
        # per body, a fixed force and moment about its centre of mass (grams-force, studs) that
        # the bands above put on it, scaled with the load factor as gravity is
        self.extra = np.zeros((count, 6)) if extra is None else np.asarray(extra, dtype=float)
        if masses is None:
            self._masses(printed, profile)
        else:
            self.mass_g, self.com, self.point_masses = masses
        self.held = self._held()
        self.topples: list[dict] = []
        # a band of :meth:`_by_bands` on the ground: the whole build rests flat on its
        # bottom layer, so the table carries there (the band's own weight is not all of it)
        self.flat_rest = False
        self.parent_bodies = self.parent_bricks = None       # set by :meth:`_model_of`
        self.band = None                     # a band's own bodies (:meth:`_by_bands`)
        # on a baseplate, whether the programs hold the points props may press up
        # (:class:`BuildChecker` sets it; on a table every point is there anyway)
        self.propping = False
        # seconds the whole build's programs may take (None: PROGRAM_WORK each, and no whole
        # program past MAX_BODIES bodies); :func:`analyse` sets it
        self.whole_seconds = None
        # the work (:func:`solver_work`) of the programs solved for this model so far, its
        # parts' and bands' included
        self.work = 0

    # -- masses ------------------------------------------------------------------------------
    def _masses(self, printed, profile) -> None:
        """Per body: mass (g) and centre of mass (studs), loads included; per brick the
        point masses resting on it (for its bending)."""
        bricks = self.layout.bricks
        lo, hi = self.layout.boxes_mm()
        centre = (lo + hi) / 2 / self.unit
        mass = np.zeros(self.nbody)
        moment = np.zeros((self.nbody, 3))
        by_part = {p.id: p for p in printed}
        for idx, b in enumerate(bricks):
            if b.kind == "printed" and b.printed_part is not None:
                continue
            m = MASS_G[b.part] if b.part in MASS_G else _solid_pla_g(hi[idx] - lo[idx])
            mass[self.body_of[idx]] += m
            moment[self.body_of[idx]] += m * centre[idx]
        for name, body in self.part_body.items():
            members = np.flatnonzero(self.body_of == body)
            part = by_part.get(name)
            if part is not None and part.mesh is not None and len(part.mesh.faces):
                m = printed_mass_g(float(part.mesh.volume), float(part.mesh.area), profile)
                com = np.asarray(part.mesh.center_mass, dtype=float) / self.unit
            else:
                m = sum(_solid_pla_g(hi[i] - lo[i]) for i in members)
                com = centre[members].mean(axis=0)
            mass[body] += m
            moment[body] += m * com
        points: dict[int, list] = {}
        for idx, b in enumerate(bricks):
            if b.load_g:
                points.setdefault(idx, []).append((centre[idx], float(b.load_g)))
        for load in self.loads:
            cells = _touched_cells(self.layout, load, self.lab)
            for c in cells:
                at = self.origin + (np.asarray(c) + 0.5) * self.cell
                points.setdefault(int(self.lab[c]), []).append((at, load.grams / len(cells)))
        for idx, items in points.items():
            for at, grams in items:
                mass[self.body_of[idx]] += grams
                moment[self.body_of[idx]] += grams * at
        self.point_masses = points
        self.mass_g = mass
        fallback = np.zeros((self.nbody, 3))
        np.add.at(fallback, self.body_of, centre)
        fallback /= np.maximum(np.bincount(self.body_of, minlength=self.nbody), 1)[:, None]
        self.com = np.where(mass[:, None] > 0, moment / np.maximum(mass, 1e-12)[:, None], fallback)

    # -- contacts ----------------------------------------------------------------------------
    def _stud_joints(self):
        """Cells (i, j, k) of every stud joint: lower body at k, upper at k + 1."""
        lower, upper = self.blab[:, :, :-1], self.blab[:, :, 1:]
        return np.nonzero((lower >= 0) & (upper >= 0) & (lower != upper))

    def _held(self) -> np.ndarray:
        """Per body: joined to the ground through joints (the others float)."""
        i, j, k = self._stud_joints()
        n = self.nbody
        ground = (np.flatnonzero(self.support) if self.on_supports
                  else np.unique(self.blab[:, :, 0][self.blab[:, :, 0] >= 0]))
        rows = np.concatenate([self.blab[i, j, k], ground])
        cols = np.concatenate([self.blab[i, j, k + 1], np.full(len(ground), n)])
        graph = sparse.coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n + 1, n + 1))
        _, comp = connected_components(graph, directed=False)
        return comp[:n] == comp[n]

    def _contact_points(self, i, j, k_up):
        """Contact points (m, 4, 3) in studs and validity (m, 4) of the studs under cells
        (i, j, k_up), shaped by the part whose underside is at k_up."""
        up = self.lab[i, j, k_up]
        dirs = contact_directions(self.sizes[up, 0], self.sizes[up, 1], i - self.corners[up, 0],
                                  j - self.corners[up, 1], self.printed_brick[up])
        centre = self.origin[:2] + (np.stack([i, j], axis=1) + 0.5) * self.cell[:2]
        xy = centre[:, None, :] + CONTACT_RADIUS * self.cell[:2] * dirs
        z = self.origin[2] + k_up * self.cell[2]
        pts = np.concatenate([xy, np.broadcast_to(z[:, None, None], xy.shape[:2] + (1,))], axis=2)
        return pts, ~np.isnan(dirs[:, :, 0])

    # -- the programs ------------------------------------------------------------------------
    def _solve(self, prog: _Program, limited: bool = True) -> tuple[str, np.ndarray | None]:
        """:meth:`_Program.solve` within :data:`PROGRAM_WORK` (or, given, within
        ``whole_seconds``; not ``limited``: however long it takes), its work added to
        :attr:`work`."""
        if not limited:
            out = prog.solve()
        elif self.whole_seconds is None:
            out = prog.solve(work=PROGRAM_WORK)
        else:
            out = prog.solve(seconds=self.whole_seconds)
        self.work += prog.spent
        return out

    def _limit_words(self) -> str:
        """What one program is given, in words (:meth:`_solve`)."""
        if self.whole_seconds is not None:
            return f"the {self.whole_seconds:.0f} s it is given"
        return _work_words("it is")

    def verdict(self, detail: bool) -> Forces:
        """:meth:`_verdict`, with :attr:`Forces.work` the work of every program it solved
        (its parts' and bands' included)."""
        start = self.work
        out = self._verdict(detail)
        out.work = self.work - start
        return out

    def _verdict(self, detail: bool) -> Forces:
        """A build whose every cell rests on a cell or the ground stands without any pull
        (no program).  Otherwise phase 1: the largest load factor (gravity and loads times
        it) the joints carry with their clutch; the worst utilisation is its inverse.  Phase
        2 (``detail``): at the real loads, each joint's utilisation, the sum of them least,
        none above phase 1's worst; past :data:`EXACT_BODIES` a build standing below
        :data:`DETAIL_ABOVE`, or standing past :data:`MAX_BODIES` (solved whole only when
        given ``whole_seconds``), gives each brick that worst instead."""
        if not self.on_supports and _supported_below(self.blab >= 0):
            # every cell rests on a cell (or the ground): it all stands in pure compression
            util = {b.id: 0.0 for b in self.layout.bricks} if detail else {}
            return self._forces(True, 0.0, util, [], [], [])
        fallen = self._falls_over()
        if fallen is not None:
            return fallen
        where = ""
        if self.nbody > EXACT_BODIES and not self.on_supports:
            parted, where = self._by_parts(detail)
            if parted is not None:
                return parted
        if self.nbody > MAX_BODIES and not self.on_supports and self.nbody <= MAX_BANDED:
            banded, why = self._by_bands()
            if banded is not None:
                return banded
            where = f"{where}; {why}" if where else why
        if self.nbody > MAX_BODIES and not self.on_supports and self.whole_seconds is None:
            out = self._forces(False, math.nan, {}, [], [], [])
            out.unchecked = (f"{self.nbody} bricks and printed parts, some of them overhanging: more "
                             f"than the {MAX_BODIES} the force check solves in one program (it would "
                             "take minutes)" + (f", and {where}" if where else "")
                             + "; the brick graph's verdict stands alone (python -m core stability "
                             "layout.json --seconds 900 solves it as one program)")
            return out
        prog, parts = self._program(detail=False)
        status, x = self._solve(prog)
        if status == "limit":
            out = self._forces(False, math.nan, {}, [], [], [])
            out.unchecked = (f"{self.nbody} bricks and printed parts: the force program of the "
                             f"whole build ran past {self._limit_words()}"
                             "; the brick graph's verdict stands alone")
            return out
        factor = float(x[parts["factor"]]) if status == "optimal" else 0.0
        worst = _worst(factor)
        floats = ~self.held[self.body_of]
        stable = bool(worst <= FAIL_ABOVE and not floats.any())
        if not detail:
            failing = [b.id for b, f in zip(self.layout.bricks, floats) if f]
            return self._forces(stable, worst, {}, sorted(failing), sorted(failing), [])
        def each_worst() -> Forces:
            return self._forces(stable, worst, {b.id: worst for b in self.layout.bricks}, [], [], [])

        if stable and (worst < DARK_BELOW or self.nbody > EXACT_BODIES
                       and (worst < DETAIL_ABOVE or self.nbody > MAX_BODIES)):
            # each brick gets the worst (as a hanging part's do): on big builds phase 2 costs
            # as much as phase 1 or more
            return each_worst()
        prog, parts = self._program(detail=True, cap=worst)
        # unless it stands, what fails and why, however long it takes
        status, x = self._solve(prog, limited=stable or self.nbody > MAX_BODIES)
        if status == "limit":
            return each_worst()                  # the worst bounds every brick's
        residual = np.zeros(self.nbody)
        if status != "optimal":
            slack = prog.columns(12 * self.nbody, 0.0, np.inf, 1e3)
            prog.put(np.repeat(parts["eq"], 2), slack, np.tile([1.0, -1.0], 6 * self.nbody))
            status, x = self._solve(prog, limited=False)
            if status != "optimal":
                raise RuntimeError(f"the force program with slack ended {status}")
            residual = np.abs(x[slack]).reshape(self.nbody, 12).sum(axis=1)
        return self._detail(x, parts, stable, worst, self._tipping(residual > 1e-6))

    def _falls_over(self) -> Forces | None:
        """On a table, a build whose every structure joined to the ground tips over as a rigid
        body (:meth:`resting`) fails whatever its joints do: the program's own answer
        (infinite utilisation, every brick tipping or floating) without solving it, so a
        toppling build of any size is judged at once.  None when something could stand."""
        if self.ground != "table" or self.on_supports:
            return None
        # every structure has table points under its lowest cells: none carries exactly
        # when each one tips
        active, self.tilt = self.resting(np.ones(self.nbody, dtype=bool))
        if active.any() or not self.topples:
            return None
        n = len(self.layout.bricks)
        floats = ~self.held[self.body_of]
        mode = np.where(floats, "floats", "tips")
        ids = [b.id for b in self.layout.bricks]
        failures = sorted((self._failure(b, math.inf, str(mode[b])) for b in range(n)),
                          key=lambda f: f["brick"])
        return self._forces(False, math.inf, {b: math.inf for b in ids}, sorted(ids), sorted(ids),
                            failures)

    def _lowest_layer(self) -> np.ndarray:
        """Per body, the lowest layer of its cells (0: on the ground)."""
        low = np.full(self.nbody, np.iinfo(np.int64).max)
        np.minimum.at(low, self.body_of, self.corners[:, 2])
        return low

    def _under(self) -> sparse.csr_matrix:
        """``under[b]`` lists the bodies that body ``b`` rests on (a cell right under one of its
        cells)."""
        lower, upper = self.blab[:, :, :-1], self.blab[:, :, 1:]
        n = self.nbody
        pairs = np.stack([lower.ravel(), upper.ravel()], 1)
        pairs = np.unique(pairs[(pairs[:, 0] >= 0) & (pairs[:, 1] >= 0) & (pairs[:, 0] != pairs[:, 1])],
                          axis=0)
        return sparse.csr_matrix((np.ones(len(pairs)), (pairs[:, 1], pairs[:, 0])), shape=(n, n))

    def _hanging_part(self, margin: int = MARGIN_LEVELS) -> tuple[np.ndarray, np.ndarray, sparse.csr_matrix]:
        """(hanging, support, under) of the bodies: *hanging* are those with a cell over air
        (not on the ground), every body resting on one of them (over and over), and
        ``margin`` levels of bodies under them off the ground with what rests on those;
        *support* the other bodies right under a hanging one; ``under[b]`` lists the bodies
        ``b`` rests on.  The bodies that are not hanging have every cell on a cell or
        on the ground, and nothing hanging rests on them but on a support."""
        lower, upper = self.blab[:, :, :-1], self.blab[:, :, 1:]
        n = self.nbody
        seeds = np.zeros(n, dtype=bool)
        seeds[np.unique(upper[(lower < 0) & (upper >= 0)])] = True
        under = self._under()
        over = under.T.tocsr()
        low = self._lowest_layer()
        hanging = _reach(over, seeds)
        for _ in range(margin):
            more = np.unique(under[np.flatnonzero(hanging)].indices)
            more = more[~hanging[more] & (low[more] >= 1)]
            if not len(more):
                break
            hanging[more] = True
            hanging = _reach(over, hanging)
        support = np.zeros(n, dtype=bool)
        support[under[np.flatnonzero(hanging)].indices] = True
        return hanging, support & ~hanging, under

    def _windows(self, hanging: np.ndarray, support: np.ndarray,
                 under: sparse.csr_matrix) -> list[np.ndarray]:
        """The hanging bodies in groups: each connected piece, and past :data:`MAX_BODIES`
        bodies cut in two across its longer side in plan until at most :data:`WINDOW_BODIES`.  A cut goes
        through the middle 40 % where both halves' centres of mass lie deepest inside the
        supports under them, in both directions (:func:`_cut_margins`): supports only press,
        so a half whose weight falls outside them tips (a bridge cut in mid-span; a roof cut
        along a row of pillars, which leaves a strip on that row alone).  A piece that no
        cut leaves with two such halves stays whole."""
        idx = np.flatnonzero(hanging)
        _, comp = connected_components(under[idx][:, idx], directed=False)
        lower, upper = self.blab[:, :, :-1], self.blab[:, :, 1:]
        si, sj, sk = np.nonzero((upper >= 0) & (lower >= 0))
        on = hanging[upper[si, sj, sk]] & support[lower[si, sj, sk]]
        rest_body, rest_ij = upper[si[on], sj[on], sk[on]], np.stack([si[on], sj[on]], 1)
        centre = (self.com[:, :2] - self.origin[:2]) / self.cell[:2]       # in cells
        out = []
        todo = [idx[comp == c] for c in np.unique(comp)]
        while todo:
            group = todo.pop()
            if len(group) <= WINDOW_BODIES or self.nbody <= MAX_BODIES:
                out.append(group)
                continue
            xy = centre[group]
            axis = int(np.argmax(np.ptp(xy, axis=0)))
            lo, mid, hi = np.quantile(xy[:, axis], [0.3, 0.5, 0.7])
            cuts = np.arange(math.ceil(lo), math.floor(hi) + 1)
            mine = np.isin(rest_body, group)
            margin = _cut_margins(cuts, axis, xy, self.mass_g[group], rest_ij[mine],
                                  centre[rest_body[mine], axis])
            if not len(cuts) or margin.max() <= 0:
                out.append(group)                # every cut would leave a half that tips
                continue
            # the deepest-seated halves, nearest the middle among equals
            off_middle = np.abs(cuts + 0.5 - mid) / (4 * max(hi - lo, 1.0))
            cut = cuts[np.argmax(np.minimum(margin, 2.0) - off_middle)] + 0.5
            left = xy[:, axis] < cut
            todo += [group[left], group[~left]]
        return self._reattached(sorted(out, key=lambda g: int(g[0])), support, under)

    def _reattached(self, groups: list[np.ndarray], support: np.ndarray,
                    under: sparse.csr_matrix) -> list[np.ndarray]:
        """``groups`` with every body that a cut left joined to no support of its own group
        moved to a group it is joined to (a few passes): alone it would float."""
        if len(groups) < 2:
            return groups
        joined = (under + under.T).tocsr()
        window = np.full(self.nbody, -1)
        for w, g in enumerate(groups):
            window[g] = w
        for _ in range(4):
            moved = False
            for w in range(len(groups)):
                mine = np.flatnonzero(window == w)
                if not len(mine):
                    continue
                rests = np.zeros(self.nbody, dtype=bool)
                rests[mine] = np.asarray((joined[mine].multiply(support[None, :].astype(float))).sum(axis=1)).ravel() > 0
                held = _reach(joined[:, mine][mine].tocsr(), rests[mine])
                for body in mine[~held].tolist():
                    near = window[joined[body].indices]
                    near = near[(near >= 0) & (near != w)]
                    if len(near):
                        window[body] = int(np.bincount(near).argmax())
                        moved = True
            if not moved:
                break
        out = [np.flatnonzero(window == w) for w in range(len(groups))]
        return [g for g in out if len(g)]

    def _by_parts(self, detail: bool) -> tuple[Forces | None, str]:
        """The verdict from the hanging parts alone (:meth:`_hanging_part`), each group of
        :meth:`_windows` one program standing on its supports, which only press: their own
        cells rest on cells down to the ground, so what presses on them goes straight down.
        Forces between two groups are held at zero; a group that does not stand so is
        solved again with the group it shares most joints with, up to
        :data:`MERGED_BODIES` and within :data:`EFFORT` (past :data:`MAX_BODIES` only: below,
        the whole program answers instead).  Put together,
        the groups' forces and pure compression elsewhere balance every body, so a build
        whose every group stands stands, with at most the groups' worst utilisation (the
        whole program's may be lower).  With ``detail``, a group whose worst is below
        :data:`DETAIL_ABOVE` gives each of its bricks that worst.  Returns (the verdict, "")
        then, else (None, where a group does not stand)."""
        hanging, support, under = self._hanging_part()
        if self.nbody <= MAX_BODIES and np.count_nonzero(hanging | support) > PART_SHARE * self.nbody:
            return None, ""                      # hardly smaller than the whole program
        if hanging.sum() > MAX_HANGING:
            return None, (f"its hanging part has {int(hanging.sum())} bricks, more than the "
                          f"{MAX_HANGING} checked in parts")
        groups = dict(enumerate(self._windows(hanging, support, under)))
        big = max(groups.values(), key=len)
        if len(big) > MERGED_BODIES:
            lay = self.layout.bricks[int(np.flatnonzero(np.isin(self.body_of, big))[0])]
            return None, (f"its hanging part from layer {lay.cell[2] + 1} (cell {lay.cell[0]}, "
                          f"{lay.cell[1]}) is one piece of {len(big)} bricks that no cut in plan "
                          f"splits into halves standing on their supports, more than the "
                          f"{MERGED_BODIES} solved in one program of a part")
        window = np.full(self.nbody, -1)
        for w, g in groups.items():
            window[g] = w
        pairs = sparse.triu(under + under.T).tocoo()
        solved: dict[int, Forces] = {}
        todo = sorted(groups)
        effort = 0
        # seated bodies a group took in (:meth:`_deepened`), and that group's (bodies, supports)
        claimed = hanging.copy()
        deep: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        while todo:
            w = todo.pop(0)
            try:
                f = self._window(groups[w], support, under, False)
            except SolverTrouble:                # as if it did not stand: merged or the whole
                f = self._forces(False, math.inf, {}, [], [], [])
            if f.unchecked:
                return None, (f"a program of {len(groups[w])} of its hanging bricks ran past "
                              + _work_words("it is"))
            effort += len(groups[w])
            if not f.stable and self.nbody > MAX_BODIES:
                f, members, below = self._deepened(groups[w], hanging, claimed, under)
                if f.stable:
                    claimed[members] = True
                    deep[w] = (members, below)
            if f.stable:
                solved[w] = f
                continue
            a, b = window[pairs.row], window[pairs.col]
            near = np.concatenate([b[(a == w) & (b >= 0) & (b != w)], a[(b == w) & (a >= 0) & (a != w)]])
            # with the group it shares most joints with
            touch = {int(np.bincount(near).argmax())} if len(near) else set()
            merged = np.concatenate([groups[v] for v in sorted(touch | {w})])
            # the whole program answers builds it can solve: merging would cost more
            if (not touch or len(merged) > MERGED_BODIES or self.nbody <= MAX_BODIES
                    or effort + len(merged) > EFFORT * int(hanging.sum())):
                lay = self.layout.bricks[int(np.flatnonzero(np.isin(self.body_of, groups[w]))[0])]
                worst = "infinite" if not math.isfinite(f.max_utilisation) else f"{f.max_utilisation:.2f}"
                count = f"{len(groups[w])} brick{'s' if len(groups[w]) != 1 else ''}"
                return None, (f"the hanging part of {count} from layer {lay.cell[2] + 1} "
                              f"(cell {lay.cell[0]}, {lay.cell[1]}) does not stand on what is under "
                              f"it alone (utilisation {worst})")
            for v in touch | {w}:
                groups.pop(v)
                solved.pop(v, None)
                if v in todo:
                    todo.remove(v)
            new = max(window) + 1
            window[merged] = new
            groups[new] = np.sort(merged)
            todo.insert(0, new)
        util = {b.id: 0.0 for b in self.layout.bricks} if detail else {}
        for w, f in solved.items():
            if not detail:
                continue
            members, below = deep.get(w, (groups[w], support))
            if f.max_utilisation >= DETAIL_ABOVE:
                try:
                    f = self._window(members, below, under, True)
                except SolverTrouble:            # each brick keeps the group's worst
                    pass
            mine = [self.layout.bricks[i].id for i in np.flatnonzero(np.isin(self.body_of, members))]
            util.update((b, f.utilisation.get(b, f.max_utilisation)) for b in mine)
        out = self._forces(True, max(f.max_utilisation for f in solved.values()), util, [], [], [])
        out.sub_structures = len(solved)
        return out, ""

    def _deepened(self, group: np.ndarray, hanging: np.ndarray, claimed: np.ndarray,
                  under: sparse.csr_matrix) -> tuple[Forces, np.ndarray, np.ndarray]:
        """The verdict of the bodies ``group`` with the seated bodies under them taken in,
        :data:`DEEPER_LEVELS` levels at a time (never a body on the ground nor one
        ``claimed`` by another group), until it stands or :data:`MERGED_BODIES`; and the
        bodies and support mask it was found with.  A strip of roof that rests on a wall
        two studs thick tips on supports that only press, where the wall's own studs,
        far enough down, hold it (seen on a 2 m hollow cube).  The bodies taken in carry
        this group's forces only: what other groups press on them goes straight down."""
        low = self._lowest_layer()
        inside = np.zeros(self.nbody, dtype=bool)
        inside[group] = True
        f = None
        for levels in DEEPER_LEVELS:
            for _ in range(levels):
                more = np.unique(under[np.flatnonzero(inside)].indices)
                more = more[~inside[more] & ~claimed[more] & (low[more] >= 1)]
                if not len(more):
                    break
                inside[more] = True
            members = np.flatnonzero(inside)
            if len(members) > MERGED_BODIES:
                break
            below = ~inside & ~hanging
            try:
                f = self._window(members, below, under, False)
            except SolverTrouble:
                f = None
            if f is not None and f.stable:
                return f, members, below
            if f is not None and f.unchecked:
                break
        return (f if f is not None else self._forces(False, math.inf, {}, [], [], [])), group, hanging

    def _by_bands(self) -> tuple[Forces | None, str]:
        """The verdict of the whole build solved top down in height bands of about
        :data:`BAND_BODIES` bodies.  Each band is one program standing on the bodies right
        under it, whose studs hold as any stud does (the bottom band stands on the ground);
        the forces it puts on them (at the real loads) are then fixed loads of the band
        below.  A band that does not stand so is solved again together with the band above
        it, up to :data:`MERGED_BODIES` bodies.

        Put together, the bands' forces balance every body with every joint within its
        strength at the bands' worst utilisation: when every band stands the build stands,
        with at most that worst (the whole program's may be lower).  For a build that rests
        flat on its bottom layer as a whole (:meth:`_falls_over` found nothing tipping).
        Returns (the verdict, each brick given its band's worst, "") or (None, where a band
        does not stand or could not be solved)."""
        start = self.work
        under = self._under()
        low = self._lowest_layer()
        band = self._bands(under, low)
        extra = np.zeros((self.nbody, 6))
        pressed: dict[int, list] = {}
        done: list[tuple[np.ndarray, Forces, dict, dict]] = []
        effort = 0
        order = sorted(set(band.tolist()))
        t = 0
        while t < len(order):
            members = np.flatnonzero(band == order[t])
            below = np.zeros(self.nbody, dtype=bool)
            below[under[members].indices] = True
            below[members] = False
            own = np.isin(self.body_of, members)             # per brick: of this band
            bricks = np.flatnonzero(own | below[self.body_of])
            ground = bool((low[members] == 0).any())
            sub = self._model_of(bricks, None if ground else below[self.body_of[bricks]],
                                 holding=below[self.body_of[bricks]], extra=extra, pressed=pressed)
            sub.flat_rest = True
            sub.band = np.isin(sub.parent_bodies, members)
            effort += len(members)
            try:
                f, push, studs = sub._carried()
            except SolverTrouble:
                f, push, studs = self._forces(False, math.inf, {}, [], [], []), {}, {}
            self.work += sub.work
            if self.work - start > PROGRAM_WORK:
                return None, ("solved in height bands, its bands' programs ran past "
                              + _work_words("they are") + " in all")
            if f.unchecked:
                return None, (f"a program of a band of {len(members)} bricks ran past "
                              + _work_words("it is"))
            if f.stable:
                for body, force in push.items():
                    extra[body] += force
                for brick, items in studs.items():
                    pressed.setdefault(brick, []).extend(items)
                done.append((members, f, push, studs))
                t += 1
                continue
            mine = np.flatnonzero(own)
            lay = self.layout.bricks[int(mine[np.argmin(self.corners[mine, 2])])]
            worst = "infinite" if not math.isfinite(f.max_utilisation) else f"{f.max_utilisation:.2f}"
            why = (f"solved in height bands, its band of {len(members)} bricks from layer "
                   f"{lay.cell[2] + 1} (cell {lay.cell[0]}, {lay.cell[1]}) does not stand on the "
                   f"bricks under it with the forces of the bands above (utilisation {worst})")
            if t == 0 or effort > EFFORT * self.nbody:
                return None, why
            above, _, gone, gone_studs = done.pop()    # solve it again with the band above
            if len(above) + len(members) > MERGED_BODIES:
                return None, why
            for body, force in gone.items():
                extra[body] -= force
            for brick, items in gone_studs.items():
                pressed[brick] = pressed[brick][:len(pressed[brick]) - len(items)]
            band[members] = order[t - 1]
            order.pop(t)
            t -= 1
        util = {}
        for members, f, _, _ in done:
            util.update((self.layout.bricks[i].id, f.max_utilisation)
                        for i in np.flatnonzero(np.isin(self.body_of, members)))
        out = self._forces(True, max(f.max_utilisation for _, f, _, _ in done), util, [], [], [])
        out.bands = len(done)
        return out, ""

    def _bands(self, under: sparse.csr_matrix, low: np.ndarray) -> np.ndarray:
        """Per body, its band of :meth:`_by_bands` (0 the top one): whole layers from the top,
        about :data:`BAND_BODIES` bodies each.  A body is never in a band above one it rests
        on (a printed part reaching down moves the body under it down).  Then a body that
        nothing joins, within its band, to a body of a band below or to the ground moves up a
        band, and so does what rests on it: held only through the band above, under forces
        fixed without it, it would float."""
        layers, counts = np.unique(low, return_counts=True)
        edges = np.zeros(len(layers), dtype=np.int64)
        size = current = 0
        for n in range(len(layers) - 1, -1, -1):
            if size >= BAND_BODIES:
                current, size = current + 1, 0
            edges[n] = current
            size += counts[n]
        band = edges[np.searchsorted(layers, low)]
        pairs = under.tocoo()
        upper, lower = pairs.row, pairs.col
        for _ in range(self.nbody):
            before = band.copy()
            np.maximum.at(band, lower, band[upper])
            if np.array_equal(before, band):
                break
        for _ in range(self.nbody):
            anchor = low == 0
            anchor[upper[band[lower] > band[upper]]] = True
            same = band[upper] == band[lower]
            graph = sparse.coo_matrix((np.ones(int(same.sum())), (upper[same], lower[same])),
                                      shape=(self.nbody, self.nbody))
            _, comp = connected_components(graph, directed=False)
            held = np.isin(comp, comp[anchor])
            loose = ~held & (band > 0)
            if not loose.any():
                break
            band[loose] -= 1
            for _ in range(self.nbody):
                before = band.copy()
                np.minimum.at(band, upper, band[lower])
                if np.array_equal(before, band):
                    break
        return band

    def _carried(self) -> tuple[Forces, dict | None, dict | None]:
        """A band of :meth:`_by_bands` (its bodies :attr:`band`, a bool per body; the others
        the supports under it): the verdict of phase 1 and, when it stands, phase 2's
        forces at the real loads (each joint carrying only what it must).  Of those, it
        returns the force and moment the band's bodies put on each body outside it (parent
        body -> 6 numbers, as :attr:`extra`) and what each stud under a band body presses on
        a brick outside (parent brick -> [(point, grams)], as :attr:`point_masses`); None
        when it does not stand."""
        prog, parts = self._program(detail=False)
        status, x = self._solve(prog)
        if status == "limit":
            out = self._forces(False, math.nan, {}, [], [], [])
            out.unchecked = "limit"
            return out, None, None
        factor = float(x[parts["factor"]]) if status == "optimal" else 0.0
        worst = _worst(factor)
        out = self._forces(bool(worst <= FAIL_ABOVE and self.held.all()), worst, {}, [], [], [])
        if not out.stable:
            return out, None, None
        prog, parts = self._program(detail=True, cap=worst)
        status, x = self._solve(prog)
        if status != "optimal":
            out.stable = False
            out.unchecked = "limit" if status == "limit" else None
            return out, None, None
        eq = parts["eq"]
        inside = self.band
        mat = prog.matrix().tocoo()
        at = (mat.row >= eq[0]) & (mat.row < eq[0] + len(eq)) & (mat.col != parts["factor"])
        rows, cols, vals = mat.row[at] - eq[0], mat.col[at], mat.data[at]
        body = rows // 6
        touches_in = np.zeros(prog.ncol, dtype=bool)
        touches_out = np.zeros(prog.ncol, dtype=bool)
        touches_in[cols[inside[body]]] = True
        touches_out[cols[~inside[body]]] = True
        across = touches_in[cols] & touches_out[cols] & ~inside[body]
        acted = np.zeros((self.nbody, 6))
        np.add.at(acted, (body[across], rows[across] % 6), vals[across] * x[cols[across]])
        push = {int(self.parent_bodies[b]): acted[b] for b in np.unique(body[across])}
        i, j, k = parts["joints"]
        lower, upper = self.blab[i, j, k], self.blab[i, j, k + 1]
        at = np.flatnonzero(inside[upper] & ~inside[lower])
        net = x[parts["studs"]["net"]][at]
        xy = self.origin[:2] + (np.stack([i[at], j[at]], 1) + 0.5) * self.cell[:2]
        z = self.origin[2] + (k[at] + 1) * self.cell[2]
        studs: dict[int, list] = {}
        for n, brick in enumerate(self.lab[i[at], j[at], k[at]].tolist()):
            studs.setdefault(int(self.parent_bricks[brick]), []).append(
                (np.array([xy[n, 0], xy[n, 1], z[n]]), float(net[n])))
        return out, push, studs

    def _window(self, group: np.ndarray, support: np.ndarray, under: sparse.csr_matrix,
                detail: bool) -> Forces:
        """The verdict of the bodies ``group`` on the supports right under them (its
        programs' work added to :attr:`work`)."""
        f = self._sub_model(group, support, under)[0].verdict(detail)
        self.work += f.work
        return f

    def _sub_model(self, group: np.ndarray, support: np.ndarray,
                   under: sparse.csr_matrix) -> tuple["_Model", np.ndarray]:
        """The model of the bodies ``group`` on the bodies of ``support`` right under them,
        and its bricks' indices in this model's layout."""
        below = np.zeros(self.nbody, dtype=bool)
        below[under[group].indices] = True
        below &= support
        inside = np.zeros(self.nbody, dtype=bool)
        inside[group] = True
        members = np.flatnonzero((inside | below)[self.body_of])
        return self._model_of(members, below[self.body_of[members]]), members

    def _model_of(self, members: np.ndarray, support: np.ndarray | None,
                  holding: np.ndarray | None = None, extra: np.ndarray | None = None,
                  pressed: dict | None = None) -> "_Model":
        """A model of this model's bricks ``members`` (indices; whole bodies) alone, their
        masses and loads as here: standing on the ground, or (``support``, a bool per
        member) on those of them that are supports, in the box of their bricks.  Supports
        whose studs may pull too are ``holding`` (a bool per member; the others only press);
        ``extra`` (per body of this model) is a fixed force and moment on a body and
        ``pressed`` (brick index -> [(point, grams)]) where it presses on a brick's studs,
        both put there by bricks left out (:meth:`_by_bands`)."""
        lo = self.corners[members].min(axis=0)
        if support is None:
            lo[2] = 0                                          # the ground stays where it is
        hi = (self.corners[members] + self.sizes[members]).max(axis=0)
        bricks = [dataclasses.replace(self.layout.bricks[i],
                                      cell=tuple(int(c - o) for c, o in zip(self.layout.bricks[i].cell, lo)))
                  for i in members]
        filled = np.zeros(tuple(int(v) for v in hi - lo), dtype=bool)
        for b in bricks:
            filled[b.slices()] = True
        grid = self.layout.grid
        cell = np.asarray(grid.cell, dtype=float)
        sub = Layout(Grid(np.asarray(grid.origin, dtype=float) + lo * cell, cell, filled), bricks)
        box = tuple(slice(a, b) for a, b in zip(lo, hi))
        clamp = None if self.studs_ok is None else (self.studs_ok[box], self.bottom_ok[box])
        bodies = self.body_of[members]
        first = np.unique(bodies, return_index=True)[1]
        full = bodies[np.sort(first)]                      # the sub-model's bodies, in its order
        pressed = pressed or {}
        points = {n: self.point_masses.get(i, []) + pressed.get(i, [])
                  for n, i in enumerate(members.tolist()) if i in self.point_masses or i in pressed}
        model = _Model(sub, self.ground, [], (), clamp, self.clutch_n, None, support=support,
                       masses=(self.mass_g[full], self.com[full], points), holding=holding,
                       extra=None if extra is None else extra[full])
        model.parent_bodies, model.parent_bricks = full, members
        return model

    def _tipping(self, pushed: np.ndarray) -> np.ndarray:
        """Per body: in a structure that tips as a whole.  Phase 2 lets every joint pull as
        hard as it must, so what still cannot balance (``pushed``: the bodies the slack had to
        push) is a rigid structure whose weight falls outside its support: all of it tips."""
        if not pushed.any():
            return pushed
        i, j, k = self._stud_joints()
        a, b = self.blab[i, j, k], self.blab[i, j, k + 1]
        graph = sparse.coo_matrix((np.ones(len(a)), (a, b)), shape=(self.nbody, self.nbody))
        _, comp = connected_components(graph, directed=False)
        return np.isin(comp, comp[pushed])

    def _program(self, detail: bool, cap: float = math.inf):
        """The LP of a phase: equilibrium rows of every held body, contacts, bending."""
        prog = _Program()
        parts: dict = {}
        if detail:
            factor = prog.columns(1, 1.0, 1.0)[0]
        else:
            factor = prog.columns(1, 0.0, LOAD_FACTOR_CAP, -1.0)[0]
        parts["factor"] = factor
        free = np.repeat(self.support, 6)                   # a support's balance is not asked
        eq = prog.new_rows(6 * self.nbody, np.where(free, -np.inf, 0.0), np.where(free, np.inf, 0.0))
        parts["eq"] = eq
        held = self.held
        prog.put(eq[6 * np.flatnonzero(held) + 2], factor, -self.mass_g[held])
        loaded = np.flatnonzero(held & ~self.support & np.any(self.extra != 0, axis=1))
        for axis in range(6):
            prog.put(eq[6 * loaded + axis], factor, self.extra[loaded, axis])
        zcap = np.inf if not math.isfinite(cap) else max(cap, 1.0 / LOAD_FACTOR_CAP) * (1 + CAP_SLACK)
        i, j, k = self._stud_joints()
        lower_b, upper_b = self.blab[i, j, k], self.blab[i, j, k + 1]
        keep = held[lower_b] & held[upper_b] & ~(self.support[lower_b] & self.support[upper_b])
        i, j, k, lower_b, upper_b = i[keep], j[keep], k[keep], lower_b[keep], upper_b[keep]
        press_only = self.support & ~self.holds
        pull_ok = ~(press_only[lower_b] | press_only[upper_b])    # most supports only press
        if self.studs_ok is not None:
            pull_ok &= self.studs_ok[i, j, k] & self.bottom_ok[i, j, k + 1]
        parts["joints"] = (i, j, k)
        pts, valid = self._contact_points(i, j, k + 1)
        parts["studs"] = self._vertical(prog, eq, pts, valid, upper_b, lower_b, pull_ok,
                                        detail, zcap)
        self._shear(prog, eq, np.stack([i, j], 1), k + 1, upper_b, lower_b)
        gi, gj = np.nonzero(self.blab[:, :, 0] >= 0) if not self.on_supports else (
            np.zeros(0, np.int64), np.zeros(0, np.int64))
        parts["ground_cells"] = (gi, gj)
        gb = self.blab[gi, gj, 0]
        if self.on_supports:
            parts["base"] = parts["table"] = None
        elif self.ground == "baseplate":
            gpts, gvalid = self._contact_points(gi, gj, np.zeros(len(gi), dtype=np.int64))
            parts["base"] = self._vertical(prog, eq, gpts, gvalid, gb, None,
                                           np.ones(len(gi), bool), detail, zcap)
            self._shear(prog, eq, np.stack([gi, gj], 1), np.zeros(len(gi), np.int64), gb, None)
            # the points props may hold up (none until a BuildChecker says which)
            parts["table"] = self._table(prog, eq, held, rest=False) if self.propping else None
        else:
            parts["base"] = None
            parts["table"] = self._table(prog, eq, held)
        parts["sections"] = self._bending(prog, parts, factor, detail, zcap)
        parts["section_rows"] = [(sec[0], sec[5]) for sec in parts["sections"]]
        return prog, parts

    def _moment_rows(self, prog, eq, body, pts, force_dir, cols, sign):
        """Add forces ``sign * force_dir * x[cols]`` at points ``pts`` to ``body``'s equations."""
        f = sign[:, None] * force_dir
        moment = np.cross(pts - self.com[body], f)
        base = 6 * body
        for axis in range(3):
            prog.put(eq[base + axis], cols, f[:, axis])
            prog.put(eq[base + 3 + axis], cols, moment[:, axis])

    def _vertical(self, prog, eq, pts, valid, upper_b, lower_b, pull_ok, detail, zcap):
        """Vertical forces at the contact points ``pts`` of each stud, on the upper body (the
        lower one, None for the baseplate, takes the opposite), pressing above 0; where the
        stud clamps a point may pull (go below 0): down to minus the clutch (phase 1), or to
        minus the clutch times its joint's utilisation z (phase 2: one z per pair of bodies).
        In phase 2 a point's force is ``w - clutch * z`` with ``w >= 0``, so that the bound
        needs no row of its own.
        Each stud's net force is a column of its own (the bending rows use it)."""
        m = len(upper_b)
        cp = np.flatnonzero(valid.ravel())
        stud = cp // 4
        p = pts.reshape(-1, 3)[cp]
        pulls = pull_ok[stud]
        lower = 0.0 if detail else np.where(pulls, -self.clutch, 0.0)
        v = prog.columns(len(cp), lower, np.inf)               # up on the upper body: press > 0
        up = np.broadcast_to(np.array([0.0, 0.0, 1.0]), (len(cp), 3))
        ones = np.ones(len(cp))
        self._moment_rows(prog, eq, upper_b[stud], p, up, v, ones)
        if lower_b is not None:
            self._moment_rows(prog, eq, lower_b[stud], p, up, v, -ones)
        net = prog.columns(m, -np.inf, np.inf)                 # net = sum of the stud's points
        rows = prog.new_rows(m, 0.0, 0.0)
        prog.put(rows, net, 1.0)
        prog.put(rows[stud], v, -1.0)
        out = {"net": net}
        if detail:
            pair = upper_b.astype(np.int64) * (self.nbody + 1) + (
                self.nbody if lower_b is None else lower_b)
            keys, joint = np.unique(pair, return_inverse=True)
            z = prog.columns(len(keys), 0.0, zcap, 1.0)
            at = np.flatnonzero(pulls)
            zcol = z[joint[stud[at]]]
            pull = -self.clutch * np.ones(len(at))
            self._moment_rows(prog, eq, upper_b[stud[at]], p[at], up[at], zcol, pull)
            if lower_b is not None:
                self._moment_rows(prog, eq, lower_b[stud[at]], p[at], up[at], zcol, -pull)
            prog.put(rows[stud[at]], zcol, self.clutch)
            out.update(z=z, joint=joint)
        return out

    def _shear(self, prog, eq, ij, k_up, upper_b, lower_b):
        """Per joint (all studs between two bodies): a horizontal force in x and y at the
        centre of its studs in the joint plane, and a twisting couple about z (free)."""
        if not len(upper_b):
            return
        pair = upper_b.astype(np.int64) * (self.nbody + 1) + (
            self.nbody if lower_b is None else lower_b)
        keys, inv = np.unique(pair, return_inverse=True)
        m = len(keys)
        count = np.bincount(inv, minlength=m)
        centre = self.origin[:2] + (ij + 0.5) * self.cell[:2]
        pts = np.stack([np.bincount(inv, centre[:, 0], m) / count,
                        np.bincount(inv, centre[:, 1], m) / count,
                        np.bincount(inv, self.origin[2] + k_up * self.cell[2], m) / count], axis=1)
        first = np.zeros(m, dtype=np.int64)
        first[inv[::-1]] = np.arange(len(inv))[::-1]
        up_b = upper_b[first]
        lo_b = None if lower_b is None else lower_b[first]
        # a band of :meth:`_by_bands` passes no shear to what is under it: fixed there, it
        # could hold bricks side by side against each other that nothing else joins
        free = np.full(m, np.inf)
        if self.band is not None and lo_b is not None:
            free[self.band[up_b] != self.band[lo_b]] = 0.0
        for axis in (0, 1):
            cols = prog.columns(m, -free, free)
            d = np.zeros((m, 3))
            d[:, axis] = 1.0
            self._moment_rows(prog, eq, up_b, pts, d, cols, np.ones(m))
            if lo_b is not None:
                self._moment_rows(prog, eq, lo_b, pts, d, cols, -np.ones(m))
        twist = prog.columns(m, -free, free)
        prog.put(eq[6 * up_b + 5], twist, 1.0)
        if lo_b is not None:
            prog.put(eq[6 * lo_b + 5], twist, -1.0)

    def _table_points(self):
        """Where the build can touch a table: the bottom corners (0.1 mm in) of every cell
        with nothing under it, in studs, with their bodies (computed once)."""
        if getattr(self, "_points", None) is None:
            filled = self.blab >= 0
            exposed = filled.copy()
            exposed[:, :, 1:] &= ~filled[:, :, :-1]
            i, j, k = np.nonzero(exposed)
            inset = 0.1 / self.unit
            corner = np.array([[inset, inset], [1 - inset, inset], [inset, 1 - inset],
                               [1 - inset, 1 - inset]])
            xy = self.origin[:2] + (np.stack([i, j], 1)[:, None, :] + corner[None]) * self.cell[:2]
            z = np.broadcast_to((self.origin[2] + k * self.cell[2])[:, None, None], (len(i), 4, 1))
            self._points = (np.concatenate([xy, z], axis=2).reshape(-1, 3),
                            np.repeat(self.blab[i, j, k], 4))
            self._point_brick = np.repeat(self.lab[i, j, k], 4)
            self._point_cells = np.ravel_multi_index((i, j, k), self.blab.shape)
        return self._points

    def points_under(self, cells) -> np.ndarray:
        """Bool per :meth:`_table_points` point: the bottom corners of ``cells`` ((n, 3) of
        i, j, k) whose bottom has nothing under it (other cells give none)."""
        pts, _ = self._table_points()
        out = np.zeros(len(pts), dtype=bool)
        cells = np.asarray(cells, dtype=np.int64).reshape(-1, 3)
        if len(cells):
            lin = np.ravel_multi_index(tuple(cells.T), self.blab.shape)
            at = np.searchsorted(self._point_cells, lin)
            ok = (at < len(self._point_cells)) & (self._point_cells[np.minimum(at, len(self._point_cells) - 1)] == lin)
            for c in range(4):
                out[4 * at[ok] + c] = True
        return out

    def resting(self, present: np.ndarray, propped: np.ndarray | None = None) -> tuple[np.ndarray, float]:
        """Which table points carry the bodies ``present`` (bool per body), and the largest
        tilt (degrees) the build rests at.  ``propped`` (bool per table point, or None) are
        the points a prop holds up from the table: a column standing on the table under the
        point's cell, so the point rests as if it were on the table itself.

        A rigid build put on a table settles on the face of its lower convex hull under its
        centre of mass (each connected structure on its own): on its bottom layer when that
        is flat under it, else tilted onto lower points elsewhere.  Only the first stands as
        built: a structure that would lean (more than :data:`MAX_TILT_DEG`) or whose centre
        of mass lies outside the hull of all its points tips over (:meth:`_topple` says how
        far it would lean), and none of its points carry."""
        from scipy.spatial import ConvexHull, QhullError
        pts, body = self._table_points()
        if propped is not None and propped.any():
            pts = pts.copy()
            pts[propped, 2] = self.origin[2]
        self.topples = []
        if self.flat_rest:
            return present[body] & (pts[:, 2] <= self.origin[2] + 1e-9), 0.0
        active = np.zeros(len(pts), dtype=bool)
        tilt = 0.0
        i, j, k = self._stud_joints()
        a, b = self.blab[i, j, k], self.blab[i, j, k + 1]
        keep = present[a] & present[b]
        n = self.nbody
        graph = sparse.coo_matrix((np.ones(int(keep.sum())), (a[keep], b[keep])), shape=(n, n))
        _, comp = connected_components(graph, directed=False)
        mine = present[body]
        for c in np.unique(comp[present]):
            members = present & (comp == c)
            sel = np.flatnonzero(mine & members[body])
            if not len(sel):
                continue
            weight = self.mass_g[members]
            com = (weight[:, None] * self.com[members]).sum(axis=0) / max(weight.sum(), 1e-12)
            p = pts[sel]
            low = p[:, 2].min()
            flat = p[:, 2] <= low + 1e-9
            facet = _facet_under(p, com[:2], ConvexHull, QhullError)
            lean = None
            if facet is not None:
                normal, offset = facet
                on = np.abs(p @ normal + offset) <= 1e-6
                lean = 0.0 if flat[on].all() else math.degrees(math.acos(min(1.0, abs(normal[2]))))
            if lean is None or lean > MAX_TILT_DEG:
                self.topples.append(self._topple(members, com, p[flat], lean))
                continue
            active[sel[on]] = True
            tilt = max(tilt, lean)
        return active, tilt

    def _topple(self, members: np.ndarray, com: np.ndarray, bottom: np.ndarray, lean) -> dict:
        """A structure that falls over on the table, in a builder's words: where its centre of
        mass is, how far beyond the outline of its bottom layer, how far it would fall."""
        from scipy.spatial import ConvexHull, QhullError
        com_mm = com * self.unit
        beyond = 0.0
        try:
            plan = ConvexHull(bottom[:, :2])
            beyond = max(0.0, float(np.max(plan.equations[:, :2] @ com[:2] + plan.equations[:, 2])))
        except (QhullError, ValueError):
            pass
        bricks = int(np.isin(self.body_of, np.flatnonzero(members)).sum())
        fall = "falls over" if lean is None else f"tips over until it rests leaning {lean:.0f}°"
        return {"bricks": bricks, "centre_of_mass_mm": [round(float(v), 1) for v in com_mm],
                "beyond_bottom_mm": round(beyond * self.unit, 1),
                "would_lean_deg": None if lean is None else round(lean, 1),
                "why": (f"The build ({bricks} bricks) {fall} on a table: its centre of mass lies "
                        f"{beyond * self.unit:.1f} mm beyond the outline of its bottom layer. Build "
                        "it on a baseplate, weigh down or widen its base, or lay it on another side "
                        "(--up, or the object's Placement in FreeCAD)")}

    def _table(self, prog, eq, present: np.ndarray, rest: bool = True):
        """Bodies on a table press down where the build rests (:meth:`resting`; the other
        points are columns held at zero, for :class:`BuildChecker`) and slide only against
        friction: |horizontal force| <= mu * press, per body.  Without ``rest`` (props on
        a baseplate) every point starts held at zero."""
        pts, body = self._table_points()
        use = present[body]
        pts, body = pts[use], body[use]
        if rest:
            active, self.tilt = self.resting(present)
        else:
            active = np.zeros(len(use), dtype=bool)
        active = active[use]
        if not len(pts):
            return {"cols": np.zeros(0, np.int64), "index": np.flatnonzero(use)}
        press = prog.columns(len(pts), 0.0, np.where(active, np.inf, 0.0))
        up = np.broadcast_to(np.array([0.0, 0.0, 1.0]), pts.shape)
        self._moment_rows(prog, eq, body, pts, up, press, np.ones(len(pts)))
        bodies = np.unique(body)
        m = len(bodies)
        where = np.searchsorted(bodies, body)
        centre = np.stack([np.bincount(where, pts[:, a]) / np.bincount(where) for a in range(3)], 1)
        for axis in (0, 1):
            f = prog.columns(m, -np.inf, np.inf)
            d = np.zeros((m, 3))
            d[:, axis] = 1.0
            self._moment_rows(prog, eq, bodies, centre, d, f, np.ones(m))
            for sign in (1.0, -1.0):                      # +-f - mu * sum(press) <= 0
                rows = prog.new_rows(m, -np.inf, 0.0)
                prog.put(rows, f, sign)
                prog.put(rows[where], press, -TABLE_FRICTION)
        twist = prog.columns(m, -np.inf, np.inf)
        prog.put(eq[6 * bodies + 5], twist, 1.0)
        return {"cols": press, "index": np.flatnonzero(use)}

    def _bending(self, prog, parts, factor, detail, zcap) -> list:
        """|bending moment| / strength <= 1 (phase 1) or <= the brick's utilisation column
        (phase 2) across every section between a LEGO brick's studs.

        The moment about a section is that of the vertical forces on one side
        of it: the studs' net forces there (and the table's press under it), and the brick's own weight shared
        by its cells and the masses resting on those cells (times the load
        factor).  Shear in the joint planes is left out.  Returns the sections
        as (brick index, net columns, coefficients, weight moment, utilisation
        column or -1, its two rows)."""
        i, j, k = parts["joints"]
        studs = parts["studs"]
        cols, signs, owner, xy = [], [], [], []
        centre = self.origin[:2] + (np.stack([i, j], 1) + 0.5) * self.cell[:2]
        for brick_lab, s in ((self.lab[i, j, k + 1], 1.0), (self.lab[i, j, k], -1.0)):
            cols.append(studs["net"])
            signs.append(np.full(len(i), s))
            owner.append(brick_lab)
            xy.append(centre)
        if parts["base"] is not None:
            gi, gj = parts["ground_cells"]
            cols.append(parts["base"]["net"])
            signs.append(np.ones(len(gi)))
            owner.append(self.lab[gi, gj, 0])
            xy.append(self.origin[:2] + (np.stack([gi, gj], 1) + 0.5) * self.cell[:2])
        table = parts.get("table")
        if table is not None and len(table["cols"]):
            # the table presses up on the bottom of the bricks it carries
            pts, _ = self._table_points()
            cols.append(table["cols"])
            signs.append(np.ones(len(table["cols"])))
            owner.append(self._point_brick[table["index"]])
            xy.append(pts[table["index"], :2])
        cols, signs, owner, xy = (np.concatenate(v) for v in (cols, signs, owner, xy))
        order = np.argsort(owner, kind="stable")
        cols, signs, owner, xy = cols[order], signs[order], owner[order], xy[order]
        bricks = self.layout.bricks
        starts = np.searchsorted(owner, np.arange(len(bricks) + 1))
        sections = []
        scale = 1000.0 / G / self.unit                      # N mm -> grams-force studs
        bound = zcap if detail else 1.0
        for idx, b in enumerate(bricks):
            if (b.part not in MASS_G or not self.held[self.body_of[idx]] or max(b.size[:2]) < 2
                    or self.support[self.body_of[idx]]):
                continue
            c, sg, p = (v[starts[idx]:starts[idx + 1]] for v in (cols, signs, xy))
            lo = self.origin + np.asarray(b.cell) * self.cell
            extra = self.point_masses.get(idx, [])
            util = prog.columns(1, 0.0, zcap, 1.0)[0] if detail else -1
            for axis in (0, 1):
                length = b.size[axis]
                if length < 2:
                    continue
                strength = bending_capacity_nmm(b.size[1 - axis], b.size[2],
                                                self.cell * self.unit) * scale
                for cut in range(1, length):
                    at = lo[axis] + cut * self.cell[axis]
                    far = p[:, axis] > at
                    share = (length - cut) / length
                    weight = MASS_G[b.part] * share * (length - cut) * self.cell[axis] / 2
                    weight += sum(g * (xyz[axis] - at) for xyz, g in extra if xyz[axis] > at)
                    arm = sg[far] * (p[far, axis] - at)
                    # the section's moment: a column within the strength (phase 1) or within
                    # the strength times the brick's utilisation column (phase 2), one row
                    moment = prog.columns(1, -bound * strength, bound * strength)[0]
                    rows = prog.new_rows(1, 0.0, 0.0)
                    prog.put(np.full(len(arm), rows[0]), c[far], arm)
                    prog.put(rows[0], factor, -weight)
                    prog.put(rows[0], moment, -1.0)
                    if detail:
                        limits = prog.new_rows(2, -np.inf, 0.0)      # +-moment - util <= 0
                        prog.put(limits, moment, [1.0, -1.0])
                        prog.put(limits, util, -strength)
                    sections.append((idx, c[far], arm / strength, weight / strength, util, rows))
        return sections

    # -- verdict -------------------------------------------------------------------------------
    def _forces(self, stable, worst, util, failing, unsupported, failures) -> Forces:
        return Forces(stable=stable, ground=self.ground, max_utilisation=worst, utilisation=util,
                      failing_bricks=failing, unsupported=unsupported, failures=failures,
                      mass_g=float(self.mass_g.sum()), clutch_n=self.clutch_n,
                      loads=[x.to_json() for x in self.loads], tilt_deg=getattr(self, "tilt", 0.0),
                      topples=list(self.topples), bodies=self.nbody)

    def _detail(self, x, parts, stable, worst, tips) -> Forces:
        """Utilisation per brick from phase 2's solution ``x``; failing and unsupported bricks."""
        bricks = self.layout.bricks
        n = len(bricks)
        below, above = np.zeros(n), np.zeros(n)
        has_below = np.zeros(n, bool)
        i, j, k = parts["joints"]
        if len(i):
            studs = parts["studs"]
            per_stud = x[studs["z"]][studs["joint"]]
            ub, lb = self.lab[i, j, k + 1], self.lab[i, j, k]
            np.maximum.at(below, ub, per_stud)
            np.maximum.at(above, lb, per_stud)
            has_below[ub] = True
        gi, gj = parts["ground_cells"]
        if len(gi):
            gb = self.lab[gi, gj, 0]
            has_below[gb] = True
            if parts["base"] is not None:
                np.maximum.at(below, gb, x[parts["base"]["z"]][parts["base"]["joint"]])
        util = np.where(has_below, below, above)
        mode = np.array(["clutch"] * n, dtype=object)
        bend = np.zeros(n)
        for idx, cols, coef, weight, _, _ in parts["sections"]:
            moment = float(coef @ x[cols]) - weight
            bend[idx] = max(bend[idx], abs(moment))
        mode[bend > util] = "bending"
        util = np.minimum(np.maximum(util, bend), worst)     # phase 2's cap has CAP_SLACK
        for body in self.part_body.values():
            members = np.flatnonzero(self.body_of == body)
            util[members] = util[members].max()
        floats = ~self.held[self.body_of]
        tipping = self.held[self.body_of] & tips[self.body_of]
        util[floats | tipping] = np.inf
        mode[floats] = "floats"
        mode[tipping] = "tips"
        failing = np.flatnonzero(util > FAIL_ABOVE)
        ids = [b.id for b in bricks]
        failures = sorted((self._failure(int(b), float(util[b]), str(mode[b])) for b in failing),
                          key=lambda f: f["brick"])
        return self._forces(stable and not len(failing), worst,
                            {ids[b]: float(util[b]) for b in range(n)},
                            sorted(ids[b] for b in failing),
                            sorted(ids[b] for b in np.flatnonzero(floats | tipping)), failures)

    def _failure(self, b: int, util: float, mode: str) -> dict:
        """One failing brick for the report: where it is, how it fails, in words."""
        brick = self.layout.bricks[b]
        what = (f"printed part {brick.printed_part}" if brick.kind == "printed"
                else f"LEGO {BY_NUMBER[brick.part].name.lower()} {brick.part}" if brick.part in BY_NUMBER
                else f"LEGO {brick.part}")
        where = f"in layer {brick.cell[2] + 1} (cell {brick.cell[0]}, {brick.cell[1]})"
        why = {"clutch": f"The {what} {where} pulls on the studs holding it with {util:.2f} times "
                         "the clutch they have: it comes off",
               "bending": f"The {what} {where} bends with {util:.2f} times the moment it takes: "
                          "it breaks",
               "floats": f"The {what} {where} is not joined to anything standing on the ground",
               "tips": f"The {what} {where} cannot be held in balance: the structure it belongs "
                       "to tips over whatever its studs do (see topples)"}[mode]
        return {"brick": int(brick.id), "part": brick.part, "kind": brick.kind,
                "printed_part": brick.printed_part, "layer": int(brick.cell[2]) + 1,
                "cell": [int(v) for v in brick.cell],
                "utilisation": None if not math.isfinite(util) else round(util, 4),
                "mode": mode, "why": why}


def _solid_pla_g(size_mm: np.ndarray) -> float:
    """Mass (g) of a box of solid PLA (1.24 g/cm^3): a printed brick without its part."""
    return 1.24 * float(np.prod(size_mm)) / 1000.0


def _touched_cells(layout: Layout, load: Load, lab: np.ndarray) -> list[tuple[int, int, int]]:
    """The filled cells ``load``'s box overlaps, and the top cells it rests on (its bottom
    within 0.5 mm of their top, overlapping them in plan); InputError when none."""
    grid = layout.grid
    cell = np.asarray(grid.cell, float)
    lo = (np.asarray(load.lo) - grid.origin) / cell
    hi = (np.asarray(load.hi) - grid.origin) / cell
    shape = np.array(grid.shape)
    a = np.clip(np.floor(lo).astype(int), 0, shape)
    b = np.clip(np.ceil(hi).astype(int), 0, shape)
    found: set[tuple[int, int, int]] = set()
    if np.all(b > a):
        sub = lab[a[0]:b[0], a[1]:b[1], a[2]:b[2]] >= 0
        for c in zip(*np.nonzero(sub)):
            cc = np.asarray(c) + a
            overlap = np.minimum(cc + 1, hi) - np.maximum(cc, lo)
            if np.all(overlap > 1e-9):
                found.add(tuple(int(v) for v in cc))
    # resting: the column's top cell just under the box's bottom
    k_top = lo[2]
    k = int(round(k_top)) - 1
    if abs(k_top - round(k_top)) * cell[2] <= 0.5 and 0 <= k < shape[2]:
        x0, x1 = np.clip([math.floor(lo[0]), math.ceil(hi[0])], 0, shape[0])
        y0, y1 = np.clip([math.floor(lo[1]), math.ceil(hi[1])], 0, shape[1])
        for i in range(x0, x1):
            for j in range(y0, y1):
                if min(i + 1, hi[0]) - max(i, lo[0]) > 1e-9 and min(j + 1, hi[1]) - max(j, lo[1]) > 1e-9:
                    if lab[i, j, k] >= 0:
                        found.add((i, j, k))
    if not found:
        raise InputError(f"--load box {list(load.lo)}..{list(load.hi)} touches no brick")
    return sorted(found)
