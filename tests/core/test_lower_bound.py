"""Tests of core.layout.bounds: known minimum covers, a brute-force check, validity."""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import pytest

from core.catalog import BY_NUMBER, CATALOG, select
from core.errors import InputError
from core.layout import bounds as lower_bound
from core.layout.bounds import brick_lower_bound, certified_bound, part_shapes
from core.model import CELL_MM, Grid


def grid_of(filled) -> Grid:
    return Grid(origin=np.zeros(3), cell=np.array(CELL_MM), filled=np.asarray(filled, dtype=bool))


def solid(nx, ny, nz) -> Grid:
    return grid_of(np.ones((nx, ny, nz), dtype=bool))


def brute_force_minimum(filled: np.ndarray, parts=CATALOG) -> int:
    """Fewest parts of an exact cover by exhaustive search (tiny grids only).

    The lexicographically first uncovered cell must be the min corner of the
    box that covers it, so only boxes anchored there are tried.
    """
    shape = filled.shape
    boxes = part_shapes(parts)

    @lru_cache(maxsize=None)
    def best(left: bytes) -> float:
        todo = np.frombuffer(left, dtype=bool).reshape(shape)
        if not todo.any():
            return 0
        i, j, k = np.argwhere(todo)[0]
        result = np.inf
        for sx, sy, sz in boxes:
            box = todo[i:i + sx, j:j + sy, k:k + sz]
            if box.shape == (sx, sy, sz) and box.all():
                rest = todo.copy()
                rest[i:i + sx, j:j + sy, k:k + sz] = False
                result = min(result, 1 + best(rest.tobytes()))
        return result

    return best(np.ascontiguousarray(filled, dtype=bool).tobytes())


@pytest.mark.parametrize("filled, expected", [
    (np.ones((2, 4, 3)), 1),            # one 2x4 brick
    (np.ones((4, 2, 3)), 1),            # the same turned by 90 degrees
    (np.ones((2, 4, 6)), 2),            # two stacked 2x4 bricks
    (np.ones((1, 5, 1)), 2),            # 1x4 + 1x1 or 1x3 + 1x2 plates
    (np.ones((3, 3, 1)), 2),            # 2x3 + 1x3 plates
    (np.ones((1, 1, 1)), 1),
    (np.ones((2, 8, 3)), 1),            # the largest part
    (np.ones((2, 8, 4)), 2),            # 2x8 brick + 2x8 plate
    (np.ones((2, 2, 2)), 2),            # two 2x2 plates (no 2-layer part)
])
def test_known_minimum(filled, expected):
    out = brick_lower_bound(grid_of(filled))
    assert out["bound"] == expected
    assert out["objective"] == expected
    assert out["optimal"] and out["status"] == "optimal"


def test_l_of_plates():
    filled = np.zeros((4, 4, 1), dtype=bool)
    filled[0, :, 0] = True
    filled[:, 0, 0] = True              # 7 cells: a 1x4 and a 1x3 plate
    assert brick_lower_bound(grid_of(filled))["bound"] == 2


def test_regions_add_up_and_diagonal_contact_separates():
    filled = np.zeros((5, 8, 3), dtype=bool)
    filled[0:2, 0:4, :] = True          # a 2x4 brick
    filled[2:4, 4:8, :] = True          # another, touching the first along an edge only
    filled[4, 0, 0] = True              # a lone 1x1 plate
    out = brick_lower_bound(grid_of(filled))
    assert out["bound"] == 3 and out["optimal"]


def test_variable_count():
    # A 1x5 row of plates: 5 + 4 + 3 + 2 placements of 1x1, 1x2, 1x3, 1x4.
    assert brick_lower_bound(grid_of(np.ones((1, 5, 1))))["variables"] == 14


def test_restricted_catalog():
    assert brick_lower_bound(solid(2, 4, 3), select("plates"))["bound"] == 3
    assert brick_lower_bound(solid(2, 4, 3), select("3024"))["bound"] == 24


def test_no_cover_without_the_1x1_plate():
    parts = (BY_NUMBER["3023"],)       # 1x2 plates only
    out = brick_lower_bound(solid(1, 3, 1), parts)
    assert out["bound"] is None and out["status"] == "infeasible"
    assert brick_lower_bound(solid(1, 4, 1), parts)["bound"] == 2


def test_empty_grid_needs_nothing():
    out = brick_lower_bound(grid_of(np.zeros((3, 3, 3))))
    assert out["bound"] == 0 and out["optimal"]


def test_bad_arguments():
    with pytest.raises(InputError):
        brick_lower_bound(solid(1, 1, 1), ())
    with pytest.raises(ValueError):
        brick_lower_bound(solid(1, 1, 1), time_limit_s=0)


def test_too_large(monkeypatch):
    monkeypatch.setattr(lower_bound, "MAX_VARIABLES", 100)
    out = brick_lower_bound(solid(4, 4, 3))
    assert out["bound"] is None and out["status"] == "too large"
    assert out["variables"] > 100


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(12))
def test_matches_brute_force_on_tiny_grids(seed):
    rng = np.random.default_rng(seed)
    shape = tuple(rng.integers(2, 5, size=2)) + (int(rng.integers(1, 5)),)
    filled = rng.random(shape) < 0.75
    out = brick_lower_bound(grid_of(filled))
    assert out["optimal"]
    assert out["bound"] == out["objective"] == brute_force_minimum(filled)


def test_matches_brute_force_with_plates_only():
    rng = np.random.default_rng(99)
    filled = rng.random((4, 4, 2)) < 0.8
    parts = select("plates")
    assert brick_lower_bound(grid_of(filled), parts)["bound"] == brute_force_minimum(filled, parts)


def box_shell(nx, ny, nz) -> np.ndarray:
    filled = np.ones((nx, ny, nz), dtype=bool)
    filled[1:-1, 1:-1, 1:-1] = False
    return filled


def test_time_limited_bound_is_valid():
    filled = box_shell(10, 8, 7)
    exact = brick_lower_bound(grid_of(filled), time_limit_s=30)
    assert exact["optimal"]
    rushed = brick_lower_bound(grid_of(filled), time_limit_s=0.02)
    trivial = -(-int(filled.sum()) // max(p.cells for p in CATALOG))
    assert trivial <= rushed["bound"] <= exact["bound"]
    if rushed["objective"] is not None:
        assert rushed["objective"] >= exact["bound"]


def test_certified_bound_from_any_prices():
    filled = np.ones((3, 3, 1), dtype=bool)
    table = lower_bound._summed_volume(filled)
    shapes = part_shapes(CATALOG)
    found = [lower_bound.fitting_positions(table, s) for s in shapes]
    labels = filled.astype(np.int32)
    _, indptr, rows, _ = lower_bound._columns(filled, labels, shapes, found)
    assert certified_bound(indptr, rows, np.zeros(9)) == 0
    assert certified_bound(indptr, rows, np.full(9, 1 / 6)) == pytest.approx(1.5)
    # Prices far too high are penalised, never give more than the optimum.
    assert certified_bound(indptr, rows, np.ones(9)) <= 2
    assert certified_bound(indptr, rows, np.random.default_rng(0).random(9)) <= 2


def test_fitting_positions():
    filled = np.zeros((3, 4, 3), dtype=bool)
    filled[0:2, 0:4, 0:3] = True
    table = lower_bound._summed_volume(filled)
    assert lower_bound.fitting_positions(table, (2, 4, 3)).tolist() == [[0, 0, 0]]
    assert len(lower_bound.fitting_positions(table, (1, 2, 1))) == 2 * 3 * 3
    assert len(lower_bound.fitting_positions(table, (4, 2, 3))) == 0
