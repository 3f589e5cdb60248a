"""Marking high-res regions: boxes, region solids and brick ids to printed bricks."""

import numpy as np
import pytest
import trimesh

from core import high_res
from core.errors import InputError
from core.layout import greedy as layout
from core.model import Brick, Grid, Layout


def _grid(shape=(4, 4, 6)):
    return Grid(origin=np.zeros(3), cell=np.array([8.0, 8.0, 3.2]), filled=np.ones(shape, bool))


def test_parse_box_orders_corners_and_refuses_bad_text():
    assert np.allclose(high_res.parse_box("10,0,5,0,8,1"), [[0, 0, 1], [10, 8, 5]])
    for bad in ("1,2,3", "a,b,c,d,e,f", "0,0,0,0,1,1", "0,0,0,nan,1,1"):
        with pytest.raises(InputError):
            high_res.parse_box(bad)


def test_box_touches_cells_sharing_positive_volume_only():
    g = _grid()
    cells = high_res.box_cells(g, [[0, 0, 0], [8, 8, 3.2]])
    assert cells.sum() == 1 and cells[0, 0, 0]
    cells = high_res.box_cells(g, [[7.9, 0.1, 3.1], [8.1, 0.2, 3.3]])
    assert {tuple(c) for c in np.argwhere(cells)} == {(0, 0, 0), (1, 0, 0), (0, 0, 1), (1, 0, 1)}
    assert not high_res.box_cells(g, [[100, 100, 100], [200, 200, 200]]).any()


def test_region_solid_marks_cells_like_a_box(tmp_path):
    g = _grid()
    path = tmp_path / "region.stl"
    trimesh.creation.box(bounds=[[1, 1, 1], [15, 7, 6]]).export(path)
    got = high_res.solid_cells(g, path)
    assert np.array_equal(got, high_res.box_cells(g, [[1, 1, 1], [15, 7, 6]]))


def test_touched_bricks_and_groups():
    g = _grid()
    bricks = [Brick(0, "3001", (2, 4, 3), (0, 0, 0)), Brick(1, "3001", (2, 4, 3), (2, 0, 0)),
              Brick(2, "3001", (2, 4, 3), (0, 0, 3)), Brick(3, "3001", (2, 4, 3), (2, 0, 3))]
    lay = Layout(g, bricks)
    cells = high_res.box_cells(g, [[1, 1, 1], [2, 2, 2]])
    assert high_res.touched_bricks(lay, cells) == [0]
    assert high_res.groups(lay, [0, 3]) == [[0], [3]]
    assert high_res.groups(lay, [3, 0, 1]) == [[0, 1, 3]]
    with pytest.raises(InputError):
        high_res.check_ids(lay, [7])


def test_lay_out_around_keeps_bricks_inside_or_outside_the_marked_cells():
    grid = _grid((6, 6, 6))
    cells = high_res.box_cells(grid, [[4, 4, 1], [20, 12, 10]])
    lay = layout.lay_out_around(grid, cells, seed=3)
    lab = lay.labels()
    assert (lab >= 0).all() and [b.id for b in lay.bricks] == list(range(len(lay.bricks)))
    for n, b in enumerate(lay.bricks):
        inside = cells[lab == n]
        assert inside.all() or not inside.any()
    touched = high_res.touched_bricks(lay, cells)
    assert sum(int(np.prod(lay.bricks[i].size)) for i in touched) == int(cells.sum())


def test_as_box_takes_text_six_numbers_or_corners():
    from core.high_res import as_box
    want = np.array([[0.0, 1.0, 2.0], [3.0, 4.0, 5.0]])
    for value in ("3,4,5,0,1,2", [0, 1, 2, 3, 4, 5], want):
        assert np.array_equal(as_box(value), want)
    for bad in ([1, 2, 3], "a,b", [[0, 0, 0], [1, 1, 0]]):
        with pytest.raises(InputError):
            as_box(bad)


def _floor_and_column() -> tuple[Grid, np.ndarray]:
    """A 6x6 floor two layers thick with a 2x2 column through all 8 layers, the column marked."""
    filled = np.zeros((6, 6, 8), dtype=bool)
    filled[:, :, :2] = True
    filled[2:4, 2:4, :] = True
    marked = np.zeros_like(filled)
    marked[2:4, 2:4, :] = True
    return Grid(np.zeros(3), np.array([8.0, 8.0, 3.2]), filled), marked


def test_anchor_adds_a_tab_under_the_lego_next_to_a_sideways_only_region():
    grid, marked = _floor_and_column()
    out = high_res.anchor(grid, marked)
    tab = out & ~marked
    assert np.array_equal(np.flatnonzero(tab.any(axis=(0, 1))), [0])
    assert tab[:, :, 0].sum() == 4
    assert {tuple(c) for c in np.argwhere(tab[:, :, 0])} == {(1, 3), (4, 3), (3, 1), (3, 4)}
    assert not (out & ~grid.filled).any()


def test_anchor_leaves_regions_that_already_touch_lego_vertically():
    grid, marked = _floor_and_column()
    marked[:, :, :1] = False
    assert np.array_equal(high_res.anchor(grid, marked), marked & grid.filled)
