"""Cells to millimetre boxes (core.model) and the brick under a picked point
(core.picking), checked against boxes computed by hand."""

from __future__ import annotations

import numpy as np
import pytest

from core import picking
from core.model import Brick, Grid, Layout


def _grid() -> Grid:
    """A grid of 4 x 2 x 6 cells of 8 x 8 x 3.2 mm from (-10, 5, 1)."""
    return Grid(np.array([-10.0, 5.0, 1.0]), np.array([8.0, 8.0, 3.2]), np.ones((4, 2, 6), bool))


def _layout() -> Layout:
    """Two 2x2 bricks side by side on the bottom, a 2x4 brick turned across them above,
    ids 7, 3 and 12 (ids are not list positions)."""
    return Layout(_grid(), [Brick(7, "3003", (2, 2, 3), (0, 0, 0)),
                            Brick(3, "3003", (2, 2, 3), (2, 0, 0)),
                            Brick(12, "3001", (4, 2, 3), (0, 0, 3))])


def test_box_of_a_cell_and_of_a_brick():
    grid = _grid()
    lo, hi = grid.box_mm((0, 0, 0))
    assert lo.tolist() == [-10.0, 5.0, 1.0]
    assert hi.tolist() == pytest.approx([-2.0, 13.0, 4.2])
    lo, hi = grid.box_mm((2, 1, 3), (2, 1, 3))
    # x: -10 + 2 * 8 = 6 .. 22; y: 5 + 8 = 13 .. 21; z: 1 + 3 * 3.2 = 10.6 .. 20.2
    assert lo.tolist() == pytest.approx([6.0, 13.0, 10.6])
    assert hi.tolist() == pytest.approx([22.0, 21.0, 20.2])
    assert grid.corner_mm((-1, 0, 0)).tolist() == [-18.0, 5.0, 1.0]


def test_nearest_cell_inverts_the_corner_also_across_grids():
    grid = _grid()
    for cell in [(0, 0, 0), (3, 1, 5), (-2, 7, 11)]:
        assert grid.nearest_cell(grid.corner_mm(cell)) == cell
    # a grid shifted by one cell and a float error: its cell (0, 0, 0) is cell (1, 0, 2) here
    other = Grid(np.array([-2.0 + 1e-9, 5.0, 7.4 - 1e-9]), grid.cell, grid.filled)
    assert grid.nearest_cell(other.corner_mm((0, 0, 0))) == (1, 0, 2)


def test_layout_boxes_follow_the_bricks_order():
    lo, hi = _layout().boxes_mm()
    assert np.allclose(lo, [[-10, 5, 1], [6, 5, 1], [-10, 5, 10.6]])
    assert np.allclose(hi, [[6, 21, 10.6], [22, 21, 10.6], [22, 21, 20.2]])
    assert Layout(_grid(), []).boxes_mm()[0].shape == (0, 3)


def test_the_brick_under_a_point_inside_or_on_its_box():
    layout = _layout()
    assert picking.brick_at(layout, (0.0, 10.0, 5.0)) == 7
    assert picking.brick_at(layout, (15.0, 10.0, 5.0)) == 3
    assert picking.brick_at(layout, (15.0, 10.0, 15.0)) == 12
    # on the outside face of a LEGO brick, 0.1 mm inside the box: still that brick
    assert picking.brick_at(layout, (-9.9, 10.0, 5.0)) == 7
    # the top of the upper brick, a float error above its box
    assert picking.brick_at(layout, (0.0, 10.0, 20.2 + 0.03)) == 12


def test_no_brick_beyond_the_tolerance():
    layout = _layout()
    assert picking.PICK_TOLERANCE_MM == 0.05
    assert picking.brick_at(layout, (0.0, 10.0, 20.2 + 0.06)) is None
    assert picking.brick_at(layout, (-10.0 - 0.06, 10.0, 5.0)) is None
    assert picking.brick_at(layout, (-10.0 - 0.06, 10.0, 5.0), tolerance=0.1) == 7
    assert picking.brick_at(Layout(_grid(), []), (0, 0, 0)) is None


def test_a_point_on_a_shared_face_takes_the_brick_whose_centre_is_nearer():
    layout = _layout()
    # x = 6 is the face between bricks 7 and 3; z = 10.6 the one between them and 12
    assert picking.brick_at(layout, (6.0, 10.0, 5.0)) == 3   # same centre distance: lower id
    assert picking.brick_at(layout, (2.0, 10.0, 10.6)) == 7  # centre of 7 at z 5.8, of 12 at 15.4
    assert picking.brick_at(layout, (2.0, 10.0, 10.6), among={12}) == 12
    assert picking.brick_at(layout, (15.0, 10.0, 5.0), among={7, 12}) is None


def test_a_brush_takes_the_bricks_within_its_radius():
    layout = _layout()
    point = (0.0, 10.0, 5.0)   # in brick 7: 6 mm from brick 3, 5.6 mm below brick 12
    assert picking.box_distances(layout, point).tolist() == pytest.approx([0.0, 6.0, 5.6])
    assert picking.bricks_within(layout, point, 0.0) == [7]
    assert picking.bricks_within(layout, point, 5.7) == [7, 12]
    assert picking.bricks_within(layout, point, 6.0) == [3, 7, 12]
    corner = (-12.0, 2.0, 1.0)  # 2 mm outside in x, 3 mm in y: 3.61 mm from brick 7
    assert picking.box_distances(layout, corner)[0] == pytest.approx(np.hypot(2.0, 3.0))
    assert picking.bricks_within(layout, corner, 3.6) == []
    assert picking.bricks_within(layout, corner, 3.61) == [7]
