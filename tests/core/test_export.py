"""Export of printed parts and the CLI's --high-res contract."""

import json
import math
import subprocess
import sys
from pathlib import Path

import cadquery as cq
import manifold3d as m3
import numpy as np
import pytest
import trimesh

from core import export, print_time, printed
from core.mesh_io import LoadedModel
from core.model import Brick, Grid, Layout

ROOT = Path(__file__).resolve().parents[2]
DEMO = ROOT / "examples" / "build" / "hmd.step"


def _manifold(mesh):
    return m3.Manifold(m3.Mesh64(vert_properties=np.ascontiguousarray(mesh.vertices, np.float64),
                                 tri_verts=np.ascontiguousarray(mesh.faces, np.uint64)))


def test_exported_parts_are_watertight_and_inside_the_model(tmp_path):
    model = trimesh.creation.icosphere(subdivisions=4, radius=14.0)
    model.apply_translation([12, 12, 8])
    source = printed.model_solid(LoadedModel(mesh=model, path="s.stl", format="stl",
                                             triangles=len(model.faces), watertight=True))
    g = Grid(origin=np.zeros(3), cell=np.array([8.0, 8.0, 3.2]), filled=np.ones((3, 3, 6), bool))
    lay = Layout(g, [Brick(0, "3003", (2, 2, 3), (0, 0, 0)), Brick(1, "3004", (1, 2, 3), (2, 0, 0)),
                     Brick(2, "3003", (2, 2, 3), (1, 1, 3))])
    parts = printed.build_parts(lay, [[0, 1], [2]], source)
    names = export.export_parts(parts, tmp_path / "parts")
    assert names == ["P1.stl", "P1.step", "P2.stl", "P2.step", "plate.3mf"]
    outside_model = _manifold(model)
    for p in parts:
        mesh = trimesh.load(tmp_path / p.stl, force="mesh")
        assert mesh.is_watertight
        assert (_manifold(mesh) - outside_model).volume() == pytest.approx(0.0, abs=1e-3)
        step = cq.importers.importStep(str(tmp_path / p.step)).val()
        assert step.isValid() and len(step.Solids()) == p.pieces
        assert step.Volume() == pytest.approx(mesh.volume, rel=1e-6)
    plate = trimesh.load(tmp_path / "parts" / "plate.3mf")
    assert len(plate.geometry) == 2 and plate.bounds[0][2] == pytest.approx(0.0, abs=1e-9)
    for p in parts:
        assert p.pose["plate"] == "parts/plate.3mf" and p.pose["studs_up"] >= 0
        # The pose maps the part's model-coordinate mesh onto its place on the plate.
        placed = p.mesh.copy().apply_transform(np.array(p.pose["matrix"]))
        assert placed.bounds == pytest.approx(plate.geometry[p.id].bounds, abs=1e-6)


def test_cli_high_res_box_on_the_demo_makes_parts(tmp_path):
    if not DEMO.exists():
        subprocess.run([sys.executable, str(ROOT / "examples" / "hmd.py"), str(DEMO.parent)],
                       check=True, cwd=ROOT)
    out = tmp_path / "out"
    run = subprocess.run([sys.executable, "-m", "core", "fabricate", str(DEMO), "--out", str(out),
                          "--high-res=-10,0,70,10,16,90", "--no-picture", "--quiet"],
                         cwd=ROOT, capture_output=True, text=True,
                         env={"FABRICKATOR_SLICER": "none", "PATH": "/usr/bin:/bin"})
    assert run.returncode == 0, run.stderr
    doc = json.loads((out / "report.json").read_text())
    assert (out / "parts" / "P1.stl").exists() and (out / "parts" / "P1.step").exists()
    part = doc["printed_parts"][0]
    assert part["id"] == "P1" and part["stl"] == "parts/P1.stl" and part["volume_mm3"] > 0
    assert doc["bricks"]["printed"] == len(part["bricks"]) > 0
    assert doc["print_time_s"]["method"].startswith("estimate")
    assert doc["speedup"] > 0 and doc["assembly_s"] > 0
    split, pt = doc["assembly_split_s"], doc["print_time_s"]
    assert split["lego"] + split["insert_printed_parts"] == pytest.approx(doc["assembly_s"], abs=0.1)
    assert doc["fabrication_s"] == pytest.approx(
        max(pt["printed_parts"], split["lego"]) + split["insert_printed_parts"], abs=0.2)
    assert doc["speedup"] == pytest.approx(pt["full_model"] / doc["fabrication_s"], rel=1e-3)
    assert doc["speedups"]["sequential"] <= doc["speedup"] == doc["speedups"]["fabrication"]
    layout = json.loads((out / "layout.json").read_text())
    kinds = {b["id"]: (b["kind"], b["printed_part"]) for b in layout["bricks"]}
    assert all(kinds[i] == ("printed", "P1") for i in part["bricks"])


def _box_source(bounds):
    box = trimesh.creation.box(bounds=bounds)
    return printed.model_solid(LoadedModel(mesh=box, path="b.stl", format="stl", triangles=12, watertight=True))


def _parts(specs, shape=(8, 4, 9)):
    """Printed parts (engraving off), one per brick list, each cut from a box covering its
    bricks in a layout of its own."""
    g = Grid(origin=np.zeros(3), cell=np.array([8.0, 8.0, 3.2]), filled=np.ones(shape, bool))
    out = []
    for n, spec in enumerate(specs):
        lay = Layout(g, [Brick(i, part, size, cell) for i, (part, size, cell) in enumerate(spec)])
        (part,) = printed.build_parts(lay, [list(range(len(spec)))], _box_source([[-1, -1, -1], [80, 40, 40]]),
                                      engrave=False)
        part.id = f"P{n + 1}"
        out.append(part)
    return out


#: An arm (a 1x8 plate) on a post of two 1x1 bricks: upright, the arm hangs 19 mm over the bed.
ARM = [("3005", (1, 1, 3), (0, 0, 0)), ("3005", (1, 1, 3), (0, 0, 3)), ("3460", (8, 1, 1), (0, 0, 6))]
#: A 2x4 plate on a 1x1 brick: a cap on a post.
CAP = [("3005", (1, 1, 3), (1, 1, 0)), ("3020", (2, 4, 1), (0, 0, 3))]


def _overlap(a, b):
    return bool(np.all(a[0][:2] < b[1][:2]) and np.all(b[0][:2] < a[1][:2]))


def test_plate_lays_parts_on_the_bed_inside_it_without_overlap():
    parts = _parts([[("3001", (2, 4, 3), (0, 0, 0))], ARM, CAP, [("3003", (2, 2, 3), (6, 2, 0))]])
    bed = print_time.build_volume(print_time.load_profile())[:2]
    (plate,) = export.plates(parts)
    assert sorted(i for i, _, _ in plate) == [0, 1, 2, 3]
    boxes = [mesh.bounds for _, mesh, _ in plate]
    for (index, mesh, pose), box in zip(plate, boxes):
        assert box[0][2] == pytest.approx(0.0, abs=1e-9)
        assert np.all(box[0][:2] >= export.SPACING_MM - 1e-9) and np.all(box[1][:2] <= bed - export.SPACING_MM + 1e-9)
        assert mesh.volume == pytest.approx(parts[index].mesh.volume, rel=1e-9)
    assert not any(_overlap(a, b) for n, a in enumerate(boxes) for b in boxes[n + 1:])
    meshes = export.plate(parts)
    assert [m.volume for m in meshes] == pytest.approx([p.mesh.volume for p in parts], rel=1e-9)


def test_parts_that_fill_a_bed_go_on_more_plates(tmp_path):
    parts = _parts([[("3001", (2, 4, 3), (2 * i, 0, 0))] for i in range(4)])
    plates = export.plates(parts, bed=(60, 60))
    assert len(plates) >= 2 and sorted(i for p in plates for i, _, _ in p) == [0, 1, 2, 3]
    for plate in plates:
        boxes = [mesh.bounds for _, mesh, _ in plate]
        assert all(np.all(b[1][:2] <= 60 - export.SPACING_MM + 1e-9) for b in boxes)
        assert not any(_overlap(a, b) for n, a in enumerate(boxes) for b in boxes[n + 1:])
    names = export.export_parts(parts, tmp_path / "parts", bed=(60, 60))
    assert "plate.3mf" in names and "plate-2.3mf" in names
    on = {p.pose["plate"] for p in parts}
    assert on == {f"parts/{n}" for n in names if n.endswith(".3mf")}


def test_overhanging_part_gets_a_flatter_pose_than_upright():
    (arm,) = _parts([ARM])
    mesh, pose = export.lay_flat(arm)
    area, height, volume = export.support_need(arm.mesh)
    assert area > 100 and height > 18
    assert pose.name != "upright" and pose.support_mm3 < volume
    assert mesh.extents[2] < arm.mesh.extents[2]
    assert pose.studs_up == pytest.approx(0.0, abs=1e-9)  # sideways, never down
    assert mesh.bounds[0] == pytest.approx([0, 0, 0], abs=1e-9)
    assert pose.cost < export.print_time.estimate_seconds([arm.mesh]) + export.support_seconds(area, height)


def test_studs_never_point_down_onto_the_bed():
    # A mushroom on its stem (studs would be on top of the cap): upright, the cap overhangs;
    # upside down, the cap would lie flat on the bed, which the studs rule forbids.
    stem = trimesh.creation.box((8, 8, 20)).apply_translation((0, 0, 10))
    cap = trimesh.creation.box((40, 40, 6)).apply_translation((0, 0, 23))
    mushroom = trimesh.boolean.union([stem, cap], engine="manifold")
    free = export.print_pose(mushroom, studs=False, clamping=False)
    assert free.studs_up == pytest.approx(-1.0) and free.support_mm2 == 0
    ruled = export.print_pose(mushroom, studs=True, clamping=False)
    assert ruled.studs_up >= 0 and ruled.cost > free.cost
    (cap,) = _parts([CAP])
    assert export.lay_flat(cap)[1].studs_up >= 0
    plain = export.print_pose(_parts([[("3001", (2, 4, 3), (0, 0, 0))]])[0].mesh)
    assert plain.name == "upright" and plain.support_mm2 == 0


def test_support_need_agrees_with_the_slicer(tmp_path):
    if print_time.slicer_path() is None:
        pytest.skip("prusa-slicer not installed (apt-get install prusa-slicer)")
    # A T: a 10 x 10 x 20 stem carrying a 30 x 10 x 4 bar, 200 mm^2 overhanging 20 mm high.
    stem = trimesh.creation.box((10, 10, 20)).apply_translation((0, 0, 10))
    bar = trimesh.creation.box((30, 10, 4)).apply_translation((0, 0, 22))
    tee = trimesh.boolean.union([stem, bar], engine="manifold")
    area, height, _ = export.support_need(tee)
    assert area == pytest.approx(200, rel=1e-6) and height == pytest.approx(20, abs=1e-6)
    plain = print_time.slice_plate([tee], tmp_path)
    settings = print_time.RETRY_SETTINGS[1][1]
    tee.export(tmp_path / "tee.stl")
    run = subprocess.run([print_time.slicer_path(), "--load", str(print_time.DEFAULT_PROFILE), *settings,
                          "--export-gcode", "--output", str(tmp_path / "tee.gcode"), str(tmp_path / "tee.stl")],
                         capture_output=True, text=True)
    assert run.returncode == 0, run.stderr[-500:]
    supported = print_time.gcode_seconds(tmp_path / "tee.gcode")
    assert export.support_seconds(area, height) == pytest.approx(supported - plain.seconds, rel=0.25)


@pytest.mark.parametrize("slope_deg, supported", [(30, True), (45, True), (60, False), (75, False)])
def test_overhang_slopes_under_the_threshold_need_support(slope_deg, supported):
    # A block 10 mm wide standing on a 10 mm foot, its right side an overhang of slope_deg from
    # horizontal reaching out 10 mm: its underside faces down at that slope.
    rise = 10 * math.tan(math.radians(slope_deg))
    profile = np.array([(0, 0), (10, 0), (20, rise), (20, rise + 5), (0, rise + 5)])  # convex, in x-z
    points = [(x, y, z) for x, z in profile for y in (0.0, 10.0)]
    block = trimesh.convex.convex_hull(points)
    area, height, _ = export.support_need(block)
    assert (area > 0) == supported
    if supported:
        assert area == pytest.approx(10 * 10 / math.cos(math.radians(slope_deg)), rel=1e-6)
        assert 0 < height < rise
