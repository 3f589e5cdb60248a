"""Layout: bricks of the allowed parts cover the filled cells exactly once, held together."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from core.catalog import BY_NUMBER, CATALOG, select
from core.errors import InputError
from core.layout import greedy as layout_stage
from core.layout.brick_cells import brick_group_candidates
from core.layout.greedy import lay_out
from core.model import CELL_MM, Grid
from core.stability import analyse

MODELS = Path(__file__).resolve().parents[2].parent / "shared" / "models"


def grid_of(filled) -> Grid:
    """A grid at the origin with the standard cell size."""
    return Grid(np.zeros(3), np.array(CELL_MM), np.asarray(filled, dtype=bool))


def assert_valid(layout, parts=CATALOG):
    """Every brick is an allowed part in a valid orientation; the bricks cover the filled cells once."""
    allowed = {p.number for p in parts}
    count = np.zeros(layout.grid.shape, dtype=int)
    for n, brick in enumerate(layout.bricks):
        assert brick.id == n
        assert brick.part in allowed
        part = BY_NUMBER[brick.part]
        assert brick.size[:2] in part.orientations()
        assert brick.size[2] == part.layers
        assert all(c >= 0 for c in brick.cell)
        assert all(c + s <= n_ for c, s, n_ in zip(brick.cell, brick.size, layout.grid.shape))
        count[brick.slices()] += 1
    np.testing.assert_array_equal(count, layout.grid.filled.astype(int))


NUMBERS = [p.number for p in CATALOG if p.number != "3024"]


@st.composite
def cases(draw):
    """A random small grid, a part set with the 1x1 plate, a seed."""
    shape = (draw(st.integers(1, 8)), draw(st.integers(1, 8)), draw(st.integers(1, 7)))
    filled = draw(arrays(np.bool_, shape))
    chosen = {"3024"} | draw(st.sets(st.sampled_from(NUMBERS)))
    parts = tuple(p for p in CATALOG if p.number in chosen)
    return filled, parts, draw(st.integers(0, 2**16))


@settings(max_examples=60, deadline=None)
@given(cases())
def test_random_grids_are_covered_exactly_once_by_allowed_parts(case):
    filled, parts, seed = case
    layout = lay_out(grid_of(filled), parts, seed=seed)
    assert_valid(layout, parts)


@settings(max_examples=15, deadline=None)
@given(cases())
def test_same_seed_same_layout(case):
    filled, parts, seed = case
    first = lay_out(grid_of(filled), parts, seed=seed)
    second = lay_out(grid_of(filled), parts, seed=seed)
    assert [b.to_json() for b in first.bricks] == [b.to_json() for b in second.bricks]


@settings(max_examples=15, deadline=None)
@given(cases())
def test_components_never_fewer_than_regions(case):
    filled, parts, seed = case
    stab = analyse(lay_out(grid_of(filled), parts, seed=seed))
    assert stab.components >= stab.regions
    assert len(stab.unconnectable) <= stab.components - stab.regions


def test_a_2x8x3_block_is_one_brick():
    layout = lay_out(grid_of(np.ones((2, 8, 3))))
    assert [(b.part, b.size) for b in layout.bricks] == [("3007", (2, 8, 3))]


def test_a_turned_2x4x3_block_is_one_2x4_brick():
    layout = lay_out(grid_of(np.ones((4, 2, 3))), select("plates,bricks"))
    assert [(b.part, b.size) for b in layout.bricks] == [("3001", (4, 2, 3))]


def test_bricks_where_three_layers_are_filled():
    layout = lay_out(grid_of(np.ones((4, 8, 6))))
    assert_valid(layout)
    assert all(b.size[2] == 3 for b in layout.bricks)
    assert len(layout.bricks) <= 8
    stab = analyse(layout)
    assert stab.components == 1 and stab.weak_points == []


def test_without_bricks_only_plates():
    layout = lay_out(grid_of(np.ones((5, 6, 7))), select("plates"))
    assert_valid(layout, select("plates"))
    assert all(b.size[2] == 1 for b in layout.bricks)


def test_only_1x1_plates():
    filled = np.random.default_rng(3).random((6, 5, 4)) < 0.5
    layout = lay_out(grid_of(filled), select("3024"))
    assert len(layout.bricks) == filled.sum()


@pytest.mark.parametrize("shape", [(6, 6, 6), (8, 8, 7), (10, 10, 9), (16, 16, 16)])
def test_solid_block_is_one_component_without_weak_points(shape):
    layout = lay_out(grid_of(np.ones(shape)))
    assert_valid(layout)
    stab = analyse(layout)
    assert stab.regions == 1
    assert stab.components == 1
    assert stab.weak_points == []
    assert len(layout.bricks) <= np.prod(shape) / 12


def test_two_regions_two_components():
    filled = np.zeros((10, 4, 6), dtype=bool)
    filled[:4] = True
    filled[6:] = True
    stab = analyse(lay_out(grid_of(filled)))
    assert stab.regions == 2 and stab.components == 2 and stab.unconnectable == []


def test_thin_floor_beside_wall_is_held_by_a_plate_reaching_into_the_wall():
    filled = np.zeros((8, 8, 9), dtype=bool)
    filled[:, :, 0] = True
    filled[:2] = True
    layout = lay_out(grid_of(filled))
    assert_valid(layout)
    stab = analyse(layout)
    assert stab.components == 1


def test_staircase_of_short_runs_is_connected():
    filled = np.zeros((6, 4, 14), dtype=bool)
    for i in range(6):
        filled[i, :, 2 * i:2 * i + 3] = True
    stab = analyse(lay_out(grid_of(filled)))
    assert stab.regions == 1 and stab.components == 1


def test_brick_cells_are_three_filled_layers_of_one_column():
    filled = np.random.default_rng(7).random((9, 9, 10)) < 0.8
    for base in brick_group_candidates(filled):
        assert ((base == -2) == ~filled).all()
        i, j, k = np.nonzero(base >= 0)
        k0 = base[i, j, k]
        assert ((k - k0 >= 0) & (k - k0 < 3)).all()
        for dk in range(3):
            assert (base[i, j, k0 + dk] == k0).all()


def test_empty_grid_gives_empty_layout():
    assert lay_out(grid_of(np.zeros((3, 3, 3)))).bricks == []


def test_part_set_without_1x1_plate_is_refused():
    with pytest.raises(InputError, match="3024"):
        lay_out(grid_of(np.ones((2, 2, 2))), tuple(p for p in CATALOG if p.number != "3024"))


def test_non_boolean_grid_is_refused():
    with pytest.raises(TypeError, match="boolean"):
        lay_out(Grid(np.zeros(3), np.array(CELL_MM), np.ones((2, 2), dtype=float)))


def test_progress_is_reported_between_0_and_1():
    seen = []
    lay_out(grid_of(np.ones((6, 6, 6))), progress=lambda f, m: seen.append((f, m)))
    assert seen and seen[-1][0] == 1.0
    assert all(0.0 <= f <= 1.0 and isinstance(m, str) for f, m in seen)
    assert [f for f, _ in seen] == sorted(f for f, _ in seen)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["relativty_hmd_body.stl", "phone_charger_stand.stl"])
def test_real_model_is_held_together(name):
    if not (MODELS / name).exists():
        pytest.skip(f"test models not found at {MODELS}")
    from core import voxelize
    from core.io import meshes as mesh_io
    model = mesh_io.load_model(MODELS / name)
    grid = voxelize.legofy(model.mesh, closed=model.watertight)
    layout = lay_out(grid)
    assert_valid(layout)
    stab = analyse(layout)
    assert stab.components == stab.regions
    assert len(layout.bricks) < grid.count / 5


def test_relaxed_brick_groups_take_each_part_in_its_own_phase():
    """Two 2x4 towers apart, one on layers 0-2 and one on layers 1-3: the exact cover's
    relaxation (one 2x4 brick each, 2 parts) gives each its own brick group, which no global
    phase does; the relaxed layout is then those two bricks."""
    filled = np.zeros((5, 4, 4), bool)
    filled[0:2, :, 0:3] = True
    filled[3:5, :, 1:4] = True
    groups = layout_stage.relaxed_brick_groups(filled, CATALOG)
    assert (groups[0:2, :, 0:3] == 0).all() and (groups[3:5, :, 1:4] == 1).all()
    assert (groups[~filled] == -2).all()
    lay = lay_out(grid_of(filled), CATALOG, relaxed=True)
    assert_valid(lay)
    assert sorted((b.part, b.cell) for b in lay.bricks) == [("3001", (0, 0, 0)),
                                                           ("3001", (3, 0, 1))]


def test_relaxed_layout_of_a_block_with_a_plate_on_top():
    """A 2x8 block four plates high: the fewest parts are a 2x8 brick and a 2x8 plate; the
    relaxed layout has two parts, one of them a brick, and covers the block once."""
    filled = np.ones((2, 8, 4), bool)
    lay = lay_out(grid_of(filled), CATALOG, relaxed=True)
    assert_valid(lay)
    assert sorted(b.part for b in lay.bricks) == ["3007", "3034"]
    assert layout_stage.relaxable(grid_of(filled), CATALOG)
