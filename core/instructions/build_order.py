"""Build order: the numbered assembly steps of a layout, bottom-up.

A *unit* is what a person puts down in one motion: a LEGO brick, or a whole printed part
(all bricks with the same ``printed_part``).  Two units *touch* where a cell of one lies
directly under a cell of the other.  Order (:func:`plan`), one pass with a priority queue
(placing a unit only makes more units placeable):

* A LEGO unit can be placed once it *attaches*: it stands on the base (layer ``k == 0``)
  or on a placed unit, or a placed unit sits on it (hung under an overhang).  A printed
  part also waits until every unit under any of its cells is in place.
* Of the placeable units, the lowest layer goes first.  Within a layer a unit over air
  goes by its *reach* (:func:`reach`), so an overhang or a bridge grows out from all its
  supports in turn (a bridge built from one end carries twice the length built from
  both); units of equal reach follow a serpentine over bands of :data:`BAND_STUDS` studs
  along y (x rising in even bands, falling in odd ones), so consecutive units are neighbours.
* When nothing attachable is left (a floating piece, printed parts that carry each other
  in a cycle), a printed part that touches a placed unit is inserted *early*; failing
  that, the lowest remaining unit is placed *unattached*.  Both are recorded.

Steps: consecutive LEGO units of one layer form a step of at most ``bricks_per_step``
bricks while each new brick lies within :data:`NEAR_STUDS` studs of the step's footprint;
a printed part is a step of its own.  A LEGO unit only attaches to units of another layer,
so every unit of a step attaches to units of earlier steps.

Standing (:func:`standing`): every partial build is checked with the forces; a step is put
earlier when that lets the build stand.  Where no order does, a *prop* (a stack of 1x1
bricks and plates on the ground under a cell with nothing under it, so never where a brick
goes later; it only presses) holds the step's furthest-reaching brick up until the build
stands without it, as a builder holds up an overhang with a spare brick.
:func:`assembly_seconds`: the time to assemble, per LEGO brick and per printed part.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np
from numba import njit
from scipy import ndimage, sparse

from core import forces
from core.catalog import BY_NUMBER
from core.errors import InputError
from core.forces import limits
from core.model import Layout
from core.request import DEFAULTS

#: Studs of overhang per step of reach (:func:`reach`): units of a layer within one step
#: of reach of each other follow the serpentine.
REACH_STUDS = 4
#: Width (studs, along y) of the bands the serpentine order runs along.
BAND_STUDS = 4
#: A brick joins the current step only within this many studs of its footprint.
NEAR_STUDS = 4
#: Default largest number of LEGO bricks in one step.
BRICKS_PER_STEP = 6
#: Default assembly estimate: seconds per LEGO brick placed (the Request table's).
SECONDS_PER_BRICK = DEFAULTS["seconds_per_brick"]
#: Default assembly estimate: seconds per printed part inserted (the Request table's).
SECONDS_PER_PART = DEFAULTS["seconds_per_part"]


@dataclass
class Step:
    """One assembly step.

    ``number`` counts from 1; ``layer`` is the lowest plate layer (k) of its
    bricks; ``bricks`` are layout brick ids in placing order;
    ``printed_part`` names the printed part the step inserts (then
    ``bricks`` are that part's bricks), else None.  ``attached`` is False
    for a unit placed with nothing to attach to; ``early`` is True for a
    printed part inserted before every unit under it was in place.
    """

    number: int
    layer: int
    bricks: list[int]
    printed_part: str | None = None
    attached: bool = True
    early: bool = False

    def to_json(self) -> dict:
        return {"number": self.number, "layer": self.layer, "bricks": list(self.bricks),
                "printed_part": self.printed_part, "attached": self.attached,
                "early": self.early}


@dataclass
class BuildOrder:
    """The steps of a layout, and what could not be ordered by the rules.

    ``unattached`` are brick ids placed without anything to attach to;
    ``early_parts`` printed part ids inserted before all units under them.
    After :func:`standing`: ``utilisation`` the worst utilisation of the
    partial build after each step (inf where something floats or tips),
    ``unstable`` the steps after which it does not stand ({"step",
    "utilisation", "bricks", "why"}), ``moved`` how many steps were put
    earlier than planned so that the build stands; ``graph_only_why`` why the steps
    with a NaN utilisation were checked by the brick graph only ("" when told by
    the number of bodies alone); ``props`` the temporary supports the build needs
    ({"step", "cell", "plates", "parts", "under", "on", "box_mm", "removed_after"}: a
    column of ``plates`` plates (``parts``: design number -> count) stood on the
    ``on`` (table or baseplate) under ``cell`` before step ``step``, under the brick ``under``, filling
    ``box_mm`` (min and max corner in the model's coordinates), taken away after
    step ``removed_after``, None when the finished build still needs it or,
    ``closed_in``, when the build closes it in before it can go); ``finished`` the
    force check of the finished build with the props that stay in it
    (:func:`finished_with_props`; None when none stays or it was not asked).
    """

    steps: list[Step] = field(default_factory=list)
    unattached: list[int] = field(default_factory=list)
    early_parts: list[str] = field(default_factory=list)
    utilisation: list[float] = field(default_factory=list)
    unstable: list[dict] = field(default_factory=list)
    moved: int = 0
    graph_only_why: str = ""
    props: list[dict] = field(default_factory=list)
    finished: dict | None = None

    def to_json(self) -> dict:
        """The order as plain data (:meth:`from_json` reads it back; NaN and inf
        utilisations stay as JSON's NaN and Infinity)."""
        return {"steps": [s.to_json() for s in self.steps], "unattached": list(self.unattached),
                "early_parts": list(self.early_parts),
                "utilisation": [float(u) for u in self.utilisation],
                "unstable": list(self.unstable), "moved": int(self.moved),
                "graph_only_why": self.graph_only_why, "props": list(self.props),
                "finished": self.finished}

    @classmethod
    def from_json(cls, doc: dict) -> "BuildOrder":
        """The order :meth:`to_json` wrote."""
        return cls([Step(**s) for s in doc["steps"]], list(doc.get("unattached", ())),
                   list(doc.get("early_parts", ())), [float(u) for u in doc.get("utilisation", ())],
                   list(doc.get("unstable", ())), int(doc.get("moved", 0)),
                   str(doc.get("graph_only_why", "")), list(doc.get("props", ())),
                   doc.get("finished"))

    def step_of(self) -> dict[int, int]:
        """Brick id -> step number."""
        return {b: s.number for s in self.steps for b in s.bricks}

    @property
    def layers(self) -> int:
        """Number of distinct layers the steps build."""
        return len({s.layer for s in self.steps})


@dataclass
class _Units:
    """Units of a layout: member brick indices, lowest layer, footprint box, kind."""

    members: list[list[int]]
    k0: np.ndarray
    box: np.ndarray
    part: list[str | None]
    below: sparse.csr_matrix
    above: sparse.csr_matrix


def units(layout: Layout) -> tuple[np.ndarray, list[list[int]], list[str | None]]:
    """Unit index per brick (by position in ``layout.bricks``), member lists and part ids.

    Every LEGO brick is its own unit; the bricks of one printed part form one
    unit.  Units are numbered in order of their first brick.
    """
    unit_of = np.empty(len(layout.bricks), dtype=np.int64)
    members: list[list[int]] = []
    part: list[str | None] = []
    by_part: dict[str, int] = {}
    for n, b in enumerate(layout.bricks):
        if b.kind == "printed" and b.printed_part is not None:
            u = by_part.get(b.printed_part)
            if u is None:
                u = by_part[b.printed_part] = len(members)
                members.append([])
                part.append(b.printed_part)
        else:
            u = len(members)
            members.append([])
            part.append(None)
        unit_of[n] = u
        members[u].append(n)
    return unit_of, members, part


def contacts(layout: Layout, unit_of: np.ndarray, count: int) -> sparse.csr_matrix:
    """0/1 matrix ``M[lower, upper]``: a cell of unit ``upper`` lies directly on one of ``lower``."""
    lab = layout.labels()
    ul = np.where(lab >= 0, unit_of[np.maximum(lab, 0)], -1)
    lower, upper = ul[:, :, :-1].ravel(), ul[:, :, 1:].ravel()
    keep = (lower >= 0) & (upper >= 0) & (lower != upper)
    m = sparse.csr_matrix((np.ones(int(keep.sum()), dtype=np.int8), (lower[keep], upper[keep])),
                          shape=(count, count))
    m.sum_duplicates()
    m.data[:] = 1
    return m


def _units(layout: Layout) -> _Units:
    unit_of, members, part = units(layout)
    count = len(members)
    cells = np.array([b.cell for b in layout.bricks], dtype=np.int64).reshape(-1, 3)
    sizes = np.array([b.size for b in layout.bricks], dtype=np.int64).reshape(-1, 3)
    k0 = np.full(count, np.iinfo(np.int64).max, dtype=np.int64)
    np.minimum.at(k0, unit_of, cells[:, 2])
    lo = np.full((count, 2), np.iinfo(np.int64).max, dtype=np.int64)
    hi = np.full((count, 2), np.iinfo(np.int64).min, dtype=np.int64)
    np.minimum.at(lo, unit_of, cells[:, :2])
    np.maximum.at(hi, unit_of, cells[:, :2] + sizes[:, :2])
    below = contacts(layout, unit_of, count)
    return _Units(members, k0, np.concatenate([lo, hi], axis=1), part,
                  below.T.tocsr(), below)


def _serpentine(box: np.ndarray) -> np.ndarray:
    """Sort keys (band, position along the band) of footprint boxes (x0, y0, x1, y1)."""
    cx = (box[:, 0] + box[:, 2]) / 2.0
    cy = (box[:, 1] + box[:, 3]) / 2.0
    band = np.floor(cy / BAND_STUDS).astype(np.int64)
    along = np.where(band % 2 == 0, cx, -cx)
    return np.stack([band, along, cy], axis=1)


def reach(layout: Layout, u: _Units | None = None) -> np.ndarray:
    """Per unit (numbered as :func:`units`), how far it sticks out over air: the distance
    in studs from its nearest cell to the nearest cell of the same layer that stands on a
    full column of cells down to the ground (a *pillar* cell), divided by
    :data:`REACH_STUDS` and rounded down.  0 for a unit with a pillar cell within
    :data:`REACH_STUDS` studs (every unit of a build without overhangs); a layer without
    pillar cells counts as one large reach."""
    u = _units(layout) if u is None else u
    unit_of, _, _ = units(layout)
    lab = layout.labels()
    filled = lab >= 0
    pillar = np.logical_and.accumulate(filled, axis=2)
    hanging = filled & ~pillar
    nearest = np.full(len(u.members), np.iinfo(np.int64).max, dtype=np.int64)
    for k in np.flatnonzero(hanging.any(axis=(0, 1))).tolist():
        far = np.full(filled.shape[:2], float(filled.shape[0] + filled.shape[1]))
        if pillar[:, :, k].any():
            far = ndimage.distance_transform_edt(~pillar[:, :, k])
        cells = hanging[:, :, k]
        np.minimum.at(nearest, unit_of[lab[:, :, k][cells]],
                      np.floor(far[cells] / REACH_STUDS).astype(np.int64))
    return np.where(nearest == np.iinfo(np.int64).max, 0, nearest)


def _check(layout: Layout, bricks_per_step: int) -> None:
    if not isinstance(layout, Layout):
        raise TypeError(f"build order needs a Layout, got {type(layout).__name__}")
    if not (isinstance(bricks_per_step, (int, np.integer)) and bricks_per_step >= 1):
        raise ValueError(f"bricks per step must be a whole number >= 1, got {bricks_per_step!r}")
    ids = [b.id for b in layout.bricks]
    if len(set(ids)) != len(ids):
        raise ValueError("the layout has bricks with the same id; cannot number the steps")


def plan(layout: Layout, bricks_per_step: int = BRICKS_PER_STEP) -> BuildOrder:
    """The assembly steps of ``layout`` (see the module docstring for the rules).

    Promises: every brick is in exactly one step; steps are numbered 1..n in
    order; a printed part's bricks are all in one step of their own; every
    unit of a step stands on the base or touches (directly above or below) a
    unit of an earlier step, except the bricks listed in ``unattached``; a
    printed part not listed in ``early_parts`` comes after every unit under
    it.  Does not modify ``layout`` (:func:`numbered` gives the layout with the steps).  Raises TypeError
    for what is not a Layout, ValueError for a layout with duplicate brick
    ids or a bad step size.
    """
    _check(layout, bricks_per_step)
    if not layout.bricks:
        return BuildOrder()
    u = _units(layout)
    count = len(u.members)
    is_part = np.array([p is not None for p in u.part], dtype=bool)
    need_below = np.diff(u.below.indptr)
    keys = _serpentine(u.box)
    rank = np.empty(count, dtype=np.int64)
    rank[np.lexsort((np.arange(count), keys[:, 2], keys[:, 1], keys[:, 0], reach(layout, u),
                     u.k0))] = np.arange(count)

    v_order = np.empty(count, np.int64)
    flags = np.empty((count, 2), np.bool_)
    _order_units(u.k0.astype(np.int64), rank, is_part, need_below.astype(np.int64),
                 u.above.indptr.astype(np.int64), u.above.indices.astype(np.int64),
                 u.below.indptr.astype(np.int64), u.below.indices.astype(np.int64),
                 v_order, flags)
    order = list(zip(v_order.tolist(), flags[:, 0].tolist(), flags[:, 1].tolist()))
    return _group(layout, u, order, bricks_per_step)


@njit(cache=True, inline="always")
def _first(key0, key1, ids, a, b):
    """Whether heap slot ``a`` comes before slot ``b``: lower layer, then lower rank."""
    return key0[a] < key0[b] or (key0[a] == key0[b] and key1[a] < key1[b])


@njit(cache=True, inline="always")
def _push(key0, key1, ids, size, layer, rank, unit):
    """Put ``unit`` with key (``layer``, ``rank``) on the heap of ``size`` slots; the new size."""
    key0[size], key1[size], ids[size] = layer, rank, unit
    c = size
    while c > 0 and _first(key0, key1, ids, c, (c - 1) // 2):
        p = (c - 1) // 2
        key0[c], key0[p] = key0[p], key0[c]
        key1[c], key1[p] = key1[p], key1[c]
        ids[c], ids[p] = ids[p], ids[c]
        c = p
    return size + 1


@njit(cache=True)
def _order_units(k0, rank, is_part, need_below, up_ptr, up_idx, down_ptr, down_idx,
                 out, flags):
    """The unit order of :func:`plan` into ``out`` with (attached, early) per unit in
    ``flags``: a priority queue on (layer, rank) of the units ready to go; when none
    is, a printed part touching a placed unit (or on the base) goes early, failing
    that the lowest-ranked unit left goes unattached."""
    count = k0.shape[0]
    placed = np.zeros(count, np.bool_)
    queued = np.zeros(count, np.bool_)
    below_done = np.zeros(count, np.int64)
    touching = np.zeros(count, np.int64)
    key0 = np.empty(count + 1, np.int64)
    key1 = np.empty(count + 1, np.int64)
    ids = np.empty(count + 1, np.int64)
    size = 0
    for v in range(count):
        if k0[v] == 0 and not queued[v] and (not is_part[v] or below_done[v] == need_below[v]):
            queued[v] = True
            size = _push(key0, key1, ids, size, k0[v], rank[v], v)
    n = 0
    while n < count:
        if size > 0:
            v = ids[0]
            size -= 1
            key0[0], key1[0], ids[0] = key0[size], key1[size], ids[size]
            c = 0
            while True:
                l, r, best = 2 * c + 1, 2 * c + 2, c
                if l < size and _first(key0, key1, ids, l, best):
                    best = l
                if r < size and _first(key0, key1, ids, r, best):
                    best = r
                if best == c:
                    break
                key0[c], key0[best] = key0[best], key0[c]
                key1[c], key1[best] = key1[best], key1[c]
                ids[c], ids[best] = ids[best], ids[c]
                c = best
            attached, early = True, False
        else:
            v = -1
            for w in range(count):
                if not placed[w] and is_part[w] and (touching[w] > 0 or k0[w] == 0):
                    if v < 0 or rank[w] < rank[v]:
                        v = w
            hooked = v >= 0
            if not hooked:
                for w in range(count):
                    if not placed[w] and (v < 0 or rank[w] < rank[v]):
                        v = w
            attached, early = hooked, hooked
        placed[v] = True
        out[n], flags[n, 0], flags[n, 1] = v, attached, early
        n += 1
        for e in range(up_ptr[v], up_ptr[v + 1]):
            w = up_idx[e]
            below_done[w] += 1
            touching[w] += 1
        for e in range(down_ptr[v], down_ptr[v + 1]):
            touching[down_idx[e]] += 1
        for half in range(2):
            ptr, idx = (up_ptr, up_idx) if half == 0 else (down_ptr, down_idx)
            for e in range(ptr[v], ptr[v + 1]):
                w = idx[e]
                attaches = k0[w] == 0 or touching[w] > 0
                if not queued[w] and not placed[w] and attaches \
                        and (not is_part[w] or below_done[w] == need_below[w]):
                    queued[w] = True
                    size = _push(key0, key1, ids, size, k0[w], rank[w], w)
    return n


def _group(layout: Layout, u: _Units, order: list[tuple[int, bool, bool]],
           bricks_per_step: int) -> BuildOrder:
    """Cut the unit order into steps (one layer, a few neighbouring bricks each)."""
    ids = [b.id for b in layout.bricks]
    result = BuildOrder()
    current: list[int] = []
    box = np.zeros(4, dtype=np.int64)

    def close(units_: list[int], part: str | None = None, attached: bool = True,
              early: bool = False) -> None:
        bricks = [ids[n] for v in units_ for n in u.members[v]]
        layer = int(min(u.k0[v] for v in units_))
        result.steps.append(Step(len(result.steps) + 1, layer, bricks, part, attached, early))

    for v, attached, early in order:
        if not attached:
            result.unattached.extend(ids[n] for n in u.members[v])
        if early and u.part[v] is not None:
            result.early_parts.append(u.part[v])
        if u.part[v] is not None or not attached:
            if current:
                close(current)
                current = []
            close([v], u.part[v], attached, early)
            continue
        b = u.box[v]
        if current:
            near = (b[0] <= box[2] + NEAR_STUDS and b[2] >= box[0] - NEAR_STUDS
                    and b[1] <= box[3] + NEAR_STUDS and b[3] >= box[1] - NEAR_STUDS)
            if u.k0[v] != u.k0[current[0]] or len(current) >= bricks_per_step or not near:
                close(current)
                current = []
        if not current:
            box = b.copy()
        else:
            box = np.concatenate([np.minimum(box[:2], b[:2]), np.maximum(box[2:], b[2:])])
        current.append(v)
    if current:
        close(current)
    return result


#: Steps ahead of the planned next one that :func:`standing` may put first.
LOOKAHEAD = 8
#: A partial build whose worst utilisation is above this is fragile (the instructions warn).
FRAGILE = limits.FRAGILE


def standing(layout: Layout, order: BuildOrder, stands, lookahead: int = LOOKAHEAD,
             props: bool = False, ground: str = "table") -> BuildOrder:
    """``order`` changed so that the partial build after every step stands, where it can.

    ``stands(present)`` says whether the bricks ``present`` (a bool per brick
    of ``layout``, in its order) stand, as (bool, worst utilisation) — e.g.
    :meth:`core.forces.BuildChecker.stands`.  Step by step, the next planned
    step is taken if the build then stands; else the first of the next
    ``lookahead`` steps (2 right after a step that did not stand) that can be placed (each of its units on the ground or
    touching a placed unit, a printed part only once every unit under it is
    placed) and leaves a standing build.  Else, with ``props`` (``stands(present,
    cells)`` then also answers with a prop on the ground under each of ``cells``), the
    planned step with a prop under its brick that reaches furthest from the cells
    standing on full columns (:class:`_Spots`), then one under each of its bricks
    that can have one: the props stay until the build stands without them (a finite
    utilisation), checked before each step that starts a layer higher than any so far
    and every ``lookahead`` steps; after the last step, until it stands
    or is checked by the brick graph only (the whole build's verdict is the force
    check's).  Else the planned step anyway, recorded
    in ``unstable`` with the reason.  Promises: the same steps with the same
    bricks, renumbered 1..n in their new order; ``utilisation`` per step (with the props
    standing then); ``props`` as :class:`BuildOrder` says, each ``on`` the ``ground`` that
    ``stands`` checks on (``table`` or ``baseplate``); the
    order is ``order``'s wherever every prefix stands.  ``order`` is not changed.
    """
    if not order.steps:
        return dataclasses.replace(order, utilisation=[], unstable=[], moved=0, props=[])
    index = {b.id: n for n, b in enumerate(layout.bricks)}
    placing = _Placing.of(layout, order, index)
    spots: list[_Spots] = []              # made when a step first needs a prop

    def spotted() -> _Spots:
        if not spots:
            spots.append(_Spots(layout, ground))
        return spots[0]

    present = np.zeros(len(layout.bricks), dtype=bool)
    remaining = list(range(len(order.steps)))
    chosen: list[int] = []
    worst: list[float] = []
    unstable: list[dict] = []
    standing_props: list[dict] = []
    done_props: list[dict] = []
    top = since = 0

    def check(trial: np.ndarray, extra: list[dict] = ()) -> tuple[bool, float]:
        cells = [p["cell"] for p in standing_props] + [p["cell"] for p in extra]
        return stands(trial, np.array(cells, dtype=np.int64)) if cells else stands(trial)

    moved = 0
    while remaining:
        # once the build does not stand, later steps rarely save it: look less far ahead
        ahead = lookahead if not unstable or unstable[-1]["step"] < len(chosen) else 2
        pick, fallback = _first_standing(remaining[:ahead], placing.placeable,
                                         lambda n: check(_with(present, index, order.steps[n])))
        if pick is None and props:
            step = order.steps[remaining[0]]
            trial = _with(present, index, step)
            for extra in spotted().props_for(step, present, len(chosen) + 1):
                ok, value = check(trial, extra)
                if ok:
                    pick = (remaining[0], value)
                    standing_props.extend(extra)
                    break
        if pick is None:
            pick = (remaining[0], fallback[1] if fallback and fallback[0] == remaining[0]
                    else check(_with(present, index, order.steps[remaining[0]]))[1])
            step = order.steps[pick[0]]
            unstable.append({"step": len(chosen) + 1, "utilisation": _finite(pick[1]),
                             "bricks": list(step.bricks), "why": _unstable_why(step, pick[1])})
        n, value = pick
        moved += n != remaining[0]
        remaining.remove(n)
        chosen.append(n)
        worst.append(float(value))
        present[[index[b] for b in order.steps[n].bricks]] = True
        placing.placed[placing.steps[n]] = True
        top = max(top, order.steps[n].layer)
        since += 1
        if standing_props and (not remaining or order.steps[remaining[0]].layer > top
                               or since >= lookahead):
            since = 0
            ok, value = stands(present)
            if ok and (np.isfinite(value) or not remaining):
                done_props += _taken_away(standing_props, spotted().open_air(present), len(chosen))
                standing_props = []
    done_props += [dict(p, removed_after=None, closed_in=False) for p in standing_props]
    steps = [dataclasses.replace(order.steps[n], number=k + 1) for k, n in enumerate(chosen)]
    return dataclasses.replace(order, steps=steps, utilisation=worst, unstable=unstable,
                               moved=moved, props=sorted(done_props, key=lambda p: p["step"]))


@dataclass
class _Placing:
    """Which steps of an order can be placed next (:func:`standing`): per step its units, per
    unit the units right under and right over it, and the units placed so far."""

    u: _Units
    steps: list[list[int]]
    below: list[set[int]]
    above: list[set[int]]
    early: set[str]
    placed: np.ndarray

    @classmethod
    def of(cls, layout: Layout, order: BuildOrder, index: dict[int, int]) -> "_Placing":
        """``order``'s steps in units of ``layout`` (``index``: brick id -> its position), none
        placed yet."""
        u = _units(layout)
        unit_of, _, _ = units(layout)
        below, above = ([set(m.indices[m.indptr[v]:m.indptr[v + 1]].tolist()) for v in range(len(u.members))]
                        for m in (u.below, u.above))
        steps = [sorted({int(unit_of[index[b]]) for b in s.bricks}) for s in order.steps]
        return cls(u, steps, below, above, set(order.early_parts), np.zeros(len(u.members), dtype=bool))

    def placeable(self, n: int) -> bool:
        """Whether step ``n`` can be placed now: each of its units on the ground or touching a
        placed unit, a printed part (unless placed early in the order) only once every unit
        under it is placed."""
        for v in self.steps[n]:
            if self.u.part[v] is not None and self.u.part[v] not in self.early \
                    and not all(self.placed[w] for w in self.below[v]):
                return False
            if self.u.k0[v] != 0 and not any(self.placed[w] for w in self.below[v] | self.above[v]):
                return False
        return True


def _first_standing(candidates: list[int], placeable, check) -> tuple[tuple | None, tuple | None]:
    """Of the steps ``candidates`` (the planned next one first, always tried), the first that
    is ``placeable(n)`` and stands by ``check(n)`` -> (bool, worst utilisation), as (n, worst),
    else None; and the first one checked, as (n, worst), or None."""
    fallback = None
    for n in candidates:
        if n != candidates[0] and not placeable(n):
            continue
        ok, value = check(n)
        if ok:
            return (n, value), fallback
        if fallback is None:
            fallback = (n, value)
    return None, fallback


def _taken_away(props: list[dict], outside: np.ndarray, after: int) -> list[dict]:
    """The ``props`` once the build stands without them after ``after`` steps: each taken
    away then if ``outside`` (a bool per column x, y) says its cell is in the open air, else
    closed in for good."""
    free = [bool(outside[p["cell"][0], p["cell"][1]]) for p in props]
    return [dict(p, removed_after=after if f else None, closed_in=not f) for p, f in zip(props, free)]


class _Spots:
    """Where a layout can be propped: the cells with nothing under them down to the
    ground (a prop is a column of 1x1 bricks and plates on the table or baseplate under such a cell),
    and how far each is from the nearest cell of its layer on a full column."""

    def __init__(self, layout: Layout, ground: str = "table"):
        self.layout = layout
        self.ground = ground
        self.lab = layout.labels()
        filled = self.lab >= 0
        under = np.zeros_like(filled)
        under[:, :, 1:] = np.logical_or.accumulate(filled, axis=2)[:, :, :-1]
        self.spot = filled & ~under
        self.spot[:, :, 0] = False
        self.pillar = np.logical_and.accumulate(filled, axis=2)
        self.index = {b.id: n for n, b in enumerate(layout.bricks)}
        self._far: dict[int, np.ndarray] = {}

    def far(self, k: int) -> np.ndarray:
        """Distance (studs) of each cell of layer ``k`` from its nearest pillar cell."""
        if k not in self._far:
            shape = self.pillar.shape[:2]
            self._far[k] = (ndimage.distance_transform_edt(~self.pillar[:, :, k])
                            if self.pillar[:, :, k].any() else np.full(shape, float(sum(shape))))
        return self._far[k]

    def best(self, brick_id: int) -> tuple[int, int, int] | None:
        """The cell of a brick that a prop can hold, furthest from the pillar cells."""
        b = self.layout.bricks[self.index[brick_id]]
        (i0, i1), (j0, j1), (k0, _) = [(c, c + s) for c, s in zip(b.cell, b.size)]
        spot = self.spot[i0:i1, j0:j1, k0]
        if not spot.any():
            return None
        far = np.where(spot, self.far(k0)[i0:i1, j0:j1], -1.0)
        i, j = np.unravel_index(int(np.argmax(far)), far.shape)
        return (i0 + int(i), j0 + int(j), int(k0))

    def open_air(self, present: np.ndarray) -> np.ndarray:
        """Per column (i, j): whether the air on the table there (layer 0, no brick of
        ``present`` in it) joins the air around the build, through cells no brick of
        ``present`` fills: a prop standing there can be taken out."""
        air = np.ones(self.lab.shape, dtype=bool)
        air[self.lab >= 0] = ~present[self.lab[self.lab >= 0]]
        around = np.pad(air, 1, constant_values=True)
        around[:, :, 0] = False                           # the table is no way out
        labels, _ = ndimage.label(around)
        return labels[1:-1, 1:-1, 1] == labels[0, 0, -1]

    def touching(self, brick_id: int) -> set[int]:
        """Ids of the bricks directly under or over brick ``brick_id``."""
        b = self.layout.bricks[self.index[brick_id]]
        (i0, i1), (j0, j1), (k0, k1) = [(c, c + s) for c, s in zip(b.cell, b.size)]
        near = [self.lab[i0:i1, j0:j1, k] for k in (k0 - 1, k1) if 0 <= k < self.lab.shape[2]]
        found = np.unique(np.concatenate([n.ravel() for n in near])) if near else np.zeros(0, int)
        return {int(self.layout.bricks[n].id) for n in found if n >= 0}

    def props_for(self, step: Step, present: np.ndarray, number: int):
        """Prop sets to try, in order, so that ``step`` (to become step ``number``, with the
        bricks ``present`` in place) stands: one prop under the brick that reaches furthest
        out, then one under each brick that can have one, among the step's bricks; failing
        that, among the placed bricks they touch, then the placed bricks those touch, and so
        on outwards until a ring of bricks has one (no fixed number of rings: even a small
        layout's prop can be four rings out).  A prop goes only where the air at its foot joins
        the air around the build (a hand can put it there)."""
        ring = set(step.bricks)
        seen = set(ring)
        outside = self.open_air(present)
        while ring:
            found = [(b, c) for b in sorted(ring) if (c := self.best(b)) is not None
                     and outside[c[0], c[1]] and self.layout.bricks[self.index[b]].kind != "printed"]
            if found:
                far = [self.far(c[2])[c[0], c[1]] for _, c in found]
                yield [self.prop(number, *found[int(np.argmax(far))])]
                if len(found) > 1:
                    yield [self.prop(number, b, c) for b, c in found]
                return
            ring = {t for b in ring for t in self.touching(b)
                    if t not in seen and present[self.index[t]]}
            seen |= ring

    def prop(self, number: int, brick_id: int, cell: tuple[int, int, int]) -> dict:
        """A prop under ``cell`` of brick ``brick_id``, stood before step ``number``; its
        box in the model's coordinates (mm), from the table to the cell."""
        plates = int(cell[2])
        parts = {k: v for k, v in (("3005", plates // 3), ("3024", plates % 3)) if v}
        size = np.asarray(self.layout.grid.cell, dtype=float)
        lo = np.asarray(self.layout.grid.origin, dtype=float) + np.array([cell[0], cell[1], 0]) * size
        hi = lo + np.array([size[0], size[1], plates * size[2]])
        return {"step": number, "cell": [int(c) for c in cell], "plates": plates,
                "parts": parts, "under": int(brick_id), "on": self.ground,
                "box_mm": [[round(float(v), 3) for v in lo], [round(float(v), 3) for v in hi]]}


def finished_with_props(layout: Layout, order: BuildOrder, stands) -> dict | None:
    """The finished build of ``layout`` held up by the props of ``order`` that stay in it
    (``removed_after`` None: still needed, or closed in), judged by ``stands`` (as
    :func:`standing`'s, e.g. :meth:`core.forces.BuildChecker.stands` built with what the
    object carries): {"props_left_in", "checked", "stands", "max_utilisation"} (stands and
    utilisation None when the check gave NaN: the brick graph only; utilisation None when
    infinite).  None when no prop stays."""
    left = [p["cell"] for p in order.props if p["removed_after"] is None]
    if not left:
        return None
    ok, value = stands(np.ones(len(layout.bricks), dtype=bool), np.array(left, dtype=np.int64))
    checked = not np.isnan(value)
    return {"props_left_in": len(left), "checked": bool(checked),
            "stands": bool(ok) if checked else None,
            "max_utilisation": _finite(value) if checked else None}


def finished_words(finished: dict, force: dict) -> str:
    """:func:`finished_with_props`'s answer in one clause, with the ground and mass of the
    ``stability.force`` document ``force``: "with its 2 prop(s) left in, it stands on a
    baseplate with 550 g: worst joint utilisation 0.12", and "(fragile: ...)" when it stands
    with its hardest joint above :data:`FRAGILE` of its strength, as a fragile step is."""
    head = f"with its {finished['props_left_in']} prop(s) left in, it "
    if not finished["checked"]:
        return head + "is checked by the brick graph only (too many bricks for the programs)"
    worst = finished["max_utilisation"]
    fragile = finished["stands"] and worst is not None and worst > FRAGILE
    verdict = forces.verdict_words({"stable": finished["stands"], "ground": force["ground"],
                                    "mass_g": force["mass_g"], "max_utilisation": worst})
    return (head + verdict
            + (f" (fragile: its hardest joint works above {FRAGILE:g} of what it holds)" if fragile else ""))


def prop_last_step(prop: dict, steps: int) -> int:
    """The last step (of ``steps``) during which ``prop`` of :attr:`BuildOrder.props`
    stands: the one after which it is taken away, else the last."""
    return prop["removed_after"] if prop["removed_after"] is not None else steps


def prop_words(layout: Layout, prop: dict) -> str:
    """A prop of :attr:`BuildOrder.props` in a builder's words: what to stack, where (the
    brick it holds and the cell's centre in the model's coordinates) and until when."""
    brick = next(b for b in layout.bricks if b.id == prop["under"])
    part = BY_NUMBER.get(brick.part)
    i, j, _ = prop["cell"]
    stack = " on ".join(f"{n} x {BY_NUMBER[p].name} ({p})" for p, n in prop["parts"].items())
    at = (np.asarray(prop["box_mm"][0]) + np.asarray(prop["box_mm"][1]))[:2] / 2
    until = (f"take it away after step {prop['removed_after']}" if prop["removed_after"] is not None
             else "the build closes it in before it can go: it stays inside" if prop.get("closed_in")
             else "the finished build still needs it")
    return (f"before step {prop['step']}, stand a prop {prop['plates']} plate(s) tall ({stack}) on "
            f"the {prop.get('on', 'table')} under stud {i - brick.cell[0] + 1},{j - brick.cell[1] + 1} of the "
            f"{part.name if part else brick.part} (brick {brick.id}; x {at[0]:.0f}, y {at[1]:.0f} mm); "
            f"{until}")


def _with(present: np.ndarray, index: dict, step: Step) -> np.ndarray:
    out = present.copy()
    out[[index[b] for b in step.bricks]] = True
    return out


def _finite(value: float) -> float | None:
    return None if not np.isfinite(value) else round(float(value), 4)


def _unstable_why(step: Step, value: float) -> str:
    """Why the build does not stand after ``step``, in a builder's words."""
    what = f"printed part {step.printed_part}" if step.printed_part else \
        f"{len(step.bricks)} brick{'s' if len(step.bricks) != 1 else ''} in layer {step.layer + 1}"
    if not np.isfinite(value):
        return (f"after placing the {what} the partial build tips over or has a piece joined to "
                "nothing; no other order of the next steps avoids it: hold it until the next steps "
                "are on")
    return (f"after placing the {what} a joint carries {value:.2f} times what its studs hold; no "
            "other order of the next steps avoids it: support it by hand until the next steps are on")


def numbered(layout: Layout, order: BuildOrder) -> Layout:
    """A new layout whose bricks carry their step numbers of ``order`` (``layout`` is not changed)."""
    step = order.step_of()
    return dataclasses.replace(layout, bricks=[dataclasses.replace(b, step=step.get(b.id))
                                               for b in layout.bricks])


def assembly_seconds(layout: Layout, seconds_per_brick: float = SECONDS_PER_BRICK,
                     seconds_per_part: float = SECONDS_PER_PART) -> float:
    """Assembly estimate: ``seconds_per_brick`` per LEGO brick + ``seconds_per_part`` per printed part
    (finding the part by its engraved ID, turning it the right way, pressing it onto its studs).

    The two are the user's settings (command line, document properties), so a
    value that is not a number of seconds >= 0 is an :class:`InputError`.
    """
    for name, value in (("seconds per brick", seconds_per_brick),
                        ("seconds per printed part", seconds_per_part)):
        if not (isinstance(value, (int, float)) and 0 <= value < 1e6):
            raise InputError(f"{name} must be a number of seconds >= 0, got {value!r}")
    lego = sum(1 for b in layout.bricks if b.kind != "printed" or b.printed_part is None)
    parts = len({b.printed_part for b in layout.bricks
                 if b.kind == "printed" and b.printed_part is not None})
    return float(seconds_per_brick) * lego + float(seconds_per_part) * parts


def callout(layout: Layout, step: Step, index: dict | None = None) -> list[tuple[str, int]]:
    """The LEGO parts of a step as (design number, count), most frequent first.

    ``index`` is ``{brick id: brick}`` of ``layout`` (made here when None; pass it when
    calling for every step, so the steps cost what their bricks do).
    """
    index = {b.id: b for b in layout.bricks} if index is None else index
    counts: dict[str, int] = {}
    if step.printed_part is None:
        for bid in step.bricks:
            counts[index[bid].part] = counts.get(index[bid].part, 0) + 1
    return sorted(counts.items(), key=lambda kv: (-kv[1], kv[0]))
