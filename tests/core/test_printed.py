"""Printed parts: the model kept whole inside the bricks, studs and sockets only where LEGO meets it.

Known answers are hand calculations of volumes and dimensions, measured on
the exported geometry (sections, STEP faces), not on our own plan.
"""

import math

import cadquery as cq
import manifold3d as m3
import numpy as np
import pytest
import trimesh
from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox
from OCP.gp import gp_Pnt

from core.errors import InputError
from core.io.meshes import LoadedModel
from core.model import Brick, Grid, Layout
from core.parts import printed
from core.parts.engraving import ENGRAVE_DEPTH_MM, text_shape
from core.parts.interfaces import Fit
from core.parts.printed_part import ModelSolid

CELL = np.array([8.0, 8.0, 3.2])


def _layout(bricks, shape):
    filled = np.zeros(shape, bool)
    for b in bricks:
        filled[b.slices()] = True
    return Layout(Grid(origin=np.zeros(3), cell=CELL.copy(), filled=filled), bricks)


def _source(kind, mesh):
    loaded = LoadedModel(mesh=mesh, path="m.stl", format="stl", triangles=len(mesh.faces), watertight=True)
    src = printed.model_solid(loaded)
    if kind == "brep":
        lo, hi = mesh.bounds
        return ModelSolid(manifold=src.manifold,
                                  brep=BRepPrimAPI_MakeBox(gp_Pnt(*lo), gp_Pnt(*hi)).Shape())
    return src


def _manifold(mesh):
    return m3.Manifold(m3.Mesh64(vert_properties=np.asarray(mesh.vertices, np.float64),
                                 tri_verts=np.asarray(mesh.faces, np.uint64)))


def _sandwich():
    """A 4x2 LEGO brick, a 4x2 brick to print on it, a 4x2 LEGO plate on top: a solid block."""
    bricks = [Brick(0, "3001", (4, 2, 3), (0, 0, 0)), Brick(1, "3001", (4, 2, 3), (0, 0, 3)),
              Brick(2, "3020", (4, 2, 1), (0, 0, 6))]
    return _layout(bricks, (4, 2, 7)), trimesh.creation.box(bounds=[[0, 0, 0], [32, 16, 22.4]])


@pytest.mark.parametrize("kind", ["brep", "mesh"])
def test_block_between_lego_is_the_block_less_one_socket_per_stud_below(kind):
    lay, block = _sandwich()
    fit = Fit()
    (part,) = printed.build_parts(lay, [[1]], _source(kind, block), fit, engrave=False)
    by_hand = (32 * 16 * 9.6 - 8 * fit.socket_width ** 2 * fit.socket_depth
               + 8 * math.pi * (fit.stud_diameter / 2) ** 2 * fit.stud_height)
    assert part.volume_mm3 == pytest.approx(by_hand, rel=2e-4 if kind == "mesh" else 1e-7)
    assert part.kept_mm3 == pytest.approx(32 * 16 * 9.6, rel=1e-9)
    assert part.engaged == {"studs": 8, "sockets": 8, "clamps": True}
    assert part.mesh.is_watertight and part.mesh.body_count == 1


@pytest.mark.parametrize("kind", ["brep", "mesh"])
def test_sections_show_the_set_stud_diameter_and_socket_width(kind):
    lay, block = _sandwich()
    fit = Fit(stud_fit=0.1, socket_fit=-0.05)
    (part,) = printed.build_parts(lay, [[1]], _source(kind, block), fit, engrave=False)
    studs = part.mesh.section(plane_origin=[0, 0, 19.2 + 0.85], plane_normal=[0, 0, 1]).discrete
    assert len(studs) == 8
    for loop in studs:
        centre = (np.floor(loop[:, :2].mean(axis=0) / 8.0) + 0.5) * 8.0  # the cell's centre
        radius = np.linalg.norm(loop[:, :2] - centre, axis=1)
        assert radius.max() == pytest.approx(4.9 / 2, abs=1e-3)
    holes = part.mesh.section(plane_origin=[0, 0, 9.6 + 1.0], plane_normal=[0, 0, 1]).discrete
    inner = sorted(holes, key=lambda e: np.ptp(e[:, 0]))[:8]
    assert len(holes) == 9  # the outline and eight square holes
    for loop in inner:
        assert np.ptp(loop[:, 0]) == pytest.approx(4.75, abs=1e-6)
        assert np.ptp(loop[:, 1]) == pytest.approx(4.75, abs=1e-6)


def test_step_studs_are_true_cylinders_of_the_setting(tmp_path):
    from core.printing.export import write_step
    lay, block = _sandwich()
    for stud_fit in (0.05, 0.15):
        (part,) = printed.build_parts(lay, [[1]], _source("brep", block), Fit(stud_fit=stud_fit),
                                      engrave=False)
        path = tmp_path / f"p{stud_fit}.step"
        write_step(part.solid, path)
        shape = cq.importers.importStep(str(path)).val()
        radii = {round(f._geomAdaptor().Cylinder().Radius(), 6) for f in shape.Faces()
                 if f.geomType() == "CYLINDER"}
        assert radii == {round((4.8 + stud_fit) / 2, 6)}


def test_nothing_is_cut_over_air_or_the_grid_bottom():
    # A 2x2 printed brick on the grid's bottom with nothing above: exactly block ∩ cells.
    lay = _layout([Brick(0, "3003", (2, 2, 3), (0, 0, 0)), Brick(1, "3003", (2, 2, 3), (2, 0, 0))], (4, 2, 3))
    block = trimesh.creation.box(bounds=[[0, 0, 0], [32, 16, 9.6]])
    (part,) = printed.build_parts(lay, [[0]], _source("mesh", block), engrave=False)
    # The side facing the LEGO brick beside it stays 0.1 mm back (LEGO's play); nothing else changes.
    assert part.volume_mm3 == pytest.approx((16 - 0.1) * 16 * 9.6, rel=1e-9)
    assert part.engaged["clamps"] is False and "sideways" in part.engaged["why"]


def _plate_model():
    """A 2 mm vertical plate 48 mm long, 16 plates high, centred in a cell row (a lens plate)."""
    return trimesh.creation.box(bounds=[[0, 3, 0], [48, 5, 51.2]])


@pytest.mark.parametrize("kind", ["brep", "mesh"])
def test_a_2mm_plate_is_kept_whole_and_gets_studs_and_sockets(kind):
    # LEGO 1x6 bricks below (layers 0-2) and above (13-15), the plate's layers 3-12 printed.
    bricks = [Brick(0, "3009", (6, 1, 3), (0, 0, 0))] + \
             [Brick(1 + n, "3009", (6, 1, 3), (0, 0, 3 + 3 * n)) for n in range(3)] + \
             [Brick(4, "3666", (6, 1, 1), (0, 0, 12)), Brick(5, "3009", (6, 1, 3), (0, 0, 13))]
    lay = _layout(bricks, (6, 1, 16))
    plate = _plate_model()
    fit = Fit()
    (part,) = printed.build_parts(lay, [[1, 2, 3, 4]], _source(kind, plate), fit, engrave=False)
    assert part.mesh.is_watertight and part.mesh.body_count == 1
    assert part.engaged == {"studs": 6, "sockets": 6, "clamps": True}
    solid, model = _manifold(part.mesh), _manifold(plate)
    cells = m3.Manifold.cube([48, 8, 32]).translate([0, 0, 9.6])
    # All of the plate inside the cells is printed but where the six sockets take a real stud.
    lost = ((model ^ cells) - solid).volume()
    assert lost == pytest.approx(6 * fit.socket_width * 2.0 * fit.socket_depth, rel=1e-3)  # the plate is 2 mm
    # Material was added only in the band around the sockets and the skin under the studs.
    added = solid - model
    lo = np.array(added.bounding_box()[:3])
    hi = np.array(added.bounding_box()[3:])
    assert lo[2] == pytest.approx(9.6, abs=1e-6) and hi[2] == pytest.approx(41.6 + fit.stud_height, abs=1e-6)
    middle = m3.Manifold.cube([48, 8, 32 - 2 * 3.2]).translate([0, 0, 9.6 + 3.2])
    # Below the skin (z 40.6) a 45° taper narrows from the cell's 8 mm to the plate's 2 mm over
    # 3 mm, so its lowest 0.8 mm reach into the middle layers: 48 x (3.6 + 2) / 2 x 0.8 less the plate.
    assert (added ^ middle).volume() == pytest.approx(48 * ((3.6 + 2) / 2 * 0.8 - 2 * 0.8), rel=1e-5)
    # Printed upright, nothing hangs over air but the socket holes' 4.8 mm bridges.
    down = part.mesh.face_normals[:, 2] < -np.cos(np.radians(45)) - 1e-6
    high = part.mesh.triangles_center[:, 2] > 9.6 + fit.socket_depth + 1e-6
    assert part.mesh.area_faces[down & high].sum() == pytest.approx(0.0, abs=1e-6)
    # The sockets' walls and the skin are at least min_wall thick: 8 - 4.8 leaves 1.6 per side,
    # and nothing of the part is thinner than a 0.4 mm nozzle prints.
    assert (8 - fit.socket_width) / 2 >= fit.min_wall
    assert part.thin["area_mm2"] == 0.0 and part.thin["thinnest_mm"] >= 1.0


def test_a_fin_thinner_than_a_nozzle_is_named():
    lay = _layout([Brick(0, "3001", (4, 2, 3), (0, 0, 0))], (4, 2, 3))
    body = trimesh.creation.box(bounds=[[0, 0, 0], [20, 16, 9.6]])
    fin = trimesh.creation.box(bounds=[[20, 5, 0], [30, 5.3, 9.6]])
    (part,) = printed.build_parts(lay, [[0]], _source("mesh", trimesh.util.concatenate([body, fin])),
                                  engrave=False)
    assert part.thin["thinnest_mm"] == pytest.approx(0.3, abs=0.01)
    assert part.thin["area_mm2"] == pytest.approx(2 * 10 * 9.6, rel=0.15)
    assert part.to_json()["thin_features"]["spots"]


def test_loose_pieces_are_joined_by_a_bar_inside_the_bricks():
    # Two pillars inside one 4x1 printed brick, with nothing between them.
    lay = _layout([Brick(0, "3010", (4, 1, 3), (0, 0, 0))], (4, 1, 3))
    pillars = trimesh.util.concatenate([trimesh.creation.box(bounds=[[1, 1, 0], [5, 7, 9.6]]),
                                        trimesh.creation.box(bounds=[[20, 1, 0], [30, 7, 9.6]])])
    (part,) = printed.build_parts(lay, [[0]], _source("mesh", pillars), engrave=False)
    assert part.mesh.body_count == 1 and part.mesh.is_watertight
    assert len(part.joins) == 1 and part.joins[0]["length_mm"] == pytest.approx(15.0, abs=1e-6)


def test_a_model_of_several_overlapping_shells_is_their_union():
    shells = trimesh.util.concatenate([trimesh.creation.box(bounds=[[0, 0, 0], [20, 16, 9.6]]),
                                       trimesh.creation.box(bounds=[[10, 0, 0], [32, 16, 9.6]])])
    lay = _layout([Brick(0, "3001", (4, 2, 3), (0, 0, 0))], (4, 2, 3))
    (part,) = printed.build_parts(lay, [[0]], _source("mesh", shells), engrave=False)
    assert part.volume_mm3 == pytest.approx(32 * 16 * 9.6, rel=1e-9)
    assert part.mesh.is_watertight and part.mesh.body_count == 1


def test_merge_split_and_bad_groups():
    assert printed.merge([[1], [2], [3]], [1, 2]) == [[3], [1, 2]]
    assert printed.split([[1, 2, 3]], [2]) == [[1, 3], [2]]
    bricks = [Brick(0, "3024", (1, 1, 1), (0, 0, 0)), Brick(1, "3024", (1, 1, 1), (2, 0, 0))]
    block = trimesh.creation.box(bounds=[[0, 0, 0], [24, 8, 3.2]])
    with pytest.raises(InputError, match="do not touch"):
        printed.build_parts(_layout(bricks, (3, 1, 1)), [[0, 1]], _source("mesh", block))
    with pytest.raises(InputError, match="not a closed manifold"):
        _source("mesh", trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]]))
    with pytest.raises(InputError, match="stud-fit"):
        Fit(stud_fit=float("nan")).check()


def _text_area(part_id, font):
    return text_shape(part_id, font, cq.Plane.XY(), 1.0).Volume()


@pytest.mark.parametrize("kind", ["brep", "mesh"])
def test_engraved_id_is_a_shallow_cut_on_a_side(kind):
    lay = _layout([Brick(0, "3001", (2, 4, 3), (0, 0, 0))], (2, 4, 3))
    block = trimesh.creation.box(bounds=[[0, 0, 0], [16, 32, 9.6]])
    plain = printed.build_part("P1", lay.bricks, lay, _source(kind, block), engrave=False)
    part = printed.build_part("P1", lay.bricks, lay, _source(kind, block))
    assert part.engraved and part.mesh.is_watertight and part.mesh.body_count == 1
    where = part.engraving
    assert where["side"] in ("side-x", "side+x") and where["normal"][2] == 0.0
    expected = _text_area("P1", where["font_size_mm"]) * ENGRAVE_DEPTH_MM
    assert plain.volume_mm3 - part.volume_mm3 == pytest.approx(expected, rel=0.03)
    removed = _manifold(plain.mesh) - _manifold(part.mesh)
    lo, hi = np.array(removed.bounding_box()[:3]), np.array(removed.bounding_box()[3:])
    normal, centre = np.array(where["normal"]), np.array(where["centre_mm"])
    depth_lo, depth_hi = sorted(float(np.dot(c - centre, normal)) for c in (lo, hi))
    assert depth_hi == pytest.approx(0.0, abs=1e-6)
    assert depth_lo == pytest.approx(-ENGRAVE_DEPTH_MM, abs=1e-6)


def test_no_engraving_without_a_flat_side_says_why():
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=3.0)
    sphere.apply_translation([4.0, 4.0, 1.6])
    lay = _layout([Brick(0, "3024", (1, 1, 1), (0, 0, 0))], (1, 1, 1))
    part = printed.build_part("P1", lay.bricks, lay, _source("mesh", sphere))
    assert not part.engraved and part.engraving.startswith("not engraved: no outer")


@pytest.mark.slow
def test_engraving_prints_no_fontconfig_error():
    import os
    import subprocess
    import sys
    from pathlib import Path
    root = Path(__file__).resolve().parents[2]
    env = {k: v for k, v in os.environ.items() if not k.startswith("FONTCONFIG")}
    code = ("import numpy as np, trimesh\n"
            "from core.parts import printed\n"
            "from core.io.meshes import LoadedModel\n"
            "from core.model import Brick, Grid, Layout\n"
            "m = trimesh.creation.box(bounds=[[0, 0, 0], [16, 32, 9.6]])\n"
            "src = printed.model_solid(LoadedModel(mesh=m, path='m.stl', format='stl', triangles=12, watertight=True))\n"
            "g = Grid(origin=np.zeros(3), cell=np.array([8.0, 8.0, 3.2]), filled=np.ones((2, 4, 3), bool))\n"
            "lay = Layout(g, [Brick(0, '3001', (2, 4, 3), (0, 0, 0))])\n"
            "print(printed.build_part('P1', lay.bricks, lay, src).engraved)\n")
    run = subprocess.run([sys.executable, "-c", code], cwd=root, env=env, capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    assert run.stdout.strip() == "True"
    assert "fontconfig" not in run.stderr.lower(), run.stderr


def test_the_id_goes_on_an_uncovered_side():
    # A 1x1 brick of the same part stands against the middle of the 2x4's -x side.
    lay = _layout([Brick(0, "3001", (2, 4, 3), (1, 0, 0)), Brick(1, "3005", (1, 1, 3), (0, 1, 0))], (3, 4, 3))
    model = trimesh.util.concatenate([trimesh.creation.box(bounds=[[8, 0, 0], [24, 32, 9.6]]),
                                      trimesh.creation.box(bounds=[[0, 8, 0], [8, 16, 9.6]])])
    (part,) = printed.build_parts(lay, [[0, 1]], _source("mesh", model))
    assert part.engraved
    where = part.engraving
    normal, centre = np.array(where["normal"]), np.array(where["centre_mm"])
    width, height = where["text_mm"]
    across = np.abs(np.cross([0, 0, 1], normal))
    half = across * width / 2 + np.array([0, 0, height / 2])
    front = np.stack([centre - half, centre + half + normal * 1.0])
    front = np.sort(front, axis=0)
    box = m3.Manifold.cube(list(front[1] - front[0])).translate(list(front[0]))
    assert (_manifold(part.mesh) ^ box).volume() == pytest.approx(0.0, abs=1e-6)


def test_apply_returns_a_new_layout_and_leaves_its_input_alone():
    lay, block = _sandwich()
    before = [b.to_json() for b in lay.bricks]
    parts = printed.build_parts(lay, [[1]], _source("mesh", block), engrave=False)
    marked = printed.apply(lay, parts)
    assert [b.to_json() for b in lay.bricks] == before
    assert [(b.kind, b.printed_part) for b in marked.bricks] == [("lego", None), ("printed", "P1"),
                                                                  ("lego", None)]
