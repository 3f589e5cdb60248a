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

from core import high_res, mesh_io, suggest

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
                       atol=1e-6)
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
    assert lines[0] == ("hole Ø6.5 mm, 9.6 mm deep at axis z through (-12.0, 4.0, 4.8): "
                        "--high-res=-16.250,-0.250,-0.500,-7.750,8.250,10.100")
    assert lines[1].startswith("1 region(s) suggested from the brep, marking ")
    doc = json.loads(out.read_text())
    assert doc["regions"][0]["high_res"] == "-16.250,-0.250,-0.500,-7.750,8.250,10.100"
    assert doc["regions"][0]["features"][0]["centre_mm"] == [-12.0, 4.0, 4.8]
    # by hand: the box spans x -16.25..-7.75 and y -0.25..8.25 on the 8 x 6 cell grid from
    # x -32, y -24: it reaches into 3 columns in x, 3 in y, in all 3 layers: 27 of 144 cells
    assert doc["share_of_cells"] == round(27 / 144, 4)


def test_the_suggest_command_refuses_bad_input_in_one_line(tmp_path, capsys):
    from core import cli

    path = _plate_with_hole(tmp_path)
    assert cli.main(["suggest", str(path), "--tolerance", "-1"]) == 2
    assert cli.main(["suggest", str(tmp_path / "none.step")]) == 2
    assert cli.main(["suggest", str(path), "--out", str(tmp_path / "no" / "r.json")]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 3 and all(line.startswith("error: ") for line in err)


@pytest.mark.slow
def test_fabricate_suggest_prints_the_hole_and_adds_the_users_marks(tmp_path):
    from core import pipeline

    path = _plate_with_hole(tmp_path)
    fab = pipeline.run(str(path), suggest=True, slice_parts=False, picture=False,
                       high_res=["20,-20,0,28,-12,3"])
    assert len(fab.printed) == 2
    doc = pipeline.report(fab)["high_res"]["suggested"]
    assert [r["reason"] for r in doc["regions"]] == ["hole Ø6.5 mm, 9.6 mm deep"]
    # the hole's wall (by hand: radius 3.25 round x -12, y 4) lies in printed bricks only
    angle = np.linspace(0, 2 * np.pi, 24, endpoint=False)
    wall = np.stack([-12 + 3.25 * np.cos(angle), 4 + 3.25 * np.sin(angle), np.full(24, 4.8)], 1)
    grid, labels = fab.layout.grid, fab.layout.labels()
    cells = np.floor((wall - grid.origin) / grid.cell).astype(int)
    kinds = {fab.layout.bricks[labels[tuple(c)]].kind for c in cells}
    assert kinds == {"printed"}
    plain = pipeline.run(str(path), slice_parts=False, picture=False)
    assert "suggested" not in pipeline.report(plain)["high_res"] and not plain.printed
