"""Alignment of a new version with the previous one: planar sides, transform, overlap."""

from __future__ import annotations

from pathlib import Path

import cadquery as cq
import manifold3d as m3
import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from core import align, diff, voxelize
from core.io import meshes as mesh_io
from core.printing import export

MODELS = Path(__file__).resolve().parents[2].parent / "shared" / "models"


def _model(name: str) -> Path:
    path = MODELS / name
    if not path.exists():
        pytest.skip(f"{path} not found: the shared test models are not next to the repository")
    return path


def _motion(seed: int) -> np.ndarray:
    """A rigid motion: rotation by an arbitrary angle (not a multiple of 90°) about a
    random axis, and a translation of tens of mm."""
    rng = np.random.default_rng(seed)
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    angle = rng.uniform(10.0, 170.0)
    assert min(angle % 90.0, 90.0 - angle % 90.0) > 1.0
    out = np.eye(4)
    out[:3, :3] = Rotation.from_rotvec(np.radians(angle) * axis).as_matrix()
    out[:3, 3] = rng.uniform(-80.0, 80.0, 3)
    return out


def _recovery_error(found: np.ndarray, motion: np.ndarray, points: np.ndarray) -> float:
    """Largest distance (mm) between the points and the points moved and moved back."""
    moved = points @ motion[:3, :3].T + motion[:3, 3]
    back = moved @ found[:3, :3].T + found[:3, 3]
    return float(np.linalg.norm(back - points, axis=1).max())


@pytest.fixture(scope="module")
def openbot_stl():
    return mesh_io.load_model(_model("openbot_body_bottom.stl"))


def test_planar_sides_of_a_box_mesh_and_brep():
    mesh = trimesh.creation.box(extents=[30, 20, 10])
    sides = align.mesh_sides(mesh)
    assert sides.planes == 6 and len(sides.directions) == 6
    assert sorted(np.round(sides.area).tolist()) == [200, 200, 300, 300, 600, 600]
    assert sorted(np.round(np.abs(sides.offset), 9).tolist()) == [5, 5, 10, 10, 15, 15]
    top = np.flatnonzero(np.isclose(sides.normal[:, 2], 1.0))
    assert len(top) == 1 and np.isclose(sides.offset[top[0]], 5.0)
    solid = cq.Workplane("XY").box(30, 20, 10).val().wrapped
    bsides = align.brep_sides(solid)
    assert bsides.planes == 6 and bsides.source == "brep"
    assert np.isclose(bsides.surface_area, 2 * (600 + 300 + 200))
    assert np.allclose(np.sort(bsides.area), np.sort(sides.area))


def test_coplanar_patches_apart_are_one_plane():
    """Two boxes standing on one plane: their bottoms are one side, their
    tops (different heights) two."""
    a = trimesh.creation.box(bounds=[[0, 0, 0], [10, 10, 10]])
    b = trimesh.creation.box(bounds=[[20, 0, 0], [30, 10, 5]])
    sides = align.mesh_sides(trimesh.util.concatenate([a, b]))
    down = np.flatnonzero(np.isclose(sides.normal[:, 2], -1.0))
    up = np.flatnonzero(np.isclose(sides.normal[:, 2], 1.0))
    assert len(down) == 1 and np.isclose(sides.area[down[0]], 200.0)
    assert len(up) == 2


@pytest.mark.slow
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_openbot_mesh_moved_by_arbitrary_rotation_is_recovered(openbot_stl, seed):
    mesh = openbot_stl.mesh
    motion = _motion(seed)
    result = align.align(align.transform_mesh(mesh, motion), mesh, new_closed=True, old_closed=True)
    assert result.confident and result.method == "planar sides"
    edge = float(np.median(mesh.edges_unique_length))
    error = _recovery_error(result.transform, motion, np.asarray(mesh.vertices))
    assert error < min(edge, 1e-3)
    assert result.overlap > 0.999 and result.residual_mm < 1e-3
    assert np.isclose(np.linalg.det(result.transform[:3, :3]), 1.0)


@pytest.mark.slow
def test_openbot_stl_file_rotated_keeps_every_cell(openbot_stl, tmp_path):
    """Through a real STL file (float32 coordinates): recovered within one triangle
    size and, on the previous grid, not one cell differs."""
    mesh = openbot_stl.mesh
    motion = _motion(7)
    path = tmp_path / "moved.stl"
    align.transform_mesh(mesh, motion).export(path)
    new = mesh_io.load_model(path)
    result = align.align(new.mesh, mesh, new_closed=new.watertight, old_closed=True)
    assert result.confident
    assert _recovery_error(result.transform, motion, np.asarray(mesh.vertices)) < float(
        np.median(mesh.edges_unique_length))
    previous = voxelize.legofy(mesh, closed=True)
    grid, offset = diff.legofy_on(previous, align.transform_mesh(new.mesh, result.transform),
                                  closed=new.watertight)
    cells = diff.cell_diff(previous, grid, offset)
    assert cells.cells_added == 0 and cells.cells_removed == 0


@pytest.mark.slow
def test_openbot_step_rotated_is_recovered_from_brep_faces(tmp_path):
    old = mesh_io.load_model(_model("openbot_body_bottom.step"))
    motion = _motion(11)
    path = tmp_path / "moved.step"
    export.write_step(align.transform_brep(old.brep, motion), path)
    new = mesh_io.load_model(path)
    result = align.align(new.mesh, old.mesh, new.brep, old.brep, new.watertight, old.watertight)
    assert result.confident and "brep" in result.message
    assert _recovery_error(result.transform, motion, np.asarray(old.mesh.vertices)) < 0.1
    assert _recovery_error(result.transform, motion, np.asarray(old.mesh.vertices)) < 1e-6
    previous = voxelize.legofy(old.mesh, closed=old.watertight)
    moved = align.transform_model(new, result.transform)
    grid, offset = diff.legofy_on(previous, moved.mesh, closed=moved.watertight)
    cells = diff.cell_diff(previous, grid, offset)
    assert cells.cells_added == 0 and cells.cells_removed == 0


@pytest.mark.slow
def test_edited_and_moved_part_still_aligns(openbot_stl):
    """A boss added changes some sides; the rest still fixes the transform."""
    mesh = openbot_stl.mesh
    cyl = trimesh.creation.cylinder(radius=5, height=14, sections=48)
    cyl.apply_translation([20, 10, 9])
    union = (_manifold(mesh) + _manifold(cyl)).to_mesh64()
    edited = trimesh.Trimesh(np.asarray(union.vert_properties)[:, :3], np.asarray(union.tri_verts))
    motion = _motion(5)
    result = align.align(align.transform_mesh(edited, motion), mesh, new_closed=True, old_closed=True)
    assert result.confident and result.overlap < 1.0
    assert _recovery_error(result.transform, motion, np.asarray(mesh.vertices)) < 1e-3


@pytest.mark.slow
def test_unmoved_version_is_the_identity(openbot_stl):
    result = align.align(openbot_stl.mesh, openbot_stl.mesh, new_closed=True, old_closed=True)
    assert result.is_identity and result.method == "identity" and result.confident


def test_unrelated_shape_is_placed_as_is():
    old = trimesh.creation.box(extents=[40, 30, 20])
    new = trimesh.creation.icosphere(subdivisions=3, radius=3.0)
    new.apply_translation([200, 0, 0])
    result = align.align(new, old, new_closed=True, old_closed=True)
    assert not result.confident and result.is_identity
    assert result.method == "placed as is" and "no confident match" in result.message


def test_rotation_hypotheses_contain_the_true_rotation():
    mesh = trimesh.creation.box(extents=[30, 20, 10])
    extra = trimesh.creation.box(extents=[8, 8, 8])
    extra.apply_translation([11, 6, 9])
    part = trimesh.util.concatenate([mesh, extra])
    motion = _motion(3)
    old, new = align.mesh_sides(part), align.mesh_sides(align.transform_mesh(part, motion))
    truth = motion[:3, :3].T
    angles = [np.degrees(np.arccos(np.clip((np.trace(r.T @ truth) - 1) / 2, -1, 1)))
              for r, _ in align.rotation_hypotheses(new, old)]
    assert min(angles) < 1e-6


def test_transform_of_mesh_and_brep_agree():
    solid = cq.Workplane("XY").box(30, 20, 10).faces(">Z").hole(6).val()
    motion = _motion(9)
    brep = align.transform_brep(solid.wrapped, motion)
    mesh = trimesh.Trimesh(*[np.asarray(a) for a in _tess(solid)])
    moved = align.transform_mesh(mesh, motion)
    vol = cq.Shape.cast(brep).Volume()
    assert np.isclose(moved.volume, mesh.volume) and np.isclose(vol, solid.Volume())
    centre = cq.Shape.cast(brep).Center()
    expected = motion[:3, :3] @ np.array(solid.Center().toTuple()) + motion[:3, 3]
    assert np.allclose([centre.x, centre.y, centre.z], expected, atol=1e-9)


def _tess(solid):
    vertices, triangles = solid.tessellate(0.05)
    return [[v.toTuple() for v in vertices], triangles]


def _manifold(mesh: trimesh.Trimesh) -> m3.Manifold:
    return m3.Manifold(m3.Mesh64(vert_properties=np.ascontiguousarray(mesh.vertices, np.float64),
                                 tri_verts=np.ascontiguousarray(mesh.faces, np.uint64)))
