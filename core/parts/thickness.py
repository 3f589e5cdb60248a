"""Local wall thickness of a printed part, and where it is too thin to print.

:func:`thin_features` measures how thick the walls of a closed triangle mesh (a printed
part, in mm) are, a shape-diameter measure along the normal, and reports where they are
thinner than a limit, by default :data:`NOZZLE_MM` (one extrusion line of a 0.4 mm nozzle):

1. **Samples** are spread evenly over the surface (seeded: the same mesh and seed give the
   same report), about ``sqrt(area / samples)`` apart (``spacing_mm``), each standing for
   ``area / samples`` of it.
2. **Rays.**  From every sample a ray runs along the inward normal of its triangle; the
   distance to the first surface it meets is the local thickness.  Hits closer than
   :data:`SELF_HIT` times the bounding-box diagonal are the sample's own triangle, not a
   wall.  A ray from near a convex edge runs parallel to the side face and meets the
   opposite face, so the edges of thick parts are *not* reported thin; a genuinely sharp
   edge (a wedge under ~45 degrees) is, as it cannot be printed either.  A ray that meets
   nothing (an open mesh) counts as not thin; an inside-out watertight mesh is measured
   with its normals flipped.
3. **Spots.**  Thin samples within about :data:`CLUSTER_MM` (or three spacings) of each
   other are one spot; at most :data:`MAX_SPOTS` are reported, largest first.

The rays are cast by a vectorised uniform-grid ray caster written here (numpy and scipy,
no Python loop over rays): trimesh's intersector without embree queries its r-tree once
per ray in Python, far too slowly.

Accuracy: a sliver narrower than the sample spacing may be missed, and areas are estimates
(about ``1/sqrt(n)`` relative error for a spot of ``n`` samples); more ``samples`` make both
finer.  The thickness is measured perpendicular to the *facet*, so a coarsely tessellated
curved wall reads off by the facet's tilt.  A thin rib seen edge-on is measured along its
length at its end face, but its side faces report it.  Walls thinner than ``SELF_HIT`` x
diagonal (0.002 mm on a 200 mm part) are not seen.
"""

from __future__ import annotations

import logging

import numpy as np
import trimesh
from scipy.ndimage import distance_transform_cdt
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

#: The default limit (mm): the thinnest wall a 0.4 mm nozzle prints.
NOZZLE_MM = 0.4

#: Thin samples closer than this (mm) belong to one spot (at least three
#: sample spacings are used on coarsely sampled, large parts).
CLUSTER_MM = 2.0

#: At most this many spots are reported.
MAX_SPOTS = 5

#: Ray hits closer than this fraction of the bounding-box diagonal are
#: the sample's own triangle (or a coplanar neighbour), not a wall.
SELF_HIT = 1e-5

#: Grid cells of the ray caster: about this many triangles per surface cell.
_TRIS_PER_CELL = 2.0
#: At most this many grid cells (memory of the cell index).
_MAX_CELLS = 1 << 22
#: At most this many (triangle, cell) candidates before the grid is coarsened.
_MAX_ENTRIES = 8_000_000
#: (triangle, cell) candidates built per chunk.
_BIN_CHUNK = 1_000_000
#: (ray, triangle) pairs tested per chunk.
_PAIR_CHUNK = 500_000


def thin_features(mesh: trimesh.Trimesh, limit_mm: float = NOZZLE_MM, samples: int = 20000,
                  seed: int = 0) -> dict:
    """Where the walls of ``mesh`` (mm) are thinner than ``limit_mm``.

    Returns a plain dict (numbers rounded to 3 decimals)::

        {"limit_mm": limit,
         "thinnest_mm": smallest measured thickness, or None if nothing was measured,
         "area_mm2": estimated surface area thinner than the limit,
         "fraction": that area / the total surface area,
         "samples": samples measured (rays that met a wall),
         "spacing_mm": typical distance between samples (the resolution),
         "spots": [{"centre_mm": [x, y, z], "thickness_mm": thinnest in the spot,
                    "area_mm2": its area}, ...]}   # up to MAX_SPOTS, largest first

    The area of a spot counts the thin *surface*: a free-standing fin of
    10 x 5 mm thinner than the limit has both its sides thin, 100 mm².
    Samples are evenly spaced about ``spacing_mm`` apart; thin features
    narrower than that may be missed (see the module docstring for the
    method and its limits).  Deterministic for a given ``seed``.
    """
    limit = float(limit_mm)
    total_area = float(mesh.area) if len(mesh.faces) else 0.0
    empty = {"limit_mm": round(limit, 3), "thinnest_mm": None, "area_mm2": 0.0,
             "fraction": 0.0, "samples": 0, "spacing_mm": None, "spots": []}
    if total_area <= 0.0 or samples <= 0:
        return empty

    points, inward, thickness = thickness_map(mesh, samples, seed)
    n = len(points)
    if n == 0:
        return empty

    measured = np.isfinite(thickness)
    per_sample = total_area / n
    spacing = float(np.sqrt(total_area / n))
    thin = measured & (thickness < limit)
    thin_area = per_sample * int(thin.sum())
    report = {
        "limit_mm": round(limit, 3),
        "thinnest_mm": round(float(thickness[measured].min()), 3) if measured.any() else None,
        "area_mm2": round(thin_area, 3),
        "fraction": round(thin_area / total_area, 3),
        "samples": int(measured.sum()),
        "spacing_mm": round(spacing, 3),
        "spots": _spots(points[thin], thickness[thin], per_sample,
                        max(CLUSTER_MM, 3.0 * spacing)),
    }
    return report


def thickness_map(mesh: trimesh.Trimesh, samples: int = 20000, seed: int = 0) -> tuple:
    """The local wall thickness of ``mesh`` (mm) at evenly spread surface samples, as
    :func:`thin_features` measures it: ``(points, inward normals, thickness)``, arrays of
    n x 3, n x 3 and n (inf where the ray met nothing).  Deterministic for a ``seed``."""
    points, face_index = _sample(mesh, int(samples), seed)
    if len(points) == 0:
        return points, np.zeros((0, 3)), np.zeros(0)
    triangles = np.asarray(mesh.triangles, dtype=np.float64)
    planes = _planes(triangles)
    # Normals from the winding (trimesh may cache face_normals that disagree).
    inward = -planes[0][face_index]
    if mesh.is_watertight and _signed_volume(triangles) < 0:
        inward = -inward
    diagonal = float(np.linalg.norm(mesh.extents))
    return points, inward, _first_hits(triangles, planes, points, inward, t_min=SELF_HIT * diagonal)


def _sample(mesh: trimesh.Trimesh, count: int, seed: int) -> tuple:
    """Evenly spread surface samples; trimesh's warning that fewer came back is muted.

    (The rejection sampling often keeps a little fewer than asked; the
    report gives the number measured.)
    """
    logger = logging.getLogger("trimesh")
    level = logger.level
    logger.setLevel(logging.ERROR)
    try:
        return trimesh.sample.sample_surface_even(mesh, count, seed=seed)
    finally:
        logger.setLevel(level)


def _signed_volume(triangles: np.ndarray) -> float:
    """Volume enclosed by the triangles, negative when their normals point inwards."""
    centre = triangles.reshape(-1, 3).mean(axis=0)
    a, b, c = (triangles[:, i] - centre for i in range(3))
    return float(np.einsum("ij,ij->", a, np.cross(b, c))) / 6.0


def _spots(points: np.ndarray, thickness: np.ndarray, per_sample: float, radius: float) -> list:
    """Thin samples grouped by proximity, largest group first (at most MAX_SPOTS).

    To keep the radius graph small however densely a thin region is
    sampled, samples are first gathered into cubic cells of ``radius / 2``;
    cells whose mean points lie within ``radius`` of each other are joined,
    and the connected groups of cells are the spots.
    """
    if len(points) == 0:
        return []
    cell = np.floor(points / (radius / 2.0)).astype(np.int64)
    _, cell_of, cell_count = np.unique(cell, axis=0, return_inverse=True, return_counts=True)
    cell_of = cell_of.ravel()
    n_cells = len(cell_count)
    means = np.zeros((n_cells, 3))
    np.add.at(means, cell_of, points)
    means /= cell_count[:, None]
    pairs = cKDTree(means).query_pairs(radius, output_type="ndarray")
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n_cells, n_cells))
    _, cell_label = connected_components(graph, directed=False)
    label = cell_label[cell_of]

    count = np.bincount(label)
    order = np.argsort(-count, kind="stable")[:MAX_SPOTS]
    spots = []
    for group in order:
        member = label == group
        spots.append({
            "centre_mm": [round(float(c), 3) for c in points[member].mean(axis=0)],
            "thickness_mm": round(float(thickness[member].min()), 3),
            "area_mm2": round(per_sample * int(count[group]), 3),
        })
    return spots


# --------------------------------------------------------------------------
# Vectorised ray casting on a uniform grid.

def _first_hits(triangles: np.ndarray, planes: tuple, origins: np.ndarray,
                directions: np.ndarray, t_min: float) -> np.ndarray:
    """Distance along each (unit) ray to the first triangle hit beyond ``t_min``, inf if none.

    The triangles are binned into a uniform grid (every cell their bounding
    box overlaps and their plane passes near); all rays then walk the grid
    cell by cell in lockstep (Amanatides-Woo traversal), each step testing
    the triangles of each ray's current cell (:func:`_test_cells`).  A ray is
    done once its nearest hit so far lies within the cells it has walked:
    every nearer triangle would have been in one of them.  Empty space is
    crossed in leaps (a chessboard distance transform of the empty cells).
    ``planes`` is :func:`_planes` of the triangles.
    """
    n_rays = len(origins)
    best = np.full(n_rays, np.inf)
    if len(triangles) == 0 or n_rays == 0:
        return best
    grid = _Grid(triangles, origins)
    lo, h, dims = grid.lo, grid.h, grid.dims

    d = np.asarray(directions, dtype=np.float64)
    o = np.asarray(origins, dtype=np.float64)
    cell = np.clip(np.floor((o - lo) / h).astype(np.int64), 0, dims - 1)
    step = np.where(d > 0, 1, np.where(d < 0, -1, 0)).astype(np.int64)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = np.where(d != 0, 1.0 / np.where(d != 0, d, 1.0), np.inf)
        t_next = np.where(step != 0, ((cell + (step > 0)) * h + lo - o) * inv, np.inf)
        t_delta = np.where(step != 0, h * np.abs(inv), np.inf)
    t_next = np.maximum(t_next, 0.0)

    active = np.arange(n_rays)
    stride = np.array([dims[1] * dims[2], dims[2], 1], dtype=np.int64)
    while len(active):
        key = cell[active] @ stride
        # Far from any triangle (an empty cube of cells around the ray's
        # cell): leap to just inside that cube's exit, then walk on.
        reach = grid.empty_reach[key]
        leap = reach >= 2
        if leap.any():
            rays = active[leap]
            r = reach[leap][:, None]
            c = cell[rays]
            bound = np.where(step[rays] > 0, c + r, c - r + 1) * h + lo
            with np.errstate(invalid="ignore"):
                t_box = np.where(step[rays] != 0, (bound - o[rays]) * inv[rays], np.inf).min(axis=1)
            t_here = np.maximum(t_box * (1 - 1e-9) - 1e-9 * h, 0.0)
            at = o[rays] + t_here[:, None] * d[rays]
            c_new = np.clip(np.floor((at - lo) / h).astype(np.int64), c - r + 1, c + r - 1)
            # The empty cube may reach past the grid: a ray leaving it is done.
            in_grid = np.all((c_new >= 0) & (c_new < dims), axis=1)
            rays, c_new = rays[in_grid], c_new[in_grid]
            cell[rays] = c_new
            with np.errstate(invalid="ignore"):
                t_next[rays] = np.where(step[rays] != 0,
                                        ((c_new + (step[rays] > 0)) * h + lo - o[rays]) * inv[rays],
                                        np.inf)
            active = active[~leap]
            key = key[~leap]
            # the leapt rays walk on from their new cells next round
            active_next = rays
        else:
            active_next = active[:0]
        start = grid.starts[key]
        count = grid.starts[key + 1] - start
        has = count > 0
        if has.any():
            _test_cells(active[has], start[has], count[has], grid.tri, o, d, planes, t_min, best)
        t_exit = t_next[active].min(axis=1)
        done = best[active] <= t_exit * (1 + 1e-9) + 1e-12
        # Step every remaining ray into its next cell; leaving the grid ends it.
        axis = np.argmin(t_next[active], axis=1)
        keep = active[~done]
        ax = axis[~done]
        cell[keep, ax] += step[keep, ax]
        t_next[keep, ax] += t_delta[keep, ax]
        inside = (cell[keep, ax] >= 0) & (cell[keep, ax] < dims[ax])
        active = np.concatenate([keep[inside], active_next])
    return best


def _test_cells(rays, start, count, cell_tri, o, d, planes, t_min, best) -> None:
    """Every ray against the triangles of its cell; lower ``best`` where one is hit nearer.

    A pair is first cut to the hits of the triangle's plane between
    ``t_min`` and the ray's best so far; only those get the inside test
    (barycentric coordinates from the precomputed dual edge vectors).
    """
    normal, offset, v0, dual_u, dual_v = planes
    total = int(count.sum())
    offsets = np.cumsum(count) - count
    for lo_pair in range(0, total, _PAIR_CHUNK):
        hi_pair = min(total, lo_pair + _PAIR_CHUNK)
        pair = np.arange(lo_pair, hi_pair)
        which = np.searchsorted(offsets, pair, side="right") - 1
        ray = rays[which]
        tri = cell_tri[start[which] + (pair - offsets[which])]
        nrm = normal[tri]
        towards = np.einsum("ij,ij->i", nrm, d[ray])
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (offset[tri] - np.einsum("ij,ij->i", nrm, o[ray])) / towards
        near = (t > t_min) & (t < best[ray])
        if not near.any():
            continue
        ray, tri, t = ray[near], tri[near], t[near]
        x = o[ray] + t[:, None] * d[ray] - v0[tri]
        u = np.einsum("ij,ij->i", x, dual_u[tri])
        v = np.einsum("ij,ij->i", x, dual_v[tri])
        tol = 1e-9
        hit = (u >= -tol) & (v >= -tol) & (u + v <= 1 + tol)
        if hit.any():
            np.minimum.at(best, ray[hit], t[hit])


def _planes(triangles: np.ndarray) -> tuple:
    """Per triangle: unit normal, its offset n.v0, v0, and the dual edge vectors.

    ``(x - v0) . dual_u`` and ``(x - v0) . dual_v`` are the barycentric
    coordinates of a point ``x`` on the plane along the edges v0->v1 and
    v0->v2.  Degenerate triangles get a zero normal: no ray hits them.
    """
    v0 = triangles[:, 0]
    e1 = triangles[:, 1] - v0
    e2 = triangles[:, 2] - v0
    normal = np.cross(e1, e2)
    length = np.linalg.norm(normal, axis=1)
    scale = np.einsum("ij,ij->i", e1, e1) + np.einsum("ij,ij->i", e2, e2)
    good = length > 1e-12 * np.maximum(scale, 1e-300)
    normal = np.where(good[:, None], normal / np.where(good, length, 1.0)[:, None], 0.0)
    offset = np.einsum("ij,ij->i", normal, v0)
    du = np.cross(e2, normal)
    dv = np.cross(normal, e1)
    with np.errstate(divide="ignore", invalid="ignore"):
        du = np.where(good[:, None], du / np.einsum("ij,ij->i", du, e1)[:, None], 0.0)
        dv = np.where(good[:, None], dv / np.einsum("ij,ij->i", dv, e2)[:, None], 0.0)
    return normal, offset, v0, du, dv


class _Grid:
    """Triangles binned into a uniform grid of cubic cells, as a CSR cell -> triangle index."""

    def __init__(self, triangles: np.ndarray, origins: np.ndarray):
        lo = np.minimum(triangles.reshape(-1, 3).min(axis=0), origins.min(axis=0))
        hi = np.maximum(triangles.reshape(-1, 3).max(axis=0), origins.max(axis=0))
        extent = hi - lo
        pad = 1e-6 * max(float(np.linalg.norm(extent)), 1e-9)
        lo = lo - pad
        extent = extent + 2 * pad
        n_tri = len(triangles)
        area = 0.5 * np.linalg.norm(np.cross(triangles[:, 1] - triangles[:, 0],
                                             triangles[:, 2] - triangles[:, 0]), axis=1).sum()
        # Surface cells ~ area / h^2, about _TRIS_PER_CELL triangles each.
        h = float(np.sqrt(_TRIS_PER_CELL * max(area, 1e-18) / n_tri))
        h = max(h, float(extent.max()) / 1024)
        while True:
            dims = np.maximum(np.ceil(extent / h).astype(np.int64), 1)
            if int(np.prod(dims)) > _MAX_CELLS:
                h *= 1.25
                continue
            binned = self._bin(triangles, lo, h, dims)
            if binned is not None:
                break
            h *= 1.5
        self.lo, self.h, self.dims = lo, h, dims
        key, tri = binned
        order = np.argsort(key, kind="stable")
        self.tri = tri[order]
        counts = np.bincount(key, minlength=int(np.prod(dims)))
        self.starts = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        # Per empty cell: the chessboard distance (cells) to the nearest
        # cell holding a triangle; all cells nearer than that are empty.
        self.empty_reach = distance_transform_cdt(
            (counts == 0).reshape(tuple(dims)), metric="chessboard").ravel().astype(np.int64)

    @staticmethod
    def _bin(triangles, lo, h, dims):
        """(cell key, triangle) for every cell a triangle may cross; None if too many.

        Candidates are the cells of each triangle's bounding box, kept where
        the triangle's plane passes within half a cell diagonal of the
        cell's centre (a conservative cut); built in chunks of triangles to
        bound the memory.
        """
        tmin = np.clip(np.floor((triangles.min(axis=1) - lo) / h).astype(np.int64), 0, dims - 1)
        tmax = np.clip(np.floor((triangles.max(axis=1) - lo) / h).astype(np.int64), 0, dims - 1)
        span = tmax - tmin + 1
        per = span.prod(axis=1)
        if int(per.sum()) > _MAX_ENTRIES:
            return None
        normal = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
        length = np.linalg.norm(normal, axis=1)
        normal = normal / np.where(length > 0, length, 1.0)[:, None]
        # plane offset of the cell centre (i + 0.5) h + lo is base + i . (n h)
        base = normal @ (lo + 0.5 * h) - np.einsum("ij,ij->i", normal, triangles[:, 0])
        nh = normal * h
        reach = 0.5 * np.sqrt(3.0) * h * (1 + 1e-6)
        per = np.where(length > 0, per, 0)  # degenerate triangles are never hit
        ends = np.cumsum(per)
        keys, tris = [], []
        first = 0
        while first < len(triangles):
            last = int(np.searchsorted(ends, ends[first] - per[first] + _BIN_CHUNK, side="right"))
            last = max(last, first + 1)
            chunk = np.arange(first, last)
            count = per[chunk]
            total = int(count.sum())
            first = last
            if total == 0:
                continue
            tri = np.repeat(chunk, count)
            k = np.arange(total) - np.repeat(np.cumsum(count) - count, count)
            syz = (span[:, 1] * span[:, 2])[tri]
            sz = span[tri, 2]
            ix = k // syz
            rest = k - ix * syz
            iy = rest // sz
            iz = rest - iy * sz
            ix += tmin[tri, 0]
            iy += tmin[tri, 1]
            iz += tmin[tri, 2]
            offset = base[tri] + ix * nh[tri, 0] + iy * nh[tri, 1] + iz * nh[tri, 2]
            near = np.abs(offset) <= reach
            keys.append((ix[near] * dims[1] + iy[near]) * dims[2] + iz[near])
            tris.append(tri[near])
        if not keys:
            return np.zeros(0, np.int64), np.zeros(0, np.int64)
        return np.concatenate(keys), np.concatenate(tris)
