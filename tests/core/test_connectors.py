"""Connectors: printed parts, even thinner than a brick, clamp onto the LEGO above and below."""

from __future__ import annotations

import cadquery as cq
import manifold3d as m3
import numpy as np
import pytest

from core import pipeline

from core import report as reporting
from core.errors import InputError
from core.model import Brick, Grid, Layout
from core.parts import connectors

#: A wall 64 mm long, 3 mm thick, 12 plates high: thinner than a stud is wide.
WALL = (64.0, 3.0, 38.4)
#: The middle of the wall, layers 4..7, x from -16 to 16 (grid x is centred on the wall).
REGION = "-15,-10,13.5,15,10,21.5"


@pytest.fixture(scope="module")
def wall_files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("wall")
    wall = cq.Workplane("XY").box(*WALL, centered=(True, True, False))
    step, stl = folder / "wall.step", folder / "wall.stl"
    cq.exporters.export(wall, str(step))
    cq.exporters.export(wall, str(stl), tolerance=0.01)
    return {"step": step, "stl": stl}


def _stack() -> Layout:
    """Three 1x2 bricks stacked, the middle one printed, a fourth beside the middle one."""
    filled = np.zeros((3, 2, 9), dtype=bool)
    filled[0, :, :] = True
    filled[1, :, 3:6] = True
    grid = Grid(np.zeros(3), np.array([8.0, 8.0, 3.2]), filled)
    bricks = [Brick(0, "3004", (1, 2, 3), (0, 0, 0)), Brick(1, "3004", (1, 2, 3), (0, 0, 3)),
              Brick(2, "3004", (1, 2, 3), (0, 0, 6)), Brick(3, "3004", (1, 2, 3), (1, 0, 3))]
    return Layout(grid, bricks)


def test_find_marks_every_vertical_contact_cell():
    found = connectors.find(_stack(), [[1]])
    assert sorted(map(tuple, found.top.tolist())) == [(0, 0, 5), (0, 1, 5)]
    assert sorted(map(tuple, found.bottom.tolist())) == [(0, 0, 3), (0, 1, 3)]


def test_a_wide_contact_gets_a_connector_at_every_stud():
    filled = np.ones((4, 2, 9), dtype=bool)
    grid = Grid(np.zeros(3), np.array([8.0, 8.0, 3.2]), filled)
    lay = Layout(grid, [Brick(n, "3001", (4, 2, 3), (0, 0, 3 * n)) for n in range(3)])
    found = connectors.find(lay, [[1]])
    assert len(found.top) == 8 and len(found.bottom) == 8


def test_bricks_of_one_part_need_no_connector_between_them():
    found = connectors.find(_stack(), [[0, 1, 2]])
    assert len(found.top) == 0 and len(found.bottom) == 0


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["step", "stl"])
def test_thin_printed_region_clamps_with_studs_and_sockets(wall_files, kind):
    fab = pipeline.run(wall_files[kind], high_res=[REGION], slice_parts=False)
    assert fab.stability.components == 1
    assert len(fab.printed) == 1
    part = fab.printed[0]
    assert part.mesh.is_watertight and part.mesh.body_count == 1
    doc = reporting.document(fab)["printed_parts"][0]
    cells = {tuple(c) for c in fab.connectors.top.tolist()}
    assert doc["engaged"]["studs"] == len(cells) > 2
    assert doc["engaged"]["sockets"] == len(fab.connectors.bottom) > 2
    assert doc["engaged"]["clamps"] is True
    # The wall is printed whole above the socket band and below the skin.
    model = m3.Manifold.cube(list(WALL)).translate([-WALL[0] / 2, -WALL[1] / 2, 0.0])
    solid = _manifold(part.mesh)
    lo = fab.grid.origin + np.min([b.cell for b in fab.layout.bricks if b.kind == "printed"], axis=0) * fab.grid.cell
    hi = fab.grid.origin + np.max([np.add(b.cell, b.size) for b in fab.layout.bricks
                                   if b.kind == "printed"], axis=0) * fab.grid.cell
    middle = m3.Manifold.cube(list(hi - lo - [0.2, 0, 2 * 3.2])).translate(list(lo + [0.1, 0, 3.2]))
    inside = model ^ middle
    assert (inside - solid).volume() < 1e-6 * inside.volume()
    assert (solid - model).volume() > 0.0


def _manifold(mesh) -> m3.Manifold:
    return m3.Manifold(m3.Mesh64(vert_properties=np.asarray(mesh.vertices, np.float64),
                                 tri_verts=np.asarray(mesh.faces, np.uint64)))


def test_without_connectors_the_thin_part_hangs_loose(wall_files):
    fab = pipeline.run(wall_files["step"], high_res=[REGION], slice_parts=False, connectors=False)
    part = fab.printed[0]
    assert not part.complete_studs and part.incomplete_studs
    assert part.engaged["clamps"] is False and "--no-connectors" in part.engaged["why"]
    assert fab.stability.components > 1


@pytest.mark.slow
def test_part_edits_split_and_merge_printed_bricks(wall_files):
    wide = "-31,-10,3.5,31,10,31"
    whole = pipeline.run(wall_files["step"], high_res=[wide], slice_parts=False)
    assert len(whole.printed) == 1 and len(whole.printed[0].bricks) >= 2
    ids = whole.printed[0].bricks
    split = pipeline.run(wall_files["step"], high_res=[wide], slice_parts=False,
                         part_edits=[{"op": "split", "bricks": ids}])
    assert len(split.printed) == len(ids)
    merged = pipeline.run(wall_files["step"], high_res=[wide], slice_parts=False,
                          part_edits=[{"op": "split", "bricks": ids}, {"op": "merge", "boxes": [wide]}])
    assert len(merged.printed) == 1 and sorted(merged.printed[0].bricks) == sorted(ids)
    with pytest.raises(InputError, match="op must be"):
        pipeline.run(wall_files["step"], high_res=[wide], slice_parts=False, part_edits=[{"op": "glue"}])


@pytest.mark.slow
def test_a_seat_standing_through_the_floor_is_anchored(tmp_path):
    floor = cq.Workplane("XY").box(48.0, 48.0, 6.4, centered=(True, True, False))
    seat = cq.Workplane("XY").circle(6.0).circle(1.7).extrude(25.6)
    step = tmp_path / "seat.step"
    cq.exporters.export(floor.union(seat), str(step))
    box = "-7,-7,0,7,7,26"
    fab = pipeline.run(step, high_res=[box], slice_parts=False)
    assert fab.stability.components == 1
    assert reporting.document(fab)["high_res"]["anchor_cells"] > 0
    assert fab.printed[0].complete_studs
    loose = pipeline.run(step, high_res=[box], slice_parts=False, connectors=False)
    assert loose.stability.components > 1


def test_the_layout_is_told_before_the_printed_parts_are_cut(wall_files):
    """``on_layout`` gets the final bricks once, before the printed_parts stage: its LEGO
    bricks are the finished layout's, and its printed ones fill the printed parts' cells."""
    told, stages = [], []
    fab = pipeline.run(wall_files["step"], high_res=[REGION], slice_parts=False,
                       progress=lambda fraction, message: stages.append(message),
                       on_layout=lambda ready: told.append((ready, len(stages))))
    assert len(told) == 1
    ready, at = told[0]
    assert "printed_parts" in stages[at:] and "printed_parts" not in stages[:at]
    assert ready.printed and ready.seconds > 0
    lego = {(b.cell, b.size) for b in fab.layout.bricks if b.kind == "lego"}
    assert {(b.cell, b.size) for b in ready.layout.bricks if b.id not in ready.printed} == lego
    assert ready.printed == {i for p in fab.printed for i in p.bricks}
    cells = sum(int(np.prod(b.size)) for b in ready.layout.bricks if b.id in ready.printed)
    assert cells == sum(p.cells for p in fab.printed)
