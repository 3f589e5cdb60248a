"""Legofy: filled cells are exactly the cells that share positive volume with the part."""

from __future__ import annotations

import itertools
from pathlib import Path

import manifold3d
import numpy as np
import pytest
import trimesh
from scipy import ndimage
from scipy.spatial.transform import Rotation

from core import voxelize
from core.model import CELL_MM

MODELS = Path(__file__).resolve().parents[2].parent / "shared" / "models"
CELL = np.array(CELL_MM)


def box(lo, hi) -> trimesh.Trimesh:
    """Closed axis-aligned box from corner ``lo`` to corner ``hi`` (mm)."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    mesh = trimesh.creation.box(extents=hi - lo)
    mesh.apply_translation((lo + hi) / 2)
    return mesh


def without_face(mesh: trimesh.Trimesh, normal) -> trimesh.Trimesh:
    """The mesh with every triangle whose normal is ``normal`` removed (an open mesh)."""
    keep = ~np.all(np.isclose(mesh.face_normals, normal), axis=1)
    return trimesh.Trimesh(mesh.vertices, mesh.faces[keep], process=False)


def brute_force(mesh: trimesh.Trimesh, origin, shape, cell=CELL, shrink: float = 0.0) -> np.ndarray:
    """Independent answer: Boolean intersection (manifold3d, double precision) of the
    closed mesh with every cell box shrunk by ``shrink`` mm on each side; a cell is
    filled when the intersection has positive volume."""
    solid = manifold3d.Manifold(manifold3d.Mesh64(
        vert_properties=np.asarray(mesh.vertices, np.float64),
        tri_verts=np.asarray(mesh.faces, np.uint64)))
    assert solid.status() == manifold3d.Error.NoError
    out = np.zeros(shape, dtype=bool)
    cube = manifold3d.Manifold.cube(tuple(np.asarray(cell) - 2 * shrink))
    for index in np.ndindex(*shape):
        lo = np.asarray(origin) + np.array(index) * cell + shrink
        out[index] = (solid ^ cube.translate(tuple(lo))).volume() > 0.0
    return out


def random_solid(seed: int) -> trimesh.Trimesh:
    """A randomly rotated and shifted closed solid: box, icosphere, torus or a box
    with a spherical pocket (non-convex), sized so that some cells are wholly inside."""
    rng = np.random.default_rng(seed)
    kind = seed % 4
    if kind == 0:
        mesh = trimesh.creation.box(extents=rng.uniform(24, 48, 3))
    elif kind == 1:
        mesh = trimesh.creation.icosphere(subdivisions=2, radius=rng.uniform(14, 24))
    elif kind == 2:
        mesh = trimesh.creation.torus(major_radius=rng.uniform(16, 22),
                                      minor_radius=rng.uniform(7, 9))
    else:
        block = manifold3d.Manifold.cube((36.0, 30.0, 24.0), center=True)
        pocket = manifold3d.Manifold.sphere(14.0, 48).translate((8.0, 0.0, 9.0))
        out = (block - pocket).to_mesh64()
        mesh = trimesh.Trimesh(np.asarray(out.vert_properties)[:, :3], np.asarray(out.tri_verts))
    transform = np.eye(4)
    transform[:3, :3] = Rotation.random(random_state=seed).as_matrix()
    transform[:3, 3] = rng.uniform(-20, 20, 3)
    mesh.apply_transform(transform)
    return mesh


def shifted_frame(mesh: trimesh.Trimesh, seed: int, cell=CELL):
    """A grid frame around the mesh with a random sub-cell shift and a spare layer."""
    origin, shape = voxelize.grid_frame(mesh.bounds, cell)
    shift = np.random.default_rng(seed + 1000).uniform(0, 1, 3) * cell
    return origin - shift, tuple(n + 1 for n in shape)


# --- grid_frame ---------------------------------------------------------------------

def test_frame_whole_cells_get_exactly_that_many():
    origin, shape = voxelize.grid_frame(np.array([[0, 0, 0], [16, 16, 6.4]]))
    assert shape == (2, 2, 2)
    np.testing.assert_allclose(origin, [0, 0, 0], atol=1e-12)
    _, shape = voxelize.grid_frame(np.array([[0, 0, 0], [16 + 5e-7, 24 - 5e-7, 3 * 3.2]]))
    assert shape == (2, 3, 3)
    _, shape = voxelize.grid_frame(np.array([[0, 0, 0], [16 + 1e-4, 8, 3.2 + 1e-4]]))
    assert shape == (3, 1, 2)


def test_frame_centres_xy_and_stands_on_zmin():
    origin, shape = voxelize.grid_frame(np.array([[1.0, 2.0, 3.0], [11.0, 2.0, 4.0]]))
    assert shape == (2, 1, 1)
    np.testing.assert_allclose(origin, [1.0 - 3.0, 2.0 - 4.0, 3.0])
    bounds = np.array([[-5.0, 0.0, -1.0], [5.0, 17.0, 9.0]])
    origin, shape = voxelize.grid_frame(bounds, cell=(2.0, 5.0, 4.0))
    assert shape == (5, 4, 3)
    np.testing.assert_allclose(origin, [-5.0, -1.5, -1.0])


@pytest.mark.parametrize("bounds", [np.array([[0, 0, np.nan], [1, 1, 1]]), np.zeros((3, 3)),
                                    np.array([[0, 0, 0], [1, -1, 1]])])
def test_frame_refuses_bad_bounds(bounds):
    with pytest.raises(ValueError):
        voxelize.grid_frame(bounds)


# --- hand-made answers --------------------------------------------------------------

@pytest.mark.parametrize("closed", [True, False])
def test_exact_box_fills_exactly_its_cells(closed):
    mesh = box([0, 0, 0], [16, 16, 6.4])
    grid = voxelize.legofy(mesh, closed=closed)
    assert grid.shape == (2, 2, 2) and grid.count == 8
    np.testing.assert_allclose(grid.origin, [0, 0, 0], atol=1e-12)
    np.testing.assert_array_equal(grid.cell, CELL)
    wide = voxelize.legofy(mesh, origin=[-8, -8, -3.2], shape=(4, 4, 4), closed=closed)
    expected = np.zeros((4, 4, 4), bool)
    expected[1:3, 1:3, 1:3] = True
    np.testing.assert_array_equal(wide.filled, expected)


@pytest.mark.parametrize("closed", [True, False])
def test_half_cell_offset_box(closed):
    grid = voxelize.legofy(box([4, 0, 0], [20, 8, 3.2]), origin=[0, 0, 0], shape=(4, 1, 1),
                           closed=closed)
    np.testing.assert_array_equal(grid.filled[:, 0, 0], [True, True, True, False])


@pytest.mark.parametrize("closed", [True, False])
def test_touching_a_cell_does_not_fill_it(closed):
    parts = trimesh.util.concatenate([box([0, 0, 0], [8, 8, 3.2]), box([8, 0, 3.2], [16, 8, 6.4])])
    grid = voxelize.legofy(parts, origin=[0, 0, 0], shape=(2, 1, 2), closed=closed)
    expected = np.zeros((2, 1, 2), bool)
    expected[0, 0, 0] = expected[1, 0, 1] = True
    np.testing.assert_array_equal(grid.filled, expected)


@pytest.mark.parametrize("top, fills", [(3 * 3.2, False), (9.6 + 5e-7, False), (9.6 + 1e-5, True)])
def test_penetration_tolerance_at_layer_boundary(top, fills):
    grid = voxelize.legofy(box([0, 0, 0], [8, 8, top]), origin=[0, 0, 0], shape=(1, 1, 5))
    np.testing.assert_array_equal(grid.filled[0, 0], [True, True, True, fills, False])


def test_thin_wall_fills_one_cell_thick():
    wall = box([11.75, 0, 0], [12.25, 16, 6.4])
    grid = voxelize.legofy(wall, origin=[0, 0, 0], shape=(3, 2, 2))
    expected = np.zeros((3, 2, 2), bool)
    expected[1] = True
    np.testing.assert_array_equal(grid.filled, expected)
    sheet = trimesh.Trimesh([[12, 0, 0], [12, 16, 0], [12, 16, 6.4], [12, 0, 6.4]],
                            [[0, 1, 2], [0, 2, 3]])
    grid = voxelize.legofy(sheet, origin=[0, 0, 0], shape=(3, 2, 2))
    np.testing.assert_array_equal(grid.filled, expected)


def test_model_outside_given_grid_is_ignored():
    grid = voxelize.legofy(box([0, 0, 0], [40, 8, 3.2]), origin=[8, 0, 0], shape=(2, 1, 1))
    assert grid.count == 2
    np.testing.assert_allclose(grid.origin, [8, 0, 0])
    inside = voxelize.legofy(box([-50, -50, -50], [50, 50, 50]), origin=[0, 0, 0], shape=(2, 2, 2))
    assert inside.count == 8


@pytest.mark.parametrize("closed", [True, False])
def test_orientation_and_overlap_use_nonzero_rule(closed):
    mesh = random_solid(4)
    origin, shape = shifted_frame(mesh, 4)
    flipped = trimesh.Trimesh(mesh.vertices, mesh.faces[:, ::-1], process=False)
    reference = voxelize.legofy(mesh, origin=origin, shape=shape, closed=closed).filled
    flipped_grid = voxelize.legofy(flipped, origin=origin, shape=shape, closed=closed)
    np.testing.assert_array_equal(flipped_grid.filled, reference)
    a, b = random_solid(8), random_solid(12)
    overlapping = trimesh.util.concatenate([a, b])
    union = trimesh.boolean.union([a, b], engine="manifold")
    assert union.volume < a.volume + b.volume - 1.0
    origin, shape = shifted_frame(overlapping, 8)
    np.testing.assert_array_equal(
        voxelize.legofy(overlapping, origin=origin, shape=shape, closed=closed).filled,
        voxelize.legofy(union, origin=origin, shape=shape, closed=True).filled)


# --- exactness against an independent brute force ----------------------------------

@pytest.mark.slow
@pytest.mark.parametrize("seed", range(24))
def test_matches_boolean_brute_force(seed):
    """Exactness: every cell the part penetrates by more than 1e-5 mm (Boolean with
    the cell shrunk by 1e-5 mm) is filled, and every filled cell shares positive volume
    with the part (Boolean with the exact cell).  Only cells penetrated by less than
    1e-5 mm, around the 1e-6 mm tolerance, may go either way; they must be rare.
    Half of the cases use an odd cell size instead of the LEGO plate."""
    mesh = random_solid(seed)
    cell = CELL if seed < 12 else np.array([5.0, 3.0, 2.2])
    origin, shape = shifted_frame(mesh, seed, cell)
    certain = brute_force(mesh, origin, shape, cell, shrink=1e-5)
    possible = brute_force(mesh, origin, shape, cell)
    assert np.count_nonzero(possible & ~certain) <= 1
    tri = (mesh.vertices - origin)[mesh.faces]
    surface = voxelize.surface_cells(tri, cell, shape)
    assert np.any(certain & ~surface), "no wholly inside cell: the inside test was not exercised"
    for closed in (True, False):
        filled = voxelize.legofy(mesh, cell, origin=origin, shape=shape, closed=closed).filled
        assert not np.any(certain & ~filled), "a cell sharing volume with the part is empty"
        assert not np.any(filled & ~possible), "a cell sharing no volume with the part is filled"


def test_rays_through_shared_vertices_and_edges_count_once():
    """Vertices placed exactly on the sample columns: every ray hits shared edges
    and vertices, which simulation of simplicity must count exactly once."""
    frac = np.array(voxelize.SAMPLE_FRACTION)
    lo = frac * CELL
    hi = lo + CELL * 4
    mesh = box(lo, hi).subdivide().subdivide()
    in_cells = mesh.vertices / CELL - frac
    assert np.allclose(in_cells, np.round(in_cells), atol=1e-12)
    assert mesh.is_watertight and mesh.is_winding_consistent
    shape = (6, 5, 6)
    below, above = voxelize._winding_along(np.ascontiguousarray(mesh.vertices[mesh.faces]), CELL,
                                           np.array(shape), 2)
    np.testing.assert_array_equal(below, above)
    assert set(np.unique(below)) == {0, 1}
    expected = brute_force(mesh, np.zeros(3), shape)
    for closed in (True, False):
        np.testing.assert_array_equal(
            voxelize.legofy(mesh, origin=np.zeros(3), shape=shape, closed=closed).filled, expected)


def _obb_cells_overlap(extents, rotation, centre, origin, shape, cell=CELL) -> np.ndarray:
    """Exact answer for a rotated box: cells whose box shares positive volume with it
    (no separating axis among the 15 of two boxes, with positive overlap)."""
    index = np.indices(shape).reshape(3, -1).T
    delta = origin + (index + 0.5) * cell - centre
    half_cell, half_box = cell / 2, np.asarray(extents) / 2
    axes = [np.eye(3)[i] for i in range(3)] + [rotation[:, i] for i in range(3)]
    axes += [np.cross(np.eye(3)[i], rotation[:, j]) for i in range(3) for j in range(3)]
    inside = np.ones(len(index), bool)
    for axis in axes:
        if np.linalg.norm(axis) < 1e-9:
            continue
        reach = np.abs(axis) @ half_cell + np.abs(rotation.T @ axis) @ half_box
        inside &= np.abs(delta @ axis) < reach - 1e-7
    return inside.reshape(shape)


@pytest.mark.parametrize("seed", range(3))
def test_huge_triangles_on_a_big_rotated_box(seed):
    extents = np.array([410.0, 250.0, 130.0])
    rotation = Rotation.random(random_state=seed).as_matrix()
    centre = np.array([3.0, -7.0, 11.0])
    mesh = trimesh.creation.box(extents=extents)
    mesh.apply_transform(np.vstack([np.c_[rotation, centre], [0, 0, 0, 1]]))
    assert len(mesh.faces) == 12
    origin, shape = voxelize.grid_frame(mesh.bounds)
    expected = _obb_cells_overlap(extents, rotation, centre, origin, shape)
    np.testing.assert_array_equal(voxelize.legofy(mesh).filled, expected)
    open_box = without_face(mesh, rotation[:, seed])
    open_grid = voxelize.legofy(open_box, origin=origin, shape=shape)
    np.testing.assert_array_equal(open_grid.filled, expected)


# --- open meshes ----------------------------------------------------------------------

@pytest.mark.parametrize("face", range(6))
def test_box_with_missing_face_equals_closed_box(face):
    normal = np.eye(3)[face // 2] * (1 if face % 2 else -1)
    closed = box([4, 3, 0.5], [44, 29, 20.5])
    opened = without_face(closed, normal)
    assert not opened.is_watertight
    origin, shape = voxelize.grid_frame(closed.bounds)
    expected = voxelize.legofy(closed, origin=origin, shape=shape).filled
    open_grid = voxelize.legofy(opened, origin=origin, shape=shape)
    np.testing.assert_array_equal(open_grid.filled, expected)
    mesh = random_solid(0)
    origin, shape = shifted_frame(mesh, 0)
    rotated_open = without_face(mesh, mesh.face_normals[0])
    assert len(rotated_open.faces) == 10
    np.testing.assert_array_equal(voxelize.legofy(rotated_open, origin=origin, shape=shape).filled,
                                  voxelize.legofy(mesh, origin=origin, shape=shape).filled)


def test_winding_number_through_boundary_cap_equals_direct_sum():
    mesh = without_face(box([0, 0, 0], [30, 20, 10]), [0, 0, 1])
    points = np.random.default_rng(3).uniform(-10, 40, (300, 3))
    tri = mesh.vertices[mesh.faces]
    below = np.array([voxelize._winding_along(
        np.ascontiguousarray(tri - (p - np.array(voxelize.SAMPLE_FRACTION))), np.ones(3),
        np.ones(3, dtype=np.int64), 2)[0][0, 0, 0] for p in points])
    cap, weight = voxelize.boundary_cap(mesh.vertices, mesh.faces)
    assert len(cap) == 4 and np.allclose(cap[:, 0], [15, 10, 10])
    via_cap = voxelize._winding_via_cap(points, below, tri, cap, weight)
    np.testing.assert_allclose(via_cap, voxelize.winding_numbers(points, tri), atol=1e-9)


def load_model(name: str, scale: float = 1.0) -> trimesh.Trimesh:
    """A shared test model, or skip when the shared models folder is absent."""
    path = MODELS / name
    if not path.exists():
        pytest.skip(f"shared test model {path} not found (needs ../shared/models next to the repo)")
    mesh = trimesh.load(path, force="mesh")
    mesh.apply_scale(scale)
    return mesh


@pytest.mark.slow
@pytest.mark.parametrize("name, scale", [("stanford_bunny_open.obj", 1000.0),
                                         ("utah_teapot_open.stl", 1.0)])
def test_open_models_fill_sensibly(name, scale):
    """Surface cells are filled; every cell crossed neither by the mesh nor by the
    caps of its holes agrees with the directly summed winding number of its sample
    point (checked on up to 300 of them); the solid has no enclosed voids."""
    mesh = load_model(name, scale)
    assert not mesh.is_watertight
    grid = voxelize.legofy(mesh)
    relative = mesh.vertices - grid.origin
    tri = relative[mesh.faces]
    cap, _ = voxelize.boundary_cap(relative, mesh.faces)
    surface = voxelize.surface_cells(tri, grid.cell, grid.shape)
    assert np.all(grid.filled[surface])
    surface |= voxelize.surface_cells(cap, grid.cell, grid.shape)
    assert np.any(grid.filled & ~surface)
    index = np.argwhere(~surface)
    pick = index[np.random.default_rng(0).choice(len(index), min(300, len(index)), replace=False)]
    gwn = voxelize.winding_numbers(voxelize.sample_points(pick, grid.cell), tri)
    np.testing.assert_array_equal(grid.filled[tuple(pick.T)], np.abs(gwn) >= 0.5)
    np.testing.assert_array_equal(ndimage.binary_fill_holes(grid.filled), grid.filled)


# --- bad input -----------------------------------------------------------------------

def test_bad_input_is_refused_with_one_line():
    good = box([0, 0, 0], [8, 8, 3.2])
    cases = [
        (trimesh.Trimesh(np.zeros((0, 3)), np.zeros((0, 3), int)), {}),
        (trimesh.Trimesh(np.where(np.arange(8)[:, None] == 0, np.nan, good.vertices), good.faces,
                         process=False), {}),
        (good, {"shape": (0, 1, 1), "origin": [0, 0, 0]}),
        (good, {"shape": (1.5, 1, 1), "origin": [0, 0, 0]}),
        (good, {"origin": [0, np.inf, 0]}),
        (good, {"cell": (8, 0, 3.2)}),
    ]
    for mesh, kwargs in cases:
        with pytest.raises(ValueError) as err:
            voxelize.legofy(mesh, **kwargs)
        assert "\n" not in str(err.value)


def test_all_corners_of_the_grid_are_reachable():
    """Cells in every corner of a grid fill, i.e. no off-by-one at the grid edges."""
    shape = (3, 4, 5)
    for corner in itertools.product(*[(0, n - 1) for n in shape]):
        lo = np.array(corner) * CELL + 0.25 * CELL
        grid = voxelize.legofy(box(lo, lo + 0.5 * CELL), origin=np.zeros(3), shape=shape)
        assert grid.count == 1 and grid.filled[corner]
