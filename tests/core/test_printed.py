"""Printed parts: brick solid ∩ part, stud completeness, merging, clearance."""

import numpy as np
import pytest
import trimesh
from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox, BRepPrimAPI_MakeSphere
from OCP.gp import gp_Pnt

from core import printed
from core.brick_solids import BrickGeometry, brick_solid, face_list
from core.errors import InputError
from core.mesh_io import LoadedModel
from core.model import Brick, Grid, Layout

import cadquery as cq


def _layout(bricks, shape=(4, 4, 6)):
    g = Grid(origin=np.zeros(3), cell=np.array([8.0, 8.0, 3.2]), filled=np.ones(shape, bool))
    return Layout(g, bricks)


def _mesh_source(mesh):
    return printed.model_solid(LoadedModel(mesh=mesh, path="m.stl", format="stl",
                                           triangles=len(mesh.faces), watertight=True))


BOX = [[-5, -5, -5], [40, 40, 30]]
SOURCES = {
    "brep": lambda: printed.ModelSolid(brep=BRepPrimAPI_MakeBox(gp_Pnt(*BOX[0]), gp_Pnt(*BOX[1])).Shape()),
    "mesh": lambda: _mesh_source(trimesh.creation.box(bounds=BOX)),
}


@pytest.mark.parametrize("kind", sorted(SOURCES))
def test_brick_inside_part_is_the_brick_with_all_studs(kind):
    lay = _layout([Brick(0, "3001", (2, 4, 3), (0, 0, 0))])
    part = printed.build_part("P1", lay.bricks, lay, SOURCES[kind](), engrave=False)
    ref = brick_solid(2, 4, 3).shape.Volume()
    assert part.volume_mm3 == pytest.approx(ref, rel=2e-3 if kind == "mesh" else 1e-9)
    assert len(part.complete_studs) == 8 and not part.incomplete_studs
    assert not part.incomplete_tubes and len(part.complete_tubes) == 4  # 3 tubes + cavity
    assert part.mesh.is_watertight and part.pieces == 1


@pytest.mark.parametrize("kind", ["brep", "mesh"])
def test_sphere_cutting_a_brick_keeps_inner_studs_only(kind):
    # Sphere centred on stud (0, 0) of a 2x2 brick, radius reaching over studs (0,0) and
    # (1,0)/(0,1) partially: stud (0,0) whole, (1,1) removed, the others cut.
    centre, radius = (4.0, 4.0, 9.6), 9.0
    if kind == "brep":
        source = printed.ModelSolid(brep=BRepPrimAPI_MakeSphere(gp_Pnt(*centre), radius).Shape())
    else:
        sphere = trimesh.creation.icosphere(subdivisions=5, radius=radius)
        sphere.apply_translation(centre)
        source = _mesh_source(sphere)
    lay = _layout([Brick(0, "3003", (2, 2, 3), (0, 0, 0))])
    part = printed.build_part("P1", lay.bricks, lay, source, engrave=False)
    assert part.complete_studs == ["0:stud:0,0"]
    assert set(part.incomplete_studs) == {"0:stud:0,1", "0:stud:1,0", "0:stud:1,1"}
    assert part.top_ok[(0, 0, 2)] and not part.top_ok[(1, 1, 2)]


@pytest.mark.parametrize("kind", sorted(SOURCES))
def test_merged_part_has_no_internal_faces_and_the_union_volume(kind):
    bricks = [Brick(0, "3001", (2, 4, 3), (0, 0, 0)), Brick(1, "3001", (2, 4, 3), (2, 0, 0))]
    lay = _layout(bricks)
    part = printed.build_parts(lay, [[0, 1]], SOURCES[kind](), engrave=False)[0]
    union = (brick_solid(2, 4, 3, flush={"side+x"}).shape.Volume()
             + brick_solid(2, 4, 3, origin=(16, 0, 0), flush={"side-x"}).shape.Volume())
    assert part.volume_mm3 == pytest.approx(union, rel=2e-3 if kind == "mesh" else 1e-6)
    assert len(part.complete_studs) == 16 and part.pieces == 1
    assert part.merge_method == "face removal" and part.to_json()["merge"] == "face removal"
    if kind == "brep":
        for face in face_list(part.solid):
            xs = [v.X for v in cq.Face(face).Vertices()]
            assert not np.allclose(xs, 16.0), "a face lies on the plane between the bricks"
    else:
        assert not np.any(np.all(np.isclose(part.mesh.triangles[:, :, 0], 16.0), axis=1))


def test_stacked_bricks_merge_without_internal_void():
    bricks = [Brick(0, "3001", (2, 4, 3), (0, 0, 0)), Brick(1, "3001", (2, 4, 3), (0, 0, 3))]
    lay = _layout(bricks)
    part = printed.build_parts(lay, [[0, 1]], SOURCES["brep"](), engrave=False)[0]
    shells = cq.Shape.cast(part.solid).Shells()
    assert len(shells) == 1
    assert len(part.studs) == 8 and all(s.startswith("1:") for s in part.studs)


def test_clearance_sets_the_printed_stud_diameter():
    lay = _layout([Brick(0, "3024", (1, 1, 1), (0, 0, 0))])
    for clearance in (0.1, 0.4):
        part = printed.build_part("P1", lay.bricks, lay, SOURCES["mesh"](),
                                  BrickGeometry(clearance=clearance), engrave=False)
        v = part.mesh.vertices
        stud = v[v[:, 2] > 3.2 + 1e-6]
        radius = np.hypot(stud[:, 0] - 4, stud[:, 1] - 4).max()
        assert radius == pytest.approx((4.8 - clearance) / 2, abs=1e-3)


def test_merge_split_and_bad_groups():
    assert printed.merge([[1], [2], [3]], [1, 2]) == [[3], [1, 2]]
    assert printed.split([[1, 2, 3]], [2]) == [[1, 3], [2]]
    bricks = [Brick(0, "3024", (1, 1, 1), (0, 0, 0)), Brick(1, "3024", (1, 1, 1), (2, 0, 0))]
    with pytest.raises(InputError):
        printed.build_parts(_layout(bricks), [[0, 1]], SOURCES["brep"]())
    with pytest.raises(InputError):
        _mesh_source(trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]]))


def _text_area(part_id, font):
    return printed._text_shape(part_id, font, cq.Plane.XY(), 1.0).Volume()


@pytest.mark.parametrize("kind", sorted(SOURCES))
def test_engraved_id_is_a_shallow_cut_on_an_outer_side(kind):
    lay = _layout([Brick(0, "3001", (2, 4, 3), (0, 0, 0))])
    plain = printed.build_part("P1", lay.bricks, lay, SOURCES[kind](), engrave=False)
    part = printed.build_part("P1", lay.bricks, lay, SOURCES[kind]())
    assert part.engraved and part.pieces == 1 and part.mesh.is_watertight
    where = part.engraving
    assert where["side"] in ("side-x", "side+x") and where["depth_mm"] == printed.ENGRAVE_DEPTH_MM
    expected = _text_area("P1", where["font_size_mm"]) * printed.ENGRAVE_DEPTH_MM
    assert plain.volume_mm3 - part.volume_mm3 == pytest.approx(expected, rel=0.03)
    removed = _mesh_source(plain.mesh).manifold - _mesh_source(part.mesh).manifold
    lo, hi = np.array(removed.bounding_box()[:3]), np.array(removed.bounding_box()[3:])
    normal, centre = np.array(where["normal"]), np.array(where["centre_mm"])
    depth_lo, depth_hi = sorted(float(np.dot(c - centre, normal)) for c in (lo, hi))
    assert depth_hi == pytest.approx(0.0, abs=1e-6)
    assert depth_lo == pytest.approx(-printed.ENGRAVE_DEPTH_MM, abs=1e-6)
    _, height = where["text_mm"]
    assert hi[2] - lo[2] == pytest.approx(height, abs=0.05)
    assert np.allclose((lo + hi) / 2 - centre, -normal * printed.ENGRAVE_DEPTH_MM / 2, atol=0.05)


def test_no_engraving_without_a_flat_side_says_why():
    # A sphere of radius 3 inside a 1x1 plate leaves no flat side at all.
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=3.0)
    sphere.apply_translation([4.0, 4.0, 1.6])
    lay = _layout([Brick(0, "3024", (1, 1, 1), (0, 0, 0))])
    part = printed.build_part("P1", lay.bricks, lay, _mesh_source(sphere))
    assert not part.engraved and part.engraving.startswith("not engraved: no outer")
    # A box inside the brick's sides cuts every side face away.
    box = trimesh.creation.box(bounds=[[0.3, 0.3, 0], [7.7, 7.7, 3.2]])
    part = printed.build_part("P1", lay.bricks, lay, _mesh_source(box))
    assert not part.engraved and "stays whole" in part.engraving


PARTIAL = {
    "2x4 beside a 2x2 offset by one stud": [Brick(0, "3001", (2, 4, 3), (0, 0, 0)),
                                            Brick(1, "3003", (2, 2, 3), (2, 1, 0))],
    "2x4 plate on three studs of a 2x4 brick": [Brick(0, "3001", (2, 4, 3), (0, 0, 0)),
                                                Brick(1, "3020", (2, 4, 1), (1, 1, 3))],
}


@pytest.mark.parametrize("case", sorted(PARTIAL))
@pytest.mark.parametrize("kind", sorted(SOURCES))
def test_partial_contacts_merge_by_face_removal(case, kind):
    from core.brick_solids import merged_solid
    bricks = PARTIAL[case]
    lay = _layout(bricks, shape=(4, 5, 6))
    part = printed.build_parts(lay, [[0, 1]], SOURCES[kind](), engrave=False)[0]
    assert part.merge_method == "face removal" and part.pieces == 1 and part.mesh.is_watertight
    fused = merged_solid([b.cell for b in bricks], [b.size for b in bricks], method="fuse")
    assert part.volume_mm3 == pytest.approx(cq.Shape.cast(fused.shape).Volume(),
                                            rel=2e-3 if kind == "mesh" else 1e-9)
    covered = 3 if "plate" in case else 0  # studs of the brick under the plate
    assert len(part.complete_studs) == 8 + (8 if "plate" in case else 4) - covered
    assert not part.incomplete_studs


def test_split_rebuilds_each_brick_with_its_faces():
    bricks = [Brick(0, "3001", (2, 4, 3), (0, 0, 0)), Brick(1, "3001", (2, 4, 3), (2, 0, 0))]
    lay = _layout(bricks)
    groups = printed.split([[0, 1]], [1])
    assert groups == [[0], [1]]
    parts = printed.build_parts(lay, groups, SOURCES["brep"](), engrave=False)
    single = brick_solid(2, 4, 3).shape.Volume()
    for part, plane in zip(parts, (15.9, 16.1)):
        assert part.merge_method == "single brick"
        assert part.volume_mm3 == pytest.approx(single, rel=1e-9)
        sides = [f for f in face_list(part.solid) if np.allclose([v.X for v in cq.Face(f).Vertices()], plane)]
        assert sides, f"the split side at x = {plane} came back"


def test_parts_sharing_a_lazy_model_boolean():
    # A mesh model that is an unevaluated manifold3d union (as with connector boxes), shared by
    # several parts: manifold3d 3.0.1 crashed on this until build_parts evaluated it once.
    import manifold3d as m3
    base = _mesh_source(trimesh.creation.box(bounds=BOX)).manifold
    lazy = m3.Manifold.batch_boolean([base, m3.Manifold.cube([4, 4, 4]).translate([50, 0, 0])], m3.OpType.Add)
    bricks = [Brick(i, "3003", (2, 2, 3), (0, 0, 3 * i)) for i in range(2)] + \
        [Brick(2 + i, "3003", (2, 2, 3), (2, 2, 3 * i)) for i in range(2)]
    lay = _layout(bricks)
    parts = printed.build_parts(lay, [[0], [1], [2], [3]], printed.ModelSolid(manifold=lazy), engrave=False)
    assert [p.pieces for p in parts] == [1, 1, 1, 1]
    assert all(p.volume_mm3 == pytest.approx(brick_solid(2, 2, 3).shape.Volume(), rel=2e-3) for p in parts)


def test_engraving_prints_no_fontconfig_error():
    import os
    import subprocess
    import sys
    from pathlib import Path
    root = Path(__file__).resolve().parents[2]
    env = {k: v for k, v in os.environ.items() if not k.startswith("FONTCONFIG")}
    code = ("import numpy as np, trimesh\n"
            "from core import printed\n"
            "from core.mesh_io import LoadedModel\n"
            "from core.model import Brick, Grid, Layout\n"
            "m = trimesh.creation.box(bounds=[[-5, -5, -5], [40, 40, 30]])\n"
            "src = printed.model_solid(LoadedModel(mesh=m, path='m.stl', format='stl', triangles=12, watertight=True))\n"
            "g = Grid(origin=np.zeros(3), cell=np.array([8.0, 8.0, 3.2]), filled=np.ones((4, 4, 6), bool))\n"
            "lay = Layout(g, [Brick(0, '3001', (2, 4, 3), (0, 0, 0))])\n"
            "print(printed.build_part('P1', lay.bricks, lay, src).engraved)\n")
    run = subprocess.run([sys.executable, "-c", code], cwd=root, env=env, capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    assert run.stdout.strip() == "True"
    assert "fontconfig" not in run.stderr.lower(), run.stderr
