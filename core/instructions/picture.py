"""The instructions' isometric view, and printed parts drawn as what they are.

:func:`screen` is the picture projection of :mod:`core.instructions.page` (view
from the front left, above: direction ``(1, 1, -1)``, the view of
:mod:`core.instructions.render`).  A printed part is not a block: it is the model inside
its bricks, with holes, rings and curved faces.  :func:`part_faces` draws
its mesh as flat-shaded triangles, cut along the grid planes so that every
piece lies inside one brick (or one column of a split brick) and can be
painted in that brick's slot of the painter's order, back to front within
it; :func:`outline` is the true outline of its picture (the union of its
projected triangles, holes included) as SVG path data, which the page
draws over everything while the part is being inserted.
"""

from __future__ import annotations

import numpy as np

#: Picture directions: screen right and screen down of a model vector (mm).
SQ2, SQ6 = np.sqrt(2.0), np.sqrt(6.0)
#: View direction towards the scene (far side = larger depth).
VIEW = np.array([1.0, 1.0, -1.0]) / np.sqrt(3.0)
#: Shade levels of a printed part's faces: 0 the dark -x side, SHADES // 2 the
#: -y side, SHADES - 1 the lit top (the three faces of a drawn box).
SHADES = 9
#: Faces whose normals differ by more than this (degrees) meet at a drawn edge.
CREASE_DEG = 35.0
#: Depth (mm) within which faces are painted grouped by shade, not strictly back to front.
DEPTH_SLAB_MM = 0.5
#: Picture mm per pixel of the raster :func:`outline` traces.
OUTLINE_RES_MM = 0.2


def screen(points_mm: np.ndarray) -> np.ndarray:
    """Picture coordinates (..., 2), x right and y down, of model points (..., 3) in mm."""
    p = np.asarray(points_mm, dtype=float)
    return np.stack([(p[..., 0] - p[..., 1]) / SQ2,
                     -(p[..., 0] + p[..., 1] + 2.0 * p[..., 2]) / SQ6], axis=-1)


def fmt(v: float) -> str:
    """A picture coordinate with one decimal (mm), no trailing zeros."""
    s = f"{v:.1f}".rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s


def _pair(p) -> str:
    """``x y`` of a picture point for SVG path data, the space left out before a minus."""
    y = fmt(p[1])
    return fmt(p[0]) + ("" if y.startswith("-") else " ") + y


def split_triangles(tri: np.ndarray, axis: int, value: float, keep=None):
    """Triangles (n, 3, 3) cut by the plane ``p[axis] == value``: every triangle that
    crosses it becomes three (one on the lone vertex's side, two on the other),
    windings kept.  ``keep`` (n, ...) per-triangle data is repeated alongside;
    returns ``(triangles, keep)``."""
    s = tri[:, :, axis] - value
    pos = s > 0
    cross = pos.any(axis=1) & ~pos.all(axis=1)
    if not cross.any():
        return tri, keep
    t, sc = tri[cross], s[cross]
    pc = pos[cross]
    # the lone vertex is the one whose side differs from the other two
    lone = np.where(pc.sum(axis=1) == 1, np.argmax(pc, axis=1), np.argmin(pc, axis=1))
    roll = (lone[:, None] + np.arange(3)[None, :]) % 3
    t = np.take_along_axis(t, roll[:, :, None], axis=1)
    sc = np.take_along_axis(sc, roll, axis=1)
    a, b, c = t[:, 0], t[:, 1], t[:, 2]
    p = a + (b - a) * (sc[:, 0] / (sc[:, 0] - sc[:, 1]))[:, None]
    q = a + (c - a) * (sc[:, 0] / (sc[:, 0] - sc[:, 2]))[:, None]
    new = np.concatenate([np.stack([a, p, q], 1), np.stack([p, b, c], 1), np.stack([p, c, q], 1)])
    out = np.concatenate([tri[~cross], new])
    if keep is not None:
        kc = keep[cross]
        keep = np.concatenate([keep[~cross], kc, kc, kc])
    return out, keep


def split_segments(seg: np.ndarray, axis: int, value: float) -> np.ndarray:
    """Segments (n, 2, 3) cut in two where they cross the plane ``p[axis] == value``."""
    s = seg[:, :, axis] - value
    cross = (s[:, 0] > 0) != (s[:, 1] > 0)
    if not cross.any():
        return seg
    a, b = seg[cross, 0], seg[cross, 1]
    m = a + (b - a) * (s[cross, 0] / (s[cross, 0] - s[cross, 1]))[:, None]
    return np.concatenate([seg[~cross], np.stack([a, m], 1), np.stack([m, b], 1)])


def shade_colours(top: str, left: str, front: str) -> list[str]:
    """The SHADES colours (``#rrggbb``) from the ``left`` (level 0) over the ``front``
    (the middle level) to the ``top`` colour (the last level), blended linearly."""
    rgb = [np.array([int(c[i:i + 2], 16) for i in (1, 3, 5)], float) for c in (left, front, top)]
    out = []
    for level in range(SHADES):
        t = 2.0 * level / (SHADES - 1)
        c = rgb[0] + (rgb[1] - rgb[0]) * t if t <= 1 else rgb[1] + (rgb[2] - rgb[1]) * (t - 1)
        out.append("#" + "".join(f"{int(round(v)):02x}" for v in c))
    return out


def shade_levels(normals: np.ndarray) -> np.ndarray:
    """Shade level 0 .. SHADES - 1 of faces with unit ``normals`` (n, 3): a blend of
    the box faces' shades by how much each face looks up (+z), to the front (-y)
    and to the left (-x); what looks elsewhere takes the dark side's shade."""
    n = np.asarray(normals, float)
    up, front, left = np.maximum(n[:, 2], 0) ** 2, np.maximum(-n[:, 1], 0) ** 2, np.maximum(-n[:, 0], 0) ** 2
    rest = np.maximum(1.0 - up - front - left, 0.0)
    t = (up * 1.0 + front * 0.5) / np.maximum(up + front + left + rest, 1e-12)
    return np.clip(np.rint(t * (SHADES - 1)), 0, SHADES - 1).astype(np.int64)


def _visible(mesh, origin):
    """Front-facing triangles (picture side) of ``mesh`` relative to ``origin``, their
    shade levels, and the edges to draw: creases between faces whose normals differ by
    more than CREASE_DEG with one of them front-facing, and contours (a front-facing
    face next to a back-facing one)."""
    normals = np.asarray(mesh.face_normals, float)
    facing = normals @ VIEW < -1e-9
    tri = np.asarray(mesh.triangles, float)[facing] - origin
    shades = shade_levels(normals[facing])
    pairs = np.asarray(mesh.face_adjacency, np.int64).reshape(-1, 2)
    angles = np.asarray(mesh.face_adjacency_angles, float)
    fa, fb = facing[pairs[:, 0]], facing[pairs[:, 1]]
    drawn = (fa != fb) | ((fa | fb) & (angles > np.radians(CREASE_DEG)))
    edges = np.asarray(mesh.vertices, float)[np.asarray(mesh.face_adjacency_edges)[drawn]] - origin
    return tri, shades, edges.reshape(-1, 2, 3)


def part_faces(mesh, origin, cell, piece_of_cell: np.ndarray, cells: np.ndarray) -> dict[int, list[tuple[str, str]]]:
    """The picture of one printed part's ``mesh`` (model mm), split into the pieces that
    draw it.

    ``origin``/``cell`` are the grid's; ``piece_of_cell`` is grid-shaped, the
    index of the drawing piece each cell belongs to (-1 elsewhere), ``cells``
    (m, 3) the part's cells.  Every front-facing triangle and every drawn
    edge is cut along the grid planes between the part's pieces and goes to
    the piece of the part's cell it lies in (a stud on top to the cell under
    it).
    Returns, per piece index, SVG elements back to front as ``(class, path
    data)``: ``"m<level>"`` for faces of that shade level (consecutive faces
    of one level share a path), ``"me"`` for edges.
    """
    origin = np.asarray(origin, float)
    cell = np.asarray(cell, float)
    tri, shades, edges = _visible(mesh, origin)
    for axis, k in _seams(piece_of_cell):
        tri, shades = split_triangles(tri, axis, k * cell[axis], shades)
        edges = split_segments(edges, axis, k * cell[axis])
    area = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    tri, shades = tri[area > 1e-9], shades[area > 1e-9]
    edges = edges[np.linalg.norm(edges[:, 1] - edges[:, 0], axis=1) > 1e-6]
    tri_piece = _piece_of_points(tri.mean(axis=1), cell, piece_of_cell, cells)
    edge_piece = _piece_of_points(edges.mean(axis=1), cell, piece_of_cell, cells)
    # edges a hair nearer than the faces they bound, so both faces are painted first
    depth = np.concatenate([tri.mean(axis=1) @ VIEW, edges.mean(axis=1) @ VIEW - 0.05])
    piece = np.concatenate([tri_piece, edge_piece])
    kind = np.concatenate([shades, np.full(len(edges), SHADES)])
    pts_tri = screen(tri)
    pts_edge = screen(edges)
    # back to front; faces less than DEPTH_SLAB_MM apart in depth hardly hide one
    # another, so within such a slab faces of one shade go together (fewer paths)
    order = np.lexsort((kind, -np.floor(depth / DEPTH_SLAB_MM), piece))
    out: dict[int, list[tuple[str, str]]] = {}
    run_piece, run_kind, run = None, None, []
    n_tri = len(tri)

    def flush():
        if run:
            out.setdefault(run_piece, []).append(("me" if run_kind == SHADES else f"m{run_kind}", "".join(run)))

    for i in order.tolist():
        p, k = int(piece[i]), int(kind[i])
        if p != run_piece or k != run_kind:
            flush()
            run_piece, run_kind, run = p, k, []
        if i < n_tri:
            a, b, c = pts_tri[i]
            run.append(f"M{_pair(a)}l{_pair(b - a)}l{_pair(c - b)}z")
        else:
            a, b = pts_edge[i - n_tri]
            run.append(f"M{_pair(a)}l{_pair(b - a)}")
    flush()
    return out


def _seams(piece_of_cell: np.ndarray) -> list[tuple[int, int]]:
    """The grid planes ``(axis, k)`` (``p[axis] == k * cell``) between two cells of
    different drawing pieces (both >= 0)."""
    out = []
    for axis in range(3):
        a = np.moveaxis(piece_of_cell, axis, 0)
        differ = (a[:-1] >= 0) & (a[1:] >= 0) & (a[:-1] != a[1:])
        out += [(axis, int(k) + 1) for k in np.flatnonzero(differ.reshape(len(differ), -1).any(axis=1))]
    return out


def _piece_of_points(points: np.ndarray, cell, piece_of_cell: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """The drawing piece of each point: that of its cell, else of the cell under it
    (a stud stands in the cell above its brick), else of the part's nearest cell."""
    shape = np.array(piece_of_cell.shape)
    ijk = np.floor(points / cell).astype(np.int64)
    out = np.full(len(points), -1, np.int64)
    for dk in (0, -1):
        c = ijk + [0, 0, dk]
        inside = np.all((c >= 0) & (c < shape), axis=1) & (out < 0)
        out[inside] = piece_of_cell[tuple(c[inside].T)]
    lost = out < 0
    if lost.any():
        centres = (cells + 0.5) * cell
        near = np.argmin(((points[lost, None, :] - centres[None]) ** 2).sum(axis=2), axis=1)
        out[lost] = piece_of_cell[tuple(cells[near].T)]
    return out


def outline(mesh, origin, res_mm: float = OUTLINE_RES_MM) -> str:
    """SVG path data of the outline of ``mesh``'s picture (the union of its projected
    triangles, relative to the grid ``origin``): every boundary, holes included,
    traced on an antialiased raster of ``res_mm`` and simplified to within half of it."""
    tri = screen(np.asarray(mesh.triangles, float) - np.asarray(origin, float))
    if len(tri) == 0:
        return ""
    lo = tri.reshape(-1, 2).min(axis=0) - 3 * res_mm
    hi = tri.reshape(-1, 2).max(axis=0) + 3 * res_mm
    w, h = (np.ceil((hi - lo) / res_mm)).astype(int)
    import contourpy                       # drawing libraries: only where a part has an outline
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.collections import PolyCollection
    from matplotlib.figure import Figure
    fig = Figure(figsize=(w / 100.0, h / 100.0), dpi=100)
    canvas = FigureCanvasAgg(fig)
    ax = fig.add_axes((0, 0, 1, 1))
    ax.set_axis_off()
    ax.set_xlim(lo[0], lo[0] + w * res_mm)
    ax.set_ylim(lo[1] + h * res_mm, lo[1])
    ax.add_collection(PolyCollection(tri, facecolors="k", edgecolors="none", antialiased=True))
    canvas.draw()
    # antialiased coverage, traced at one half: the outline to a fraction of a pixel
    coverage = 1.0 - np.asarray(canvas.buffer_rgba())[:h, :w, 0] / 255.0
    lines = contourpy.contour_generator(z=coverage).lines(0.5)
    out = []
    for line in lines:
        pts = lo + (np.asarray(line, float) + 0.5) * res_mm
        pts = _simplify(pts, res_mm / 2)
        if len(pts) < 3:
            continue
        out.append("M" + "L".join(f"{fmt(x)} {fmt(y)}" for x, y in pts) + "z")
    return "".join(out)


def _simplify(pts: np.ndarray, tol: float) -> np.ndarray:
    """Ramer-Douglas-Peucker: the points of the polyline ``pts`` needed to stay within ``tol``."""
    keep = np.zeros(len(pts), bool)
    keep[[0, -1]] = True
    stack = [(0, len(pts) - 1)]
    while stack:
        a, b = stack.pop()
        if b - a < 2:
            continue
        seg = pts[b] - pts[a]
        rel = pts[a + 1:b] - pts[a]
        norm = np.hypot(*seg)
        dist = np.abs(seg[0] * rel[:, 1] - seg[1] * rel[:, 0]) / norm if norm > 0 else np.hypot(rel[:, 0], rel[:, 1])
        i = int(np.argmax(dist))
        if dist[i] > tol:
            m = a + 1 + i
            keep[m] = True
            stack += [(a, m), (m, b)]
    return pts[keep]
