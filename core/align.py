"""Alignment: place a new version of a part where the previous version stood.

Between two design iterations the user may have moved or rotated the part (paper,
"Calculating changes between design iterations").  A re-export tessellates everything anew,
so triangles are no features to match on; planar *sides* survive, and the alignment uses them:

1. **Sides.**  A mesh's neighbouring coplanar triangles are merged into facets; a B-rep's
   (STEP, FCStd) planar faces are taken directly, with their exact normals, areas and
   centroids.  Patches on one plane (normal within :data:`PLANE_ANGLE_DEG`, offset within
   :data:`PLANE_OFFSET_MM`) are one *plane*; planes with one normal are one *direction*
   (the paper's "side").  Only planes of at least :data:`MIN_SIDE_FRACTION` of the surface
   area count.
2. **Rotation hypotheses.**  Every pair of non-parallel large directions of the new version
   is matched with every pair of the previous one that encloses the same angle, areas
   within :data:`AREA_RATIO`; each match fixes a rotation, scored by the area of the new
   directions it maps onto previous ones (an extended Gaussian image comparison).  The best
   distinct ones are kept, and always the identity.
3. **Translation.**  Under a rotation, a new plane ``n.x = d`` maps onto a previous plane
   ``n'.x = d'`` when ``n'.t = d' - d``.  Per direction the shift supported by the most
   plane area wins (a 1-D Hough vote, so edited planes do not disturb it); the shifts give
   ``t`` by least squares, and what no plane fixes comes from the volume centroids.  Then
   rotation (Kabsch) and translation are refined once on all matched planes; for exact
   planes this is exact.
4. **Check.**  Each candidate is scored by the intersection over union of the two volumes
   on a fine common grid (:func:`volume_overlap`), and the best one wins.  Below
   :data:`MIN_OVERLAP` there is no confident match: the new version is taken as placed
   where it is (the identity), and the alignment says so.

Bulk work is vectorised (numpy, scipy's KD-tree, :func:`core.voxelize.legofy`); Python
loops only run over the few planes and hypotheses.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import trimesh
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from core import voxelize

#: Normals closer than this (degrees) belong to one plane / direction.
PLANE_ANGLE_DEG = 0.5
#: Parallel patches closer than this (mm) lie on one plane.
PLANE_OFFSET_MM = 0.05
#: A plane counts as a side when it has at least this fraction of the surface area.
MIN_SIDE_FRACTION = 0.002
#: At most this many planes (the largest) take part in the matching.
MAX_PLANES = 64
#: Directions of the new / previous version tried in rotation hypotheses (the largest).
HYPOTHESIS_DIRECTIONS = (8, 12)
#: Two directions enclosing less than this angle (degrees) with each other or with
#: the opposite direction are too close to parallel to fix a rotation.
MIN_PAIR_ANGLE_DEG = 15.0
#: Rotated normals within this angle (degrees) match.
MATCH_ANGLE_DEG = 1.0
#: In a hypothesis, matched directions may differ in area by up to this factor (edits).
AREA_RATIO = 2.0
#: Rotations kept for the translation step: those scoring at least this fraction of
#: the best, at most :data:`MAX_ROTATIONS`, distinct by more than MATCH_ANGLE_DEG.
ROTATION_KEEP = 0.8
MAX_ROTATIONS = 12
#: Candidates (by plane score) whose volume overlap is measured: at most this
#: many, each with at least CANDIDATE_KEEP of the best plane score (and the identity).
OVERLAP_CANDIDATES = 4
CANDIDATE_KEEP = 0.5
#: Matched planes agree in offset within this (mm) after alignment.
MATCH_OFFSET_MM = 0.1
#: Volume intersection over union needed for a confident match.
MIN_OVERLAP = 0.6
#: Cells of the grid on which the volume overlap is measured (about).
OVERLAP_CELLS = 400_000
#: Points sampled on each surface for the residual.
RESIDUAL_SAMPLES = 4000


@dataclass(frozen=True)
class Sides:
    """The planar sides of one version of a part.

    Per plane: unit outward ``normal`` (P, 3), ``offset`` (P,) with
    ``normal . x = offset`` on the plane (mm), ``area`` (P,) mm², area
    ``centroid`` (P, 3) and ``direction`` (P,) the index of its direction.
    Per direction: unit ``directions`` (D, 3) and ``direction_area`` (D,).
    ``surface_area`` is the whole surface's area, ``centre`` the volume
    centroid (area centroid for an open surface), ``source`` "mesh" or
    "brep".  Planes are sorted by decreasing area, directions too.
    """

    normal: np.ndarray
    offset: np.ndarray
    area: np.ndarray
    centroid: np.ndarray
    direction: np.ndarray
    directions: np.ndarray
    direction_area: np.ndarray
    surface_area: float
    centre: np.ndarray
    source: str

    @property
    def planes(self) -> int:
        return int(len(self.area))


@dataclass(frozen=True)
class Alignment:
    """How the new version was placed onto the previous one.

    ``transform`` (4, 4) maps new-file coordinates to the previous frame
    (``x_prev = R x_new + t``).  ``confident`` is False when no candidate
    reached :data:`MIN_OVERLAP`; the transform is then the identity and
    ``message`` says so.  ``overlap`` is the volume intersection over union
    after alignment, ``residual_mm`` the median distance of points sampled
    on the aligned new surface to the previous surface (point to plane; it
    ignores a local edit), ``planes_matched`` how many planar sides of the
    new version lie on a previous side after alignment, ``side_score`` the
    fraction of planar side area they make up, ``method`` what decided it
    ("planar sides", "identity" or "placed as is").
    """

    transform: np.ndarray
    confident: bool
    overlap: float
    residual_mm: float
    planes_matched: int
    side_score: float
    method: str
    message: str
    sides: tuple[int, int] = (0, 0)

    @property
    def rotation_deg(self) -> float:
        """Angle of the rotation part, in degrees."""
        c = (np.trace(self.transform[:3, :3]) - 1.0) / 2.0
        return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))

    @property
    def is_identity(self) -> bool:
        return bool(np.allclose(self.transform, np.eye(4), atol=1e-9))

    def to_json(self) -> dict:
        return {
            "matrix": [[round(float(v), 9) for v in row] for row in self.transform],
            "rotation_deg": round(self.rotation_deg, 6),
            "translation_mm": [round(float(v), 6) for v in self.transform[:3, 3]],
            "confident": self.confident,
            "method": self.method,
            "overlap": round(self.overlap, 6),
            "residual_mm": round(self.residual_mm, 6),
            "planes_matched": self.planes_matched,
            "side_score": round(self.side_score, 4),
            "planar_sides": {"new": self.sides[0], "previous": self.sides[1]},
            "message": self.message,
        }


def mesh_sides(mesh: trimesh.Trimesh) -> Sides:
    """Planar sides of a triangle mesh: coplanar neighbouring triangles merged
    (trimesh facets, single triangles too), then patches on one plane merged."""
    area = np.asarray(mesh.area_faces, dtype=np.float64)
    normal = np.asarray(mesh.face_normals, dtype=np.float64)
    centre = np.asarray(mesh.triangles_center, dtype=np.float64)
    label = np.arange(len(area), dtype=np.int64)
    facets = mesh.facets
    if len(facets):
        lengths = np.array([len(f) for f in facets])
        label[np.concatenate(facets)] = len(area) + np.repeat(np.arange(len(facets)), lengths)
    _, patch = np.unique(label, return_inverse=True)
    patch_area = np.bincount(patch, weights=area)
    keep = patch_area >= MIN_SIDE_FRACTION * max(float(area.sum()), 1e-300) * 0.25
    weight = area[:, None]
    sums_n = np.stack([np.bincount(patch, weights=(normal * weight)[:, i]) for i in range(3)], axis=1)
    sums_c = np.stack([np.bincount(patch, weights=(centre * weight)[:, i]) for i in range(3)], axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        n = sums_n[keep] / np.linalg.norm(sums_n[keep], axis=1, keepdims=True)
        c = sums_c[keep] / patch_area[keep, None]
    good = np.all(np.isfinite(n), axis=1)
    return _sides(n[good], c[good], patch_area[keep][good], float(area.sum()), _centre(mesh), "mesh")


def brep_sides(shape) -> Sides:
    """Planar sides of an OpenCascade shape: its planar faces (exact plane, area and
    centroid from the B-rep), faces on one plane merged."""
    from OCP.BRepAdaptor import BRepAdaptor_Surface
    from OCP.BRepGProp import BRepGProp
    from OCP.GeomAbs import GeomAbs_Plane
    from OCP.GProp import GProp_GProps
    from OCP.TopAbs import TopAbs_REVERSED

    from core.parts.brick_solids import face_list

    normals, centroids, areas = [], [], []
    total = 0.0
    for face in face_list(shape):
        props = GProp_GProps()
        BRepGProp.SurfaceProperties_s(face, props)
        total += props.Mass()
        surface = BRepAdaptor_Surface(face)
        if surface.GetType() != GeomAbs_Plane:
            continue
        d = surface.Plane().Axis().Direction()
        n = np.array([d.X(), d.Y(), d.Z()])
        if face.Orientation() == TopAbs_REVERSED:
            n = -n
        c = props.CentreOfMass()
        normals.append(n)
        centroids.append([c.X(), c.Y(), c.Z()])
        areas.append(props.Mass())
    vprops = GProp_GProps()
    BRepGProp.VolumeProperties_s(shape, vprops)
    vc = vprops.CentreOfMass()
    centre = np.array([vc.X(), vc.Y(), vc.Z()])
    return _sides(np.array(normals).reshape(-1, 3), np.array(centroids).reshape(-1, 3),
                  np.array(areas, dtype=np.float64), total, centre, "brep")


def _centre(mesh: trimesh.Trimesh) -> np.ndarray:
    """Volume centroid of a closed mesh, area centroid of the surface otherwise."""
    if mesh.is_watertight and abs(mesh.volume) > 1e-9:
        return np.asarray(mesh.center_mass, dtype=np.float64)
    area = mesh.area_faces
    return (mesh.triangles_center * area[:, None]).sum(axis=0) / max(area.sum(), 1e-300)


def _clusters(points: np.ndarray, radius: float) -> np.ndarray:
    """Connected components of the points closer than ``radius`` (label per point)."""
    if len(points) == 0:
        return np.zeros(0, dtype=np.int64)
    pairs = cKDTree(points).query_pairs(radius, output_type="ndarray")
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])),
                       shape=(len(points), len(points)))
    return connected_components(graph, directed=False)[1]


def _merge(labels: np.ndarray, vectors: np.ndarray, points: np.ndarray,
           area: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Area-weighted unit normal, area centroid and total area per label."""
    if len(labels) == 0:
        return np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0)
    count = labels.max() + 1
    a = np.bincount(labels, weights=area, minlength=count)
    n = np.stack([np.bincount(labels, weights=vectors[:, i] * area, minlength=count)
                  for i in range(3)], axis=1)
    c = np.stack([np.bincount(labels, weights=points[:, i] * area, minlength=count)
                  for i in range(3)], axis=1)
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    return n, c / np.maximum(a, 1e-300)[:, None], a


def _sides(normal: np.ndarray, centroid: np.ndarray, area: np.ndarray, surface_area: float,
           centre: np.ndarray, source: str) -> Sides:
    """Merge planar patches into planes and directions; keep the large planes."""
    angle = np.radians(PLANE_ANGLE_DEG)
    offset = np.einsum("ij,ij->i", normal, centroid)
    features = np.column_stack([normal, offset * (angle / PLANE_OFFSET_MM)])
    n, c, a = _merge(_clusters(features, angle), normal, centroid, area)
    keep = np.argsort(-a, kind="stable")
    keep = keep[a[keep] >= MIN_SIDE_FRACTION * surface_area][:MAX_PLANES]
    n, c, a = n[keep], c[keep], a[keep]
    d_label = _clusters(n, angle)
    dn, _, da = _merge(d_label, n, c, a)
    order = np.argsort(-da, kind="stable")
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    return Sides(normal=n, offset=np.einsum("ij,ij->i", n, c), area=a, centroid=c,
                 direction=rank[d_label] if len(d_label) else d_label,
                 directions=dn[order].reshape(-1, 3), direction_area=da[order],
                 surface_area=float(surface_area), centre=np.asarray(centre, np.float64),
                 source=source)


def _frames(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Orthonormal frames (..., 3, 3), columns a, b orthogonalised, a x b."""
    u = b - np.sum(a * b, axis=-1, keepdims=True) * a
    u /= np.linalg.norm(u, axis=-1, keepdims=True)
    return np.stack([a, u, np.cross(a, u)], axis=-1)


def rotation_hypotheses(new: Sides, old: Sides) -> list[tuple[np.ndarray, float]]:
    """Distinct rotations (new -> previous) with their direction score, best first.

    See the module docstring (step 2); the identity is always among them.
    """
    kn, ko = HYPOTHESIS_DIRECTIONS
    dn, an = new.directions[:kn], new.direction_area[:kn]
    do, ao = old.directions[:ko], old.direction_area[:ko]
    rotations = [np.eye(3)]
    if len(dn) >= 2 and len(do) >= 2:
        lo = np.cos(np.radians(180.0 - MIN_PAIR_ANGLE_DEG))
        hi = np.cos(np.radians(MIN_PAIR_ANGLE_DEG))
        i, j = np.triu_indices(len(dn), 1)
        cn = np.sum(dn[i] * dn[j], axis=1)
        ok = (cn > lo) & (cn < hi)
        i, j, cn = i[ok], j[ok], cn[ok]
        p, q = np.nonzero(~np.eye(len(do), dtype=bool))
        co = np.sum(do[p] * do[q], axis=1)
        tol = np.radians(MATCH_ANGLE_DEG)
        same_angle = np.abs(np.arccos(np.clip(cn, -1, 1))[:, None]
                            - np.arccos(np.clip(co, -1, 1))[None, :]) < tol

        def similar(x, y):
            ratio = x[:, None] / y[None, :]
            return (ratio <= AREA_RATIO) & (ratio >= 1.0 / AREA_RATIO)

        fit = same_angle & similar(an[i], ao[p]) & similar(an[j], ao[q])
        h, g = np.nonzero(fit)
        if len(h):
            fn = _frames(dn[i[h]], dn[j[h]])
            fo = _frames(do[p[g]], do[q[g]])
            rotations += list(fo @ np.swapaxes(fn, 1, 2))
    stack = np.asarray(rotations)
    scores = _direction_scores(stack, new, old)
    order = np.argsort(-scores, kind="stable")
    best = scores[order[0]]
    out: list[tuple[np.ndarray, float]] = []
    for idx in order:
        if scores[idx] < ROTATION_KEEP * best or len(out) >= MAX_ROTATIONS:
            break
        r = stack[idx]
        if all(_angle_between(r, o) > MATCH_ANGLE_DEG for o, _ in out):
            out.append((r, float(scores[idx])))
    if not any(np.allclose(r, np.eye(3)) for r, _ in out):
        out.append((np.eye(3), float(scores[0])))
    return out


def _angle_between(a: np.ndarray, b: np.ndarray) -> float:
    """Angle (degrees) of the rotation taking ``a`` to ``b``."""
    c = (np.trace(a.T @ b) - 1.0) / 2.0
    return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))


def _direction_scores(rotations: np.ndarray, new: Sides, old: Sides) -> np.ndarray:
    """Per rotation: the new direction area that lands on previous directions
    (each direction counted up to the area it lands on), over the larger total."""
    total = max(new.direction_area.sum(), old.direction_area.sum(), 1e-300)
    if len(new.directions) == 0 or len(old.directions) == 0:
        return np.zeros(len(rotations))
    cos = np.cos(np.radians(MATCH_ANGLE_DEG))
    out = np.empty(len(rotations))
    for start in range(0, len(rotations), 4096):
        r = rotations[start:start + 4096]
        turned = np.einsum("hij,dj->hdi", r, new.directions)
        match = (turned @ old.directions.T) > cos
        landed = match.astype(np.float64) @ old.direction_area
        out[start:start + 4096] = np.minimum(new.direction_area, landed).sum(axis=1) / total
    return out


def _plane_pairs(rotation: np.ndarray, t: np.ndarray, new: Sides, old: Sides,
                 tol: float) -> tuple[np.ndarray, np.ndarray]:
    """Index pairs (new plane, previous plane) that coincide under (rotation, t):
    normals within MATCH_ANGLE_DEG, offsets within ``tol``; the nearest per new plane."""
    if new.planes == 0 or old.planes == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    turned = new.normal @ rotation.T
    parallel = (turned @ old.normal.T) > np.cos(np.radians(MATCH_ANGLE_DEG))
    moved = new.offset[:, None] + (turned @ t)[:, None]
    gap = np.where(parallel, np.abs(old.offset[None, :] - moved), np.inf)
    best = np.argmin(gap, axis=1)
    ok = gap[np.arange(new.planes), best] < tol
    return np.flatnonzero(ok), best[ok]


def _translation(rotation: np.ndarray, new: Sides, old: Sides) -> np.ndarray:
    """Translation under ``rotation`` from a 1-D Hough vote of plane shifts per
    direction; what no plane fixes comes from the centroids (module docstring, step 3)."""
    t0 = old.centre - rotation @ new.centre
    if new.planes == 0 or old.planes == 0:
        return t0
    turned = new.normal @ rotation.T
    parallel = (turned @ old.normal.T) > np.cos(np.radians(MATCH_ANGLE_DEG))
    rows, shifts, weights = [], [], []
    for d in range(len(new.directions)):
        mine = np.flatnonzero(new.direction == d)
        j, k = np.nonzero(parallel[mine])
        if len(j) == 0:
            continue
        j = mine[j]
        s = old.offset[k] - new.offset[j]
        a1, a2 = new.area[j], old.area[k]
        w = np.minimum(a1, a2) * np.minimum(a1, a2) / np.maximum(a1, a2)
        support = (np.abs(s[:, None] - s[None, :]) < MATCH_OFFSET_MM) @ w
        best = int(np.argmax(support))
        normal = new.directions[d] @ rotation.T
        rows.append(normal)
        shifts.append(s[best] - normal @ t0)
        weights.append(support[best])
    if not rows:
        return t0
    a, b, w = np.asarray(rows), np.asarray(shifts), np.asarray(weights)
    return t0 + _least_squares(a, b, w)


def _least_squares(a: np.ndarray, b: np.ndarray, w: np.ndarray) -> np.ndarray:
    """The x of least norm minimising sum w (a.x - b)^2 (directions a do not fix stay 0)."""
    sw = np.sqrt(w)[:, None]
    x, *_ = np.linalg.lstsq(a * sw, b * sw[:, 0], rcond=1e-9)
    return x


def _refine(rotation: np.ndarray, t: np.ndarray, new: Sides,
            old: Sides) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One refinement on all matched planes: Kabsch on the normals (when they span
    two directions), then least squares on the plane equations; returns (R, t, pairs)."""
    j, k = _plane_pairs(rotation, t, new, old, MATCH_OFFSET_MM)
    if len(j) == 0:
        return rotation, t, j, k
    w = np.minimum(new.area[j], old.area[k])
    h = (new.normal[j] * w[:, None]).T @ old.normal[k]
    if np.linalg.matrix_rank(h, tol=1e-6 * np.abs(h).max()) >= 2:
        u, _, vt = np.linalg.svd(h)
        fix = np.diag([1.0, 1.0, np.sign(np.linalg.det(vt.T @ u.T))])
        rotation = vt.T @ fix @ u.T
    turned = new.normal[j] @ rotation.T
    base = old.centre - rotation @ new.centre
    t = base + _least_squares(turned, old.offset[k] - new.offset[j] - turned @ base, w)
    j, k = _plane_pairs(rotation, t, new, old, MATCH_OFFSET_MM)
    return rotation, t, j, k


def _matrix(rotation: np.ndarray, t: np.ndarray) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3], out[:3, 3] = rotation, t
    return out


def transform_mesh(mesh: trimesh.Trimesh, transform: np.ndarray) -> trimesh.Trimesh:
    """A copy of ``mesh`` moved by the 4x4 rigid ``transform``."""
    m = np.asarray(transform, dtype=np.float64)
    vertices = np.asarray(mesh.vertices, dtype=np.float64) @ m[:3, :3].T + m[:3, 3]
    return trimesh.Trimesh(vertices, np.asarray(mesh.faces).copy(), process=False)


def transform_brep(shape, transform: np.ndarray):
    """A copy of the OpenCascade ``shape`` moved by the 4x4 rigid ``transform``."""
    from OCP.BRepBuilderAPI import BRepBuilderAPI_Transform
    from OCP.gp import gp_Trsf

    m = np.asarray(transform, dtype=np.float64)
    trsf = gp_Trsf()
    trsf.SetValues(*m[0], *m[1], *m[2])
    return BRepBuilderAPI_Transform(shape, trsf, True).Shape()


def transform_model(model, transform: np.ndarray):
    """A :class:`~core.io.meshes.LoadedModel` (mesh and B-rep) moved by ``transform``."""
    brep = None if model.brep is None else transform_brep(model.brep, transform)
    return dataclasses.replace(model, mesh=transform_mesh(model.mesh, transform), brep=brep)


def overlap_frame(bounds) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(origin, cell, shape) of a grid of about :data:`OVERLAP_CELLS` cubic cells
    over all the given bounds ((2, 3) arrays)."""
    b = np.asarray(bounds, dtype=np.float64).reshape(-1, 2, 3)
    lo, hi = b[:, 0].min(axis=0), b[:, 1].max(axis=0)
    extent = np.maximum(hi - lo, 1e-6)
    size = max(float(np.cbrt(np.prod(extent) / OVERLAP_CELLS)), float(extent.max()) / 1000.0)
    cell = np.full(3, size)
    shape = np.maximum(np.ceil(extent / cell).astype(np.int64) + 1, 1)
    return lo - (shape * cell - extent) / 2.0, cell, shape


def _occupancy(mesh: trimesh.Trimesh, frame, closed: bool | None) -> np.ndarray:
    origin, cell, shape = frame
    return voxelize.legofy(mesh, cell=cell, origin=origin, shape=shape, closed=closed).filled


def _iou(a: np.ndarray, b: np.ndarray) -> float:
    union = np.count_nonzero(a | b)
    return float(np.count_nonzero(a & b) / union) if union else 0.0


def volume_overlap(a: trimesh.Trimesh, b: trimesh.Trimesh, closed_a: bool | None = None,
                   closed_b: bool | None = None) -> float:
    """Intersection over union of the volumes of ``a`` and ``b``, measured on a common
    grid of about :data:`OVERLAP_CELLS` cubic cells over both bounding boxes (a cell
    counts when it shares volume with the part, :func:`core.voxelize.legofy`)."""
    frame = overlap_frame([a.bounds, b.bounds])
    return _iou(_occupancy(a, frame, closed_a), _occupancy(b, frame, closed_b))


def _moved_bounds(bounds: np.ndarray, matrix: np.ndarray) -> np.ndarray:
    """Bounds of the box ``bounds`` moved by ``matrix`` (contains the moved part)."""
    corners = np.array(np.meshgrid(*bounds.T, indexing="ij")).reshape(3, -1).T
    moved = corners @ matrix[:3, :3].T + matrix[:3, 3]
    return np.stack([moved.min(axis=0), moved.max(axis=0)])


def surface_residual(moved: trimesh.Trimesh, target: trimesh.Trimesh,
                     samples: int = RESIDUAL_SAMPLES, seed: int = 0) -> float:
    """Median distance (mm) from points sampled on ``moved`` to the surface of
    ``target``: to the tangent plane of the nearest of as many points sampled on
    ``target`` (exact on planar areas).  The median ignores a local edit."""
    if len(moved.faces) == 0 or len(target.faces) == 0:
        return float("inf")
    pts, _ = trimesh.sample.sample_surface(moved, samples, seed=seed)
    ref, faces = trimesh.sample.sample_surface(target, samples * 8, seed=seed + 1)
    _, idx = cKDTree(ref).query(pts)
    normal = target.face_normals[faces[idx]]
    return float(np.median(np.abs(np.einsum("ij,ij->i", pts - ref[idx], normal))))


def align(new_mesh: trimesh.Trimesh, old_mesh: trimesh.Trimesh, new_brep=None, old_brep=None,
          new_closed: bool | None = None, old_closed: bool | None = None) -> Alignment:
    """The rigid transform that places ``new_mesh`` onto ``old_mesh`` (module docstring).

    With both B-reps given, their planar faces are the sides; otherwise
    the meshes' coplanar triangles.  Promises: the returned transform is a
    proper rigid motion; among the candidates tried (the identity always
    among them) it has the largest volume overlap; when that is below
    :data:`MIN_OVERLAP` the identity is returned with ``confident`` False.
    """
    if new_brep is not None and old_brep is not None:
        sn, so = brep_sides(new_brep), brep_sides(old_brep)
    else:
        sn, so = mesh_sides(new_mesh), mesh_sides(old_mesh)
    candidates = []
    for rotation, _ in rotation_hypotheses(sn, so):
        t = _translation(rotation, sn, so)
        rotation, t, j, k = _refine(rotation, t, sn, so)
        side = float(np.minimum(sn.area[j], so.area[k]).sum()
                     / max(sn.area.sum(), so.area.sum(), 1e-300)) if len(j) else 0.0
        candidates.append((side, _matrix(rotation, t), len(j)))
    identity = np.eye(4)
    jj, kk = _plane_pairs(np.eye(3), np.zeros(3), sn, so, MATCH_OFFSET_MM)
    id_side = float(np.minimum(sn.area[jj], so.area[kk]).sum()
                    / max(sn.area.sum(), so.area.sum(), 1e-300)) if len(jj) else 0.0
    candidates.sort(key=lambda c: -c[0])
    tried = [(id_side, identity, len(jj))]
    for c in candidates:
        if len(tried) > OVERLAP_CANDIDATES or c[0] < CANDIDATE_KEEP * candidates[0][0]:
            break
        if not any(np.allclose(c[1], o[1], atol=1e-6) for o in tried):
            tried.append(c)
    frame = overlap_frame([old_mesh.bounds] + [_moved_bounds(new_mesh.bounds, m) for _, m, _ in tried])
    before = _occupancy(old_mesh, frame, old_closed)
    scored = []
    for side, matrix, matched in tried:
        moved = new_mesh if matrix is identity else transform_mesh(new_mesh, matrix)
        scored.append((_iou(_occupancy(moved, frame, new_closed), before), side, matrix,
                       matched, moved))
    best = max(scored, key=lambda s: (round(s[0], 4), s[1], s[2] is identity))
    overlap, side, matrix, matched, moved = best
    counts = (sn.planes, so.planes)
    if overlap < MIN_OVERLAP:
        id_overlap, id_sides, _, id_matched, _ = scored[0]
        return Alignment(identity, False, id_overlap, surface_residual(new_mesh, old_mesh),
                         id_matched, id_sides, "placed as is",
                         f"no confident match with the previous version (best volume overlap "
                         f"{overlap:.2f} < {MIN_OVERLAP}): the new version is taken as placed "
                         "where it is", counts)
    method = "identity" if matrix is identity else "planar sides"
    residual = surface_residual(moved, old_mesh)
    message = ("the new version stands where the previous one stood" if matrix is identity else
               f"aligned by {matched} matched planar side(s) ({sn.source}): "
               f"volume overlap {overlap:.3f}, median surface distance {residual:.2g} mm")
    return Alignment(matrix, True, overlap, residual, matched, side, method, message, counts)
