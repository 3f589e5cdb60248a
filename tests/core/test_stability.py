"""Stability: the brick graph, its components, weak points and why regions fall apart."""

from __future__ import annotations

import networkx as nx
import numpy as np
import pytest

from core.connectivity import articulation_points, regions
from core.layout.greedy import lay_out
from core.model import CELL_MM, Brick, Grid, Layout
from core.stability import analyse, brick_graph


def layout_of(shape, bricks) -> Layout:
    """A layout of ``bricks`` given as (part, size, cell); the grid is filled exactly where they are."""
    filled = np.zeros(shape, dtype=bool)
    out = []
    for n, (part, size, cell) in enumerate(bricks):
        b = Brick(id=n, part=part, size=size, cell=cell)
        assert not filled[b.slices()].any()
        filled[b.slices()] = True
        out.append(b)
    return Layout(Grid(np.zeros(3), np.array(CELL_MM), filled), out)


def edges(layout):
    g = brick_graph(layout)
    rows, cols = g.nonzero()
    return {(int(a), int(b)) for a, b in zip(rows, cols) if a < b}


def test_plates_stacked_with_overlap_connect():
    lay = layout_of((4, 2, 2), [("3023", (2, 1, 1), (0, 0, 0)), ("3023", (2, 1, 1), (1, 0, 1))])
    assert edges(lay) == {(0, 1)}
    g = brick_graph(lay)
    assert (g != g.T).nnz == 0
    assert set(g.data) == {1}


def test_plates_side_by_side_do_not_connect():
    lay = layout_of((4, 1, 1), [("3023", (2, 1, 1), (0, 0, 0)), ("3023", (2, 1, 1), (2, 0, 0))])
    assert edges(lay) == set()
    stab = analyse(lay)
    assert stab.regions == 1 and stab.components == 2


def test_bricks_of_one_printed_part_are_one_rigid_piece():
    lay = layout_of((4, 1, 1), [("3023", (2, 1, 1), (0, 0, 0)), ("3023", (2, 1, 1), (2, 0, 0))])
    for b in lay.bricks:
        b.kind, b.printed_part = "printed", "P1"
    assert edges(lay) == {(0, 1)}
    assert analyse(lay).components == 1


def test_plates_touching_only_at_an_edge_do_not_connect():
    lay = layout_of((2, 1, 2), [("3024", (1, 1, 1), (0, 0, 0)), ("3024", (1, 1, 1), (1, 0, 1))])
    assert edges(lay) == set()
    assert analyse(lay).regions == 2


def test_brick_on_two_plates_bridges_them():
    lay = layout_of((4, 2, 4), [("3020", (2, 2, 1), (0, 0, 0)), ("3020", (2, 2, 1), (2, 0, 0)),
                                ("3001", (4, 2, 3), (0, 0, 1))])
    assert edges(lay) == {(0, 2), (1, 2)}
    stab = analyse(lay)
    assert stab.components == 1 and stab.regions == 1
    assert stab.weak_points == [2]
    assert stab.unconnectable == []


def test_chain_has_its_inner_bricks_as_weak_points():
    lay = layout_of((1, 1, 4), [("3024", (1, 1, 1), (0, 0, k)) for k in range(4)])
    stab = analyse(lay)
    assert stab.weak_points == [1, 2]
    assert stab.components == 1


def test_two_bricks_alone_have_no_weak_point():
    lay = layout_of((1, 1, 2), [("3024", (1, 1, 1), (0, 0, 0)), ("3024", (1, 1, 1), (0, 0, 1))])
    assert analyse(lay).weak_points == []


def test_crossed_plates_have_no_weak_points():
    bricks = [("3710", (1, 4, 1), (0, 0, 0)), ("3710", (1, 4, 1), (1, 0, 0)),
              ("3022", (2, 2, 1), (0, 0, 1)), ("3022", (2, 2, 1), (0, 2, 1))]
    lay = layout_of((2, 4, 2), bricks)
    assert edges(lay) == {(0, 2), (0, 3), (1, 2), (1, 3)}
    stab = analyse(lay)
    assert stab.components == 1
    assert stab.weak_points == []


def test_articulation_points_agree_with_networkx():
    rng = np.random.default_rng(0)
    for _ in range(20):
        g = nx.gnm_random_graph(30, int(rng.integers(20, 60)), seed=int(rng.integers(1 << 30)))
        a = nx.to_scipy_sparse_array(g, format="csr")
        art = articulation_points(a.indptr.astype(np.int64), a.indices.astype(np.int64), 30)
        assert set(np.flatnonzero(art)) == set(nx.articulation_points(g))


def test_single_wide_plate_layer_cannot_be_joined():
    lay = layout_of((12, 2, 1), [("3034", (8, 2, 1), (0, 0, 0)), ("3020", (4, 2, 1), (8, 0, 0))])
    stab = analyse(lay)
    assert stab.regions == 1 and stab.components == 2
    [entry] = stab.unconnectable
    assert entry["region"] == 1 and entry["components"] == 2 and entry["cells"] == 24
    assert "layer 1 " in entry["reason"] and "12 x 2" in entry["reason"]  # layers count from 1


def test_wide_sheet_beside_a_tower_cannot_be_joined():
    filled = np.zeros((13, 1, 6), dtype=bool)
    filled[0] = True
    filled[:, :, 5] = True
    lay = lay_out(Grid(np.zeros(3), np.array(CELL_MM), filled))
    stab = analyse(lay)
    assert stab.regions == 1 and stab.components >= 2
    [entry] = stab.unconnectable
    assert entry["cells"] == 18
    # the sheet is cell layer k = 5: the sixth layer, counted from 1 as everywhere a user reads
    assert "layer(s) 6" in entry["reason"] and "no part can span" in entry["reason"]


def test_seam_a_part_could_have_spanned_is_reported_as_such():
    lay = layout_of((4, 1, 2), [("3023", (2, 1, 1), (0, 0, 0)), ("3023", (2, 1, 1), (2, 0, 0)),
                                ("3023", (2, 1, 1), (0, 0, 1)), ("3023", (2, 1, 1), (2, 0, 1))])
    [entry] = analyse(lay).unconnectable
    assert "could span" in entry["reason"]


def test_regions_use_face_connectivity():
    filled = np.zeros((3, 3, 3), dtype=bool)
    filled[0, 0, 0] = filled[1, 1, 0] = filled[1, 1, 1] = filled[2, 2, 2] = True
    assert regions(filled)[1] == 3
    filled[1, 0, 0] = True
    assert regions(filled)[1] == 2


def test_empty_layout():
    stab = analyse(Layout(Grid(np.zeros(3), np.array(CELL_MM), np.zeros((2, 2, 2), bool)), []))
    assert (stab.regions, stab.components, stab.weak_points, stab.unconnectable) == (0, 0, [], [])


@pytest.mark.parametrize("shape", [(6, 6, 6), (12, 9, 10)])
def test_layout_of_a_block_analyses_as_one_piece(shape):
    stab = analyse(lay_out(Grid(np.zeros(3), np.array(CELL_MM), np.ones(shape, bool))))
    assert (stab.regions, stab.components) == (1, 1)


def test_leaf_supports_tell_single_leaves_from_substructures():
    """A brick holding one leaf brick is a weak point that only supports a leaf;
    a brick holding a stack of two is a weak point carrying a substructure."""
    filled = np.zeros((8, 1, 4), bool)
    bricks = [Brick(0, "3460", (8, 1, 1), (0, 0, 0)),       # base 1x8 plate
              Brick(1, "3024", (1, 1, 1), (0, 0, 1)),       # support A on the base
              Brick(2, "3024", (1, 1, 1), (0, 0, 2)),       # leaf on A
              Brick(3, "3024", (1, 1, 1), (7, 0, 1)),       # support B on the base
              Brick(4, "3024", (1, 1, 1), (7, 0, 2)),       # stack on B ...
              Brick(5, "3024", (1, 1, 1), (7, 0, 3))]       # ... of two bricks
    for b in bricks:
        filled[b.slices()] = True
    st = analyse(Layout(Grid(np.zeros(3), np.array(CELL_MM), filled), bricks))
    assert st.weak_points == [0, 1, 3, 4]
    assert st.leaf_supports == [1, 4]
