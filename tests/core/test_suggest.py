"""The suggest stage (core/suggest.py): holes and pins found, grown, merged, capped.

The reference for the shared B-rep models is the models' own cylinder faces read by
FreeCAD's Part API in freecadcmd (a separate OpenCascade build and API), grouped here:
the faces of one cylinder (same radius and axis line) whose boxes touch are one hole
(concave, at least half way round: a bore or the end of a slot) or one pin (convex,
more than half way round; two fillets rounding a wall's top go exactly half way).
"""

from __future__ import annotations

import json
import math
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
import trimesh

from core import high_res, suggest
from core.io import meshes as mesh_io

ROOT = Path(__file__).resolve().parents[2]
MODELS = ROOT.parent / "shared" / "models"

FREECAD_CYLINDERS = '''
import json, os, FreeCAD, Part
path = os.environ["FC_MODEL"]
if path.lower().endswith(".fcstd"):
    doc = FreeCAD.openDocument(path)
    shapes = [o.Shape for o in doc.Objects if o.TypeId == "PartDesign::Body" and o.Shape.Solids]
else:
    shapes = [Part.read(path)]
faces = []
for shape in shapes:
    for face in shape.Faces:
        surface = face.Surface
        if not isinstance(surface, Part.Cylinder):
            continue
        u0, u1, v0, v1 = face.ParameterRange
        point = face.valueAt((u0 + u1) / 2, (v0 + v1) / 2)
        normal = face.normalAt((u0 + u1) / 2, (v0 + v1) / 2)
        centre, axis = surface.Center, surface.Axis
        radial = (point - centre) - axis * ((point - centre).dot(axis))
        box = face.BoundBox
        faces.append({"radius": surface.Radius, "axis": [axis.x, axis.y, axis.z],
                      "centre": [centre.x, centre.y, centre.z], "turn": u1 - u0,
                      "concave": normal.dot(radial) < 0,
                      "box": [[box.XMin, box.YMin, box.ZMin], [box.XMax, box.YMax, box.ZMax]]})
json.dump(faces, open(os.environ["FC_OUT"], "w"))
'''


def shared(name: str) -> Path:
    path = MODELS / name
    if not path.is_file():
        pytest.skip(f"{path} not found: the shared test models are not next to the repository")
    return path


def freecad_cylinders(path: Path, tmp_path: Path) -> list[dict]:
    """The cylinder faces of ``path`` as FreeCAD reads them (skip without freecadcmd)."""
    if shutil.which("freecadcmd") is None:
        pytest.skip("freecadcmd not installed: no independent reading of the B-rep")
    script, out = tmp_path / "cylinders.py", tmp_path / "cylinders.json"
    script.write_text(FREECAD_CYLINDERS)
    subprocess.run(["freecadcmd", str(script)], env={"FC_MODEL": str(path), "FC_OUT": str(out),
                                                    "HOME": str(tmp_path), "PATH": "/usr/bin:/bin"},
                   check=True, capture_output=True, timeout=300)
    return json.loads(out.read_text())


def holes_and_pins(faces: list[dict], limit_mm: float) -> list[dict]:
    """The holes and pins (module docstring) under ``limit_mm`` across: concave, diameter,
    and the box of their faces."""
    groups: dict = {}
    for f in faces:
        a = np.array(f["axis"])
        a = a if a[np.argmax(np.abs(a))] > 0 else -a
        c = np.array(f["centre"])
        line = c - np.dot(c, a) * a
        key = (round(f["radius"], 3), f["concave"], tuple(np.round(a, 3)), tuple(np.round(line, 2)))
        groups.setdefault(key, []).append(f)
    out = []
    for key, same in groups.items():
        boxes = [np.array(f["box"]) for f in same]
        label = list(range(len(same)))
        for i in range(len(same)):          # boxes that touch, transitively
            for j in range(len(same)):
                if np.all(boxes[i][0] <= boxes[j][1] + 0.01) and np.all(boxes[j][0] <= boxes[i][1] + 0.01):
                    old, new = label[j], label[i]
                    label = [new if x == old else x for x in label]
        for g in set(label):
            members = [n for n in range(len(same)) if label[n] == g]
            turn = sum(same[n]["turn"] for n in members)
            diameter = 2 * key[0]
            if diameter >= limit_mm or turn < (math.pi * 0.99 if key[1] else math.pi * 1.05):
                continue
            out.append({"concave": key[1], "diameter": diameter,
                        "box": np.stack([np.min([boxes[n][0] for n in members], axis=0),
                                         np.max([boxes[n][1] for n in members], axis=0)])})
    return out


def inside(box, regions) -> bool:
    return any(np.all(box[0] >= r.box[0] - 1e-3) and np.all(box[1] <= r.box[1] + 1e-3)
               for r in regions)


@pytest.mark.slow
@pytest.mark.parametrize("name, least", [("freecad_drilling_plate.FCStd", 15),
                                         ("asm4_connecting_rod.FCStd", 2),
                                         ("openbot_body_bottom.step", 60)])
def test_every_hole_and_pin_of_the_brep_is_inside_a_region(name, least, tmp_path):
    path = shared(name)
    model = mesh_io.load_model(path)
    assert not any(model.offset_mm)
    found = suggest.suggest(model)
    reference = holes_and_pins(freecad_cylinders(path, tmp_path), suggest.LIMIT_MM)
    assert len(reference) >= least
    missed = [(f["diameter"], f["box"].round(1).tolist()) for f in reference
              if not inside(f["box"], found.regions)]
    assert not missed
    assert not found.dropped
    assert found.share <= suggest.MAX_SHARE
    for region in found.regions:
        assert region.reason and region.where
        assert all(f.reason.startswith(("hole Ø", "pin Ø")) for f in region.features)


def _step(shape, tmp_path, name="part.step") -> Path:
    import cadquery as cq

    path = tmp_path / name
    cq.exporters.export(shape, str(path))
    return path


def test_a_hole_and_a_pin_are_found_with_their_size_and_place(tmp_path):
    import cadquery as cq

    plate = (cq.Workplane("XY").box(48, 48, 9.6, centered=(True, True, False))
             .faces(">Z").workplane().center(-10, 0).hole(6.5)
             .faces(">Z").workplane().center(22, 10).circle(1.5).extrude(6))
    found = suggest.suggest(mesh_io.load_model(_step(plate, tmp_path)))
    words = sorted(f.reason for r in found.regions for f in r.features)
    # by hand: the Ø6.5 hole goes through the 9.6 mm plate; the Ø3 pin stands 6 mm on it
    assert words == ["hole Ø6.5 mm, 9.6 mm deep", "pin Ø3.0 mm, 6.0 mm long"]
    hole = next(f for r in found.regions for f in r.features if f.kind == "hole")
    assert hole.where == "axis z through (-10.0, 0.0, 4.8)"
    assert np.allclose(hole.box, [[-10 - 3.25 - suggest.WALL_MM, -3.25 - suggest.WALL_MM, -suggest.END_MM],
                                  [-10 + 3.25 + suggest.WALL_MM, 3.25 + suggest.WALL_MM, 9.6 + suggest.END_MM]],
                       atol=0.01)
    assert 0 < found.share <= suggest.MAX_SHARE and not found.warnings


def test_a_plain_block_and_its_rounded_edges_suggest_nothing(tmp_path):
    import cadquery as cq

    block = cq.Workplane("XY").box(40, 24, 16, centered=False).edges("|Z").fillet(3)
    found = suggest.suggest(mesh_io.load_model(_step(block, tmp_path)))
    assert found.regions == () and found.share == 0.0


def test_a_part_of_fine_detail_keeps_under_the_cap_with_a_warning(tmp_path):
    import cadquery as cq

    plate = (cq.Workplane("XY").box(32, 32, 3.2, centered=(True, True, False)).faces(">Z").workplane()
             .rarray(8, 8, 4, 4).hole(3))
    found = suggest.suggest(mesh_io.load_model(_step(plate, tmp_path)))
    assert found.dropped and found.share <= suggest.MAX_SHARE
    assert "decorative" in found.warnings[0]
    assert len(found.regions) + len(found.dropped) <= 16


def test_regions_that_nearly_touch_are_merged_and_far_ones_are_not(tmp_path):
    import cadquery as cq

    plate = (cq.Workplane("XY").box(96, 32, 6.4, centered=False).faces(">Z").workplane(centerOption="CenterOfBoundBox")
             .pushPoints([(-40, 0), (-33, 0), (40, 0)]).hole(3))
    found = suggest.suggest(mesh_io.load_model(_step(plate, tmp_path)))
    sizes = sorted(len(r.features) for r in found.regions)
    assert sizes == [1, 2]


def _plate_with_hole(tmp_path) -> Path:
    import cadquery as cq

    plate = (cq.Workplane("XY").box(64, 48, 9.6, centered=(True, True, False))
             .faces(">Z").workplane().center(-12, 4).hole(6.5))
    return _step(plate, tmp_path, "plate.step")


def test_the_suggest_command_prints_a_line_per_region_and_writes_them(tmp_path, capsys):
    from core import cli

    path, out = _plate_with_hole(tmp_path), tmp_path / "regions.json"
    assert cli.main(["suggest", str(path), "--out", str(out)]) == 0
    lines = capsys.readouterr().out.splitlines()
    words, box = lines[0].split(": --high-res=")
    assert words == "hole Ø6.5 mm, 9.6 mm deep at axis z through (-12.0, 4.0, 4.8)"
    # by hand: the hole's box (x -15.25..-8.75, y 0.75..7.25, z 0..9.6) grown by the wall
    by_hand = [-16.25, -0.25, -0.5, -7.75, 8.25, 10.1]
    assert np.allclose([float(v) for v in box.split(",")], by_hand, atol=0.01)
    # by hand: 27 of the 144 cells; they hold 27 * 8 * 8 * 3.2 mm³ less the hole's
    # 3.25² * pi * 9.6 mm³ of the plate's 64 * 48 * 9.6 - 3.25² * pi * 9.6 mm³
    hole = 3.25 ** 2 * np.pi * 9.6
    share = (27 * 8 * 8 * 3.2 - hole) / (64 * 48 * 9.6 - hole)
    assert lines[1] == (f"1 region(s) suggested from the brep, marking cells that hold "
                        f"{share:.0%} of the part (19% of its cells)")
    doc = json.loads(out.read_text())
    assert doc["regions"][0]["high_res"] == box
    assert doc["regions"][0]["features"][0]["centre_mm"] == [-12.0, 4.0, 4.8]
    # by hand: the box spans x -16.25..-7.75 and y -0.25..8.25 on the 8 x 6 cell grid from
    # x -32, y -24: it reaches into 3 columns in x, 3 in y, in all 3 layers: 27 of 144 cells
    assert doc["share_of_cells"] == round(27 / 144, 4)
    assert abs(doc["share_of_volume"] - share) < 0.01


def test_the_suggest_command_refuses_bad_input_in_one_line(tmp_path, capsys):
    from core import cli

    path = _plate_with_hole(tmp_path)
    assert cli.main(["suggest", str(path), "--tolerance", "-1"]) == 2
    assert cli.main(["suggest", str(tmp_path / "none.step")]) == 2
    assert cli.main(["suggest", str(path), "--out", str(tmp_path / "no" / "r.json")]) == 2
    assert cli.main(["suggest", str(path), "--out", str(path)]) == 2      # the model itself
    assert cli.main(["suggest", str(path), "--min-speedup", "-1"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 5 and all(line.startswith("error: ") for line in err)
    assert "not a regions file" in err[3] and path.stat().st_size > 1000
    assert "--min-speedup" in err[4]
    out = tmp_path / "regions.json"
    assert cli.main(["suggest", str(path), "--out", str(out)]) == 0
    assert cli.main(["suggest", str(path), "--out", str(out)]) == 0     # its own file again


@pytest.mark.slow
def test_fabricate_suggest_prints_the_hole_and_adds_the_users_marks(tmp_path):
    from core import pipeline
    from core import report as reporting

    path = _plate_with_hole(tmp_path)
    fab = pipeline.run(str(path), suggest=True, slice_parts=False, picture=False,
                       high_res=["20,-20,0,28,-12,3"])
    assert len(fab.printed) == 2
    doc = reporting.document(fab)["high_res"]["suggested"]
    assert [r["reason"] for r in doc["regions"]] == ["hole Ø6.5 mm, 9.6 mm deep"]
    # the hole's wall (by hand: radius 3.25 round x -12, y 4) lies in printed bricks only
    angle = np.linspace(0, 2 * np.pi, 24, endpoint=False)
    wall = np.stack([-12 + 3.25 * np.cos(angle), 4 + 3.25 * np.sin(angle), np.full(24, 4.8)], 1)
    grid, labels = fab.layout.grid, fab.layout.labels()
    cells = np.floor((wall - grid.origin) / grid.cell).astype(int)
    kinds = {fab.layout.bricks[labels[tuple(c)]].kind for c in cells}
    assert kinds == {"printed"}
    # the shares are on the grid laid out (moved by the grid fit): by hand, the cells the
    # region box touches, their part of the plate less the hole, of the plate less the hole
    box = np.array(doc["regions"][0]["box_mm"])
    first = np.floor((box[0] - grid.origin) / grid.cell + 1e-6)
    stop = np.ceil((box[1] - grid.origin) / grid.cell - 1e-6)
    lo, hi = grid.origin + first * grid.cell, grid.origin + stop * grid.cell
    plate = np.array([[-32, -24, 0], [32, 24, 9.6]])
    hole = 3.25 ** 2 * np.pi * 9.6
    inside = np.prod(np.clip(np.minimum(hi, plate[1]) - np.maximum(lo, plate[0]), 0, None))
    assert abs(doc["share_of_volume"] - (inside - hole) / (64 * 48 * 9.6 - hole)) < 0.01
    touched = np.zeros(grid.shape, dtype=bool)
    touched[tuple(slice(max(int(a), 0), int(b)) for a, b in zip(first, stop))] = True
    assert doc["share_of_cells"] == round(np.count_nonzero(touched & grid.filled) / grid.count, 4)
    plain = pipeline.run(str(path), slice_parts=False, picture=False)
    assert "suggested" not in reporting.document(plain)["high_res"] and not plain.printed


def section_round_loops(mesh: trimesh.Trimesh, axis: int, at: float) -> list[tuple]:
    """The round loops of the section of ``mesh`` across ``axis`` at ``at`` (mm): (centre
    in the section's two other axes, diameter) of each closed loop whose points lie within
    3 % of their mean distance from their centre."""
    normal = np.eye(3)[axis]
    origin = normal * at
    section = mesh.section(plane_origin=origin, plane_normal=normal)
    keep = [n for n in range(3) if n != axis]
    out = []
    for loop in section.discrete:
        p = loop[:, keep]
        c = p.mean(axis=0)
        r = np.linalg.norm(p - c, axis=1)
        if r.std() < 0.03 * r.mean():
            out.append((c, 2 * r.mean()))
    return out


@pytest.mark.slow
def test_the_round_holes_of_the_motor_bracket_mesh_are_covered():
    # Reference: the boundary loops of planar sections across y (the holes' axis) at 20 %
    # and 50 % of the height, y = 5.8 and 14.5 mm (trimesh.section): five round loops of
    # Ø4.47 mm at x, z = (28.7, -3.0), (28.7, 60.5), (-2.9, 28.8), (60.5, 28.7),
    # (28.7, 77.5), the screw holes; a Ø57.4 mm round loop, the motor bore (over 20 mm);
    # and the part's outlines, not round.
    model = mesh_io.load_model(shared("openbot_motor_bracket.stl"))
    assert model.brep is None and not any(model.offset_mm)
    found = suggest.suggest(model)
    holes = []
    for y in (5.8, 14.5):
        loops = [(c, d) for c, d in section_round_loops(model.mesh, 1, y) if d < suggest.LIMIT_MM]
        assert len(loops) == 5 and all(abs(d - 4.47) < 0.05 for _, d in loops)
        holes += [(y, c, d) for c, d in loops]
    angle = np.linspace(0, 2 * np.pi, 16, endpoint=False)
    covered = 0
    for y, (x, z), d in holes:
        rim = np.stack([x + d / 2 * np.cos(angle), np.full(16, y), z + d / 2 * np.sin(angle)], axis=1)
        covered += all(inside(np.stack([p, p]), found.regions) for p in rim)
    assert covered >= 0.9 * len(holes)
    assert found.share <= suggest.MAX_SHARE
    reasons = [f.reason for r in found.regions for f in r.features if f.kind == "hole"]
    assert len(reasons) == 5 and all(w.startswith("hole Ø4.") for w in reasons)


def test_the_volume_per_cell_adds_up_to_the_parts_volume(tmp_path):
    """By hand: a 30 x 20 x 9.6 mm plate with a 6 mm bore through it holds
    30 * 20 * 9.6 - pi * 3^2 * 9.6 = 5488.6 mm^3, off the grid's lattice; the fine cells
    count it within 2 % (the cells the surface touches would count 10 % more)."""
    import cadquery as cq

    plate = (cq.Workplane("XY").box(30, 20, 9.6, centered=False)
             .faces(">Z").workplane(centerOption="CenterOfBoundBox").hole(6).translate((1.3, 2.7, 0.5)))
    model = mesh_io.load_model(_stl(plate, tmp_path))
    origin, shape = suggest.voxelize.grid_frame(model.mesh.bounds)
    total = suggest.volume_per_cell(model.mesh, origin, shape, True).sum()
    fine_mm3 = np.prod(np.asarray(suggest.CELL_MM) / np.array(suggest.FINE_SPLIT))
    assert total * fine_mm3 == pytest.approx(30 * 20 * 9.6 - math.pi * 9 * 9.6, rel=0.02)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["asm4_connecting_rod.FCStd", "openbot_motor_bracket.stl"])
def test_the_volume_per_cell_of_a_shared_model_is_its_volume(name):
    """Against the mesh's own (divergence-theorem) volume: within 3 %."""
    model = mesh_io.load_model(shared(name))
    origin, shape = suggest.voxelize.grid_frame(model.mesh.bounds)
    total = suggest.volume_per_cell(model.mesh, origin, shape, model.watertight).sum()
    fine_mm3 = np.prod(np.asarray(suggest.CELL_MM) / np.array(suggest.FINE_SPLIT))
    assert total * fine_mm3 == pytest.approx(abs(model.mesh.volume), rel=0.03)


def test_a_region_is_priced_as_the_block_it_cuts_out_of_the_model(tmp_path):
    """By hand: a region inside a plain block prints as the cell-aligned box it cuts out,
    every face of it a cut; the block whole prints in its flattest pose.  Both are timed
    by the calibrated estimate of those boxes, without supports."""
    from core.printing import estimate

    block = trimesh.creation.box((64.0, 48.0, 19.2))
    block.apply_translation(-block.bounds[0])
    block.export(tmp_path / "block.stl")
    model = mesh_io.load_model(tmp_path / "block.stl")
    grid, weight = suggest._grid(model)
    price = suggest.Pricer(model.mesh, grid, weight)
    box = np.array([[20.0, 14.0, 5.0], [35.0, 30.0, 12.0]])
    first, stop = high_res.box_range(grid.origin, grid.cell, box)
    size = (stop - first) * np.asarray(grid.cell)
    assert np.all(size > 0) and np.all(size < [64, 48, 19.2])
    cut = trimesh.creation.box(size)
    region = suggest.Region(box, ())
    assert price.seconds([region]) == pytest.approx(estimate.estimate_seconds([cut]), rel=0.01)
    flattest = trimesh.creation.box((64.0, 48.0, 19.2))
    assert price.whole == pytest.approx(estimate.estimate_seconds([flattest]), rel=0.01)


@pytest.mark.slow
def test_the_motor_brackets_walls_are_dropped_for_the_speedup_and_its_holes_kept():
    """The bracket's thin walls would make its printed parts slower than the bracket whole
    (PrusaSlicer: 3 h 26 min against 3 h 22 min with them marked); they are dropped with
    a warning giving the estimate, and its five screw holes stay marked."""
    model = mesh_io.load_model(shared("openbot_motor_bracket.stl"))
    everything = suggest.suggest(model, min_speedup=0)
    assert any(f.kind == "wall" for r in everything.regions for f in r.features)
    assert not any("estimated" in w for w in everything.warnings)
    found = suggest.suggest(model)
    kinds = [f.kind for r in found.regions for f in r.features]
    assert kinds.count("hole") == 5 and "wall" not in kinds
    assert {f.kind for r in found.dropped for f in r.features} == {"wall"}
    times = found.to_json()["estimate"]
    assert times["speedup"] < 1 < times["kept_speedup"]
    assert any("estimated" in w and "dropped" in w for w in found.warnings)


@pytest.mark.slow
def test_the_lens_mount_is_all_fine_detail_and_is_left_to_print_whole():
    # Reference: sections across z at 10 %, 50 % and 90 % of its height hold two loops each
    # (trimesh.section): the lens bore, round, Ø34.8 to 36.9 mm, and the thread's outline
    # (Ø40.5 to 40.9 mm, round within 3 % at some heights); no round hole under 20 mm. Its 2.6 mm thin
    # ring of a wall is the whole part.
    model = mesh_io.load_model(shared("relativty_lens_mount.stl"))
    low, high = model.mesh.bounds[:, 2]
    for f in (0.1, 0.5, 0.9):
        loops = section_round_loops(model.mesh, 2, low + f * (high - low))
        assert 1 <= len(loops) <= 2 and min(d for _, d in loops) > 34
    found = suggest.suggest(model)
    assert found.share <= suggest.MAX_SHARE
    assert found.dropped and "decorative" in found.warnings[0]
    assert found.dropped[0].features[0].kind == "wall"
    # Its round holes are over 20 mm. Taken as features all the same (under 40 mm), holes
    # before walls: the 3.1 mm deep Ø36.9 mm seat at the top is kept (cells holding 23 % of
    # the part), but the Ø34.9 mm bore's box touches cells holding 98 % of it (every
    # column of the 6 x 6 cells over 22.5 of its 25.6 mm): no region covers it under the cap.
    wide = suggest.suggest(model, limit_mm=40.0)
    kept = [f for r in wide.regions for f in r.features]
    assert [f.kind for f in kept] == ["hole"] and 36 < kept[0].size_mm < 38
    bore = [f for r in wide.dropped for f in r.features if f.kind == "hole"]
    assert len(bore) == 1 and 34 < bore[0].size_mm < 36
    assert wide.share <= suggest.MAX_SHARE


def _stl(shape, tmp_path, name="part.stl") -> Path:
    import cadquery as cq

    path = tmp_path / name
    cq.exporters.export(shape, str(path), tolerance=0.01, angularTolerance=0.1)
    return path


def test_a_mesh_hole_is_found_by_its_cylinder_fit(tmp_path):
    import cadquery as cq

    plate = (cq.Workplane("XY").box(48, 48, 9.6, centered=(True, True, False))
             .faces(">Z").workplane().center(-10, 0).hole(6.5))
    model = mesh_io.load_model(_stl(plate, tmp_path))
    found = suggest.suggest(model)
    assert found.source == "mesh"
    hole = [f for r in found.regions for f in r.features if f.kind == "hole"]
    assert len(hole) == 1
    assert hole[0].reason == "hole Ø6.5 mm, 9.6 mm deep"
    assert np.allclose(hole[0].centre, (-10, 0, 4.8), atol=0.05) and np.allclose(hole[0].axis, (0, 0, 1))


def test_a_thin_upright_fin_is_a_wall_and_a_plain_block_is_nothing(tmp_path):
    import cadquery as cq

    block = cq.Workplane("XY").box(64, 24, 6.4, centered=False)
    assert suggest.suggest(mesh_io.load_model(_stl(block, tmp_path, "block.stl"))).regions == ()
    fin = block.union(cq.Workplane("XY").box(2, 24, 12.8, centered=False).translate((35, 0, 6.4)))
    found = suggest.suggest(mesh_io.load_model(_stl(fin, tmp_path, "fin.stl")))
    walls = [f for r in found.regions for f in r.features if f.kind == "wall"]
    assert walls and all(f.reason == "wall 2.0 mm thin" for f in walls)
    # by hand: the fin spans x 35..37, z 6.4..19.2: its region holds it, grown by the wall
    assert len(found.regions) == 1
    assert np.allclose(found.regions[0].box[:, 0], [35 - suggest.WALL_MM, 37 + suggest.WALL_MM], atol=0.01)
    assert found.regions[0].box[0, 2] <= 6.5 and found.regions[0].box[1, 2] >= 19.1
