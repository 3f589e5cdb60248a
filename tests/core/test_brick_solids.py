"""Tests for core.parts.brick_solids: exact LEGO brick solids with tagged faces."""

from __future__ import annotations

import io
import math
from dataclasses import replace

import cadquery as cq
import numpy as np
import pytest
from OCP.Bnd import Bnd_Box
from OCP.BRepAdaptor import BRepAdaptor_Surface
from OCP.BRepBndLib import BRepBndLib
from OCP.BRepCheck import BRepCheck_Analyzer
from OCP.GeomAbs import GeomAbs_Cylinder, GeomAbs_Plane
from OCP.TopAbs import TopAbs_REVERSED

from core.catalog import CATALOG
from core.errors import InputError
from core.parts.brick_solids import SIDE_TAGS, BrickGeometry, brick_solid, face_list, to_trimesh

GEO = BrickGeometry()
FOOTPRINTS = sorted({(sx, sy, p.layers) for p in CATALOG for sx, sy in p.orientations()})


def bbox(shape) -> np.ndarray:
    """Tight bounding box [[xmin, ymin, zmin], [xmax, ymax, zmax]] of an OCP/cadquery shape."""
    box = Bnd_Box()
    BRepBndLib.AddOptimal_s(getattr(shape, "wrapped", shape), box, False, False)
    return np.array(box.Get()).reshape(2, 3)


def surface(face):
    """(kind, data) of a face: ("plane", (outward normal, point)) or ("cylinder", (radius, axis xy))."""
    s = BRepAdaptor_Surface(face)
    if s.GetType() == GeomAbs_Plane:
        pl = s.Plane()
        d, o = pl.Axis().Direction(), pl.Location()
        n = np.array([d.X(), d.Y(), d.Z()])
        if (face.Orientation() == TopAbs_REVERSED) == pl.Direct():
            n = -n
        return "plane", (n, np.array([o.X(), o.Y(), o.Z()]))
    assert s.GetType() == GeomAbs_Cylinder
    cyl = s.Cylinder()
    o = cyl.Location()
    return "cylinder", (cyl.Radius(), np.array([o.X(), o.Y()]))


def expected_volume(sx, sy, layers, g=GEO):
    """Volume of the brick from its dimensions, by hand."""
    h, inner_h = layers * g.plate_height, layers * g.plate_height - g.top
    ox, oy = sx * g.pitch - 2 * g.play, sy * g.pitch - 2 * g.play
    w = g.printed_wall
    v = ox * oy * h - (ox - 2 * w) * (oy - 2 * w) * inner_h
    v += sx * sy * math.pi * (g.printed_stud_diameter / 2) ** 2 * g.stud_height
    if sx >= 2 and sy >= 2:
        v += (sx - 1) * (sy - 1) * math.pi * ((g.printed_tube_outer / 2) ** 2
                                              - (g.printed_tube_inner / 2) ** 2) * inner_h
    elif max(sx, sy) >= 2:
        v += (max(sx, sy) - 1) * math.pi * (g.printed_pin_diameter / 2) ** 2 * inner_h
    return v


def radii(brick, tag):
    """Radii of the cylindrical faces carrying ``tag``."""
    return sorted(round(surface(f)[1][0], 9) for f in brick.faces(tag)
                  if surface(f)[0] == "cylinder")


@pytest.fixture(scope="module")
def all_bricks():
    """Every catalog footprint in both orientations, as plates and bricks."""
    return {fp: brick_solid(*fp) for fp in FOOTPRINTS}


def test_2x4_brick_bbox_and_volume():
    b = brick_solid(2, 4, 3)
    lo, hi = bbox(b.shape)
    assert lo == pytest.approx([0.1, 0.1, 0.0], abs=1e-6)
    assert hi - lo == pytest.approx([15.8, 31.8, 9.6 + 1.7], abs=1e-6)
    block = 15.8 * 31.8 * 9.6
    vol = b.shape.Volume()
    assert vol == pytest.approx(expected_volume(2, 4, 3), rel=1e-7)
    assert 0.25 * block < vol < block


def test_origin_moves_brick_and_plate_cavity_is_shallow():
    plate = brick_solid(4, 2, 1, origin=(8.0, -16.0, 3.2))
    lo, hi = bbox(plate.shape)
    assert lo == pytest.approx([8.1, -15.9, 3.2], abs=1e-6)
    assert hi == pytest.approx([8.0 + 31.9, -16.0 + 15.9, 3.2 + 3.2 + 1.7], abs=1e-6)
    for brick, ceiling in ((plate, 3.2 + 3.2 - 1.0), (brick_solid(4, 2, 3), 9.6 - 1.0)):
        heights = [surface(f)[1][1][2] for f in brick.faces("cavity")
                   if surface(f)[0] == "plane" and abs(surface(f)[1][0][2]) > 0.5]
        assert heights == pytest.approx([ceiling])


@pytest.mark.parametrize("clearance", [0.0, 0.1, 0.3])
def test_clearance_sets_stud_tube_pin_diameters(clearance):
    g = replace(GEO, clearance=clearance)
    wide, narrow = brick_solid(2, 4, 3, g), brick_solid(1, 3, 1, g)
    for tag in (t for t in wide.tags if t.startswith("stud:")):
        assert [2 * r for r in radii(wide, tag)] == pytest.approx([4.8 - clearance])
    for tag in (t for t in wide.tags if t.startswith("tube:")):
        assert [2 * r for r in radii(wide, tag)] == pytest.approx([4.8 + clearance, 6.51 - clearance])
    for tag in (t for t in narrow.tags if t.startswith("pin:")):
        assert [2 * r for r in radii(narrow, tag)] == pytest.approx([3.2 - clearance])
    assert wide.shape.Volume() == pytest.approx(expected_volume(2, 4, 3, g), rel=1e-7)
    assert narrow.shape.Volume() == pytest.approx(expected_volume(1, 3, 1, g), rel=1e-7)


def test_counts_on_2x4_brick_and_1x4_brick():
    b = brick_solid(2, 4, 3)
    assert sorted(t for t in b.tags if t.startswith("stud:")) == sorted(
        f"stud:{a},{c}" for a in range(2) for c in range(4))
    assert sorted(t for t in b.tags if t.startswith("tube:")) == ["tube:0,0", "tube:0,1", "tube:0,2"]
    assert not any(t.startswith("pin:") for t in b.tags)
    one = brick_solid(1, 4, 3)
    assert sorted(t for t in one.tags if t.startswith("pin:")) == ["pin:0", "pin:1", "pin:2"]
    assert not any(t.startswith("tube:") for t in one.tags)
    centres = sorted(tuple(np.round(surface(one.faces(f"pin:{a}")[0])[1][1], 9)) for a in range(3)
                     if surface(one.faces(f"pin:{a}")[0])[0] == "cylinder")
    assert all(c[0] == 4.0 for c in centres)
    lone = brick_solid(1, 1, 3)
    assert not any(t.startswith(("pin:", "tube:")) for t in lone.tags)


@pytest.mark.slow
@pytest.mark.parametrize("fp", FOOTPRINTS, ids=lambda fp: "x".join(map(str, fp)))
def test_catalog_solids_valid_tagged_watertight(all_bricks, fp):
    sx, sy, layers = fp
    b = all_bricks[fp]
    assert BRepCheck_Analyzer(b.shape.wrapped).IsValid()
    assert b.shape.ShapeType() == "Solid" and len(b.shape.Shells()) == 1
    assert b.shape.Shells()[0].Closed()
    n = len(face_list(b.shape))
    idx = sorted(i for v in b.tags.values() for i in v)
    assert idx == list(range(n)), "every face has exactly one tag"
    studs = [t for t in b.tags if t.startswith("stud:")]
    tubes = [t for t in b.tags if t.startswith("tube:")]
    pins = [t for t in b.tags if t.startswith("pin:")]
    assert len(studs) == sx * sy
    assert len(tubes) == ((sx - 1) * (sy - 1) if min(sx, sy) >= 2 else 0)
    assert len(pins) == (max(sx, sy) - 1 if min(sx, sy) == 1 else 0)
    assert set(b.tags) == set(SIDE_TAGS) | {"top", "bottom", "cavity"} | set(studs + tubes + pins)
    assert b.shape.Volume() == pytest.approx(expected_volume(sx, sy, layers), rel=1e-7)
    mesh = to_trimesh(b.shape)
    assert mesh.is_watertight and mesh.is_winding_consistent
    assert mesh.volume == pytest.approx(b.shape.Volume(), rel=5e-3)


def test_tags_agree_with_geometry():
    g = GEO
    b = brick_solid(2, 3, 3, origin=(16.0, 8.0, 0.0))
    x0, x1, y0, y1, h = 16.1, 31.9, 8.1, 31.9, 9.6
    want = {"side-x": ([-1, 0, 0], 0, x0), "side+x": ([1, 0, 0], 0, x1),
            "side-y": ([0, -1, 0], 1, y0), "side+y": ([0, 1, 0], 1, y1),
            "top": ([0, 0, 1], 2, h), "bottom": ([0, 0, -1], 2, 0.0)}
    for tag, (normal, axis, at) in want.items():
        (face,) = b.faces(tag)
        kind, (n, point) = surface(face)
        assert kind == "plane" and n == pytest.approx(normal) and point[axis] == pytest.approx(at)
    for a in range(2):
        for c in range(3):
            centre = [16.0 + (a + 0.5) * 8, 8.0 + (c + 0.5) * 8]
            faces = b.faces(f"stud:{a},{c}")
            lo, hi = np.min([bbox(f)[0] for f in faces], 0), np.max([bbox(f)[1] for f in faces], 0)
            r = g.printed_stud_diameter / 2
            assert lo == pytest.approx([centre[0] - r, centre[1] - r, h], abs=1e-6)
            assert hi == pytest.approx([centre[0] + r, centre[1] + r, h + g.stud_height], abs=1e-6)
    for c in range(2):
        faces = b.faces(f"tube:0,{c}")
        axes = [surface(f)[1][1] for f in faces if surface(f)[0] == "cylinder"]
        assert axes and all(ax == pytest.approx([24.0, 8.0 + (c + 1) * 8]) for ax in axes)
    for face in b.faces("cavity"):
        lo, hi = bbox(face)
        assert x0 + g.printed_wall - 1e-6 <= lo[0] and hi[0] <= x1 - g.printed_wall + 1e-6
        assert 0.0 <= lo[2] and hi[2] <= h - g.top + 1e-6


def test_face_order_is_stable():
    b = brick_solid(2, 2, 3)
    again = brick_solid(2, 2, 3)
    assert again.tags == b.tags
    assert [f.wrapped.IsSame(g) for f, g in zip(b.shape.Faces(), face_list(b.shape))] == [True] * len(b.tag_of())
    buf = io.BytesIO()
    b.shape.exportBrep(buf)
    buf.seek(0)
    back = cq.Shape.importBrep(buf)
    before, after = face_list(b.shape), face_list(back)
    assert len(after) == len(before)
    for f, g in zip(before, after):
        assert bbox(f) == pytest.approx(bbox(g), abs=1e-9)
    moved = b.shape.translate(cq.Vector(8, 0, 0))
    for f, g in zip(before, face_list(moved)):
        assert bbox(f) + [[8, 0, 0], [8, 0, 0]] == pytest.approx(bbox(g), abs=1e-9)


@pytest.mark.parametrize("call", [
    lambda: brick_solid(0, 2, 3),
    lambda: brick_solid(2, 2, 2.5),
    lambda: brick_solid(2, 2, 3, origin=(0, float("nan"), 0)),
    lambda: brick_solid(2, 2, 3, replace(GEO, clearance=5.0)),
    lambda: brick_solid(2, 2, 1, replace(GEO, top=3.2)),
    lambda: brick_solid(2, 2, 1, replace(GEO, wall=float("inf"))),
    lambda: to_trimesh("not a shape"),
    lambda: to_trimesh(brick_solid(1, 1, 1).shape, tolerance=0),
])
def test_bad_arguments_are_value_or_type_errors(call):
    with pytest.raises((ValueError, TypeError)) as err:
        call()
    assert not isinstance(err.value, InputError)  # a wrong call of ours, not the user's input
    assert "\n" not in str(err.value)


#: Merge cases: (grid cells, sizes) of face-to-face connected bricks.
MERGES = {
    "side by side": ([(0, 0, 0), (2, 0, 0)], [(2, 4, 3), (2, 4, 3)]),
    "2x4 beside 2x2 offset one stud": ([(0, 0, 0), (2, 1, 0)], [(2, 4, 3), (2, 2, 3)]),
    "stacked": ([(0, 0, 0), (0, 0, 3)], [(2, 4, 3), (2, 4, 3)]),
    "plate on part of a brick": ([(0, 0, 0), (1, 2, 3)], [(2, 4, 3), (2, 4, 1)]),
    "1x4 on a 1x2 and a plate beside": ([(0, 0, 0), (0, 0, 3), (1, 0, 0)], [(1, 2, 3), (1, 4, 3), (1, 2, 1)]),
    "L of three with a cap": ([(0, 0, 0), (2, 0, 0), (1, 1, 3)], [(2, 2, 3), (1, 2, 3), (2, 2, 3)]),
}


def _exposed_studs(n, cells, sizes):
    """Stud tags of brick ``n`` that no other brick of the group stands on."""
    (i, j, k), (sx, sy, sz) = cells[n], sizes[n]
    covered = {(a, b) for (ci, cj, ck), (tx, ty, _) in zip(cells, sizes) if ck == k + sz
               for a in range(sx) for b in range(sy) if ci <= i + a < ci + tx and cj <= j + b < cj + ty}
    return {f"stud:{a},{b}" for a in range(sx) for b in range(sy) if (a, b) not in covered}


def _on_boundary(face, solid) -> bool:
    """True when the face lies on the boundary of ``solid``: just outside it along the face's
    outward normal is outside the solid, just inside is inside.  Tested at the surface point
    of the centre (in the face's (u, v)) of the largest triangle of the face's mesh, a point
    strictly inside the face."""
    from OCP.BRep import BRep_Tool
    from OCP.BRepClass3d import BRepClass3d_SolidClassifier
    from OCP.BRepGProp import BRepGProp_Face
    from OCP.BRepMesh import BRepMesh_IncrementalMesh
    from OCP.gp import gp_Pnt, gp_Vec
    from OCP.TopAbs import TopAbs_IN, TopAbs_OUT
    from OCP.TopLoc import TopLoc_Location
    BRepMesh_IncrementalMesh(face, 0.05, False, 0.3, False)
    tri = BRep_Tool.Triangulation_s(face, TopLoc_Location())
    uv = np.array([[tri.UVNode(i).X(), tri.UVNode(i).Y()] for i in range(1, tri.NbNodes() + 1)])
    xyz = np.array([[tri.Node(i).X(), tri.Node(i).Y(), tri.Node(i).Z()] for i in range(1, tri.NbNodes() + 1)])
    triangles = np.array([[t.Value(1) - 1, t.Value(2) - 1, t.Value(3) - 1]
                          for t in (tri.Triangle(i) for i in range(1, tri.NbTriangles() + 1))])
    corners = xyz[triangles]
    k = int(np.argmax(np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1)))
    u, v = uv[triangles[k]].mean(axis=0)
    point, normal = gp_Pnt(), gp_Vec()
    BRepGProp_Face(face).Normal(u, v, point, normal)
    c = np.array([point.X(), point.Y(), point.Z()])
    n = np.array([normal.X(), normal.Y(), normal.Z()])
    n /= np.linalg.norm(n)
    classifier = BRepClass3d_SolidClassifier(solid.wrapped)
    states = []
    for p in (c + 1e-3 * n, c - 1e-3 * n):
        classifier.Perform(gp_Pnt(*p), 1e-7)
        states.append(classifier.State())
    return states == [TopAbs_OUT, TopAbs_IN]


