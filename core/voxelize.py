"""Legofy: which 1x1 plate cells of a grid a part fills.

A cell is filled exactly when it shares positive volume with the part.  The answer is
computed exactly (no sampling approximation), as the union of two sets:

1. **Surface cells** (:func:`surface_cells`).  A cell is filled when some triangle meets
   the *open* interior of its box: Akenine-Möller's separating axis test (13 axes) against
   the box shrunk by :data:`EPS_MM`, with strict inequalities.  So a face flush with a cell
   face, or a part merely touching a cell, does not fill it, and rounding
   (``3 * 3.2 = 9.600000000000001``) does not leak a face into the next layer; a thin wall
   through a cell fills it.  A triangle visits only the cells its plane can meet, so huge
   triangles cost what they cover.

2. **Inside cells.**  The surface crosses no other cell's open interior, so each is wholly
   inside or outside and one sample point decides (:data:`SAMPLE_FRACTION`: a generic point,
   so that rays miss the edges and vertices of axis-aligned models).  Rays along an axis
   count signed crossings; edge tests in canonical order with simulation of simplicity
   count a ray through a shared edge or vertex exactly once.  Closed (watertight) meshes:
   rays along +z, inside where the winding number is non-zero.  Open, non-manifold or
   self-intersecting meshes (:func:`_vote_inside`, after Nooruddin & Turk): six ray
   estimates (along x, y, z, from below and above) where all agree, else the generalized
   winding number (van Oosterom & Strackee), inside at magnitude 0.5 or more, summed
   through a cap of the holes (:func:`boundary_cap`, :func:`_winding_via_cap`).  Cells the
   cap passes through count as surface cells too, so a box with a missing face is filled
   as if the hole were closed by its cap.

Both inside tests count with sign, so each shell must be consistently oriented (either way:
the non-zero rule also takes an inside-out shell as solid); overlapping shells add up, so
self-intersecting parts are their union.  All geometry is shifted to the grid origin first,
so cell bounds are exact multiples of the cell size.
"""

from __future__ import annotations

import math

import numba
import numpy as np
import trimesh
from numba import njit, prange
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from core.errors import InputError
from core.model import CELL_MM, Grid

#: A triangle must penetrate a cell's interior by more than this (mm) to fill it.
EPS_MM = 1e-6
#: An extent within this (mm) of a whole number of cells gets exactly that many.
WHOLE_CELL_TOL_MM = 1e-6
#: Vertex coordinates this close (mm) to a cell boundary of a grid are put on it
#: by :func:`snap_to_lattice`: an STL stores float32 and CAD tessellates in floats,
#: so a face meant to lie on a boundary (a re-export, a wall at whole millimetres)
#: comes back some 1e-5 mm off it, and legofy would count that as filling the next
#: cell.  Absolute: where the model sits does not change it (a model too far from
#: the origin for float32 is moved to it when loaded, :mod:`core.io.meshes`).
LATTICE_SNAP_MM = 1e-4
#: Sample point of each cell, in cells from the cell's min corner.
SAMPLE_FRACTION = (0.5 + 0.1234567, 0.5 + 0.0765432, 0.5 + 0.1471)


def _cell_size(cell) -> np.ndarray:
    """The cell size as a float array of 3 positive finite numbers, else ValueError."""
    c = np.asarray(cell, dtype=np.float64)
    if c.shape != (3,) or not np.all(np.isfinite(c)) or np.any(c <= 0):
        raise ValueError(f"cell size must be three positive numbers in mm, got {cell!r}")
    return c


def grid_frame(bounds: np.ndarray, cell=CELL_MM) -> tuple[np.ndarray, tuple[int, int, int]]:
    """Origin (min corner, mm) and shape (nx, ny, nz) of the grid for a part with
    bounds [[xmin,ymin,zmin],[xmax,ymax,zmax]]: the bounding box grown to whole cells.

    Alignment: z starts at the part's lowest point (the part stands on the base
    plate); in x and y the grown box is centred on the part's box (equal overhang
    both sides).  At least one cell per axis.  A part extent that is a whole number
    of cells (within 1e-6 mm) gets exactly that many cells.  Raises ValueError for
    bounds that are not finite or not ordered (the model loader refuses such a
    model first, :mod:`core.io.meshes`).
    """
    c = _cell_size(cell)
    b = np.asarray(bounds, dtype=np.float64)
    if b.shape != (2, 3) or not np.all(np.isfinite(b)):
        raise ValueError("model bounds are not finite (empty mesh or NaN/inf coordinates)")
    extent = b[1] - b[0]
    if np.any(extent < 0):
        raise ValueError("model bounds are not ordered (max below min)")
    counts = np.maximum(1, np.ceil((extent - WHOLE_CELL_TOL_MM) / c)).astype(np.int64)
    origin = b[0] - (counts * c - extent) / 2.0
    origin[2] = b[0, 2]
    return origin, tuple(int(n) for n in counts)


#: Most cells the bounding box of a part may have: legofy holds a few arrays of this
#: size (some 25 bytes a cell for a closed mesh, 70 for an open one) and the layout
#: a few more; 64 million cells is a part of about 2.3 m each way.
MAX_GRID_CELLS = 64_000_000
#: Most filled cells laid out: the layout's time and memory grow with them (a solid
#: 1 m cube has 4.9 million, a hollowed 2 m cube 4.2 million).
MAX_LAYOUT_CELLS = 12_000_000

_UNIT_NAMES = {"mm": "millimetres", "cm": "centimetres", "m": "metres", "in": "inches"}


def check_size(mesh: trimesh.Trimesh, units: str = "mm", name: str = "the model",
               cell=CELL_MM, unit_mm: dict | None = None) -> tuple[int, int, int]:
    """The grid shape of ``mesh`` (:func:`grid_frame`), or one-line InputError when its
    bounding box has more than :data:`MAX_GRID_CELLS` cells: the message names the size
    in cells and mm and the likely mistake (another unit, a scale, or pieces far apart).

    Computes only bounds (and, for the message, the pieces' bounds): nothing of the
    grid's size is allocated.  ``unit_mm`` maps unit names to mm (the request's UNITS).
    """
    c = _cell_size(cell)
    bounds = np.asarray(mesh.bounds, dtype=np.float64)
    _, shape = grid_frame(bounds, c)
    total = math.prod(shape)
    if total <= MAX_GRID_CELLS:
        return shape
    size = bounds[1] - bounds[0]
    scale = (MAX_GRID_CELLS / total) ** (1 / 3)
    side = (MAX_GRID_CELLS * float(np.prod(c))) ** (1 / 3)
    unit_mm = unit_mm or {"mm": 1.0, "cm": 10.0, "m": 1000.0, "in": 25.4}
    hint = _size_hint(mesh, units, float(size.max()), scale, side, c, unit_mm)
    raise InputError(
        f"{name} is {' x '.join(f'{n:,}' for n in shape)} cells ({' x '.join(f'{v:,.0f}' for v in size)} mm): "
        f"more than the {MAX_GRID_CELLS:,} cells this machine can legofy (a cube up to about "
        f"{side / 1000:.1f} m); {hint}")


def _size_hint(mesh, units: str, largest: float, scale: float, side: float, cell,
               unit_mm: dict) -> str:
    """The likely mistake behind a part too big to legofy (``scale``: the factor that
    would make it fit; ``side``: the largest cube that fits, mm), as advice."""
    here = unit_mm.get(units, 1.0)
    smaller = sorted((u for u, mm in unit_mm.items()
                      if mm / here <= scale and largest * mm / here >= cell[0]),
                     key=lambda u: (u != "mm", -unit_mm[u]))
    if smaller:
        u, others = smaller[0], smaller[1:]
        more = f" (or {', '.join(f'--units {o}' for o in others)})" if others else ""
        return f"is it in {_UNIT_NAMES.get(u, u)}? try --units {u}{more}"
    piece = _largest_piece_extent(mesh)
    if piece is not None and piece <= side:
        return (f"its pieces lie {largest / 1000:,.1f} m apart, while the largest piece is "
                f"{piece / 1000:,.2f} m across: remove the stray pieces far from the rest")
    factor = 10 ** math.ceil(math.log10(1 / scale))
    return f"is it in tenths of mm or µm? try --scale {1 / factor:g}"


def _largest_piece_extent(mesh) -> float | None:
    """The largest extent (mm) of the pieces (vertex-connected) of ``mesh``, None for one piece."""
    faces = np.asarray(mesh.faces, dtype=np.int64)
    v = np.asarray(mesh.vertices, dtype=np.float64)
    if len(faces) == 0:
        return None
    edges = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]]])
    graph = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(len(v), len(v)))
    n, label = connected_components(graph, directed=False)
    if n < 2:
        return None
    lo = np.full((n, 3), np.inf)
    hi = np.full((n, 3), -np.inf)
    used = np.unique(faces)
    np.minimum.at(lo, label[used], v[used])
    np.maximum.at(hi, label[used], v[used])
    ok = np.isfinite(lo[:, 0])
    return float((hi[ok] - lo[ok]).max())


def check_volume(mesh: trimesh.Trimesh, closed: bool, hollow_setting: int, cell=CELL_MM) -> None:
    """:func:`check_cells` before legofy for a part built solid (``hollow_setting`` 0): a
    closed part of volume V fills at least V / (cell volume) cells, since its filled
    cells cover it."""
    if hollow_setting == 0 and closed:
        least = int(abs(float(mesh.volume)) / float(np.prod(_cell_size(cell))))
        check_cells(least, hollow_setting, "at least ")


def check_cells(count: int, hollow_setting: int, least: str = "") -> None:
    """One-line InputError when ``count`` filled cells are more than :data:`MAX_LAYOUT_CELLS`."""
    if count > MAX_LAYOUT_CELLS:
        advice = ("build it hollow (leave out --hollow=0) or smaller (--scale)"
                  if hollow_setting == 0 else "build it smaller (--scale) or with a thinner shell")
        raise InputError(f"the part fills {least}{count:,} cells: more than the {MAX_LAYOUT_CELLS:,} "
                         f"this machine lays out in minutes; {advice}")


def snap_to_lattice(mesh: trimesh.Trimesh, origin, cell) -> trimesh.Trimesh:
    """``mesh`` (a copy when anything moves) with every vertex coordinate within
    the snap tolerance of a lattice plane ``origin + n * cell`` put on that plane."""
    v = np.asarray(mesh.vertices, dtype=np.float64)
    if len(v) == 0:
        return mesh
    rel = (v - origin) / cell
    near = np.rint(rel)
    close = np.abs(rel - near) * cell < LATTICE_SNAP_MM
    if not close.any():
        return mesh
    out = mesh.copy()
    out.vertices = np.where(close, origin + near * cell, v)
    return out


def legofy(mesh: trimesh.Trimesh, cell=CELL_MM, origin=None, shape=None,
           closed: bool | None = None) -> Grid:
    """Grid of filled cells: a cell is filled exactly when it shares positive volume
    with the part (more than EPS_MM penetration; for open meshes the part is the
    mesh with its holes capped, inside decided by the generalized winding number).

    origin/shape default to grid_frame(mesh.bounds); given explicitly (e.g. to
    legofy a new version on an old grid), parts of the model outside the grid are
    ignored (they still decide what is inside).  closed defaults to
    mesh.is_watertight and decides which inside test is used: one ray family for
    closed meshes, six-way voting plus generalized winding numbers otherwise (see
    the module docstring).  Raises ValueError for a mesh without triangles, with
    non-finite coordinates, or a bad cell size, origin or shape: the user's
    files are refused before, by :mod:`core.io.meshes`.
    """
    origin, c, surface, inside = _occupancy(mesh, cell, origin, shape, closed)
    return Grid(origin=origin.copy(), cell=c.copy(), filled=surface | inside)


def sampled(mesh: trimesh.Trimesh, cell=CELL_MM, origin=None, shape=None,
            closed: bool | None = None) -> Grid:
    """Grid of the cells whose sample point (:data:`SAMPLE_FRACTION`, near the centre) is
    inside the part, as :func:`legofy` decides inside: their count times a cell's volume
    is a point-sampled estimate of the part's volume, where :func:`legofy` counts every
    cell the surface touches.  Arguments and errors as :func:`legofy`."""
    origin, c, _, inside = _occupancy(mesh, cell, origin, shape, closed)
    return Grid(origin=origin.copy(), cell=c.copy(), filled=inside)


def _occupancy(mesh: trimesh.Trimesh, cell, origin, shape, closed):
    """``(origin, cell, surface cells, cells whose sample point is inside)`` for
    :func:`legofy` and :func:`sampled`."""
    c = _cell_size(cell)
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    faces = np.asarray(mesh.faces, dtype=np.int64)
    if faces.ndim != 2 or len(faces) == 0:
        raise ValueError("mesh has no triangles")
    if not np.all(np.isfinite(vertices)):
        raise ValueError("mesh has NaN or infinite vertex coordinates")
    if origin is None or shape is None:
        frame_origin, frame_shape = grid_frame(mesh.bounds, c)
        origin = frame_origin if origin is None else origin
        shape = frame_shape if shape is None else shape
    origin = np.asarray(origin, dtype=np.float64)
    if origin.shape != (3,) or not np.all(np.isfinite(origin)):
        raise ValueError(f"grid origin must be three finite numbers, got {origin!r}")
    dims = np.asarray(shape)
    if dims.shape != (3,) or not np.issubdtype(dims.dtype, np.integer) or np.any(dims < 1):
        raise ValueError(f"grid shape must be three positive integers, got {shape!r}")
    dims = dims.astype(np.int64)
    if closed is None:
        closed = bool(mesh.is_watertight)

    relative = vertices - origin
    tri = np.ascontiguousarray(relative[faces])
    surface = surface_cells(tri, c, dims)
    if closed:
        inside = _winding_along(tri, c, dims, 2)[0] != 0
    else:
        cap, weight = boundary_cap(relative, faces)
        if len(cap):
            surface |= surface_cells(cap, c, dims)
        inside = _vote_inside(tri, cap, weight, c, dims, surface)
    return origin, c, surface, inside


def surface_cells(tri: np.ndarray, cell: np.ndarray, shape) -> np.ndarray:
    """Boolean (nx, ny, nz) array: cells whose open interior some triangle of
    ``tri`` (F, 3, 3; mm relative to the grid origin) penetrates by more than
    EPS_MM (exact separating axis test)."""
    out = np.zeros(tuple(int(n) for n in shape), dtype=np.uint8)
    _surface_kernel(np.ascontiguousarray(tri, dtype=np.float64), np.asarray(cell, np.float64),
                    EPS_MM, out)
    return out.view(bool)


def sample_points(index: np.ndarray, cell: np.ndarray) -> np.ndarray:
    """Sample points (mm, relative to the grid origin) of the cells ``index`` (N, 3)."""
    return (np.asarray(index, np.float64) + np.asarray(SAMPLE_FRACTION)) * np.asarray(cell)


def winding_numbers(points: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Generalized winding number of each point (N, 3) w.r.t. the triangles
    (F, 3, 3): the sum of their signed solid angles over 4 pi (exact, O(N F))."""
    return _gwn_kernel(np.ascontiguousarray(points, np.float64),
                       np.ascontiguousarray(tri, np.float64))


def _winding_along(tri: np.ndarray, cell: np.ndarray, shape: np.ndarray,
                   axis: int) -> tuple[np.ndarray, np.ndarray]:
    """Signed crossing counts of rays along ``axis`` through every cell's sample
    point (+1 entering through a face whose normal points against the ray, -1 leaving):
    (counted from below, counted from above), each an (nx, ny, nz) int array."""
    perm = np.array([(axis + 1) % 3, (axis + 2) % 3, axis])
    frac = np.asarray(SAMPLE_FRACTION)[perm]
    chunks = numba.get_num_threads()
    deltas = _ray_kernel(tri, perm, cell[perm], frac, shape[perm], chunks).sum(axis=0)
    below = np.cumsum(deltas, axis=2)[:, :, :-1]
    above = below - deltas.sum(axis=2)[:, :, None]
    back = np.argsort(perm)
    return below.transpose(back), above.transpose(back)


def _vote_inside(tri: np.ndarray, cap: np.ndarray, weight: np.ndarray, cell: np.ndarray,
                 shape: np.ndarray, surface: np.ndarray) -> np.ndarray:
    """Inside test for open / non-manifold meshes: six ray estimates per sample
    point, the exact generalized winding number where they disagree."""
    counts = [_winding_along(tri, cell, shape, axis) for axis in range(3)]
    votes = sum((w != 0).astype(np.int8) for pair in counts for w in pair)
    inside = votes == 6
    undecided = (votes > 0) & (votes < 6) & ~surface
    if np.any(undecided):
        points = sample_points(np.argwhere(undecided), cell)
        gwn = _winding_via_cap(points, counts[2][0][undecided], tri, cap, weight)
        inside[undecided] = np.abs(gwn) >= 0.5
    return inside


def boundary_cap(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Triangles (B, 3, 3) and integer weights (B,) that close the mesh's holes.

    The boundary of the triangle chain is every edge whose net count (uses as
    u->v minus uses as v->u) is non-zero; each connected piece of it is joined
    to one apex, the mean of its vertices (a planar convex hole gets exactly its
    missing face).  The mesh minus the weighted cap is a closed chain.  Any
    connectivity (non-manifold, inconsistently oriented) is fine.
    """
    start = faces.reshape(-1)
    end = faces[:, [1, 2, 0]].reshape(-1)
    lo, hi = np.minimum(start, end), np.maximum(start, end)
    keys, inverse = np.unique(lo * len(vertices) + hi, return_inverse=True)
    net = np.bincount(inverse, weights=np.where(start < end, 1.0, -1.0)).round().astype(np.int64)
    open_edges = np.flatnonzero(net)
    u, v = np.divmod(keys[open_edges], len(vertices))
    links = coo_matrix((np.ones(len(u)), (u, v)), shape=(len(vertices),) * 2)
    _, piece = connected_components(links, directed=False)
    ends = np.concatenate([u, v])
    size = np.bincount(piece[ends], minlength=piece.max() + 1)[:, None]
    apex = np.stack([np.bincount(piece[ends], weights=vertices[ends, d], minlength=len(size))
                     for d in range(3)], axis=1) / np.maximum(size, 1)
    cap = np.stack([apex[piece[u]], vertices[u], vertices[v]], axis=1)
    return np.ascontiguousarray(cap, dtype=np.float64), net[open_edges]


def _winding_via_cap(points: np.ndarray, below_z: np.ndarray, tri: np.ndarray,
                     cap: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """Exact generalized winding numbers of the points, given their signed +z ray
    crossing counts ``below_z`` and a cap of the mesh boundary (:func:`boundary_cap`).

    Mesh minus cap is closed, so its winding number is a ray crossing count, and
    gwn(mesh) = below_z(mesh) - below_z(cap) + gwn(cap): an O(points x boundary
    edges) sum instead of O(points x triangles).  Falls back to the direct sum
    when the boundary is not smaller than the mesh."""
    if len(cap) >= len(tri):
        return winding_numbers(points, tri)
    return below_z + _cap_kernel(np.ascontiguousarray(points), cap, weight.astype(np.float64))


@njit(cache=True, inline="always")
def _edge_sign(px, py, qx, qy, x, y):
    """Sign of orient2d(p, q, (x, y)), evaluated with the endpoints in canonical
    order (so a shared edge gives the same value in both triangles) and exact zeros
    broken by perturbing the point by (e, e^2); 0 only for a degenerate edge."""
    flip = 1
    if qx < px or (qx == px and qy < py):
        px, py, qx, qy = qx, qy, px, py
        flip = -1
    e = (qx - px) * (y - py) - (qy - py) * (x - px)
    if e > 0:
        return flip
    if e < 0:
        return -flip
    if qy != py:
        return -flip if qy > py else flip
    if qx != px:
        return flip if qx > px else -flip
    return 0


@njit(cache=True, inline="always")
def _cell_range(lo, hi, size, n):
    """First and last of the n cells of the given size whose closed span meets
    [lo, hi] (clamped before rounding, so far-away coordinates cannot overflow)."""
    first = math.floor(min(max(lo / size, -1.0), n + 1.0))
    last = math.floor(min(max(hi / size, -1.0), n + 1.0))
    return max(first, 0), min(last, n - 1)


@njit(cache=True, inline="always")
def _sample_range(lo, hi, size, frac, n):
    """First and last of the n sample coordinates (i + frac) * size in [lo, hi]
    (clamped before rounding, so far-away coordinates cannot overflow)."""
    first = math.ceil(min(max(lo / size - frac, -1.0), n + 1.0))
    last = math.floor(min(max(hi / size - frac, -1.0), n + 1.0))
    return max(first, 0), min(last, n - 1)


@njit(cache=True, parallel=True)
def _ray_kernel(tri, perm, cell, frac, shape, chunks):
    """Per-chunk signed crossing deltas, shape (chunks, na, nb, nc + 1), of rays
    along axis perm[2] through the sample points: a crossing at height t adds its
    sign at the first layer whose sample lies above t (0 below the grid, nc above)."""
    ia, ib, ic = perm[0], perm[1], perm[2]
    ca, cb, cc = cell[0], cell[1], cell[2]
    fa, fb, fc = frac[0], frac[1], frac[2]
    na, nb, nc = shape[0], shape[1], shape[2]
    nt = tri.shape[0]
    out = np.zeros((chunks, na, nb, nc + 1), dtype=np.int32)
    for ch in prange(chunks):
        for t in range(nt * ch // chunks, nt * (ch + 1) // chunks):
            a0, b0, c0 = tri[t, 0, ia], tri[t, 0, ib], tri[t, 0, ic]
            a1, b1, c1 = tri[t, 1, ia], tri[t, 1, ib], tri[t, 1, ic]
            a2, b2, c2 = tri[t, 2, ia], tri[t, 2, ib], tri[t, 2, ic]
            i0, i1 = _sample_range(min(a0, a1, a2), max(a0, a1, a2), ca, fa, na)
            j0, j1 = _sample_range(min(b0, b1, b2), max(b0, b1, b2), cb, fb, nb)
            if i0 > i1 or j0 > j1:
                continue
            n_a = (b1 - b0) * (c2 - c0) - (c1 - c0) * (b2 - b0)
            n_b = (c1 - c0) * (a2 - a0) - (a1 - a0) * (c2 - c0)
            n_c = (a1 - a0) * (b2 - b0) - (b1 - b0) * (a2 - a0)
            if n_c == 0.0:
                continue
            cmin, cmax = min(c0, c1, c2), max(c0, c1, c2)
            for i in range(i0, i1 + 1):
                x = (i + fa) * ca
                for j in range(j0, j1 + 1):
                    y = (j + fb) * cb
                    s = _edge_sign(a0, b0, a1, b1, x, y)
                    if s == 0 or _edge_sign(a1, b1, a2, b2, x, y) != s \
                            or _edge_sign(a2, b2, a0, b0, x, y) != s:
                        continue
                    h = c0 - (n_a * (x - a0) + n_b * (y - b0)) / n_c
                    h = min(max(h, cmin), cmax)
                    m = math.floor(min(max(h / cc - fc, -2.0), nc + 1.0)) + 1
                    m = min(max(m, 0), nc)
                    out[ch, i, j, m] -= s
    return out


@njit(cache=True, inline="always")
def _tri_box(x0, y0, z0, x1, y1, z1, x2, y2, z2, nx, ny, nz, hx, hy, hz):
    """True when the triangle (coordinates relative to the box centre, normal n)
    meets the open box of half sizes h: no separating axis among the 13."""
    if min(x0, x1, x2) >= hx or max(x0, x1, x2) <= -hx:
        return False
    if min(y0, y1, y2) >= hy or max(y0, y1, y2) <= -hy:
        return False
    if min(z0, z1, z2) >= hz or max(z0, z1, z2) <= -hz:
        return False
    d = nx * x0 + ny * y0 + nz * z0
    if abs(d) >= hx * abs(nx) + hy * abs(ny) + hz * abs(nz):
        return False
    for e in range(3):
        if e == 0:
            ex, ey, ez = x1 - x0, y1 - y0, z1 - z0
        elif e == 1:
            ex, ey, ez = x2 - x1, y2 - y1, z2 - z1
        else:
            ex, ey, ez = x0 - x2, y0 - y2, z0 - z2
        r = hy * abs(ez) + hz * abs(ey)
        if r > 0.0:
            p0 = ey * z0 - ez * y0
            p1 = ey * z1 - ez * y1
            p2 = ey * z2 - ez * y2
            if min(p0, p1, p2) >= r or max(p0, p1, p2) <= -r:
                return False
        r = hx * abs(ez) + hz * abs(ex)
        if r > 0.0:
            p0 = ez * x0 - ex * z0
            p1 = ez * x1 - ex * z1
            p2 = ez * x2 - ex * z2
            if min(p0, p1, p2) >= r or max(p0, p1, p2) <= -r:
                return False
        r = hx * abs(ey) + hy * abs(ex)
        if r > 0.0:
            p0 = ex * y0 - ey * x0
            p1 = ex * y1 - ey * x1
            p2 = ex * y2 - ey * x2
            if min(p0, p1, p2) >= r or max(p0, p1, p2) <= -r:
                return False
    return True


@njit(cache=True, inline="always")
def _tri_column(x0, y0, x1, y1, x2, y2, hx, hy):
    """True when the xy projection of the triangle (relative to the column centre)
    meets the open rectangle of half sizes h: the 2-D separating axis test."""
    if min(x0, x1, x2) >= hx or max(x0, x1, x2) <= -hx:
        return False
    if min(y0, y1, y2) >= hy or max(y0, y1, y2) <= -hy:
        return False
    for e in range(3):
        if e == 0:
            ex, ey = x1 - x0, y1 - y0
        elif e == 1:
            ex, ey = x2 - x1, y2 - y1
        else:
            ex, ey = x0 - x2, y0 - y2
        r = hx * abs(ey) + hy * abs(ex)
        if r > 0.0:
            p0 = ex * y0 - ey * x0
            p1 = ex * y1 - ey * x1
            p2 = ex * y2 - ey * x2
            if min(p0, p1, p2) >= r or max(p0, p1, p2) <= -r:
                return False
    return True


@njit(cache=True, parallel=True)
def _surface_kernel(tri, cell, eps, out):
    """Set out[i, j, k] = 1 for every cell whose box shrunk by eps meets a triangle
    (separating axis test); per triangle only the columns its projection meets and,
    per column, only the layers its plane spans there are tested."""
    cx, cy, cz = cell[0], cell[1], cell[2]
    hx, hy, hz = cx / 2 - eps, cy / 2 - eps, cz / 2 - eps
    gx, gy, gz = out.shape
    for t in prange(tri.shape[0]):
        x0, y0, z0 = tri[t, 0, 0], tri[t, 0, 1], tri[t, 0, 2]
        x1, y1, z1 = tri[t, 1, 0], tri[t, 1, 1], tri[t, 1, 2]
        x2, y2, z2 = tri[t, 2, 0], tri[t, 2, 1], tri[t, 2, 2]
        xmin, xmax = min(x0, x1, x2), max(x0, x1, x2)
        ymin, ymax = min(y0, y1, y2), max(y0, y1, y2)
        zmin, zmax = min(z0, z1, z2), max(z0, z1, z2)
        i0, i1 = _cell_range(xmin, xmax, cx, gx)
        j0, j1 = _cell_range(ymin, ymax, cy, gy)
        k0, k1 = _cell_range(zmin, zmax, cz, gz)
        if i0 > i1 or j0 > j1 or k0 > k1:
            continue
        nx = (y1 - y0) * (z2 - z0) - (z1 - z0) * (y2 - y0)
        ny = (z1 - z0) * (x2 - x0) - (x1 - x0) * (z2 - z0)
        nz = (x1 - x0) * (y2 - y0) - (y1 - y0) * (x2 - x0)
        margin = eps + 1e-9 * (zmax - zmin + abs(z0))
        for i in range(i0, i1 + 1):
            mx = (i + 0.5) * cx
            for j in range(j0, j1 + 1):
                my = (j + 0.5) * cy
                if not _tri_column(x0 - mx, y0 - my, x1 - mx, y1 - my, x2 - mx, y2 - my,
                                   hx, hy):
                    continue
                lo, hi = zmin, zmax
                if nz != 0.0:
                    xa, xb = max(i * cx, xmin), min((i + 1) * cx, xmax)
                    ya, yb = max(j * cy, ymin), min((j + 1) * cy, ymax)
                    za = z0 - (nx * (xa - x0) + ny * (ya - y0)) / nz
                    zb = z0 - (nx * (xb - x0) + ny * (ya - y0)) / nz
                    zc = z0 - (nx * (xa - x0) + ny * (yb - y0)) / nz
                    zd = z0 - (nx * (xb - x0) + ny * (yb - y0)) / nz
                    lo = max(lo, min(za, zb, zc, zd) - margin)
                    hi = min(hi, max(za, zb, zc, zd) + margin)
                ka, kb = _cell_range(lo, hi, cz, gz)
                ka, kb = max(ka, k0), min(kb, k1)
                for k in range(ka, kb + 1):
                    mz = (k + 0.5) * cz
                    if out[i, j, k] == 0 and _tri_box(
                            x0 - mx, y0 - my, z0 - mz, x1 - mx, y1 - my, z1 - mz,
                            x2 - mx, y2 - my, z2 - mz, nx, ny, nz, hx, hy, hz):
                        out[i, j, k] = 1


@njit(cache=True, inline="always")
def _solid_angle(ax, ay, az, bx, by, bz, qx, qy, qz):
    """Signed solid angle of the triangle (a, b, q) seen from the origin:
    2 atan2(det[a b q], |a||b||q| + (a.b)|q| + (b.q)|a| + (q.a)|b|)
    (van Oosterom & Strackee)."""
    la = math.sqrt(ax * ax + ay * ay + az * az)
    lb = math.sqrt(bx * bx + by * by + bz * bz)
    lc = math.sqrt(qx * qx + qy * qy + qz * qz)
    det = ax * (by * qz - bz * qy) - ay * (bx * qz - bz * qx) + az * (bx * qy - by * qx)
    den = (la * lb * lc + (ax * bx + ay * by + az * bz) * lc
           + (bx * qx + by * qy + bz * qz) * la + (qx * ax + qy * ay + qz * az) * lb)
    return 2.0 * math.atan2(det, den)


@njit(cache=True, parallel=True)
def _cap_kernel(points, cap, weight):
    """Per point: sum over cap triangles of weight * (solid angle / 4 pi minus the
    signed crossing of the ray from the point down along z), the crossing counted
    like :func:`_ray_kernel` (+1 entering, shared edges once)."""
    n = points.shape[0]
    out = np.empty(n, dtype=np.float64)
    for p in prange(n):
        px, py, pz = points[p, 0], points[p, 1], points[p, 2]
        acc = 0.0
        for t in range(cap.shape[0]):
            x0, y0, z0 = cap[t, 0, 0], cap[t, 0, 1], cap[t, 0, 2]
            x1, y1, z1 = cap[t, 1, 0], cap[t, 1, 1], cap[t, 1, 2]
            x2, y2, z2 = cap[t, 2, 0], cap[t, 2, 1], cap[t, 2, 2]
            value = _solid_angle(x0 - px, y0 - py, z0 - pz, x1 - px, y1 - py, z1 - pz,
                                 x2 - px, y2 - py, z2 - pz) / (4.0 * math.pi)
            n_c = (x1 - x0) * (y2 - y0) - (y1 - y0) * (x2 - x0)
            if n_c != 0.0:
                s = _edge_sign(x0, y0, x1, y1, px, py)
                if s != 0 and _edge_sign(x1, y1, x2, y2, px, py) == s \
                        and _edge_sign(x2, y2, x0, y0, px, py) == s:
                    n_a = (y1 - y0) * (z2 - z0) - (z1 - z0) * (y2 - y0)
                    n_b = (z1 - z0) * (x2 - x0) - (x1 - x0) * (z2 - z0)
                    h = z0 - (n_a * (px - x0) + n_b * (py - y0)) / n_c
                    if h < pz:
                        value += s
            acc += weight[t] * value
        out[p] = acc
    return out


@njit(cache=True, parallel=True)
def _gwn_kernel(points, tri):
    """Generalized winding number of each point: sum over triangles of the signed
    solid angle (:func:`_solid_angle`), divided by 4 pi."""
    n = points.shape[0]
    out = np.empty(n, dtype=np.float64)
    for p in prange(n):
        px, py, pz = points[p, 0], points[p, 1], points[p, 2]
        acc = 0.0
        for t in range(tri.shape[0]):
            acc += _solid_angle(tri[t, 0, 0] - px, tri[t, 0, 1] - py, tri[t, 0, 2] - pz,
                                tri[t, 1, 0] - px, tri[t, 1, 1] - py, tri[t, 1, 2] - pz,
                                tri[t, 2, 0] - px, tri[t, 2, 1] - py, tri[t, 2, 2] - pz)
        out[p] = acc / (4.0 * math.pi)
    return out
