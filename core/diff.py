"""Diff of two design iterations: cells, changed surface, printed geometry.

After :mod:`core.align` has placed the new version in the previous frame:

* :func:`legofy_on` legofies it on the previous grid's lattice (same origin
  modulo whole cells, same cell size), grown or shrunk to the new version's
  bounding box, so a cell means the same place in both versions;
  ``offset`` converts indices (previous index = new index + offset).
* :func:`cell_diff` compares the 1x1 plate cells: added and removed.
* :func:`changed_boxes` finds where the *surface* changed, also inside
  cells that stay filled (a widened hole): triangles (meshes) or faces
  (B-reps) of one version that the other version does not have at the same
  place, narrowed down to the points on them that are off the other
  version's surface, as boxes.  A region no box touches has identical
  geometry.
* :func:`symmetric_difference_volume` measures how much a printed part
  changed: the volume of old XOR new (manifold3d, exact on the meshes); a
  part is reprinted when that exceeds :func:`reprint_threshold`.
"""

from __future__ import annotations

from dataclasses import dataclass

import manifold3d as m3
import numpy as np
import trimesh
from scipy.spatial import cKDTree

from core import voxelize
from core.errors import InputError
from core.model import Grid

#: Extents within this (mm) of a whole number of cells get exactly that many.
WHOLE_CELL_TOL_MM = 1e-6
#: Triangles / faces whose corners (centroid, area) agree within this (mm) are the same.
SAME_SURFACE_MM = 1e-3
#: At most this many unmatched triangles are narrowed down to the places that differ
#: (more: a re-exported mesh; then every unmatched triangle counts as changed).
REFINE_TRIANGLES = 20_000
#: Spacing (mm) of the probe points on unmatched triangles, and at most this many.
PROBE_SPACING_MM = 1.0
MAX_PROBES = 50_000
#: Bin size (mm) for finding the triangles near a probe point, and the most
#: (bin, triangle) and (point, triangle) pairs the exact check may use.
BIN_MM = 2.0
MAX_PAIRS = 5_000_000
#: A printed part is reprinted when old XOR new exceeds this volume (mm³) ...
REPRINT_MIN_MM3 = 1.0
#: ... and this fraction of its volume (re-tessellation of curved faces alone
#: differs by far less; a widened bore or a moved boss by far more).
REPRINT_FRACTION = 0.002


@dataclass
class CellDiff:
    """Cells of the new version against the previous grid.

    ``grid`` is the new version legofied on the previous lattice, cropped
    to its filled cells; ``offset`` (3,) int: previous index = new index +
    offset.  ``added`` is grid-shaped: cells filled now and not before;
    ``removed`` (n, 3) int: previously filled cells now empty, as *new*
    indices (they may lie outside the new grid).
    """

    grid: Grid
    offset: np.ndarray
    added: np.ndarray
    removed: np.ndarray

    @property
    def cells_added(self) -> int:
        return int(np.count_nonzero(self.added))

    @property
    def cells_removed(self) -> int:
        return int(len(self.removed))


def legofy_on(previous: Grid, mesh: trimesh.Trimesh,
              closed: bool | None = None) -> tuple[Grid, np.ndarray]:
    """``mesh`` legofied on the lattice of ``previous``: the new grid and its offset.

    Vertex coordinates within :data:`core.voxelize.LATTICE_SNAP_MM` of a
    cell boundary are first put on it (:func:`core.voxelize.snap_to_lattice`).  The grid covers the
    mesh's bounding box in whole cells of the previous lattice and is then
    cropped to its filled cells; returns ``(grid, offset)`` with previous
    index = new index + offset.  Raises :class:`InputError` when the mesh
    fills no cell.
    """
    cell = np.asarray(previous.cell, dtype=np.float64)
    origin = np.asarray(previous.origin, dtype=np.float64)
    mesh = voxelize.snap_to_lattice(mesh, origin, cell)
    tol = WHOLE_CELL_TOL_MM / cell
    lo = np.floor((mesh.bounds[0] - origin) / cell + tol).astype(np.int64)
    hi = np.ceil((mesh.bounds[1] - origin) / cell - tol).astype(np.int64)
    hi = np.maximum(hi, lo + 1)
    grid = voxelize.legofy(mesh, cell=cell, origin=origin + lo * cell, shape=hi - lo, closed=closed)
    if grid.count == 0:
        raise InputError("the new version fills no cell of the previous grid")
    idx = np.argwhere(grid.filled)
    a, b = idx.min(axis=0), idx.max(axis=0) + 1
    filled = np.ascontiguousarray(grid.filled[a[0]:b[0], a[1]:b[1], a[2]:b[2]])
    return Grid(origin=origin + (lo + a) * cell, cell=cell.copy(), filled=filled), lo + a


def cell_diff(previous: Grid, grid: Grid, offset: np.ndarray) -> CellDiff:
    """Added and removed cells of ``grid`` (offset as from :func:`legofy_on`) against ``previous``."""
    offset = np.asarray(offset, dtype=np.int64)
    before = shift_into(previous.filled, -offset, grid.shape)
    added = np.asarray(grid.filled, dtype=bool) & ~before
    old = np.argwhere(previous.filled) - offset
    inside = np.all((old >= 0) & (old < np.array(grid.shape)), axis=1)
    still = np.zeros(len(old), dtype=bool)
    still[inside] = grid.filled[tuple(old[inside].T)]
    return CellDiff(grid=grid, offset=offset, added=added, removed=old[~still])


def shift_into(array: np.ndarray, shift, shape) -> np.ndarray:
    """A bool array of ``shape`` holding ``array`` moved by ``shift`` cells
    (``out[i + shift] = array[i]``); what falls outside is dropped."""
    out = np.zeros(tuple(int(s) for s in shape), dtype=bool)
    shift = np.asarray(shift, dtype=np.int64)
    src, dst = [], []
    for s, n_in, n_out in zip(shift, array.shape, out.shape):
        a0, a1 = max(0, -s), min(n_in, n_out - s)
        if a1 <= a0:
            return out
        src.append(slice(a0, a1))
        dst.append(slice(a0 + s, a1 + s))
    out[tuple(dst)] = np.asarray(array, dtype=bool)[tuple(src)]
    return out


def changed_boxes(old: trimesh.Trimesh, new: trimesh.Trimesh, old_brep=None, new_brep=None,
                  tol: float = SAME_SURFACE_MM) -> np.ndarray:
    """Boxes (m, 2, 3) of min/max corners (mm) around the surface that differs.

    ``new`` (and ``new_brep``) must already be aligned to the previous
    frame.  First the surface elements of one version without an equal
    one in the other are found: with both B-reps, faces (surface type,
    area, centroid within ``tol``); otherwise triangles (same three corners
    within ``tol``).  Then, unless there are more than
    :data:`REFINE_TRIANGLES` triangles of them, the difference is narrowed
    down (a face with a new hole in it changed, but only around the hole):
    probe points on the unmatched triangles of each version (corners, edge
    midpoints, centroids, and one point per :data:`PROBE_SPACING_MM` squared
    of area) that lie farther than ``tol`` from the other version's
    unmatched triangles are the change, each boxed with the probe spacing.
    Regions that no box meets have the same surface in both versions.
    """
    if old_brep is not None and new_brep is not None:
        from core.parts.brick_solids import TessellationFailed

        a, b = _face_table(old_brep), _face_table(new_brep)
        keep_a, keep_b = _faces_matched(a, b, tol), _faces_matched(b, a, tol)
        gone = [f for f, ok in zip(a.faces, keep_a) if not ok]
        came = [f for f, ok in zip(b.faces, keep_b) if not ok]
        coarse = np.concatenate([a.boxes[~keep_a], b.boxes[~keep_b]])
        try:
            before, after = _face_triangles(gone), _face_triangles(came)
        except TessellationFailed:
            return coarse
    else:
        ta, tb = np.asarray(old.triangles), np.asarray(new.triangles)
        before, after = ta[~_triangles_matched(ta, tb, tol)], tb[~_triangles_matched(tb, ta, tol)]
        coarse = _triangle_boxes(np.concatenate([before, after]))
    if len(before) + len(after) > REFINE_TRIANGLES:
        return coarse
    points = np.concatenate([_off_surface(_probe_points(after)[0], before, tol),
                             _off_surface(_probe_points(before)[0], after, tol)])
    pad = PROBE_SPACING_MM + tol
    return np.stack([points - pad, points + pad], axis=1)


def _triangle_boxes(tri: np.ndarray) -> np.ndarray:
    """Bounding boxes (n, 2, 3) of triangles (n, 3, 3)."""
    return np.stack([tri.min(axis=1), tri.max(axis=1)], axis=1).reshape(-1, 2, 3)


def _face_triangles(faces: list) -> np.ndarray:
    """Triangles (n, 3, 3) of a list of OpenCascade faces, meshed at 0.05 mm."""
    if not faces:
        return np.zeros((0, 3, 3))
    from OCP.BRep import BRep_Builder
    from OCP.TopoDS import TopoDS_Compound

    from core.parts.brick_solids import to_trimesh

    compound = TopoDS_Compound()
    builder = BRep_Builder()
    builder.MakeCompound(compound)
    for f in faces:
        builder.Add(compound, f)
    return np.asarray(to_trimesh(compound).triangles)


def _probe_points(tri: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points on triangles (n, 3, 3) and the triangle of each: corners, edge
    midpoints, centroids, and area-weighted samples about one per
    PROBE_SPACING_MM squared (at most MAX_PROBES)."""
    if len(tri) == 0:
        return np.zeros((0, 3)), np.zeros(0, dtype=np.int64)
    n = np.arange(len(tri))
    mids = (tri + np.roll(tri, 1, axis=1)) / 2.0
    points = [tri.reshape(-1, 3), mids.reshape(-1, 3), tri.mean(axis=1)]
    owner = [np.repeat(n, 3), np.repeat(n, 3), n]
    area = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1) / 2.0
    count = int(min(MAX_PROBES, area.sum() / PROBE_SPACING_MM ** 2))
    if count > 0:
        rng = np.random.default_rng(0)
        pick = rng.choice(len(tri), size=count, p=area / area.sum())
        u, v = rng.random((2, count))
        flip = u + v > 1.0
        u, v = np.where(flip, 1.0 - u, u), np.where(flip, 1.0 - v, v)
        t = tri[pick]
        points.append(t[:, 0] + u[:, None] * (t[:, 1] - t[:, 0]) + v[:, None] * (t[:, 2] - t[:, 0]))
        owner.append(pick)
    return np.concatenate(points), np.concatenate(owner)


def _off_surface(points: np.ndarray, tri: np.ndarray, tol: float) -> np.ndarray:
    """The points farther than ``tol`` from every triangle of ``tri`` (exact).

    Triangles are binned by their bounding boxes (grown by ``tol``) into
    cubic bins of :data:`BIN_MM`; each point is measured exactly
    (:func:`trimesh.triangles.closest_point`) against the triangles of its
    bin only, all pairs at once.  When the binning would need more than
    :data:`MAX_PAIRS` entries every point counts as off (a re-check of a
    printed part costs time, never correctness).
    """
    if len(points) == 0 or len(tri) == 0:
        return points
    lo, hi = tri.min(axis=1) - tol, tri.max(axis=1) + tol
    origin = np.minimum(lo.min(axis=0), points.min(axis=0))
    ilo = np.floor((lo - origin) / BIN_MM).astype(np.int64)
    span = np.floor((hi - origin) / BIN_MM).astype(np.int64) - ilo + 1
    counts = np.prod(span, axis=1)
    if counts.sum() > MAX_PAIRS:
        return points
    dims = np.maximum((ilo + span).max(axis=0), np.floor((points.max(axis=0) - origin) / BIN_MM) + 1)
    dims = dims.astype(np.int64)
    owner = np.repeat(np.arange(len(tri)), counts)
    local = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
    sx, sy = span[owner, 0], span[owner, 1]
    cell = ilo[owner] + np.stack([local % sx, (local // sx) % sy, local // (sx * sy)], axis=1)
    keys = np.ravel_multi_index(cell.T, dims)
    order = np.argsort(keys, kind="stable")
    keys, owner = keys[order], owner[order]
    pcell = np.floor((points - origin) / BIN_MM).astype(np.int64)
    pkey = np.ravel_multi_index(np.clip(pcell, 0, dims - 1).T, dims)
    start, stop = np.searchsorted(keys, pkey, "left"), np.searchsorted(keys, pkey, "right")
    per = stop - start
    if per.sum() > MAX_PAIRS:
        return points
    which = np.repeat(np.arange(len(points)), per)
    pos = np.arange(per.sum()) - np.repeat(np.cumsum(per) - per, per) + np.repeat(start, per)
    distance = np.full(len(points), np.inf)
    if len(which):
        closest = trimesh.triangles.closest_point(tri[owner[pos]], points[which])
        np.minimum.at(distance, which, np.linalg.norm(closest - points[which], axis=1))
    return points[distance > tol]


def _triangles_matched(tri: np.ndarray, other: np.ndarray, tol: float) -> np.ndarray:
    """Per triangle of ``tri`` (n, 3, 3): does ``other`` hold one with the same corners?"""
    if len(other) == 0:
        return np.zeros(len(tri), dtype=bool)
    dist, idx = cKDTree(other.mean(axis=1)).query(tri.mean(axis=1), distance_upper_bound=tol)
    ok = np.isfinite(dist)
    cand = other[np.where(ok, idx, 0)]
    best = np.full(len(tri), np.inf)
    for roll in range(3):
        gap = np.linalg.norm(np.roll(cand, roll, axis=1) - tri, axis=2).max(axis=1)
        best = np.minimum(best, gap)
    return ok & (best <= tol)


@dataclass
class _Faces:
    """Per face of a B-rep: surface type, area, centroid, bounding box, the face."""

    kind: np.ndarray
    area: np.ndarray
    centroid: np.ndarray
    boxes: np.ndarray
    faces: list


def _face_table(shape) -> _Faces:
    """The faces of an OpenCascade shape as a :class:`_Faces` table."""
    from OCP.Bnd import Bnd_Box
    from OCP.BRepAdaptor import BRepAdaptor_Surface
    from OCP.BRepBndLib import BRepBndLib
    from OCP.BRepGProp import BRepGProp
    from OCP.GProp import GProp_GProps

    from core.parts.brick_solids import face_list

    kind, area, centroid, boxes, faces = [], [], [], [], []
    for face in face_list(shape):
        props = GProp_GProps()
        BRepGProp.SurfaceProperties_s(face, props)
        c = props.CentreOfMass()
        box = Bnd_Box()
        BRepBndLib.Add_s(face, box, False)
        if box.IsVoid():
            continue
        kind.append(int(BRepAdaptor_Surface(face).GetType()))
        area.append(props.Mass())
        centroid.append([c.X(), c.Y(), c.Z()])
        x0, y0, z0, x1, y1, z1 = box.Get()
        boxes.append([[x0, y0, z0], [x1, y1, z1]])
        faces.append(face)
    return _Faces(np.array(kind, dtype=np.int64), np.array(area, dtype=np.float64),
                  np.array(centroid, dtype=np.float64).reshape(-1, 3),
                  np.array(boxes, dtype=np.float64).reshape(-1, 2, 3), faces)


def _faces_matched(a: _Faces, b: _Faces, tol: float) -> np.ndarray:
    """Per face of ``a``: does ``b`` hold a face of the same type, area and centroid?"""
    if len(b.area) == 0 or len(a.area) == 0:
        return np.zeros(len(a.area), dtype=bool)
    tree = cKDTree(b.centroid)
    near = tree.query_ball_point(a.centroid, tol)
    out = np.zeros(len(a.area), dtype=bool)
    for i, cand in enumerate(near):
        if cand:
            c = np.asarray(cand)
            same = (b.kind[c] == a.kind[i]) & (np.abs(b.area[c] - a.area[i])
                                                <= tol * np.sqrt(max(a.area[i], 1e-12)) + 1e-9)
            out[i] = bool(same.any())
    return out


def boxes_meet(boxes: np.ndarray, region: np.ndarray) -> bool:
    """Does any of ``boxes`` (m, 2, 3) overlap any box of ``region`` (r, 2, 3)?"""
    if len(boxes) == 0 or len(region) == 0:
        return False
    lo = np.maximum(boxes[:, None, 0], region[None, :, 0])
    hi = np.minimum(boxes[:, None, 1], region[None, :, 1])
    return bool(np.any(np.all(lo <= hi, axis=2)))


def _manifold(mesh: trimesh.Trimesh) -> m3.Manifold | None:
    """``mesh`` as a manifold3d solid, or None when it is not a closed manifold."""
    if len(mesh.faces) == 0:
        return None
    solid = m3.Manifold(m3.Mesh64(vert_properties=np.ascontiguousarray(mesh.vertices, np.float64),
                                  tri_verts=np.ascontiguousarray(mesh.faces, np.uint64)))
    return solid if solid.status() == m3.Error.NoError else None


def symmetric_difference_volume(a: trimesh.Trimesh, b: trimesh.Trimesh) -> float:
    """Volume (mm³) of the points inside exactly one of the two closed meshes.

    Exact on the meshes with manifold3d: vol(a) + vol(b) - 2 vol(a ∩ b).
    Where a mesh is not a closed manifold, it is measured on a grid of
    0.1 mm cells instead (cells sharing volume with one part and not the other).
    """
    ma, mb = _manifold(a), _manifold(b)
    if ma is not None and mb is not None:
        return max(0.0, ma.volume() + mb.volume() - 2.0 * (ma ^ mb).volume())
    if len(a.faces) == 0 or len(b.faces) == 0:
        return float(abs(a.volume) if len(a.faces) else 0.0) + float(abs(b.volume) if len(b.faces) else 0.0)
    lo = np.minimum(a.bounds[0], b.bounds[0])
    hi = np.maximum(a.bounds[1], b.bounds[1])
    cell = np.full(3, 0.1)
    shape = np.ceil((hi - lo) / cell).astype(np.int64) + 1
    fa = voxelize.legofy(a, cell=cell, origin=lo, shape=shape).filled
    fb = voxelize.legofy(b, cell=cell, origin=lo, shape=shape).filled
    return float(np.count_nonzero(fa ^ fb)) * float(np.prod(cell))


def reprint_threshold(volume_mm3: float) -> float:
    """The symmetric-difference volume (mm³) above which a part of ``volume_mm3`` is reprinted."""
    return max(REPRINT_MIN_MM3, REPRINT_FRACTION * abs(float(volume_mm3)))
