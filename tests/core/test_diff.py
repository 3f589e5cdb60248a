"""Diff of two versions: cells on the previous lattice, changed surface, printed volume."""

from __future__ import annotations

import cadquery as cq
import numpy as np
import pytest
import trimesh

from core import diff, voxelize
from core.errors import InputError
from core.model import Grid


def _box(lo, hi) -> trimesh.Trimesh:
    return trimesh.creation.box(bounds=[lo, hi])


def test_same_mesh_gives_the_same_grid():
    mesh = _box([0.5, 0.5, 0], [30.5, 21, 10])
    previous = voxelize.legofy(mesh)
    grid, offset = diff.legofy_on(previous, mesh, closed=True)
    assert np.array_equal(offset, [0, 0, 0]) and np.array_equal(grid.filled, previous.filled)
    assert np.allclose(grid.origin, previous.origin)
    cells = diff.cell_diff(previous, grid, offset)
    assert cells.cells_added == 0 and cells.cells_removed == 0


def test_grown_version_keeps_the_lattice_and_shifts_indices():
    """Grown below and to -x: the grid grows by whole cells, indices shift by the
    offset, the old cells are still filled and only the new ones are added."""
    old = _box([0, 0, 0], [16, 16, 6.4])
    previous = voxelize.legofy(old)
    assert previous.shape == (2, 2, 2)
    new = _box([-8, 0, -3.2], [16, 16, 6.4])
    grid, offset = diff.legofy_on(previous, new, closed=True)
    assert np.array_equal(offset, [-1, 0, -1]) and grid.shape == (3, 2, 3)
    assert np.allclose(grid.origin, previous.origin + offset * previous.cell)
    cells = diff.cell_diff(previous, grid, offset)
    assert cells.cells_removed == 0 and cells.cells_added == 18 - 8
    assert not cells.added[1:, :, 1:].any()


def test_shrunk_version_reports_removed_cells_outside_the_new_grid():
    previous = voxelize.legofy(_box([0, 0, 0], [32, 8, 3.2]))
    grid, offset = diff.legofy_on(previous, _box([16, 0, 0], [32, 8, 3.2]), closed=True)
    assert np.array_equal(offset, [2, 0, 0]) and grid.shape == (2, 1, 1)
    cells = diff.cell_diff(previous, grid, offset)
    assert cells.cells_added == 0 and cells.cells_removed == 2
    assert sorted(map(tuple, cells.removed.tolist())) == [(-2, 0, 0), (-1, 0, 0)]


def test_float32_noise_at_a_cell_boundary_is_snapped():
    """A face 2e-5 mm below the grid's bottom (an STL's float32 after a rotation)
    would fill a whole layer below; snapped to the lattice it does not."""
    previous = voxelize.legofy(_box([0, 0, 0], [16, 16, 6.4]))
    noisy = _box([0, 0, -2e-5], [16, 16, 6.4])
    raw = voxelize.legofy(noisy, cell=previous.cell, origin=previous.origin - [0, 0, 3.2],
                          shape=(2, 2, 3))
    assert raw.filled[:, :, 0].all()
    grid, offset = diff.legofy_on(previous, noisy, closed=True)
    assert np.array_equal(offset, [0, 0, 0]) and np.array_equal(grid.filled, previous.filled)
    far = _box([0, 0, -0.01], [16, 16, 6.4])
    grid, offset = diff.legofy_on(previous, far, closed=True)
    assert offset[2] == -1 and grid.shape[2] == 3


def test_shift_into_moves_and_clips():
    a = np.zeros((3, 3, 3), bool)
    a[0, 0, 0] = a[2, 2, 2] = True
    assert np.argwhere(diff.shift_into(a, (1, 0, 1), (3, 3, 3))).tolist() == [[1, 0, 1]]
    assert np.argwhere(diff.shift_into(a, (-1, -1, -1), (3, 3, 3))).tolist() == [[1, 1, 1]]
    assert np.argwhere(diff.shift_into(a, (0, 0, 0), (2, 2, 2))).tolist() == [[0, 0, 0]]
    assert not diff.shift_into(a, (5, 0, 0), (3, 3, 3)).any()


def test_no_cell_filled_is_refused():
    previous = voxelize.legofy(_box([0, 0, 0], [8, 8, 3.2]))
    flat = trimesh.Trimesh([[0, 0, 0], [8, 0, 0], [0, 8, 0]], [[0, 1, 2]])
    with pytest.raises(InputError):
        diff.legofy_on(previous, flat, closed=False)


def test_changed_boxes_of_meshes_find_only_the_edit():
    a = _box([0, 0, 0], [40, 40, 10])
    bump = _box([30, 30, 10], [36, 36, 14])
    b = trimesh.util.concatenate([a, bump])
    assert len(diff.changed_boxes(a, a.copy())) == 0
    boxes = diff.changed_boxes(a, b)
    assert len(boxes) > 0
    assert diff.boxes_meet(boxes, np.array([[[29, 29, 9], [37, 37, 15]]]))
    assert not diff.boxes_meet(boxes, np.array([[[0, 0, 0], [20, 20, 10]]]))


def test_changed_boxes_of_breps_compare_faces():
    """The top and bottom faces change (they get a hole) but only around the hole."""
    plain = cq.Workplane("XY").box(40, 40, 10, centered=False).val()
    holed = (cq.Workplane("XY").box(40, 40, 10, centered=False)
             .cut(cq.Workplane("XY").center(10, 10).circle(2).extrude(10)).val())
    assert holed.Volume() < plain.Volume() - 100
    assert len(diff.changed_boxes(None, None, plain.wrapped, plain.copy().wrapped)) == 0
    boxes = diff.changed_boxes(None, None, plain.wrapped, holed.wrapped)
    hole_region = np.array([[[7.5, 7.5, 0], [12.5, 12.5, 10]]])
    assert diff.boxes_meet(boxes, hole_region)
    far_on_the_same_faces = np.array([[[20, 20, -1], [40, 40, 11]]])
    assert not diff.boxes_meet(boxes, far_on_the_same_faces)


def test_symmetric_difference_volume_is_exact():
    a = _box([0, 0, 0], [10, 10, 10])
    b = _box([5, 0, 0], [15, 10, 10])
    assert np.isclose(diff.symmetric_difference_volume(a, b), 1000.0)
    assert diff.symmetric_difference_volume(a, a.copy()) < 1e-9
    open_a = a.copy()
    open_a.update_faces(np.arange(len(open_a.faces)) > 0)
    assert abs(diff.symmetric_difference_volume(open_a, b) - 1000.0) < 60.0


def test_reprint_threshold():
    assert diff.reprint_threshold(10.0) == diff.REPRINT_MIN_MM3
    assert np.isclose(diff.reprint_threshold(1e5), 1e5 * diff.REPRINT_FRACTION)


def test_cell_diff_against_hand_made_grids():
    prev = Grid(origin=np.zeros(3), cell=np.array([8.0, 8.0, 3.2]), filled=np.ones((2, 2, 1), bool))
    filled = np.zeros((2, 2, 2), bool)
    filled[:, :, 0] = True
    filled[0, 0, 0] = False
    filled[1, 1, 1] = True
    grid = Grid(origin=np.zeros(3), cell=prev.cell, filled=filled)
    cells = diff.cell_diff(prev, grid, np.zeros(3, int))
    assert cells.cells_added == 1 and cells.added[1, 1, 1]
    assert cells.removed.tolist() == [[0, 0, 0]]
