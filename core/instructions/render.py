"""An isometric picture of a brick layout, drawn the way LEGO looks.

The layout is seen from the front left, above (view direction ``(1, 1, -1)``
in model mm, so the faces facing -x, -y and +z are visible), in true
proportions (cells are 8 x 8 x 3.2 mm).

Drawing is a painter's algorithm over unit cell faces, which is exact for
boxes on a grid: a ray along the view direction visits cells with
non-decreasing i and j and non-increasing k, so a cell can only hide cells
whose ``8 i + 8 j - 3.2 k`` (its depth) is larger, and drawing cells from
the largest depth to the smallest paints every hidden face before what
hides it.  Per cell, the exposed visible faces are drawn (a face whose
neighbour cell is empty), then the outline segments of those faces that lie
on a brick boundary (the neighbouring face in the same plane is missing or
belongs to another brick), and the studs on exposed tops of LEGO bricks are
drawn with the empty cell above them.  Everything is one
:class:`~matplotlib.collections.PolyCollection` built with numpy, and the
figure is an Agg canvas, so pyplot's global state is never touched.

Colours are the ones :mod:`core.colours` decides for the ``palette``: with
``"bom"`` (the default) every LEGO brick in the colour the bill of
materials orders, with ``"random"`` a LEGO colour per brick, neighbours
different.  Printed bricks are the printed parts' orange and have no studs
drawn.
"""

from __future__ import annotations

import os
import textwrap

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import PolyCollection
from matplotlib.figure import Figure
from scipy import ndimage

from core.colours import PRINTED_COLOR, brick_colours as decided_colours, rgb as colour_rgb
from core.model import Layout

#: Colour of printed bricks: the printed parts' colour of every output.
PRINTED_RGB = np.array(colour_rgb(PRINTED_COLOR))

#: Background and outline colours.
BACKGROUND_RGB = (1.0, 1.0, 1.0)
OUTLINE_RGB = (0.08, 0.08, 0.1)

#: Brightness of the faces facing -x, -y and +z (a light from above left).
SHADE = np.array([0.78, 0.6, 1.0])

#: Stud diameter and height in mm.
STUD_DIAMETER_MM = 4.8
STUD_HEIGHT_MM = 1.7

#: View direction in model mm (towards the scene), screen right and up.
VIEW = np.array([1.0, 1.0, -1.0]) / np.sqrt(3.0)
RIGHT = np.array([1.0, -1.0, 0.0]) / np.sqrt(2.0)
UP = np.array([1.0, 1.0, 2.0]) / np.sqrt(6.0)

#: Visible face directions and their corners (unit cell coordinates, in
#: order around the face).
FACE_NORMALS = np.array([(-1, 0, 0), (0, -1, 0), (0, 0, 1)])
FACE_CORNERS = np.array([
    [(0, 0, 0), (0, 1, 0), (0, 1, 1), (0, 0, 1)],
    [(0, 0, 0), (1, 0, 0), (1, 0, 1), (0, 0, 1)],
    [(0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)],
], dtype=float)

#: Studs narrower than this in the picture (pixels) are not drawn (a 2 m part at
#: 1200 x 900 pixels: half a million studs of 2 pixels).
MIN_STUD_PX = 2.5

#: Vertices per stud half-outline; every polygon is padded to 2 * this.
_ARC = 9
_VERTS = 2 * _ARC


def _edge_directions() -> np.ndarray:
    """(3, 4, 3): the in-plane direction away from the face across each edge."""
    centre = FACE_CORNERS.mean(axis=1, keepdims=True)
    middle = (FACE_CORNERS + np.roll(FACE_CORNERS, -1, axis=1)) / 2
    return np.rint(2 * (middle - centre)).astype(np.int64)


def _project(points_mm: np.ndarray) -> np.ndarray:
    """Screen coordinates (..., 2) of model points (..., 3) in mm."""
    return np.stack([points_mm @ RIGHT, points_mm @ UP], axis=-1)


def _pad(polys: np.ndarray) -> np.ndarray:
    """Repeat the last vertex so that every polygon has ``_VERTS`` vertices."""
    extra = _VERTS - polys.shape[1]
    return np.concatenate([polys, np.repeat(polys[:, -1:], extra, axis=1)], axis=1)


def brick_colours(layout: Layout, labels: np.ndarray, palette: str = "bom") -> np.ndarray:
    """RGB (n_bricks, 3) of the bricks as drawn with ``palette``: the colours
    :func:`core.colours.brick_colours` decides (``labels`` is ``layout.labels()``)."""
    return decided_colours(layout, palette, labels)


def _outside(empty: np.ndarray) -> np.ndarray:
    """The cells of the bool grid ``empty`` (padded by one empty cell all round) that
    are joined to the outside through empty cells (6-connected): an enclosed cavity
    (a hollowed part's inside) is not, and nothing facing it can be seen."""
    lab, _ = ndimage.label(empty)
    return lab == lab[0, 0, 0]


def _scene(layout: Layout, palette: str = "bom", studs: bool = True, rgb: np.ndarray | None = None,
           geometry: tuple | None = None):
    """Polygons (n, _VERTS, 2) in screen mm in drawing order, their kinds and RGB: the
    polygons of :func:`_geometry` (or ``geometry``, its answer for this layout and ``studs``)
    in each brick's colour (``rgb``, else the ``palette``'s), shaded by the side they face."""
    polys, kinds, owner, shade = _geometry(layout, studs) if geometry is None else geometry
    rgb = (brick_colours(layout, layout.labels(), palette) if rgb is None
           else np.asarray(rgb, dtype=float))
    colours = rgb[np.maximum(owner, 0)] * shade[:, None]
    colours[owner < 0] = 0.0
    return polys, kinds, colours


def _geometry(layout: Layout, studs: bool = True):
    """Polygons (n, _VERTS, 2) in screen mm in drawing order, their kinds, the brick each
    belongs to (its index in ``layout.bricks``; -1 for an outline segment) and its shade.

    kind 0 = face, 1 = outline segment, 2 = stud side, 3 = stud top.  Faces
    and studs facing an enclosed cavity (:func:`_outside`) are left out, and
    all studs when ``studs`` is False.
    """
    cell = np.asarray(layout.grid.cell, dtype=float)
    labels = layout.labels()
    padded = np.pad(labels, 1, constant_values=-1)
    outside = _outside(padded < 0)
    is_lego = np.array([b.kind != "printed" for b in layout.bricks], dtype=bool)
    near_outside = outside[:-2, 1:-1, 1:-1] | outside[1:-1, :-2, 1:-1] | outside[1:-1, 1:-1, 2:]
    cells = np.argwhere((labels >= 0) & near_outside)
    own = labels[tuple(cells.T)]
    at = cells + 1

    def label_at(offset) -> np.ndarray:
        p = at + offset
        return padded[p[..., 0], p[..., 1], p[..., 2]]

    def open_at(offset) -> np.ndarray:
        p = at + offset
        return outside[p[..., 0], p[..., 1], p[..., 2]]

    def depth(index: np.ndarray) -> np.ndarray:
        return ((index + 0.5) * cell) @ VIEW

    edges = _edge_directions()
    polys, keys, sub, kinds, owner, shade = [], [], [], [], [], []
    for f, normal in enumerate(FACE_NORMALS):
        exposed = open_at(normal)
        c, lab = cells[exposed], own[exposed]
        corners = _project((c[:, None, :] + FACE_CORNERS[f][None]) * cell)
        polys.append(_pad(corners))
        keys.append(depth(c))
        sub.append(np.full(len(c), f))
        kinds.append(np.zeros(len(c), dtype=np.int64))
        owner.append(lab)
        shade.append(np.full(len(c), SHADE[f]))
        for e, t in enumerate(edges[f]):
            same = (label_at(t)[exposed] == lab) & (label_at(t + normal)[exposed] < 0)
            seg = corners[~same][:, [e, (e + 1) % 4]]
            polys.append(_pad(seg))
            keys.append(depth(c[~same]))
            sub.append(np.full(len(seg), 3))
            kinds.append(np.ones(len(seg), dtype=np.int64))
            owner.append(np.full(len(seg), -1))
            shade.append(np.zeros(len(seg)))

    tops = open_at(FACE_NORMALS[2]) & is_lego[own] & studs
    c = cells[tops]
    centre = (c + [0.5, 0.5, 1.0]) * cell
    r = STUD_DIAMETER_MM / 2
    lower = np.linspace(0.75 * np.pi, 1.75 * np.pi, _ARC)
    upper = np.linspace(-0.25 * np.pi, 0.75 * np.pi, _ARC)
    ring = np.linspace(0, 2 * np.pi, _VERTS, endpoint=False)

    def circle(theta, z) -> np.ndarray:
        pts = np.stack([r * np.cos(theta), r * np.sin(theta), np.full_like(theta, z)], axis=-1)
        return _project(centre[:, None, :] + pts[None])

    side = np.concatenate([circle(lower, 0.0), circle(upper, STUD_HEIGHT_MM)], axis=1)
    top = circle(ring, STUD_HEIGHT_MM)
    above = depth(c + [0, 0, 1])
    for kind, poly, factor in ((2, side, SHADE[1]), (3, top, SHADE[2])):
        polys.append(poly)
        keys.append(above)
        sub.append(np.full(len(c), kind + 2))
        kinds.append(np.full(len(c), kind))
        owner.append(own[tops])
        shade.append(np.full(len(c), factor))

    keys, sub = np.concatenate(keys), np.concatenate(sub)
    order = np.lexsort((sub, -np.round(keys, 6)))
    return (np.concatenate(polys)[order], np.concatenate(kinds)[order],
            np.concatenate(owner).astype(np.int64)[order], np.concatenate(shade)[order])


def _drawable(title: str) -> str:
    """``title`` with each character the picture's font has no glyph for (an emoji, a
    script the font lacks, a name that is not UTF-8) shown as ``?``: matplotlib would
    draw an empty box and warn on stderr for each one."""
    from matplotlib import font_manager, ft2font

    try:
        font = ft2font.FT2Font(font_manager.findfont(font_manager.FontProperties()))
        have = set(font.get_charmap())
    except (OSError, RuntimeError, ValueError):
        return title.encode("ascii", "replace").decode("ascii")
    return "".join(c if c.isspace() or ord(c) in have else "?" for c in str(title))


def _fitted(fig: Figure, title: str, fontsize: float, width_px: float) -> tuple[str, int]:
    """``title`` broken at spaces into the fewest lines (up to 4) that are each at most
    ``width_px`` wide at ``fontsize`` on ``fig``, and how many lines that is."""
    renderer = fig.canvas.get_renderer()
    for lines in range(1, 5):
        text = textwrap.fill(title, width=-(-len(title) // lines), break_long_words=False) if lines > 1 else title
        probe = fig.text(0, 0, text, fontsize=fontsize, parse_math=False)
        wide = probe.get_window_extent(renderer).width
        probe.remove()
        if wide <= width_px:
            break
    return text, text.count("\n") + 1


def render_layout(layout: Layout, path: str | os.PathLike, size_px=(1200, 900),
                  title: str | None = None, palette: str = "bom",
                  colours: np.ndarray | None = None, cache: dict | None = None) -> None:
    """Write an isometric PNG picture of ``layout`` to ``path``, ``size_px`` (width, height).

    Bricks are shaded boxes with black outlines along brick edges and studs
    on their exposed tops (unless they would be under :data:`MIN_STUD_PX` wide), in the colours :mod:`core.colours` decides for
    ``palette`` (printed bricks orange), or ``colours`` (RGB per brick, e.g.
    :func:`core.colours.stress_rgb`); ``title`` goes above.  ``cache`` (a dict the caller
    keeps for one layout) holds the drawing's polygons for its next picture, in other colours.
    A layout without bricks gives a picture that says so.  Raises
    ValueError for a size that is not two integers from 16 to 20000 and
    FileNotFoundError for a path whose folder does not exist (the caller
    makes the folder).
    """
    try:
        width, height = (int(s) for s in size_px)
    except (TypeError, ValueError):
        raise ValueError(f"picture size must be two integers (width, height), got {size_px!r}") from None
    if width < 16 or height < 16 or width > 20000 or height > 20000:
        raise ValueError(f"picture size must be 16 to 20000 pixels each way, got {width} x {height}")
    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        raise FileNotFoundError(f"cannot write the picture: folder {folder} does not exist")

    dpi = 100
    fig = Figure(figsize=(width / dpi, height / dpi), dpi=dpi, facecolor=BACKGROUND_RGB)
    FigureCanvasAgg(fig)
    top_margin = 0.99
    if title:
        fontsize = min(16.0, max(7.0, 0.03 * height))
        text, lines = _fitted(fig, _drawable(title), fontsize, 0.98 * width)
        line_px = fontsize * 1.25 * dpi / 72
        top_margin = 1.0 - (lines * line_px + 0.03 * height) / height
        fig.text(0.5, 1.0 - (lines * line_px / 2 + 0.015 * height) / height, text, ha="center",
                 va="center", parse_math=False, fontsize=fontsize, multialignment="center")
    ax = fig.add_axes((0.01, 0.01, 0.98, top_margin - 0.01))
    ax.set_axis_off()

    if not layout.bricks:
        ax.text(0.5, 0.5, "no bricks", ha="center", va="center", fontsize=14,
                color=(0.4, 0.4, 0.4), transform=ax.transAxes)
        fig.savefig(path, format="png", dpi=dpi, facecolor=BACKGROUND_RGB)
        return

    corners = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], dtype=float)
    extent = _project(corners * np.asarray(layout.grid.shape) * np.asarray(layout.grid.cell))
    span_mm = np.maximum(extent.max(axis=0) - extent.min(axis=0), 1e-9)
    stud_px = STUD_DIAMETER_MM * min(0.98 * width / span_mm[0],
                                     (top_margin - 0.02) * height / span_mm[1])
    studs = bool(stud_px >= MIN_STUD_PX)
    geometry = None if cache is None else cache.get(studs)
    if geometry is None:
        geometry = _geometry(layout, studs)
        if cache is not None:
            cache[studs] = geometry
    polys, kinds, colours = _scene(layout, palette, studs, rgb=colours, geometry=geometry)
    lo, hi = polys.reshape(-1, 2).min(axis=0), polys.reshape(-1, 2).max(axis=0)
    span = np.maximum(hi - lo, 1e-9) * 1.04
    box_w, box_h = 0.98 * width, (top_margin - 0.01) * height
    px_per_mm = min(box_w / span[0], box_h / span[1])
    centre = (lo + hi) / 2
    ax.set_xlim(centre[0] - box_w / px_per_mm / 2, centre[0] + box_w / px_per_mm / 2)
    ax.set_ylim(centre[1] - box_h / px_per_mm / 2, centre[1] + box_h / px_per_mm / 2)

    pt_per_px = 72.0 / dpi
    outline = np.clip(0.3 * px_per_mm, 0.4, 1.6) * pt_per_px
    face = np.ones((len(kinds), 4))
    face[:, :3] = np.clip(colours, 0, 1)
    edge = face.copy()
    segment = kinds == 1
    face[segment, 3] = 0.0
    edge[segment, :3] = OUTLINE_RGB
    stud_top = kinds == 3
    edge[stud_top, :3] = np.clip(colours[stud_top] * 0.55, 0, 1)
    widths = np.zeros(len(kinds))
    widths[segment] = outline
    widths[stud_top] = 0.5 * outline
    widths[kinds == 2] = 0.5 * pt_per_px
    ax.add_collection(PolyCollection(polys, closed=True, facecolors=face, edgecolors=edge,
                                     linewidths=widths, antialiaseds=kinds != 0,
                                     capstyle="round", joinstyle="round"))
    fig.savefig(path, format="png", dpi=dpi, facecolor=BACKGROUND_RGB)
