"""Tests for core.parts.brick_solids: exact LEGO brick solids with tagged faces."""

from __future__ import annotations

import io
import math
from dataclasses import replace

import cadquery as cq
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from OCP.Bnd import Bnd_Box
from OCP.BRepAdaptor import BRepAdaptor_Surface
from OCP.BRepBndLib import BRepBndLib
from OCP.BRepCheck import BRepCheck_Analyzer
from OCP.GeomAbs import GeomAbs_Cylinder, GeomAbs_Plane
from OCP.TopAbs import TopAbs_REVERSED

from core.parts.brick_solids import (SIDE_TAGS, BrickGeometry, brick_solid, face_list,
                               facing_sides, to_trimesh)
from core.catalog import CATALOG
from core.errors import InputError

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


def test_flush_sides_meet_neighbour_exactly():
    a = brick_solid(2, 4, 3, flush={"side+x"})
    b = brick_solid(2, 2, 3, origin=(16.0, 8.0, 0.0), flush={"side-x"})
    pair = facing_sides((0, 0, 0), (2, 4, 3), (2, 1, 0), (2, 2, 3))
    assert pair == ("side+x", "side-x")
    (fa,), (fb,) = a.faces(pair[0]), b.faces(pair[1])
    assert bbox(fa)[:, 0] == pytest.approx([16.0, 16.0]) and bbox(fb)[:, 0] == pytest.approx([16.0, 16.0])
    assert bbox(a.shape)[0] == pytest.approx([0.1, 0.1, 0.0])
    assert BRepCheck_Analyzer(a.shape.wrapped).IsValid()
    assert a.shape.Volume() > brick_solid(2, 4, 3).shape.Volume()


@pytest.mark.parametrize("a_cell, a_size, b_cell, b_size, want", [
    ((0, 0, 0), (2, 4, 3), (2, 0, 0), (1, 2, 1), ("side+x", "side-x")),
    ((2, 0, 0), (1, 2, 1), (0, 0, 0), (2, 4, 3), ("side-x", "side+x")),
    ((0, 0, 0), (2, 4, 3), (1, 4, 2), (2, 2, 3), ("side+y", "side-y")),
    ((0, 5, 0), (2, 2, 3), (0, 0, 0), (2, 5, 3), ("side-y", "side+y")),
    ((0, 0, 0), (2, 4, 3), (0, 0, 3), (2, 4, 3), None),   # stacked
    ((0, 0, 0), (2, 2, 3), (2, 2, 0), (2, 2, 3), None),   # corner only
    ((0, 0, 0), (2, 2, 3), (2, 0, 3), (2, 2, 3), None),   # edge only
    ((0, 0, 0), (2, 2, 3), (3, 0, 0), (2, 2, 3), None),   # apart
    ((0, 0, 0), (2, 2, 3), (1, 0, 0), (2, 2, 3), None),   # overlapping
    ((0, 0), (2, 4), (0, 4), (1, 1), ("side+y", "side-y")),
])
def test_facing_sides(a_cell, a_size, b_cell, b_size, want):
    assert facing_sides(a_cell, a_size, b_cell, b_size) == want


box = st.tuples(st.tuples(*[st.integers(-4, 4)] * 3), st.tuples(*[st.integers(1, 4)] * 3))


@settings(max_examples=300, deadline=None)
@given(box, box)
def test_facing_sides_symmetric_and_consistent(a, b):
    pair = facing_sides(*a, *b)
    back = facing_sides(*b, *a)
    assert back == (None if pair is None else pair[::-1])
    if pair is not None:
        axis = "xy".index(pair[0][-1])
        sign = 1 if pair[0][-2] == "+" else -1
        a_face = a[0][axis] + (a[1][axis] if sign > 0 else 0)
        b_face = b[0][axis] + (0 if sign > 0 else b[1][axis])
        assert a_face == b_face
        assert pair[1] == ("side-" if sign > 0 else "side+") + "xy"[axis]


@pytest.mark.parametrize("call", [
    lambda: brick_solid(0, 2, 3),
    lambda: brick_solid(2, 2, 2.5),
    lambda: brick_solid(2, 2, 3, flush={"side+z"}),
    lambda: brick_solid(2, 2, 3, origin=(0, float("nan"), 0)),
    lambda: brick_solid(2, 2, 3, replace(GEO, clearance=5.0)),
    lambda: brick_solid(2, 2, 1, replace(GEO, top=3.2)),
    lambda: brick_solid(2, 2, 1, replace(GEO, wall=float("inf"))),
    lambda: facing_sides((0, 0, 0), (0, 1, 1), (1, 0, 0), (1, 1, 1)),
    lambda: facing_sides((0, 0, 0), (1, 1), (1, 0, 0), (1, 1, 1)),
    lambda: to_trimesh("not a shape"),
    lambda: to_trimesh(brick_solid(1, 1, 1).shape, tolerance=0),
])
def test_bad_arguments_are_value_or_type_errors(call):
    with pytest.raises((ValueError, TypeError)) as err:
        call()
    assert not isinstance(err.value, InputError)  # a wrong call of ours, not the user's input
    assert "\n" not in str(err.value)


def test_no_studs_and_solid_underside_cells():
    b = brick_solid(2, 4, 3, no_studs={(0, 0), (1, 0)}, solid_under={(0, 0), (1, 0), (0, 1), (1, 1)})
    assert BRepCheck_Analyzer(b.shape.wrapped).IsValid()
    assert sorted(t for t in b.tags if t.startswith("stud:")) == sorted(
        f"stud:{a},{c}" for a in range(2) for c in range(1, 4))
    # Tube 0,0 stands over solid cells only: gone; tube 0,1 is half over them: kept, clipped.
    assert sorted(t for t in b.tags if t.startswith("tube:")) == ["tube:0,1", "tube:0,2"]
    for face in b.faces("tube:0,1"):
        assert bbox(face)[0][1] >= 16.0 - 1e-6
    # The underside is solid over y < 16: the bottom face is the rim plus that rectangle whole
    # (the clipped tube's half annulus next to it keeps its tube tag).
    bottom = sum(cq.Face(f).Area() for f in b.faces("bottom"))
    rim = 15.8 * 31.8 - (15.8 - 2 * GEO.printed_wall) * (31.8 - 2 * GEO.printed_wall)
    solid_part = (15.8 - 2 * GEO.printed_wall) * (16.0 - 0.1 - GEO.printed_wall)
    assert bottom == pytest.approx(rim + solid_part, rel=1e-9)
    half_annulus = math.pi * ((GEO.printed_tube_outer / 2) ** 2 - (GEO.printed_tube_inner / 2) ** 2) / 2
    tube_bottom = [cq.Face(f).Area() for f in b.faces("tube:0,1") if np.allclose(bbox(f)[:, 2], 0.0)]
    assert sum(tube_bottom) == pytest.approx(half_annulus, rel=1e-9)


def test_joint_rectangle_becomes_one_face():
    rect = ((16.0, 8.1, 3.2), (16.0, 23.9, 9.6))
    b = brick_solid(2, 4, 3, flush={"side+x"}, joints={"j": rect})
    assert BRepCheck_Analyzer(b.shape.wrapped).IsValid()
    (i,) = b.joints["j"]
    face = face_list(b.shape)[i]
    assert bbox(face) == pytest.approx(np.array(rect), abs=1e-9)
    assert cq.Face(face).Area() == pytest.approx(15.8 * 6.4)
    assert b.tag_of()[i] == "side+x" and len(b.faces("side+x")) == 2  # the rest is one U-shaped face
    assert b.shape.Volume() == pytest.approx(brick_solid(2, 4, 3, flush={"side+x"}).shape.Volume())
    with pytest.raises(ValueError):
        brick_solid(2, 4, 3, joints={"bad": ((0, 0, 0), (1, 1, 1))})


#: Merge cases: (grid cells, sizes) of face-to-face connected bricks.
MERGES = {
    "side by side": ([(0, 0, 0), (2, 0, 0)], [(2, 4, 3), (2, 4, 3)]),
    "2x4 beside 2x2 offset one stud": ([(0, 0, 0), (2, 1, 0)], [(2, 4, 3), (2, 2, 3)]),
    "stacked": ([(0, 0, 0), (0, 0, 3)], [(2, 4, 3), (2, 4, 3)]),
    "plate on part of a brick": ([(0, 0, 0), (1, 2, 3)], [(2, 4, 3), (2, 4, 1)]),
    "1x4 on a 1x2 and a plate beside": ([(0, 0, 0), (0, 0, 3), (1, 0, 0)], [(1, 2, 3), (1, 4, 3), (1, 2, 1)]),
    "L of three with a cap": ([(0, 0, 0), (2, 0, 0), (1, 1, 3)], [(2, 2, 3), (1, 2, 3), (2, 2, 3)]),
}


def _fused(cells, sizes):
    """The Boolean union (computed here, independently) of the bricks built as merging builds them."""
    from OCP.BRepAlgoAPI import BRepAlgoAPI_Fuse
    from core.parts.brick_solids import part_contacts
    solids = [brick_solid(*s, GEO, tuple(np.array(c) * [8.0, 8.0, 3.2]), k.flush, k.no_studs, k.solid_under).shape
              for c, s, k in zip(cells, sizes, part_contacts(cells, sizes))]
    out = solids[0]
    for s in solids[1:]:
        out = cq.Shape.cast(BRepAlgoAPI_Fuse(out.wrapped, s.wrapped).Shape())
    return out


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


@pytest.mark.slow
@pytest.mark.parametrize("case", sorted(MERGES))
def test_merge_by_face_removal_is_the_union_without_internal_faces(case):
    from core.parts.brick_solids import merged_solid
    cells, sizes = MERGES[case]
    merged = merged_solid(cells, sizes, method="remove")
    assert merged.method == "face removal" and merged.removed_faces >= 2
    shape = cq.Shape.cast(merged.shape)
    assert shape.ShapeType() == "Solid" and BRepCheck_Analyzer(merged.shape).IsValid()
    assert len(shape.Shells()) == 1 and shape.Shells()[0].Closed()
    union = _fused(cells, sizes)
    assert len(union.Solids()) == 1
    assert shape.Volume() == pytest.approx(union.Volume(), rel=1e-9)
    assert len(shape.Faces()) <= len(union.Faces())
    faces = face_list(merged.shape)
    assert all(_on_boundary(f, union) for f in faces), "a face of the merged solid is not on the outside"
    from core.parts.brick_solids import _face_map
    fmap = _face_map(merged.shape)
    tagged = {fmap.FindIndex(f) for f, _ in merged.tagged}
    assert tagged == set(range(1, len(faces) + 1)), "every face keeps a tag, every tag is on a face"
    studs = {t for _, t in merged.tagged if ":stud:" in t}
    assert studs == {f"{n}:{t}" for n, (c, s) in enumerate(zip(cells, sizes)) for t in _exposed_studs(n, cells, sizes)}
    mesh = to_trimesh(merged.shape)
    assert mesh.is_watertight and mesh.volume == pytest.approx(union.Volume(), rel=5e-3)


def test_fuse_fallback_gives_the_same_solid_and_split_restores_faces():
    from core.parts.brick_solids import merged_solid
    cells, sizes = MERGES["2x4 beside 2x2 offset one stud"]
    removed, fused = merged_solid(cells, sizes), merged_solid(cells, sizes, method="fuse")
    assert removed.method == "face removal" and fused.method == "fuse"
    assert cq.Shape.cast(fused.shape).Volume() == pytest.approx(cq.Shape.cast(removed.shape).Volume(), rel=1e-9)
    # Merged: no face on the joint plane x = 16 over the 2x2's span; split: each brick has its side back.
    on_joint = [f for f in face_list(removed.shape)
                if np.allclose(bbox(f)[:, 0], 16.0) and bbox(f)[0][1] < 16 < bbox(f)[1][1]]
    assert not on_joint
    alone = [merged_solid([c], [s]) for c, s in zip(cells, sizes)]
    assert [a.method for a in alone] == ["single brick"] * 2
    for a, (c, s) in zip(alone, zip(cells, sizes)):
        plain = brick_solid(*s, origin=tuple(np.array(c) * [8.0, 8.0, 3.2]))
        assert cq.Shape.cast(a.shape).Volume() == pytest.approx(plain.shape.Volume(), rel=1e-12)
    assert any(np.allclose(bbox(f)[:, 0], 15.9) for f in face_list(alone[0].shape))


@pytest.mark.parametrize("cells, sizes", [
    ([(0, 0, 0), (1, 0, 0)], [(2, 2, 3), (2, 2, 3)]),   # overlapping
    ([(0, 0, 0), (3, 0, 0)], [(2, 2, 3), (2, 2, 3)]),   # apart
    ([(0, 0, 0), (2, 2, 0)], [(2, 2, 3), (2, 2, 3)]),   # corner only
    ([], []),
])
def test_merge_refuses_bad_groups(cells, sizes):
    from core.parts.brick_solids import merged_solid
    with pytest.raises(ValueError):
        merged_solid(cells, sizes)


def test_failed_face_removal_falls_back_to_the_fuse(monkeypatch):
    from core.parts import brick_solids
    cells, sizes = MERGES["stacked"]
    good = brick_solids.merged_solid(cells, sizes)

    def refuse(bricks, tagged):
        raise brick_solids._MergeFailed("sewing left 2 free and 0 multiple edges")
    monkeypatch.setattr(brick_solids, "_sew", refuse)
    fallback = brick_solids.merged_solid(cells, sizes)
    assert fallback.method == "fuse (face removal failed: sewing left 2 free and 0 multiple edges)"
    assert cq.Shape.cast(fallback.shape).Volume() == pytest.approx(cq.Shape.cast(good.shape).Volume(), rel=1e-9)
    assert BRepCheck_Analyzer(fallback.shape).IsValid()
    with pytest.raises(RuntimeError, match="face removal failed"):
        brick_solids.merged_solid(cells, sizes, method="remove")
