"""The Booleans a printed part is cut with: manifold3d for mesh models, OpenCascade for B-rep.

:class:`Mesh` and :class:`Brep` offer the same operations (boxes, stud cylinders, bars,
tapers, union, cut, intersection, the model inside an envelope, volume, pieces, the one
solid and its mesh), so one construction serves both kinds of model.  :func:`finished` makes
the result one solid with a watertight mesh, welding edges where it touches itself;
:class:`InvalidSolid` says the Booleans gave something else (the part is then made on the
mesh).  OpenCascade is imported only where a B-rep operation runs.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import manifold3d as m3
import numpy as np
import trimesh

if TYPE_CHECKING:  # OpenCascade is imported where B-rep parts are made
    from OCP.TopoDS import TopoDS_Shape


#: Segments of a stud's circle in a mesh part (the B-rep part has a true cylinder).
STUD_SEGMENTS = 96
#: Tessellation of a B-rep part's STL: linear (mm) and angular (rad) deflection, fine
#: enough that a stud's flats are within 0.01 mm of its diameter.
MESH_TOL_MM = 0.01
MESH_ANGLE_RAD = 0.1
#: Fuzzy tolerance (mm) of the part's OpenCascade Booleans.
FUZZY_MM = 1e-5
#: Thickness (mm) of the weld that fills an edge where a part touches itself.
WELD_MM = 0.4
#: A piece of a part smaller than this (mm³) is a Boolean crumb, dropped.
CRUMB_MM3 = 1e-3


class InvalidSolid(Exception):
    """The B-rep Booleans gave a shape that is not one valid solid; the message says how."""


def finished(engine, shape, part_id: str, rounds: int = 3):
    """``shape`` as one solid (:meth:`only_solid`) and its watertight mesh, tessellated
    once per round: every edge where it touches itself (four faces on one edge, as where
    a model edge meets a socket's corner exactly) is filled by a box :data:`WELD_MM`
    thick round the edge, up to ``rounds`` times, so that its STL is a 2-manifold.
    Raises :class:`InvalidSolid` when the mesh is still not watertight."""
    for n in range(rounds + 1):
        solid = engine.only_solid(shape, part_id)
        mesh = engine.mesh(solid)
        edges, counts = np.unique(mesh.edges_sorted, axis=0, return_counts=True)
        touching = edges[counts > 2]
        if len(touching) == 0 or n == rounds:
            break
        ends = mesh.vertices[touching]
        shape = engine.union([solid] + [engine.box(e.min(axis=0) - WELD_MM / 2, e.max(axis=0) + WELD_MM / 2)
                                        for e in ends])
    if not mesh.is_watertight:
        raise InvalidSolid("a solid whose tessellation is not watertight")
    return solid, mesh


def cube(lo, hi) -> m3.Manifold:
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    return m3.Manifold.cube(list(hi - lo)).translate(list(lo))


class Mesh:
    """The part's Booleans on manifold3d Manifolds (mesh models)."""

    def __init__(self, model: m3.Manifold):
        self.model = model

    def box(self, lo, hi) -> m3.Manifold:
        return cube(lo, hi)

    def cylinder(self, x, y, z0, z1, r) -> m3.Manifold:
        return m3.Manifold.cylinder(float(z1 - z0), float(r), -1.0, STUD_SEGMENTS).translate([x, y, z0])

    def bar(self, a, b, side) -> m3.Manifold:
        return _bar_hull(np.asarray(a), np.asarray(b), side)

    def taper(self, rects) -> m3.Manifold:
        return m3.Manifold.hull_points(_rect_corners(rects).reshape(-1, 3).tolist())

    def union(self, shapes):
        return shapes[0] if len(shapes) == 1 else m3.Manifold.batch_boolean(shapes, m3.OpType.Add)

    def cut(self, shape, tools):
        return shape if not tools else shape - self.union(tools)

    def intersect(self, a, b):
        return a ^ b

    def common(self, envelope, lo, hi):
        return m3.Manifold(((self.model ^ cube(lo, hi)) ^ envelope).to_mesh64())

    def volume(self, shape) -> float:
        return float(shape.volume())

    def pieces(self, shape) -> list:
        return [p for p in shape.decompose() if p.volume() > CRUMB_MM3]

    def only_solid(self, shape, part_id: str):
        pieces = self.pieces(shape)
        if len(pieces) != 1:
            raise InvalidSolid(f"{len(pieces)} pieces")
        return m3.Manifold(pieces[0].to_mesh64())

    def mesh(self, shape) -> trimesh.Trimesh:
        out = shape.to_mesh64()
        mesh = trimesh.Trimesh(np.asarray(out.vert_properties, np.float64)[:, :3],
                               np.asarray(out.tri_verts, np.int64), process=False)
        mesh.merge_vertices()
        return mesh


def _bar_hull(a: np.ndarray, b: np.ndarray, side: float) -> m3.Manifold:
    """The convex hull of two axis-aligned cubes of ``side`` centred on ``a`` and ``b``."""
    corners = np.array(np.meshgrid(*[[-side / 2, side / 2]] * 3, indexing="ij")).reshape(3, -1).T
    return m3.Manifold.hull_points(np.concatenate([a + corners, b + corners]).tolist())


def _rect_corners(rects: np.ndarray) -> np.ndarray:
    """(2, 4, 3): the corners, in order round, of the two flat rectangles of a taper."""
    out = []
    for lo, hi in (rects[:2], rects[2:]):
        z = lo[2]
        out.append([[lo[0], lo[1], z], [hi[0], lo[1], z], [hi[0], hi[1], z], [lo[0], hi[1], z]])
    return np.asarray(out, dtype=float)


class Brep:
    """The part's Booleans on OpenCascade shapes (B-rep models)."""

    def __init__(self, model: TopoDS_Shape):
        self.model = model

    def box(self, lo, hi) -> TopoDS_Shape:
        from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox
        from OCP.gp import gp_Pnt
        return BRepPrimAPI_MakeBox(gp_Pnt(*map(float, lo)), gp_Pnt(*map(float, hi))).Shape()

    def cylinder(self, x, y, z0, z1, r) -> TopoDS_Shape:
        from OCP.BRepPrimAPI import BRepPrimAPI_MakeCylinder
        from OCP.gp import gp_Ax2, gp_Dir, gp_Pnt
        axis = gp_Ax2(gp_Pnt(float(x), float(y), float(z0)), gp_Dir(0, 0, 1))
        return BRepPrimAPI_MakeCylinder(axis, float(r), float(z1 - z0)).Shape()

    def bar(self, a, b, side) -> TopoDS_Shape:
        from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox
        from OCP.gp import gp_Ax2, gp_Dir, gp_Pnt
        a, b = np.asarray(a, float), np.asarray(b, float)
        axis = b - a
        length = float(np.linalg.norm(axis))
        direction = axis / length if length > 1e-9 else np.array([0.0, 0.0, 1.0])
        frame = gp_Ax2(gp_Pnt(0, 0, 0), gp_Dir(*direction))
        x, y = (np.array([v.X(), v.Y(), v.Z()]) for v in (frame.XDirection(), frame.YDirection()))
        corner = a - direction * side / 2 - (x + y) * side / 2
        return BRepPrimAPI_MakeBox(gp_Ax2(gp_Pnt(*corner), gp_Dir(*direction), gp_Dir(*x)),
                                   side, side, length + side).Shape()

    def taper(self, rects) -> TopoDS_Shape:
        from OCP.BRepBuilderAPI import BRepBuilderAPI_MakePolygon
        from OCP.BRepOffsetAPI import BRepOffsetAPI_ThruSections
        from OCP.gp import gp_Pnt
        loft = BRepOffsetAPI_ThruSections(True, True)
        for corners in _rect_corners(rects):
            loft.AddWire(BRepBuilderAPI_MakePolygon(*[gp_Pnt(*map(float, c)) for c in corners], True).Wire())
        loft.Build()
        return loft.Shape()

    def union(self, shapes):
        from OCP.BRepAlgoAPI import BRepAlgoAPI_Fuse
        return shapes[0] if len(shapes) == 1 else unified(_occ(BRepAlgoAPI_Fuse(), shapes[0], shapes[1:]))

    def cut(self, shape, tools):
        from OCP.BRepAlgoAPI import BRepAlgoAPI_Cut
        return shape if not tools else unified(_occ(BRepAlgoAPI_Cut(), shape, tools))

    def intersect(self, a, b):
        from OCP.BRepAlgoAPI import BRepAlgoAPI_Common
        return unified(_occ(BRepAlgoAPI_Common(), a, [b]))

    def common(self, envelope, lo, hi):
        from OCP.BRepAlgoAPI import BRepAlgoAPI_Common
        return unified(_occ(BRepAlgoAPI_Common(), self.model, [envelope]))

    def volume(self, shape) -> float:
        return occ_volume(shape) if occ_solids(shape) else 0.0

    def pieces(self, shape) -> list:
        return [s for s in occ_solids(shape) if occ_volume(s) > CRUMB_MM3]

    def only_solid(self, shape, part_id: str):
        from OCP.BRepCheck import BRepCheck_Analyzer
        from OCP.ShapeFix import ShapeFix_Shape
        pieces = self.pieces(shape)
        if len(pieces) != 1:
            raise InvalidSolid(f"{len(pieces)} pieces")
        solid = pieces[0]
        if not BRepCheck_Analyzer(solid).IsValid():
            fix = ShapeFix_Shape(solid)
            fix.Perform()
            solid = fix.Shape()
            if len(occ_solids(solid)) != 1 or not BRepCheck_Analyzer(solid).IsValid():
                raise InvalidSolid("not a valid solid")
        return occ_solids(solid)[0]

    def mesh(self, shape) -> trimesh.Trimesh:
        from core.parts.brick_solids import to_trimesh
        return to_trimesh(shape, MESH_TOL_MM, MESH_ANGLE_RAD)


def occ_solids(shape: TopoDS_Shape) -> list[TopoDS_Shape]:
    from OCP.TopAbs import TopAbs_SOLID

    from core.parts.brick_solids import sub_shapes
    return sub_shapes(shape, TopAbs_SOLID)


def occ_volume(shape: TopoDS_Shape) -> float:
    """The volume (mm³) of the OCC ``shape``."""
    import cadquery as cq
    return float(cq.Shape.cast(shape).Volume())


def _occ(op, argument, tools):
    """:func:`core.parts.brick_solids.run_boolean` inside a part's construction: a failure
    makes the part on the mesh instead (:class:`InvalidSolid`).  Faces closer than
    :data:`FUZZY_MM` count as one (a model aligned onto an earlier version lies a
    rounding error off the cell planes)."""
    from core.parts.brick_solids import BooleanFailed, run_boolean
    op.SetFuzzyValue(FUZZY_MM)
    try:
        return run_boolean(op, argument, list(tools), None, True)
    except BooleanFailed:
        raise InvalidSolid("an OpenCascade Boolean that failed") from None


def unified(shape: TopoDS_Shape) -> TopoDS_Shape:
    """``shape`` with coplanar / co-cylindrical neighbouring faces merged into one."""
    from OCP.ShapeUpgrade import ShapeUpgrade_UnifySameDomain
    unify = ShapeUpgrade_UnifySameDomain(shape, True, True, False)
    unify.Build()
    return unify.Shape()


def as_manifold(mesh: trimesh.Trimesh) -> m3.Manifold:
    """``mesh`` (closed) as a manifold3d Manifold."""
    return m3.Manifold(m3.Mesh64(vert_properties=np.ascontiguousarray(mesh.vertices, np.float64),
                                 tri_verts=np.ascontiguousarray(mesh.faces, np.uint64)))
