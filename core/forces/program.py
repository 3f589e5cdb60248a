"""The rows of a force model's linear program: each body's equilibrium, its studs' pull and
shear, the table's push and friction and each brick's bending (:class:`ProgramRows`, a
part of :class:`core.forces.analyse._Model`).
"""

from __future__ import annotations

import math

import numpy as np

from core.catalog import MASS_G
from core.forces import joints, limits
from core.forces.joints import bending_capacity_nmm
from core.forces.solver import Program, work_words


class ProgramRows:
    """The program methods of :class:`core.forces.analyse._Model`."""

    def _program(self, detail: bool, cap: float = math.inf):
        """The LP of a phase: equilibrium rows of every held body, contacts, bending."""
        prog = Program()
        parts: dict = {}
        if detail:
            factor = prog.columns(1, 1.0, 1.0)[0]
        else:
            factor = prog.columns(1, 0.0, limits.LOAD_FACTOR_CAP, -1.0)[0]
        parts["factor"] = factor
        free = np.repeat(self.support, 6)                   # a support's balance is not asked
        eq = prog.new_rows(6 * self.nbody, np.where(free, -np.inf, 0.0), np.where(free, np.inf, 0.0))
        parts["eq"] = eq
        held = self.held
        prog.put(eq[6 * np.flatnonzero(held) + 2], factor, -self.mass_g[held])
        loaded = np.flatnonzero(held & ~self.support & np.any(self.extra != 0, axis=1))
        for axis in range(6):
            prog.put(eq[6 * loaded + axis], factor, self.extra[loaded, axis])
        zcap = np.inf if not math.isfinite(cap) else max(cap, 1.0 / limits.LOAD_FACTOR_CAP) * (1 + limits.CAP_SLACK)
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
                prog.put(rows[where], press, -joints.TABLE_FRICTION)
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
        scale = 1000.0 / joints.G / self.unit                      # N mm -> grams-force studs
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

    # -- the programs ------------------------------------------------------------------------
    def _solve(self, prog: Program, limited: bool = True) -> tuple[str, np.ndarray | None]:
        """:meth:`Program.solve` within :data:`limits.PROGRAM_WORK` (or, given, within
        ``whole_seconds``; not ``limited``: however long it takes), its work added to
        :attr:`work`."""
        if not limited:
            out = prog.solve()
        elif self.whole_seconds is None:
            out = prog.solve(work=limits.PROGRAM_WORK)
        else:
            out = prog.solve(seconds=self.whole_seconds)
        self.work += prog.spent
        return out

    def _limit_words(self) -> str:
        """What one program is given, in words (:meth:`_solve`)."""
        if self.whole_seconds is not None:
            return f"the {self.whole_seconds:.0f} s it is given"
        return work_words("it is")
