"""Suggesting high-res regions: the functional features a LEGO grid cannot hold.

A 1x1 plate cell is 8 x 8 x 3.2 mm; a bore, a screw hole or a pin narrower
than a few cells comes out of legofication as a lump or a gap.  This stage
finds such features in the model and proposes a region box (model mm) for
each, with a reason in words and where the feature is (its axis and centre):

* **B-rep** (STEP, BREP, FCStd): the cylindrical, conical and toroidal faces of
  OpenCascade (``BRepAdaptor_Surface.GetType``), those of one surface that touch
  taken together (:func:`brep_features`).  Concave ones that go at least half way
  round their axis are a hole (a bore, a screw hole, a slot's end), convex ones
  that go more than half way a pin or boss; those less than :data:`LIMIT_MM`
  across are features.  Fillets, rounded edges and planes are not.
* **Meshes**: the same holes and pins from circle fits on the smooth patches
  of faces (:func:`round_features`), and walls thinner than the cell across
  them from the wall-thickness map (:func:`thin_walls`,
  :func:`core.parts.thickness.thickness_map`).  Plane walls as thick as the cells
  across them give nothing.

A feature's region is the box of its faces grown by :data:`WALL_MM` of material
(:data:`END_MM` along its axis): what carries it in the printed part.  The driver
marks every cell a box touches, so a printed part is whole cells and gets its
studs and sockets there (and anchor tabs, :func:`core.high_res.anchor`).  The
cells the regions mark may hold at most :data:`MAX_SHARE` of the part's volume
(:func:`capped`): holes and pins are kept before walls, cheapest first, and the
rest are dropped with a warning, as a part that is all fine detail prints faster
whole (the paper's limit for artistic or decorative shapes).  The regions are then
priced by the calibrated print-time estimate (:class:`Pricer`) and dropped, walls
first, until printing them is :data:`MIN_SPEEDUP` times faster than printing the
model whole (:func:`sped_up`).  Kept regions closer than a cell are merged (:func:`merged`)
when that marks little more.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import trimesh
from scipy import sparse
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from core import high_res, voxelize
from core.model import CELL_MM, Grid
from core.parts import thickness
from core.printing import estimate, poses
from core.request import DEFAULTS

#: Features less than this across (mm) are suggested: holes, pins and bosses.
LIMIT_MM = 20.0
#: Material (mm) kept around a feature in its region, across its axis and along it.
WALL_MM = 1.0
END_MM = 0.5
#: Default --tolerance (mm), from the one table of defaults: a feature whose loss under
#: legofication (a hole's or pin's radius, a wall's thickness) is not more than this is
#: not suggested.
TOLERANCE_MM = DEFAULTS["suggest_tolerance"]
#: Concave faces of one surface that go at least this far round their axis (radians)
#: are a hole (half way: the end of a slot), convex ones a pin when they go more than
#: :data:`MIN_PIN_TURN` round (two fillets rounding off a wall's top go exactly half way).
MIN_TURN = math.pi * 0.99
MIN_PIN_TURN = math.pi * 1.05
#: Faces of one surface whose boxes come this close (mm) are one feature.
TOUCH_MM = 0.01
#: Mesh faces are one patch across edges that bend less than this (radians).
SMOOTH_RAD = math.radians(40.0)
#: A patch of fewer faces is no round feature.
MIN_PATCH_FACES = 6
#: A round patch's normals are at most this cosine off perpendicular to its axis.
MAX_AXIS_COS = 0.1
#: Its facet centres lie within this fraction of the radius from one circle.
FIT_RESIDUAL = 0.08
#: Its turn round the axis is counted in this many sectors.
TURN_BINS = 36
#: A thin wall is a spot of at least this much thin surface (mm²).
MIN_WALL_MM2 = 16.0
#: Two regions are merged when their union box holds at most this many times their volume.
MERGE_GROWTH = 1.1
#: The model's volume per cell is counted in cells this many times finer along x, y, z.
FINE_SPLIT = (8, 8, 4)
#: Most share of the model's volume the suggestions may mark: what is left must be
#: worth building from LEGO.
MAX_SHARE = 0.35
#: Default least speed-up (the whole model's estimated print time over the suggested
#: regions'), from the one table of defaults: regions are dropped until it holds.
MIN_SPEEDUP = DEFAULTS["suggest_speedup"]


@dataclass(frozen=True)
class Feature:
    """One feature found: ``kind`` (hole, pin, wall), its ``reason`` in words, ``box`` the
    region box (2, 3) in model mm around it, its ``centre``, ``axis`` (a wall's: across
    it) and ``size_mm`` (diameter or thickness)."""

    kind: str
    reason: str
    box: np.ndarray
    centre: tuple
    axis: tuple
    size_mm: float

    def place(self, offset=(0.0, 0.0, 0.0)) -> str:
        """Where it is in words, its centre moved back by ``-offset``."""
        at = _point(np.asarray(self.centre) - np.asarray(offset, dtype=float))
        if self.kind == "wall":
            return f"across {_axis_words(self.axis)} at {at}"
        return f"axis {_axis_words(self.axis)} through {at}"

    @property
    def where(self) -> str:
        return self.place()


@dataclass(frozen=True)
class Region:
    """A suggested region: its ``box`` (2, 3) in model mm and the features it holds."""

    box: np.ndarray
    features: tuple

    @property
    def reason(self) -> str:
        """The features' reasons, joined."""
        words = [f.reason for f in self.features]
        return "; ".join(words[:3]) + (f" and {len(words) - 3} more" if len(words) > 3 else "")

    @property
    def where(self) -> str:
        """Where its first features are, in words."""
        return "; ".join(f.where for f in self.features[:3])

    def line(self, offset=(0.0, 0.0, 0.0)) -> str:
        """One line: the reason, where, and the box as a --high-res option (all moved back
        by ``-offset``, as :meth:`to_json`)."""
        doc = self.to_json(offset)
        where = "; ".join(f["where"] for f in doc["features"][:3])
        return f"{self.reason} at {where}: --high-res={doc['high_res']}"

    def to_json(self, offset=(0.0, 0.0, 0.0)) -> dict:
        """The region as JSON, its box and points moved back by ``-offset`` (the frame
        of --high-res boxes when the loader moved the model by ``offset``)."""
        back = -np.asarray(offset, dtype=float)
        return {"box_mm": [[round(float(v), 3) for v in c] for c in self.box + back],
                "high_res": ",".join(f"{v:.3f}" for v in (self.box + back).ravel()),
                "reason": self.reason,
                "features": [{"kind": f.kind, "reason": f.reason, "where": f.place(offset),
                              "centre_mm": [round(float(v), 3) for v in np.asarray(f.centre) + back],
                              "axis": [round(float(v), 4) for v in f.axis],
                              "size_mm": round(f.size_mm, 3)} for f in self.features]}


@dataclass(frozen=True)
class Suggestions:
    """What :func:`suggest` found: the ``regions`` to mark, the ``dropped`` ones (too
    costly), the ``share`` of the model's volume in the cells the regions mark and
    ``cells_share``, that of its filled cells (on the grid centred on the part), and
    ``warnings`` in words."""

    regions: tuple
    dropped: tuple = ()
    share: float = 0.0
    warnings: tuple = ()
    source: str = "mesh"
    cells_share: float = 0.0
    times: dict | None = None

    @property
    def boxes(self) -> list:
        """The regions' boxes ((2, 3) arrays, model mm), as :class:`core.high_res.Regions` takes them."""
        return [r.box for r in self.regions]

    def to_json(self, offset=(0.0, 0.0, 0.0)) -> dict:
        return {"source": self.source, "share_of_volume": round(self.share, 4),
                "share_of_cells": round(self.cells_share, 4),
                "regions": [r.to_json(offset) for r in self.regions],
                "dropped": [r.to_json(offset) for r in self.dropped],
                "estimate": self.times, "warnings": list(self.warnings)}


def suggest(model, tolerance_mm: float = TOLERANCE_MM, limit_mm: float = LIMIT_MM,
            max_share: float = MAX_SHARE, min_speedup: float = MIN_SPEEDUP) -> Suggestions:
    """The suggested regions of a loaded model (:class:`core.io.meshes.LoadedModel`), in its
    frame: from its B-rep faces when it has one, else from its mesh; capped at
    ``max_share`` of its volume (:func:`capped`: walls, then the costliest, dropped with a
    warning), then at an estimated printing speed-up of ``min_speedup`` (:func:`sped_up`,
    0: no cap), and merged (:func:`merged`) as long as that stays under the share cap."""
    if model.brep is not None:
        features, source = brep_features(model.brep, tolerance_mm, limit_mm), "brep"
    else:
        features, source = mesh_features(model.mesh, tolerance_mm, limit_mm), "mesh"
    grid, weight = _grid(model)
    kept, dropped, wanted = capped(grid, weight, [Region(f.box, (f,)) for f in features], max_share)
    price = Pricer(model.mesh, grid, weight)
    kept, slow = sped_up(kept, price, min_speedup)
    joined = merged(kept, grid, weight)
    share = share_of(grid, [r.box for r in joined], weight)
    if share > max_share:
        joined, share = kept, share_of(grid, [r.box for r in kept], weight)
    warnings = []
    if dropped:
        warnings.append(f"the cells the suggestions mark would hold {wanted:.0%} of the part; "
                        f"{len(dropped)} of them were dropped to stay under {max_share:.0%}, holes "
                        f"and pins kept before walls, cheapest first ({_reasons(dropped)}): a part "
                        f"that is mostly fine detail prints faster whole (the limit for artistic "
                        f"or decorative shapes)")
    times = price.times(kept + slow, kept) if kept or slow else None
    if slow:
        warnings.append(f"printing all the suggested regions would take an estimated "
                        f"{times['regions_s'] / 60:.0f} min against {times['whole_s'] / 60:.0f} min "
                        f"for the model whole (a speed-up of {times['speedup']:.2f}); {len(slow)} of "
                        f"them were dropped, the slowest walls first, toward {min_speedup:g} times "
                        f"faster (holes and pins only where they are slower than the whole) "
                        f"({_reasons(slow)}): mark them yourself where they matter")
    return Suggestions(tuple(joined), tuple(dropped) + tuple(slow), share, tuple(warnings), source,
                       share_of(grid, [r.box for r in joined]), times)


def _reasons(regions: list) -> str:
    return "; ".join(r.reason for r in regions[:3]) + (" ..." if len(regions) > 3 else "")


class Pricer:
    """Estimated print times of the model whole and of regions printed on their own.

    The whole model is timed by :func:`core.printing.poses.weigh` in the fastest of its axis
    poses.  A region is timed as the model inside the cells it marks, upright: the
    calibrated estimate's plate features (:func:`core.printing.estimate.plate_features`) from
    the volume there (``weight``), the model's surface there plus the cut across the box
    faces, and its height, plus the supports of the model's downward faces in it
    (:func:`core.printing.poses.support_seconds`).  The regions of a set share one plate.
    """

    def __init__(self, mesh: trimesh.Trimesh, grid, weight):
        self._grid, self._weight = grid, np.asarray(weight)
        self._fine_mm3 = float(np.prod(np.asarray(CELL_MM) / np.array(FINE_SPLIT)))
        self._centres, self._areas = mesh.triangles_center, mesh.area_faces
        down = mesh.face_normals[:, 2] < -math.cos(math.radians(poses.OVERHANG_DEG))
        self._down, self._coeffs, self._support = down, np.asarray(estimate.ESTIMATE_COEFFS), poses.support_seconds
        self._plate, self._layer_mm = estimate.plate_features, estimate.ESTIMATE_LAYER_MM
        self._whole = min(poses.weigh(mesh, name, rotation, poses.OVERHANG_DEG, 0.0)[0].cost
                          for name, rotation in poses.AXIS_POSES)
        self._cache: dict[int, tuple] = {}

    def _parts(self, region: Region) -> tuple:
        """(cells mask, faces mask, faces lifted off its bottom, cut area mm^2, height mm,
        bottom z mm) of ``region`` printed on its own."""
        key = id(region)
        if key not in self._cache:
            grid = self._grid
            first, stop = (np.clip(v, 0, grid.shape) for v in high_res.box_range(grid.origin, grid.cell, region.box))
            lo = np.asarray(grid.origin) + first * np.asarray(grid.cell)
            hi = np.asarray(grid.origin) + stop * np.asarray(grid.cell)
            cells = high_res.box_cells(grid, region.box)
            block = self._weight[first[0]:stop[0], first[1]:stop[1], first[2]:stop[2]]
            full = float(np.prod(FINE_SPLIT))
            cut = sum(float((block.take(0, axis) + block.take(-1, axis)).sum()) / full
                      * float(np.prod(np.delete(np.asarray(grid.cell), axis))) for axis in range(3))
            inside = np.all((self._centres >= lo) & (self._centres <= hi), axis=1)
            lifted = inside & self._down & (self._centres[:, 2] > lo[2] + self._layer_mm)
            self._cache[key] = (cells, inside, lifted, cut, float(hi[2] - lo[2]), lo[2])
        return self._cache[key]

    def seconds(self, regions: list) -> float:
        """Estimated print time (s) of ``regions`` printed on their own, on one plate: the
        model in the cells any of them marks, the cuts and heights of each."""
        if not regions:
            return 0.0
        parts = [self._parts(r) for r in regions]
        cells = np.logical_or.reduce([p[0] for p in parts])
        inside = np.logical_or.reduce([p[1] for p in parts])
        lifted = np.logical_or.reduce([p[2] for p in parts])
        volume = float(self._weight[cells].sum()) * self._fine_mm3
        area = float(self._areas[inside].sum()) + sum(p[3] for p in parts)
        bottom = min(p[5] for p in parts)
        support = self._support(float(self._areas[lifted].sum()),
                                float(self._centres[lifted, 2].max() - bottom) if lifted.any() else 0.0)
        heights = [p[4] for p in parts]
        features = self._plate([volume] + [0.0] * (len(heights) - 1), [area] + [0.0] * (len(heights) - 1), heights)
        return float(features @ self._coeffs + support)

    def times(self, regions: list, kept: list) -> dict:
        """The report's figures: the model whole, all ``regions`` and those ``kept``, and the
        speed-ups they give (``kept_speedup`` None when none is kept)."""
        parts, rest = self.seconds(regions), self.seconds(kept)
        return {"whole_s": round(self._whole, 1), "regions_s": round(parts, 1),
                "speedup": round(self._whole / max(parts, 1e-9), 3), "kept_s": round(rest, 1),
                "kept_speedup": round(self._whole / max(rest, 1e-9), 3) if kept else None}

    @property
    def whole(self) -> float:
        """Estimated print time (s) of the model whole."""
        return self._whole


def sped_up(regions: list, price: Pricer, min_speedup: float) -> tuple[list, list]:
    """``(kept, dropped)``: ``regions`` less the walls, slowest to print first
    (:class:`Pricer`), until the rest prints at least ``min_speedup`` times faster than the
    model whole, then less the holes and pins, slowest first, while printing them would
    still be slower than printing it whole (they carry the function: they are dropped only
    where they destroy the speed-up); all kept for ``min_speedup`` 0."""
    kept = list(regions)
    if min_speedup <= 0:
        return kept, []
    walls = [r for r in kept if any(f.kind == "wall" for f in r.features)]
    others = [r for r in kept if not any(f.kind == "wall" for f in r.features)]
    dropped = []
    for group, least in ((walls, min_speedup), (others, min(1.0, min_speedup))):
        for region in sorted(group, key=lambda r: -price.seconds([r])):
            if price.whole >= least * price.seconds(kept):
                break
            kept = [r for r in kept if r is not region]
            dropped.append(region)
    return kept, dropped


def share_of(grid, boxes, weight=None) -> float:
    """The share of ``grid``'s filled cells that the ``boxes`` touch, or with ``weight``
    (grid-shaped, the model's volume per cell) the share of the model's volume in them."""
    weight = np.asarray(grid.filled, dtype=np.int64) if weight is None else weight
    total = weight.sum()
    if not boxes or total == 0:
        return 0.0
    return float(weight[high_res.Regions.of(boxes).cells(grid)].sum()) / float(total)


def volume_per_cell(mesh, origin, shape, closed=None) -> np.ndarray:
    """Per cell of the grid of plate cells from ``origin`` of ``shape``, the part's volume
    in it, in cells of that grid split :data:`FINE_SPLIT` times along x, y, z (an eighth
    of a stud and a quarter of a plate): the fine cells whose sample point is inside
    (:func:`core.voxelize.sampled`), a point-sampled volume."""
    cell, split = np.asarray(CELL_MM), np.array(FINE_SPLIT)
    fine = voxelize.sampled(voxelize.snap_to_lattice(mesh, origin, cell / split), cell=cell / split,
                           origin=origin, shape=tuple(int(v) for v in np.array(shape) * split),
                           closed=closed)
    (a, b, c), (x, y, z) = shape, FINE_SPLIT
    return fine.filled.reshape(a, x, b, y, c, z).sum(axis=(1, 3, 5)).astype(np.int64)


def shares(grid, regions, weight) -> tuple:
    """``(share of the volume, share of the cells)``: the share of the part's volume
    (``weight``, :func:`volume_per_cell` on ``grid``'s frame) in the cells the
    :class:`core.high_res.Regions` ``regions`` touch, and the share of ``grid``'s filled
    cells they touch (a hollowed grid's cells: its volume is still the whole part's)."""
    whole = Grid(np.asarray(grid.origin), np.asarray(grid.cell), weight > 0)
    total = int(weight.sum())
    volume = float(weight[regions.cells(whole)].sum()) / total if regions and total else 0.0
    cells = float(np.count_nonzero(regions.cells(grid))) / grid.count if regions and grid.count else 0.0
    return volume, cells


def _grid(model):
    """The grid centred on the model, and per cell the model's volume in it
    (:func:`volume_per_cell`)."""
    origin, shape = voxelize.grid_frame(model.mesh.bounds)
    grid = voxelize.legofy(voxelize.snap_to_lattice(model.mesh, origin, np.asarray(CELL_MM)),
                           origin=origin, shape=shape, closed=model.watertight)
    return grid, volume_per_cell(model.mesh, origin, shape, model.watertight) * grid.filled


def capped(grid, weight, regions: list, max_share: float):
    """``regions`` kept while together they mark at most ``max_share`` of the model's volume
    (``weight``: per cell of ``grid``), holes and pins before walls, each kind cheapest
    first: ``(kept, dropped costliest first, share of the volume all of them would mark)``."""
    if not regions:
        return [], [], 0.0
    masks = [high_res.box_cells(grid, r.box) & grid.filled for r in regions]
    total = max(int(weight.sum()), 1)
    cost = [int(weight[m].sum()) for m in masks]
    wanted = float(weight[np.logical_or.reduce(masks)].sum()) / total
    order = sorted(range(len(regions)),
                   key=lambda n: (any(f.kind == "wall" for f in regions[n].features), cost[n]))
    union = np.zeros(grid.shape, dtype=bool)
    kept, dropped = [], []
    for n in order:
        more = union | masks[n]
        if weight[more].sum() <= max_share * total:
            union = more
            kept.append(n)
        else:
            dropped.append(n)
    dropped.sort(key=lambda n: -cost[n])
    return [regions[n] for n in sorted(kept)], [regions[n] for n in dropped], wanted


def merged(regions: list, grid, weight) -> list:
    """``regions`` with those closer than a cell on every axis merged into their union
    box, when that box holds at most :data:`MERGE_GROWTH` times the model volume
    (``weight``, per cell of ``grid``) the two mark: no sliver of LEGO is left between two
    printed parts."""
    out = list(regions)
    count = _counter(grid, weight)
    cell = np.asarray(grid.cell)
    changed = True
    while changed:
        changed = False
        lo = np.array([r.box[0] for r in out]).reshape(-1, 3)
        hi = np.array([r.box[1] for r in out]).reshape(-1, 3)
        gap = np.maximum(lo[:, None], lo[None]) - np.minimum(hi[:, None], hi[None])
        near = np.all(gap < cell, axis=2) & np.triu(np.ones((len(out),) * 2, dtype=bool), 1)
        for a, b in zip(*np.nonzero(near)):
            ra, rb = out[a], out[b]
            union = np.stack([np.minimum(ra.box[0], rb.box[0]), np.maximum(ra.box[1], rb.box[1])])
            apart = count(ra.box) + count(rb.box) - count(ra.box, rb.box)
            if count(union) <= MERGE_GROWTH * apart:
                out[a] = Region(union, ra.features + rb.features)
                del out[b]
                changed = True
                break
    return out


def _counter(grid, weight):
    """A function: the sum of ``weight`` (grid-shaped) over the cells a box touches (the
    cells of :func:`core.high_res.box_cells`), or that two boxes both touch, from a table
    of running sums."""
    table = np.zeros(tuple(n + 1 for n in grid.shape), dtype=np.int64)
    table[1:, 1:, 1:] = np.asarray(weight, dtype=np.int64).cumsum(0).cumsum(1).cumsum(2)
    shape = np.array(grid.shape)

    def count(box, other=None) -> int:
        first, stop = high_res.box_range(grid.origin, grid.cell, box)
        if other is not None:
            first2, stop2 = high_res.box_range(grid.origin, grid.cell, other)
            first, stop = np.maximum(first, first2), np.minimum(stop, stop2)
        (i0, j0, k0), (i1, j1, k1) = np.clip(first, 0, shape), np.clip(stop, 0, shape)
        if i1 <= i0 or j1 <= j0 or k1 <= k0:
            return 0
        t = table
        return int(t[i1, j1, k1] - t[i0, j1, k1] - t[i1, j0, k1] - t[i1, j1, k0]
                   + t[i0, j0, k1] + t[i0, j1, k0] + t[i1, j0, k0] - t[i0, j0, k0])

    return count


def _point(p) -> str:
    return "(" + ", ".join(f"{v:.1f}" for v in p) + ")"


def _axis_words(axis) -> str:
    a = np.asarray(axis, dtype=float)
    for name, n in (("x", 0), ("y", 1), ("z", 2)):
        if abs(abs(a[n]) - 1.0) < 1e-6:
            return name
    return "(" + ", ".join(f"{v:.2f}" for v in a) + ")"


def _feature(kind: str, diameter: float, depth: float, centre, axis, lo, hi) -> Feature:
    """A hole or pin feature with its words and its region box: its faces' box ``lo``-``hi``
    grown by :data:`WALL_MM` across the axis and :data:`END_MM` along it."""
    reason = f"{kind} Ø{diameter:.1f} mm, {depth:.1f} mm {'deep' if kind == 'hole' else 'long'}"
    a = np.abs(np.asarray(axis, dtype=float))
    grow = WALL_MM * np.sqrt(np.clip(1.0 - a * a, 0.0, 1.0)) + END_MM * a
    box = np.stack([np.asarray(lo, dtype=float) - grow, np.asarray(hi, dtype=float) + grow])
    return Feature(kind, reason, box, tuple(float(v) for v in centre),
                   tuple(float(v) for v in axis), float(diameter))


# --- B-rep --------------------------------------------------------------------------------

def brep_features(shape, tolerance_mm: float = TOLERANCE_MM, limit_mm: float = LIMIT_MM) -> list:
    """Holes and pins of the OCP ``shape``: its cylindrical, conical and toroidal faces,
    those on one surface (same kind, axis, size and side) taken together, that go at
    least half way round their axis and are under ``limit_mm`` across, with a radius
    over ``tolerance_mm``."""
    from OCP.TopAbs import TopAbs_FACE
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    surfaces: dict = {}
    explorer = TopExp_Explorer(shape, TopAbs_FACE)
    while explorer.More():
        face = _round_face(TopoDS.Face_s(explorer.Current()))
        explorer.Next()
        if face is not None and face["diameter"] < limit_mm and face["diameter"] / 2 > tolerance_mm:
            surfaces.setdefault(face["key"], []).append(face)
    out = []
    for faces in (c for same in surfaces.values() for c in _touching(same)):
        turn = sum(f["turn"] for f in faces)
        if turn < (MIN_TURN if faces[0]["concave"] else MIN_PIN_TURN):
            continue
        a, line = faces[0]["axis"], faces[0]["line"]
        along = np.concatenate([f["points"] for f in faces]) @ a
        lo = np.min([f["lo"] for f in faces], axis=0)
        hi = np.max([f["hi"] for f in faces], axis=0)
        centre = line + (along.min() + along.max()) / 2 * a
        out.append(_feature("hole" if faces[0]["concave"] else "pin", faces[0]["diameter"],
                            float(along.max() - along.min()), centre, a, lo, hi))
    return out


def _touching(faces: list) -> list:
    """``faces`` in groups whose boxes touch (within :data:`TOUCH_MM`), transitively."""
    lo = np.array([f["lo"] for f in faces])
    hi = np.array([f["hi"] for f in faces])
    near = np.all((lo[:, None] <= hi[None] + TOUCH_MM) & (lo[None] <= hi[:, None] + TOUCH_MM), axis=2)
    _, label = connected_components(sparse.csr_matrix(near), directed=False)
    return [[f for f, n in zip(faces, label) if n == c] for c in np.unique(label)]


def _round_face(face) -> dict | None:
    """A cylindrical, conical or toroidal face's measures (None for another kind): the
    ``key`` of its surface, ``diameter`` (widest), ``turn`` round the axis (radians), the
    unit ``axis`` (sign normalised), ``line`` (the axis's point nearest the origin),
    ``concave``, sampled surface ``points`` and their box ``lo``-``hi``."""
    from OCP.BRepAdaptor import BRepAdaptor_Surface
    from OCP.BRepGProp import BRepGProp_Face
    from OCP.BRepTools import BRepTools
    from OCP.GeomAbs import GeomAbs_Cone, GeomAbs_Cylinder, GeomAbs_Torus
    from OCP.gp import gp_Pnt, gp_Vec

    surface = BRepAdaptor_Surface(face)
    kind = surface.GetType()
    if kind not in (GeomAbs_Cylinder, GeomAbs_Cone, GeomAbs_Torus):
        return None
    umin, umax, vmin, vmax = BRepTools.UVBounds_s(face)
    if kind == GeomAbs_Cylinder:
        geom = surface.Cylinder()
        diameter, size = 2 * geom.Radius(), (geom.Radius(),)
    elif kind == GeomAbs_Cone:
        geom = surface.Cone()
        radii = [geom.RefRadius() + v * math.sin(geom.SemiAngle()) for v in (vmin, vmax)]
        diameter, size = 2 * max(abs(r) for r in radii), (geom.SemiAngle(),)
    else:
        geom = surface.Torus()
        diameter, size = 2 * (geom.MajorRadius() + geom.MinorRadius()), \
            (geom.MajorRadius(), geom.MinorRadius())
    place = geom.Position()
    a = np.array(place.Direction().Coord())
    a = a if a[np.argmax(np.abs(a))] > 0 else -a
    origin = np.array(place.Location().Coord())
    line = origin - np.dot(origin, a) * a
    # the face's box from its surface sampled every 5 degrees round (within 0.1 % of its
    # radius), along the axis at both ends and the middle (a torus at 9 heights)
    u_count = max(2, int(math.ceil((umax - umin) / math.radians(5.0))) + 1)
    uv = np.stack(np.meshgrid(np.linspace(umin, umax, u_count),
                              np.linspace(vmin, vmax, 9 if kind == GeomAbs_Torus else 3)),
                  -1).reshape(-1, 2)
    points = np.array([surface.Value(float(u), float(v)).Coord() for u, v in uv])
    point, normal = gp_Pnt(), gp_Vec()
    BRepGProp_Face(face).Normal((umin + umax) / 2, (vmin + vmax) / 2, point, normal)
    p = np.array(point.Coord())
    radial = (p - origin) - np.dot(p - origin, a) * a
    concave = float(np.dot(np.array(normal.Coord()), radial)) < 0
    key = (int(kind), concave, tuple(np.round(a, 3)), tuple(np.round(line, 2)),
           tuple(round(v, 3) for v in size))
    return {"key": key, "diameter": float(diameter), "turn": float(umax - umin), "axis": a,
            "line": line, "concave": concave, "points": points,
            "lo": points.min(axis=0), "hi": points.max(axis=0)}


# --- meshes -------------------------------------------------------------------------------

def mesh_features(mesh: trimesh.Trimesh, tolerance_mm: float = TOLERANCE_MM,
                  limit_mm: float = LIMIT_MM) -> list:
    """Round holes and pins of a triangle mesh (:func:`round_features`) and its walls
    thinner than a cell (:func:`thin_walls`)."""
    return round_features(mesh, tolerance_mm, limit_mm) + thin_walls(mesh, tolerance_mm)


def patches(mesh: trimesh.Trimesh) -> np.ndarray:
    """Per face, the label of its *patch*: faces joined across edges where the surface
    bends by less than :data:`SMOOTH_RAD` (a cylinder's facets, not a box's sides)."""
    pairs = mesh.face_adjacency[mesh.face_adjacency_angles < SMOOTH_RAD]
    n = len(mesh.faces)
    graph = sparse.coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    return connected_components(graph, directed=False)[1]


def round_features(mesh: trimesh.Trimesh, tolerance_mm: float = TOLERANCE_MM,
                   limit_mm: float = LIMIT_MM) -> list:
    """Holes and pins of a mesh: the patches (:func:`patches`) whose normals stay
    perpendicular to one axis and whose faces lie on a circle round it (a least-squares
    circle fit across the axis, within :data:`FIT_RESIDUAL` of its radius), going at least
    half way round it (holes) or more (pins), under ``limit_mm`` across."""
    label = patches(mesh)
    count = np.bincount(label)
    normals = np.asarray(mesh.face_normals)
    centres = np.asarray(mesh.triangles_center)
    area = np.asarray(mesh.area_faces)
    order = np.argsort(label, kind="stable")
    starts = np.concatenate([[0], np.cumsum(count)])
    out = []
    for patch in np.flatnonzero(count >= MIN_PATCH_FACES):
        faces = order[starts[patch]:starts[patch + 1]]
        feature = _fit_round(normals[faces], centres[faces], area[faces],
                             mesh.vertices[mesh.faces[faces].ravel()])
        if feature is not None and tolerance_mm < feature.size_mm / 2 and feature.size_mm < limit_mm:
            out.append(feature)
    return out


def _fit_round(normals, centres, area, vertices) -> Feature | None:
    """The hole or pin a patch of faces (their normals, centres, areas, and the corners)
    is, or None when it is not round enough."""
    weighted = normals * area[:, None]
    _, vectors = np.linalg.eigh(weighted.T @ normals)
    axis = vectors[:, 0]
    axis = axis if axis[np.argmax(np.abs(axis))] > 0 else -axis
    if np.max(np.abs(normals @ axis)) > MAX_AXIS_COS:
        return None
    u = vectors[:, 1]
    v = np.cross(axis, u)
    x, y = centres @ u, centres @ v
    design = np.stack([x, y, np.ones_like(x)], axis=1)
    (a, b, c), *_ = np.linalg.lstsq(design, x * x + y * y, rcond=None)
    cx, cy = a / 2, b / 2
    radius2 = c + cx * cx + cy * cy
    if radius2 <= 0:
        return None
    radius = math.sqrt(radius2)
    off = np.hypot(x - cx, y - cy)
    # facet centres of a polygon of n sides lie cos(pi / n) of the radius out
    if np.max(np.abs(off - np.median(off))) > FIT_RESIDUAL * radius:
        return None
    radius = float(np.max(np.hypot(vertices @ u - cx, vertices @ v - cy)))
    angles = np.arctan2(normals @ v, normals @ u)
    bins = np.unique(np.floor((angles + math.pi) / (2 * math.pi) * TURN_BINS).astype(int))
    turn = 2 * math.pi * len(bins) / TURN_BINS
    concave = float(np.sum(((x - cx) * (normals @ u) + (y - cy) * (normals @ v)) * area)) < 0
    if turn < (MIN_TURN if concave else MIN_PIN_TURN) - 2 * math.pi / TURN_BINS:
        return None
    along = vertices @ axis
    centre = cx * u + cy * v + (along.min() + along.max()) / 2 * axis
    return _feature("hole" if concave else "pin", 2 * radius, float(along.max() - along.min()),
                    centre, axis, vertices.min(axis=0), vertices.max(axis=0))


def thin_walls(mesh: trimesh.Trimesh, tolerance_mm: float = TOLERANCE_MM,
               samples: int = 20000) -> list:
    """Walls thinner than a cell across them: the samples of the thickness map
    (:func:`core.parts.thickness.thickness_map`) thinner than the cell along their normal
    (3.2 mm across a horizontal wall, 8 mm across an upright one) and thicker than
    ``tolerance_mm``, in spots of at least :data:`MIN_WALL_MM2`, each a feature."""
    points, inward, depth = thickness.thickness_map(mesh, samples)
    if len(points) == 0:
        return []
    across = np.abs(inward) @ np.asarray(CELL_MM)
    thin = np.isfinite(depth) & (depth < across - 1e-6) & (depth > tolerance_mm)
    if not thin.any():
        return []
    spacing = math.sqrt(mesh.area / len(points))
    pts, nrm, dep = points[thin], inward[thin], depth[thin]
    far = pts + dep[:, None] * nrm                  # the wall's other side
    # samples on both sides of one wall share their midpoints
    pairs = cKDTree((pts + far) / 2).query_pairs(3 * spacing, output_type="ndarray")
    n = len(pts)
    graph = sparse.coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    out = []
    for group in np.flatnonzero(np.bincount(label) * spacing ** 2 >= MIN_WALL_MM2):
        member = label == group
        normal = np.mean(nrm[member] * np.sign(nrm[member] @ nrm[member][0])[:, None], axis=0)
        normal /= max(np.linalg.norm(normal), 1e-12)
        t = float(np.median(dep[member]))
        both = np.concatenate([pts[member], far[member]])
        lo, hi = both.min(axis=0), both.max(axis=0)
        box = np.stack([lo - WALL_MM, hi + WALL_MM])
        out.append(Feature("wall", f"wall {t:.1f} mm thin", box,
                           tuple(float(v) for v in (lo + hi) / 2),
                           tuple(float(v) for v in np.round(normal, 4)), t))
    return out
