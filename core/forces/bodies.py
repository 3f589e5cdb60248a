"""The bodies of a force model and their contacts: masses, stud joints, the table under
them and where a build rests (:class:`Bodies`, a part of :class:`core.forces.analyse._Model`).
"""

from __future__ import annotations

import math

import numpy as np
from scipy import sparse
from scipy.sparse.csgraph import connected_components

from core.catalog import MASS_G
from core.errors import InputError
from core.forces import joints
from core.forces.joints import contact_directions, printed_mass_g, solid_pla_g
from core.model import Layout, Load


def touched_cells(layout: Layout, load: Load, lab: np.ndarray) -> list[tuple[int, int, int]]:
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


def facet_under(points: np.ndarray, xy: np.ndarray, hull_of, hull_error):
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


def reach(graph: sparse.csr_matrix, start: np.ndarray) -> np.ndarray:
    """The nodes ``start`` (bool) and every node reached from them along ``graph``'s edges."""
    seen = np.asarray(start, dtype=bool).copy()
    frontier = np.flatnonzero(seen)
    while len(frontier):
        nxt = np.unique(graph[frontier].indices)
        frontier = nxt[~seen[nxt]]
        seen[frontier] = True
    return seen


class Bodies:
    """The bodies methods of :class:`core.forces.analyse._Model`."""

    def __init__(self, layout: Layout, ground: str, loads: list[Load], printed, clamp,
                 clutch_n: float, profile, support: np.ndarray | None = None, masses=None,
                 holding: np.ndarray | None = None, extra: np.ndarray | None = None):
        self.layout, self.ground, self.loads = layout, ground, loads
        self.clutch_n = clutch_n
        self.clutch = clutch_n / (joints.G / 1000.0)                 # grams-force
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
        # seconds the whole build's programs may take (None: limits.PROGRAM_WORK each, and no whole
        # program past limits.MAX_BODIES bodies); :func:`analyse` sets it
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
            m = MASS_G[b.part] if b.part in MASS_G else solid_pla_g(hi[idx] - lo[idx])
            mass[self.body_of[idx]] += m
            moment[self.body_of[idx]] += m * centre[idx]
        for name, body in self.part_body.items():
            members = np.flatnonzero(self.body_of == body)
            part = by_part.get(name)
            if part is not None and part.mesh is not None and len(part.mesh.faces):
                m = printed_mass_g(float(part.mesh.volume), float(part.mesh.area), profile)
                com = np.asarray(part.mesh.center_mass, dtype=float) / self.unit
            else:
                m = sum(solid_pla_g(hi[i] - lo[i]) for i in members)
                com = centre[members].mean(axis=0)
            mass[body] += m
            moment[body] += m * com
        points: dict[int, list] = {}
        for idx, b in enumerate(bricks):
            if b.load_g:
                points.setdefault(idx, []).append((centre[idx], float(b.load_g)))
        for load in self.loads:
            cells = touched_cells(self.layout, load, self.lab)
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
        xy = centre[:, None, :] + joints.CONTACT_RADIUS * self.cell[:2] * dirs
        z = self.origin[2] + k_up * self.cell[2]
        pts = np.concatenate([xy, np.broadcast_to(z[:, None, None], xy.shape[:2] + (1,))], axis=2)
        return pts, ~np.isnan(dirs[:, :, 0])

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
        built: a structure that would lean (more than :data:`joints.MAX_TILT_DEG`) or whose centre
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
            facet = facet_under(p, com[:2], ConvexHull, QhullError)
            lean = None
            if facet is not None:
                normal, offset = facet
                on = np.abs(p @ normal + offset) <= 1e-6
                lean = 0.0 if flat[on].all() else math.degrees(math.acos(min(1.0, abs(normal[2]))))
            if lean is None or lean > joints.MAX_TILT_DEG:
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
