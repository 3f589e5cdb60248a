"""Suggesting high-res regions: the functional features a LEGO grid cannot hold.

A 1x1 plate cell is 8 x 8 x 3.2 mm; a bore, a screw hole or a pin narrower
than a few cells comes out of legofication as a lump or a gap.  This stage
finds such features in the model and proposes a region box (model mm) for
each, with a reason in words and where the feature is:

* **B-rep** (STEP, BREP, FCStd): every cylindrical, conical and toroidal face
  of OpenCascade (``BRepAdaptor_Surface.GetType``) that goes at least half way
  round its axis and is less than :data:`LIMIT_MM` across is a feature; the
  face's normal against its axis tells a hole (concave) from a pin or boss
  (convex).  Partial faces (fillets, rounded edges) and planes are not.
* **Meshes**: round holes and pins from cylinder fits on the patches of
  triangles whose normals stay perpendicular to one axis (:func:`_mesh_features`),
  and walls thinner than a cell from :func:`core.thickness.thin_features`.

A feature's region is the box of its faces grown by :data:`WALL_MM` of
material around it (:data:`END_MM` along its axis) (what carries it in the printed part; the driver marks
every cell the box touches, so the part is whole cells and gets its studs and
sockets there).  Regions closer than a cell on every axis are merged when
their union box costs little more than the two.  When the regions would mark
more than :data:`MAX_SHARE` of the model's cells, the regions that mark the
most cells are dropped with a warning: a model that is all fine detail prints
whole faster than as a LEGO build (the paper's limit for decorative shapes).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import trimesh
from scipy import sparse
from scipy.sparse.csgraph import connected_components

from core import high_res, thickness, voxelize
from core.model import CELL_MM
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
#: Most share of the model's filled cells the suggestions may mark.
MAX_SHARE = 0.35
#: Concave faces of one surface that go at least this far round their axis (radians)
#: are a hole (half way: the end of a slot), convex ones a pin when they go more than
#: :data:`MIN_PIN_TURN` round (two fillets rounding off a wall's top go exactly half way).
MIN_TURN = math.pi * 0.99
MIN_PIN_TURN = math.pi * 1.05
#: Faces of one surface whose boxes come this close (mm) are one feature.
TOUCH_MM = 0.01
#: Two regions are merged when their union box marks at most this many times their cells.
MERGE_GROWTH = 1.1


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
    costly), the ``share`` of the model's filled cells the regions mark (on the grid
    centred on the part), and ``warnings`` in words."""

    regions: tuple
    dropped: tuple = ()
    share: float = 0.0
    warnings: tuple = ()
    source: str = "mesh"

    @property
    def boxes(self) -> list:
        """The regions' boxes ((2, 3) arrays, model mm), as :class:`core.high_res.Regions` takes them."""
        return [r.box for r in self.regions]

    def to_json(self, offset=(0.0, 0.0, 0.0)) -> dict:
        return {"source": self.source, "share_of_cells": round(self.share, 4),
                "regions": [r.to_json(offset) for r in self.regions],
                "dropped": [r.to_json(offset) for r in self.dropped],
                "warnings": list(self.warnings)}


def suggest(model, tolerance_mm: float = TOLERANCE_MM, limit_mm: float = LIMIT_MM,
            max_share: float = MAX_SHARE) -> Suggestions:
    """The suggested regions of a loaded model (:class:`core.mesh_io.LoadedModel`), in its
    frame: from its B-rep faces when it has one, else from its mesh; merged, and capped
    at ``max_share`` of its cells (the costliest dropped with a warning)."""
    if model.brep is not None:
        features, source = brep_features(model.brep, tolerance_mm, limit_mm), "brep"
    else:
        features, source = mesh_features(model.mesh, tolerance_mm, limit_mm), "mesh"
    grid = _grid(model)
    regions = merged([Region(f.box, (f,)) for f in features], grid)
    kept, dropped, share = _capped(grid, regions, max_share)
    warnings = ()
    if dropped:
        warnings = (f"the suggestions would mark {share[1]:.0%} of the part; "
                    f"{len(dropped)} region(s) marking the most were dropped to stay under "
                    f"{max_share:.0%} ({dropped[0].reason}{', ...' if len(dropped) > 1 else ''}): "
                    f"a part that is mostly fine detail prints faster whole "
                    f"(artistic or decorative shapes)",)
    return Suggestions(tuple(kept), tuple(dropped), share[0], warnings, source)


def share_of(grid, boxes) -> float:
    """The share of ``grid``'s filled cells that the ``boxes`` touch."""
    if not boxes or grid.count == 0:
        return 0.0
    return float(np.count_nonzero(high_res.Regions.of(boxes).cells(grid))) / grid.count


def _grid(model):
    origin, shape = voxelize.grid_frame(model.mesh.bounds)
    return voxelize.legofy(voxelize.snap_to_lattice(model.mesh, origin, np.asarray(CELL_MM)),
                           origin=origin, shape=shape, closed=model.watertight)


def _capped(grid, regions: list, max_share: float):
    """``regions`` without the costliest until they mark at most ``max_share`` of ``grid``:
    (kept, dropped, (share kept, share of all))."""
    if not regions:
        return [], [], (0.0, 0.0)
    masks = [high_res.Regions.of([r.box]).cells(grid) for r in regions]
    total = max(grid.count, 1)
    union = np.logical_or.reduce(masks)
    first = float(np.count_nonzero(union)) / total
    order = sorted(range(len(regions)), key=lambda n: -np.count_nonzero(masks[n]))
    dropped: list = []
    share = first
    for n in order:
        if share <= max_share:
            break
        dropped.append(n)
        rest = [masks[m] for m in range(len(regions)) if m not in dropped]
        share = float(np.count_nonzero(np.logical_or.reduce(rest))) / total if rest else 0.0
    kept = [r for n, r in enumerate(regions) if n not in dropped]
    return kept, [regions[n] for n in dropped], (share, first)


def merged(regions: list, grid) -> list:
    """``regions`` with those closer than a cell on every axis merged into their union
    box, when that box marks at most :data:`MERGE_GROWTH` times the cells of ``grid``
    the two mark (so that no sliver of LEGO is left between two printed parts)."""
    out = list(regions)
    cells = [high_res.box_cells(grid, r.box) & grid.filled for r in out]
    cell = np.asarray(grid.cell)
    changed = True
    while changed:
        changed = False
        for a in range(len(out)):
            for b in range(a + 1, len(out)):
                ra, rb = out[a], out[b]
                gap = np.maximum(ra.box[0], rb.box[0]) - np.minimum(ra.box[1], rb.box[1])
                if np.any(gap >= cell):
                    continue
                union = np.stack([np.minimum(ra.box[0], rb.box[0]), np.maximum(ra.box[1], rb.box[1])])
                marks = high_res.box_cells(grid, union) & grid.filled
                if np.count_nonzero(marks) > MERGE_GROWTH * np.count_nonzero(cells[a] | cells[b]):
                    continue
                out[a], cells[a] = Region(union, ra.features + rb.features), marks
                del out[b], cells[b]
                changed = True
                break
            if changed:
                break
    return out


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
    ``concave``, sampled surface ``points`` and its box ``lo``-``hi``."""
    from OCP.BRepAdaptor import BRepAdaptor_Surface
    from OCP.BRepBndLib import BRepBndLib
    from OCP.BRepGProp import BRepGProp_Face
    from OCP.BRepTools import BRepTools
    from OCP.Bnd import Bnd_Box
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
    uv = np.stack(np.meshgrid(np.linspace(umin, umax, 5), np.linspace(vmin, vmax, 5)), -1).reshape(-1, 2)
    points = np.array([surface.Value(float(u), float(v)).Coord() for u, v in uv])
    point, normal = gp_Pnt(), gp_Vec()
    BRepGProp_Face(face).Normal((umin + umax) / 2, (vmin + vmax) / 2, point, normal)
    p = np.array(point.Coord())
    radial = (p - origin) - np.dot(p - origin, a) * a
    concave = float(np.dot(np.array(normal.Coord()), radial)) < 0
    box = Bnd_Box()
    BRepBndLib.AddOptimal_s(face, box, False, False)
    key = (int(kind), concave, tuple(np.round(a, 3)), tuple(np.round(line, 2)),
           tuple(round(v, 3) for v in size))
    return {"key": key, "diameter": float(diameter), "turn": float(umax - umin), "axis": a,
            "line": line, "concave": concave, "points": points,
            "lo": np.minimum(box.CornerMin().Coord(), points.min(axis=0)),
            "hi": np.maximum(box.CornerMax().Coord(), points.max(axis=0))}


# --- meshes -------------------------------------------------------------------------------

def mesh_features(mesh: trimesh.Trimesh, tolerance_mm: float = TOLERANCE_MM,
                  limit_mm: float = LIMIT_MM) -> list:
    """Round holes and pins of a triangle mesh (:func:`_round_features`) and its walls
    thinner than a cell (:func:`_thin_walls`)."""
    return _round_features(mesh, tolerance_mm, limit_mm) + _thin_walls(mesh, tolerance_mm)


def _round_features(mesh, tolerance_mm, limit_mm) -> list:
    return []


def _thin_walls(mesh, tolerance_mm) -> list:
    return []
