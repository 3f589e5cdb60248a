"""The force stage's entry point: :func:`analyse` a layout into a :class:`Forces` verdict.

:class:`_Model` joins the bodies (:mod:`core.forces.bodies`), the program's rows
(:mod:`core.forces.program`) and the big-build cuts (:mod:`core.forces.decompose`), and
says whether every body is held and how hard the hardest joint works.
"""

from __future__ import annotations

import copy
import math
import time

import numpy as np

from core.catalog import BY_NUMBER
from core.errors import InputError
from core.forces import joints, limits
from core.forces.bodies import Bodies
from core.forces.decompose import Decompositions
from core.forces.limits import worst_of
from core.forces.program import ProgramRows
from core.forces.verdict import Forces
from core.model import Layout
from core.request import parse_load


def analyse(layout: Layout, ground: str = "table", loads=(), printed=(), clamp=None,
            clutch_n: float = joints.CLUTCH_N, profile: dict[str, str] | None = None,
            detail: bool = True, seconds: float | None = None) -> Forces:
    """The force verdict of ``layout`` standing on ``ground`` ("table" or "baseplate").

    ``loads`` are :class:`Load` (or "X0,Y0,Z0,X1,Y1,Z1:GRAMS" strings),
    ``printed`` the :class:`core.parts.printed_part.PrintedPart` list (their masses;
    without it a printed part weighs as if solid PLA), ``clamp`` the
    (studs_ok, bottom_ok) masks of :func:`core.parts.printed.clamp_masks` (None:
    every stud and socket whole), ``clutch_n`` the tension of one contact
    point in N, ``profile`` the slicer settings printed masses follow.
    ``detail`` False gives the verdict and the worst utilisation only (one
    small program), with ``utilisation`` and ``failures`` left empty.
    ``seconds`` (None: :data:`limits.PROGRAM_WORK` per program, and past :data:`limits.MAX_BODIES`
    bodies no whole program) is what the whole build's programs may take; given,
    a build past :data:`limits.MAX_BODIES` that its parts and bands do not settle is
    solved as one program too (minutes for thousands of bricks).

    Promises: ``stable`` is True exactly when every body is held and the
    worst utilisation is at most 1; with ``detail`` every brick has a
    utilisation and ``failing_bricks`` are those above 1; ``layout`` is
    not changed.  Raises :class:`InputError` for an unknown ground, a
    clutch not > 0, a load that touches no brick, or ``seconds`` not > 0.
    """
    return Analysis(layout, ground, loads, printed, clamp, clutch_n, profile, seconds).verdict(detail)


class Analysis:
    """The force model of one layout (:func:`analyse`'s arguments and errors), judged as often
    as asked: the verdict alone first and then in detail solves the verdict's programs once
    (reinforce screens its candidates so)."""

    def __init__(self, layout: Layout, ground: str = "table", loads=(), printed=(), clamp=None,
                 clutch_n: float = joints.CLUTCH_N, profile: dict[str, str] | None = None,
                 seconds: float | None = None):
        start = time.perf_counter()
        if seconds is not None and not (isinstance(seconds, (int, float)) and not isinstance(seconds, bool)
                                        and math.isfinite(seconds) and seconds > 0):
            raise InputError(f"--seconds {seconds!r} must be a number of seconds above 0")
        if ground not in joints.GROUNDS:
            raise InputError(f"--ground {ground!r}: choose table or baseplate")
        if isinstance(clutch_n, bool) or not (isinstance(clutch_n, (int, float))
                                              and math.isfinite(clutch_n) and clutch_n > 0):
            raise InputError(f"--clutch {clutch_n!r} must be a force in N above 0")
        self.layout, self.loads = layout, [parse_load(x) for x in loads]
        self.ground, self.clutch_n = ground, float(clutch_n)
        self.model = None
        if layout.bricks:
            self.model = _Model(layout, ground, self.loads, printed, clamp, float(clutch_n), profile)
            self.model.whole_seconds = seconds
        self._build_s = time.perf_counter() - start

    def verdict(self, detail: bool = True) -> Forces:
        """The verdict (with ``detail``, every brick's utilisation), as :func:`analyse`; its
        ``seconds`` count the model's building in the first answer."""
        start = time.perf_counter()
        if self.model is None:
            return Forces(True, self.ground, 0.0, clutch_n=self.clutch_n,
                          loads=[x.to_json() for x in self.loads], seconds=self._build_s)
        forces = self.model.verdict(detail)
        forces.seconds = time.perf_counter() - start + self._build_s
        self._build_s = 0.0
        return forces


def supported_below(lab: np.ndarray) -> bool:
    """Every filled cell of ``lab`` (bool grid) is in the bottom layer or on a filled cell."""
    return not np.any(lab[:, :, 1:] & ~lab[:, :, :-1])


class _Model(Decompositions, ProgramRows, Bodies):
    """Bodies, contacts and the programs of one :class:`Analysis`.

    Inside the programs lengths are in studs (8 mm) and forces in grams-force,
    so that the coefficients stay near 1."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        #: the verdicts given (by ``detail``), phase 1's answer (:meth:`_phase_one`) and the
        #: models of the hanging parts' groups (:meth:`_window`): each found once
        self._verdicts: dict[bool, Forces] = {}
        self._first: tuple | None = None
        self._group_models: dict[tuple, "_Model"] = {}

    def verdict(self, detail: bool) -> Forces:
        """:meth:`_verdict`, with :attr:`Forces.work` the work of every program it solved
        (its parts' and bands' included); a verdict asked again is a copy of the first (and
        the verdict's programs are not solved again for the detail, :meth:`_phase_one`)."""
        known = self._verdicts
        if detail not in known:
            start = self.work
            known[detail] = self._verdict(detail)
            known[detail].work = self.work - start
            return copy.copy(known[detail])
        out = copy.copy(known[detail])
        out.work = 0
        return out

    def _phase_one(self) -> tuple[str, np.ndarray | None, int]:
        """Phase 1 of the whole program: (its status, solution, load-factor column), solved
        once per model."""
        if self._first is None:
            prog, parts = self._program(detail=False)
            status, x = self._solve(prog)
            self._first = (status, x, parts["factor"])
        return self._first

    def _verdict(self, detail: bool) -> Forces:
        """A build whose every cell rests on a cell or the ground stands without any pull
        (no program).  Otherwise phase 1: the largest load factor (gravity and loads times
        it) the joints carry with their clutch; the worst utilisation is its inverse.  Phase
        2 (``detail``): at the real loads, each joint's utilisation, the sum of them least,
        none above phase 1's worst; past :data:`limits.EXACT_BODIES` a build standing below
        :data:`limits.DETAIL_ABOVE`, or standing past :data:`limits.MAX_BODIES` (solved whole only when
        given ``whole_seconds``), gives each brick that worst instead."""
        if not self.on_supports and supported_below(self.blab >= 0):
            # every cell rests on a cell (or the ground): it all stands in pure compression
            util = {b.id: 0.0 for b in self.layout.bricks} if detail else {}
            return self._forces(True, 0.0, util, [], [], [])
        fallen = self._falls_over()
        if fallen is not None:
            return fallen
        where = ""
        if self.nbody > limits.EXACT_BODIES and not self.on_supports:
            parted, where = self._by_parts(detail)
            if parted is not None:
                return parted
        if self.nbody > limits.MAX_BODIES and not self.on_supports and self.nbody <= limits.MAX_BANDED:
            banded, why = self._by_bands()
            if banded is not None:
                return banded
            where = f"{where}; {why}" if where else why
        if self.nbody > limits.MAX_BODIES and not self.on_supports and self.whole_seconds is None:
            out = self._forces(False, math.nan, {}, [], [], [])
            out.unchecked = (f"{self.nbody} bricks and printed parts, some of them overhanging: more "
                             f"than the {limits.MAX_BODIES} the force check solves in one program (it would "
                             "take minutes)" + (f", and {where}" if where else "")
                             + "; the brick graph's verdict stands alone (python -m core stability "
                             "layout.json --seconds 900 solves it as one program)")
            return out
        status, x, factor_col = self._phase_one()
        if status == "limit":
            out = self._forces(False, math.nan, {}, [], [], [])
            out.unchecked = (f"{self.nbody} bricks and printed parts: the force program of the "
                             f"whole build ran past {self._limit_words()}"
                             "; the brick graph's verdict stands alone")
            return out
        factor = float(x[factor_col]) if status == "optimal" else 0.0
        worst = worst_of(factor)
        floats = ~self.held[self.body_of]
        stable = bool(worst <= joints.FAIL_ABOVE and not floats.any())
        if not detail:
            failing = [b.id for b, f in zip(self.layout.bricks, floats) if f]
            return self._forces(stable, worst, {}, sorted(failing), sorted(failing), [])
        def each_worst() -> Forces:
            return self._forces(stable, worst, {b.id: worst for b in self.layout.bricks}, [], [], [])

        if stable and (worst < limits.DARK_BELOW or self.nbody > limits.EXACT_BODIES
                       and (worst < limits.DETAIL_ABOVE or self.nbody > limits.MAX_BODIES)):
            # each brick gets the worst (as a hanging part's do): on big builds phase 2 costs
            # as much as phase 1 or more
            return each_worst()
        prog, parts = self._program(detail=True, cap=worst)
        # unless it stands, what fails and why, however long it takes
        status, x = self._solve(prog, limited=stable or self.nbody > limits.MAX_BODIES)
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
        worst = worst_of(factor)
        out = self._forces(bool(worst <= joints.FAIL_ABOVE and self.held.all()), worst, {}, [], [], [])
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
        util = np.minimum(np.maximum(util, bend), worst)     # phase 2's cap has limits.CAP_SLACK
        for body in self.part_body.values():
            members = np.flatnonzero(self.body_of == body)
            util[members] = util[members].max()
        floats = ~self.held[self.body_of]
        tipping = self.held[self.body_of] & tips[self.body_of]
        util[floats | tipping] = np.inf
        mode[floats] = "floats"
        mode[tipping] = "tips"
        failing = np.flatnonzero(util > joints.FAIL_ABOVE)
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
