"""Big builds cut into programs that stay small: the parts that hang, solved on supports that
only press, and height bands top down (:class:`Decompositions`, a part of
:class:`core.forces.analyse._Model`).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy import sparse
from scipy.sparse.csgraph import connected_components

from core.forces import limits
from core.forces.bodies import reach
from core.forces.solver import SolverTrouble, work_words
from core.forces.verdict import Forces
from core.model import Grid, Layout


def cut_margins(cuts: np.ndarray, axis: int, xy: np.ndarray, mass: np.ndarray,
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


def reattached(groups: list[np.ndarray], support: np.ndarray,
               under: sparse.csr_matrix) -> list[np.ndarray]:
    """``groups`` with every body that a cut (:meth:`Decompositions._windows`) left joined to
    no support of its own group moved to a group it is joined to (a few passes): alone it
    would float.  ``support`` is a bool per body and ``under[b]`` lists the bodies body ``b``
    rests on."""
    if len(groups) < 2:
        return groups
    nbody = under.shape[0]
    joined = (under + under.T).tocsr()
    window = np.full(nbody, -1)
    for w, g in enumerate(groups):
        window[g] = w
    for _ in range(4):
        moved = False
        for w in range(len(groups)):
            mine = np.flatnonzero(window == w)
            if not len(mine):
                continue
            rests = np.zeros(nbody, dtype=bool)
            rests[mine] = np.asarray((joined[mine].multiply(support[None, :].astype(float))).sum(axis=1)).ravel() > 0
            held = reach(joined[:, mine][mine].tocsr(), rests[mine])
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


def height_bands(under: sparse.csr_matrix, low: np.ndarray) -> np.ndarray:
    """Per body, its band of :meth:`Decompositions._by_bands` (0 the top one): whole layers
    from the top, about :data:`limits.BAND_BODIES` bodies each.  A body is never in a band
    above one it rests on (a printed part reaching down moves the body under it down).  Then
    a body that nothing joins, within its band, to a body of a band below or to the ground
    moves up a band, and so does what rests on it: held only through the band above, under
    forces fixed without it, it would float.  ``under[b]`` lists the bodies body ``b`` rests
    on and ``low`` is each body's lowest layer."""
    nbody = under.shape[0]
    layers, counts = np.unique(low, return_counts=True)
    edges = np.zeros(len(layers), dtype=np.int64)
    size = current = 0
    for n in range(len(layers) - 1, -1, -1):
        if size >= limits.BAND_BODIES:
            current, size = current + 1, 0
        edges[n] = current
        size += counts[n]
    band = edges[np.searchsorted(layers, low)]
    pairs = under.tocoo()
    upper, lower = pairs.row, pairs.col
    for _ in range(nbody):
        before = band.copy()
        np.maximum.at(band, lower, band[upper])
        if np.array_equal(before, band):
            break
    for _ in range(nbody):
        anchor = low == 0
        anchor[upper[band[lower] > band[upper]]] = True
        same = band[upper] == band[lower]
        graph = sparse.coo_matrix((np.ones(int(same.sum())), (upper[same], lower[same])),
                                  shape=(nbody, nbody))
        _, comp = connected_components(graph, directed=False)
        held = np.isin(comp, comp[anchor])
        loose = ~held & (band > 0)
        if not loose.any():
            break
        band[loose] -= 1
        for _ in range(nbody):
            before = band.copy()
            np.minimum.at(band, upper, band[lower])
            if np.array_equal(before, band):
                break
    return band


class Decompositions:
    """The decompose methods of :class:`core.forces.analyse._Model`."""

    def _hanging_part(self, margin: int = limits.MARGIN_LEVELS) -> tuple[np.ndarray, np.ndarray, sparse.csr_matrix]:
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
        hanging = reach(over, seeds)
        for _ in range(margin):
            more = np.unique(under[np.flatnonzero(hanging)].indices)
            more = more[~hanging[more] & (low[more] >= 1)]
            if not len(more):
                break
            hanging[more] = True
            hanging = reach(over, hanging)
        support = np.zeros(n, dtype=bool)
        support[under[np.flatnonzero(hanging)].indices] = True
        return hanging, support & ~hanging, under

    def _windows(self, hanging: np.ndarray, support: np.ndarray,
                 under: sparse.csr_matrix) -> list[np.ndarray]:
        """The hanging bodies in groups: each connected piece, and past :data:`limits.MAX_BODIES`
        bodies cut in two across its longer side in plan until at most :data:`limits.WINDOW_BODIES`.  A cut goes
        through the middle 40 % where both halves' centres of mass lie deepest inside the
        supports under them, in both directions (:func:`cut_margins`): supports only press,
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
            if len(group) <= limits.WINDOW_BODIES or self.nbody <= limits.MAX_BODIES:
                out.append(group)
                continue
            xy = centre[group]
            axis = int(np.argmax(np.ptp(xy, axis=0)))
            lo, mid, hi = np.quantile(xy[:, axis], [0.3, 0.5, 0.7])
            cuts = np.arange(math.ceil(lo), math.floor(hi) + 1)
            mine = np.isin(rest_body, group)
            margin = cut_margins(cuts, axis, xy, self.mass_g[group], rest_ij[mine],
                                 centre[rest_body[mine], axis])
            if not len(cuts) or margin.max() <= 0:
                out.append(group)                # every cut would leave a half that tips
                continue
            # the deepest-seated halves, nearest the middle among equals
            off_middle = np.abs(cuts + 0.5 - mid) / (4 * max(hi - lo, 1.0))
            cut = cuts[np.argmax(np.minimum(margin, 2.0) - off_middle)] + 0.5
            left = xy[:, axis] < cut
            todo += [group[left], group[~left]]
        return reattached(sorted(out, key=lambda g: int(g[0])), support, under)

    def _by_parts(self, detail: bool) -> tuple[Forces | None, str]:
        """The verdict from the hanging parts alone (:meth:`_hanging_part`), each group of
        :meth:`_windows` one program standing on its supports, which only press: their own
        cells rest on cells down to the ground, so what presses on them goes straight down.
        Forces between two groups are held at zero; a group that does not stand so is
        solved again with the group it shares most joints with, up to
        :data:`limits.MERGED_BODIES` and within :data:`limits.EFFORT` (past :data:`limits.MAX_BODIES` only: below,
        the whole program answers instead).  Put together,
        the groups' forces and pure compression elsewhere balance every body, so a build
        whose every group stands stands, with at most the groups' worst utilisation (the
        whole program's may be lower).  With ``detail``, a group whose worst is below
        :data:`limits.DETAIL_ABOVE` gives each of its bricks that worst.  Returns (the verdict, "")
        then, else (None, where a group does not stand)."""
        hanging, support, under = self._hanging_part()
        if self.nbody <= limits.MAX_BODIES and np.count_nonzero(hanging | support) > limits.PART_SHARE * self.nbody:
            return None, ""                      # hardly smaller than the whole program
        if hanging.sum() > limits.MAX_HANGING:
            return None, (f"its hanging part has {int(hanging.sum())} bricks, more than the "
                          f"{limits.MAX_HANGING} checked in parts")
        groups = dict(enumerate(self._windows(hanging, support, under)))
        big = max(groups.values(), key=len)
        if len(big) > limits.MERGED_BODIES:
            lay = self.layout.bricks[int(np.flatnonzero(np.isin(self.body_of, big))[0])]
            return None, (f"its hanging part from layer {lay.cell[2] + 1} (cell {lay.cell[0]}, "
                          f"{lay.cell[1]}) is one piece of {len(big)} bricks that no cut in plan "
                          f"splits into halves standing on their supports, more than the "
                          f"{limits.MERGED_BODIES} solved in one program of a part")
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
                              + work_words("it is"))
            effort += len(groups[w])
            if not f.stable and self.nbody > limits.MAX_BODIES:
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
            if (not touch or len(merged) > limits.MERGED_BODIES or self.nbody <= limits.MAX_BODIES
                    or effort + len(merged) > limits.EFFORT * int(hanging.sum())):
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
            if f.max_utilisation >= limits.DETAIL_ABOVE:
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
        :data:`limits.DEEPER_LEVELS` levels at a time (never a body on the ground nor one
        ``claimed`` by another group), until it stands or :data:`limits.MERGED_BODIES`; and the
        bodies and support mask it was found with.  A strip of roof that rests on a wall
        two studs thick tips on supports that only press, where the wall's own studs,
        far enough down, hold it (seen on a 2 m hollow cube).  The bodies taken in carry
        this group's forces only: what other groups press on them goes straight down."""
        low = self._lowest_layer()
        inside = np.zeros(self.nbody, dtype=bool)
        inside[group] = True
        f = None
        for levels in limits.DEEPER_LEVELS:
            for _ in range(levels):
                more = np.unique(under[np.flatnonzero(inside)].indices)
                more = more[~inside[more] & ~claimed[more] & (low[more] >= 1)]
                if not len(more):
                    break
                inside[more] = True
            members = np.flatnonzero(inside)
            if len(members) > limits.MERGED_BODIES:
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
        :data:`limits.BAND_BODIES` bodies.  Each band is one program standing on the bodies right
        under it, whose studs hold as any stud does (the bottom band stands on the ground);
        the forces it puts on them (at the real loads) are then fixed loads of the band
        below.  A band that does not stand so is solved again together with the band above
        it, up to :data:`limits.MERGED_BODIES` bodies.

        Put together, the bands' forces balance every body with every joint within its
        strength at the bands' worst utilisation: when every band stands the build stands,
        with at most that worst (the whole program's may be lower).  For a build that rests
        flat on its bottom layer as a whole (:meth:`_falls_over` found nothing tipping).
        Returns (the verdict, each brick given its band's worst, "") or (None, where a band
        does not stand or could not be solved)."""
        start = self.work
        under = self._under()
        low = self._lowest_layer()
        band = height_bands(under, low)
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
            if self.work - start > limits.PROGRAM_WORK:
                return None, ("solved in height bands, its bands' programs ran past "
                              + work_words("they are") + " in all")
            if f.unchecked:
                return None, (f"a program of a band of {len(members)} bricks ran past "
                              + work_words("it is"))
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
            if t == 0 or effort > limits.EFFORT * self.nbody:
                return None, why
            above, _, gone, gone_studs = done.pop()    # solve it again with the band above
            if len(above) + len(members) > limits.MERGED_BODIES:
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

    def _window(self, group: np.ndarray, support: np.ndarray, under: sparse.csr_matrix,
                detail: bool) -> Forces:
        """The verdict of the bodies ``group`` on the supports right under them (its
        programs' work added to :attr:`work`).  The model of a group is made once, so its
        detail after its verdict solves only the detail (:meth:`verdict`)."""
        models = self._group_models
        key = (np.asarray(group).tobytes(), np.asarray(support).tobytes())
        if key not in models:
            models[key] = self._sub_model(group, support, under)[0]
        f = models[key].verdict(detail)
        self.work += f.work
        return f

    def _sub_model(self, group: np.ndarray, support: np.ndarray,
                   under: sparse.csr_matrix) -> tuple["Decompositions", np.ndarray]:
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
                  pressed: dict | None = None) -> "Decompositions":
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
        model = type(self)(sub, self.ground, [], (), clamp, self.clutch_n, None, support=support,
                       masses=(self.mass_g[full], self.com[full], points), holding=holding,
                       extra=None if extra is None else extra[full])
        model.parent_bodies, model.parent_bricks = full, members
        return model
