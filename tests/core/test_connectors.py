"""Connectors: printed parts thinner than a brick still clamp onto the LEGO above and below."""

from __future__ import annotations

import cadquery as cq
import manifold3d as m3
import numpy as np
import pytest

from core import connectors, pipeline, printed
from core.brick_solids import BrickGeometry, brick_solid, to_trimesh
from core.errors import InputError
from core.model import Brick, Grid, Layout

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


def test_find_marks_vertical_contacts_only():
    found = connectors.find(_stack(), [[1]])
    assert sorted(map(tuple, found.top.tolist())) == [(0, 0, 5), (0, 1, 5)]
    assert sorted(map(tuple, found.bottom.tolist())) == [(0, 0, 3), (0, 1, 3)]
    assert len(found.boxes) == 4
    g = BrickGeometry()
    tops = found.boxes[found.boxes[:, 1, 2] > 19.2]
    assert np.allclose(tops[:, 0, 2], 19.2 - connectors.TOP_BAND_MM)
    assert np.all(tops[:, 1, 2] > 19.2 + g.stud_height)


def test_bricks_of_one_part_need_no_connector_between_them():
    found = connectors.find(_stack(), [[0, 1, 2]])
    assert len(found.top) == 0 and len(found.bottom) == 0
    assert connectors.with_connectors(printed.ModelSolid(manifold=m3.Manifold.cube([1, 1, 1])),
                                      found).manifold.volume() == pytest.approx(1.0)


@pytest.mark.parametrize("kind", ["step", "stl"])
def test_thin_printed_region_clamps_with_connectors(wall_files, kind):
    fab = pipeline.run(wall_files[kind], high_res=[REGION], slice_parts=False)
    assert fab.stability.components == 1
    assert len(fab.printed) == 1
    part = fab.printed[0]
    assert part.complete_studs, "the studs under the LEGO above must be complete"
    assert not any(part.bottom_ok.get(tuple(c), True) is False for c in fab.connectors.bottom.tolist())
    assert part.mesh.is_watertight
    doc = pipeline.report(fab)["printed_parts"][0]
    assert doc["connectors"]["studs_kept"] == len(fab.connectors.top) > 0
    assert doc["connectors"]["sockets_kept"] == len(fab.connectors.bottom) > 0
    # The part leaves the model only inside the connector boxes.
    model = m3.Manifold.cube(list(WALL)).translate([-WALL[0] / 2, -WALL[1] / 2, 0.0])
    boxes = [m3.Manifold.cube(list(hi - lo)).translate(list(lo)) for lo, hi in fab.connectors.boxes]
    allowed = m3.Manifold.batch_boolean([model, *boxes], m3.OpType.Add)
    solid = _manifold(part.mesh)
    assert (solid - allowed).volume() < 1e-3 * solid.volume()
    assert (solid - model).volume() > 0.0
    # Inside its connector boxes the part is the brick itself (what mark_grip relies on).
    (brick,) = [b for b in fab.layout.bricks if b.kind == "printed"]
    origin = fab.grid.origin + np.array(brick.cell) * fab.grid.cell
    whole = _manifold(to_trimesh(brick_solid(*brick.size, BrickGeometry(), tuple(origin)).shape))
    for box in boxes:
        assert (solid ^ box).volume() == pytest.approx((whole ^ box).volume(), rel=2e-3)


def _manifold(mesh) -> m3.Manifold:
    return m3.Manifold(m3.Mesh(vert_properties=np.asarray(mesh.vertices, np.float32),
                               tri_verts=np.asarray(mesh.faces, np.uint32)))


def test_without_connectors_the_thin_part_hangs_loose(wall_files):
    fab = pipeline.run(wall_files["step"], high_res=[REGION], slice_parts=False, connectors=False)
    part = fab.printed[0]
    assert not part.complete_studs
    assert fab.stability.components > 1
    (split,) = fab.stability.unconnectable
    assert "P1" in split["reason"] and "cuts their studs" in split["reason"]


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


def test_a_seat_standing_through_the_floor_is_anchored(tmp_path):
    floor = cq.Workplane("XY").box(48.0, 48.0, 6.4, centered=(True, True, False))
    seat = cq.Workplane("XY").circle(6.0).circle(1.7).extrude(25.6)
    step = tmp_path / "seat.step"
    cq.exporters.export(floor.union(seat), str(step))
    box = "-7,-7,0,7,7,26"
    fab = pipeline.run(step, high_res=[box], slice_parts=False)
    assert fab.stability.components == 1
    assert pipeline.report(fab)["high_res"]["anchor_cells"] > 0
    assert fab.printed[0].complete_studs
    loose = pipeline.run(step, high_res=[box], slice_parts=False, connectors=False)
    assert loose.stability.components > 1
