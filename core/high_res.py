"""Marking high-res regions: which bricks of a layout become printed.

A user marks what must be exact by a box in model mm, by a region solid
(an STL/OBJ/PLY/3MF/STEP/FCStd file in the model's units), or by brick ids
through the API.  A mark *touches* a cell when the two share positive
volume; every brick with a touched filled cell becomes printed (paper,
"Converting Lego bricks into 3D printable bricks").  By default the marked
bricks of one connected region form one printed part (:func:`groups`);
bricks are connected when they touch face to face, side by side or one on
the other with overlapping footprints.  Marks by box or solid are made
before the layout: :func:`core.layout.greedy.lay_out_around` lays out the marked cells and the
rest separately, so printed and LEGO bricks meet cleanly on the region's
boundary and a printed part is no larger than the cells the region touches.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh
from scipy import ndimage, sparse
from scipy.sparse.csgraph import connected_components

from core import voxelize
from core.errors import InputError
from core.io import meshes as mesh_io
from core.model import Grid, Layout

#: A box must overlap a cell by more than this (mm) along every axis to touch it.
EPS_MM = 1e-6
#: Cell numbers a box is clipped to (each way): far beyond any grid, well within int64.
CELL_REACH = 1e12
#: A brick marked by its id is recorded as its box shrunk by this much (mm) on every
#: side, so that the box touches exactly the brick's own cells.
BRICK_INSET_MM = 1e-3


def parse_box(text: str) -> np.ndarray:
    """The box ``"X0,Y0,Z0,X1,Y1,Z1"`` (model mm) as a (2, 3) array of min and max corner.

    The corners may be given in any order per axis; the box must have
    positive volume.  Raises :class:`InputError` for anything else.
    """
    try:
        values = [float(v) for v in str(text).split(",")]
    except ValueError:
        raise InputError(f"--high-res {text!r}: expected six numbers X0,Y0,Z0,X1,Y1,Z1 in mm") from None
    if len(values) != 6 or not np.all(np.isfinite(values)):
        raise InputError(f"--high-res {text!r}: expected six finite numbers X0,Y0,Z0,X1,Y1,Z1 in mm")
    corners = np.array(values).reshape(2, 3)
    box = np.stack([corners.min(axis=0), corners.max(axis=0)])
    if np.any(box[1] - box[0] <= 0):
        raise InputError(f"--high-res {text!r}: the box has no volume")
    return box


def as_box(value) -> np.ndarray:
    """A box given as ``"X0,Y0,Z0,X1,Y1,Z1"``, six numbers or a (2, 3) array, as
    :func:`parse_box` returns it; InputError for anything else."""
    if isinstance(value, str):
        return parse_box(value)
    try:
        flat = np.asarray(value, dtype=np.float64).ravel()
    except (TypeError, ValueError):
        flat = np.zeros(0)
    return parse_box(",".join(repr(float(v)) for v in flat) if flat.size == 6 else repr(value))


def box_range(origin, cell, box) -> tuple[np.ndarray, np.ndarray]:
    """Cell indices ``first`` (inclusive) and ``stop`` (exclusive) per axis of the cells of
    the lattice ``origin + n * cell`` that share positive volume with ``box`` ((2, 3) mm);
    not clipped to any grid."""
    cell = np.asarray(cell, dtype=np.float64)
    rel = (np.asarray(box, dtype=np.float64) - origin) / cell
    rel = np.clip(rel, -CELL_REACH, CELL_REACH)     # a box of 1e300 mm holds the whole part
    eps = EPS_MM / cell
    return np.floor(rel[0] + eps).astype(np.int64), np.ceil(rel[1] - eps).astype(np.int64)


def box_cells(grid: Grid, box) -> np.ndarray:
    """Grid-shaped bool array: the cells that share positive volume with ``box`` ((2, 3) mm)."""
    first, stop = box_range(grid.origin, grid.cell, box)
    lo = np.clip(first, 0, grid.shape)
    hi = np.clip(stop, 0, grid.shape)
    out = np.zeros(grid.shape, dtype=bool)
    out[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]] = True
    return out


def load_region(region, units: str = "mm", scale: float = 1.0, up: str = "z") -> mesh_io.LoadedModel:
    """A region solid: ``region`` itself when already loaded, else the file loaded like a
    model (:func:`core.io.meshes.load_model`, turned as its model, where it stands: the driver
    moves it with its model); InputError for a file that cannot be loaded."""
    if isinstance(region, mesh_io.LoadedModel):
        return region
    return mesh_io.load_model(region, units=units, scale=scale, recentre=False, up=up)


def solid_cells(grid: Grid, path, units: str = "mm",
                scale: float = 1.0) -> np.ndarray:
    """Grid-shaped bool array: the cells the region solid in file ``path`` shares volume with.

    ``path`` may also be a region already loaded (:func:`load_region`).
    The solid is loaded like a model (:func:`core.io.meshes.load_model`) and
    legofied on the model's grid (same origin and shape), so the answer is
    exact in the same sense as legofy's.  Raises :class:`InputError` for a
    file that cannot be loaded.
    """
    region = load_region(path, units=units, scale=scale)
    return voxelize.legofy(region.mesh, cell=grid.cell, origin=grid.origin,
                           shape=np.array(grid.shape, dtype=np.int64),
                           closed=region.watertight).filled


def marked_cells(grid: Grid, boxes=(), solids=(), units: str = "mm",
                 scale: float = 1.0) -> np.ndarray:
    """Filled cells touched by any of ``boxes`` ((2, 3) arrays or "X0,..,Z1" strings) or
    region ``solids`` (file paths or loaded regions); a grid-shaped bool array."""
    return Regions.of(boxes, [load_region(p, units=units, scale=scale) for p in solids]).cells(grid)


@dataclass(frozen=True)
class Regions:
    """The high-res regions of a run in one frame (model mm): what a later iteration re-marks.

    ``boxes`` are (2, 3) arrays of min and max corner, ``solids`` pairs of
    a region mesh and whether it is closed (watertight).  Immutable: the
    methods return new Regions.
    """

    boxes: tuple = ()
    solids: tuple = ()

    @classmethod
    def of(cls, boxes=(), regions=()) -> "Regions":
        """Regions of boxes (any form :func:`as_box` takes) and loaded region solids
        (:class:`core.io.meshes.LoadedModel`); InputError for a bad box."""
        return cls(tuple(as_box(b) for b in boxes),
                   tuple((r.mesh, bool(r.watertight)) for r in regions))

    @classmethod
    def of_bricks(cls, layout: Layout, brick_ids) -> "Regions":
        """The boxes of the bricks ``brick_ids`` of ``layout`` (each shrunk by
        :data:`BRICK_INSET_MM`, so it marks exactly that brick's cells)."""
        by_id = {b.id: b for b in layout.bricks}
        grid = layout.grid
        boxes = []
        for i in brick_ids:
            b = by_id[int(i)]
            lo = grid.origin + np.asarray(b.cell) * grid.cell + BRICK_INSET_MM
            hi = grid.origin + (np.asarray(b.cell) + np.asarray(b.size)) * grid.cell - BRICK_INSET_MM
            boxes.append(np.stack([lo, hi]))
        return cls(tuple(boxes), ())

    def __add__(self, other: "Regions") -> "Regions":
        return Regions(self.boxes + other.boxes, self.solids + other.solids)

    def __bool__(self) -> bool:
        return bool(self.boxes or self.solids)

    def cells(self, grid: Grid) -> np.ndarray:
        """Grid-shaped bool array: the filled cells of ``grid`` that a box or solid shares
        volume with (solids legofied on the grid, :func:`core.voxelize.legofy`)."""
        out = np.zeros(grid.shape, dtype=bool)
        for box in self.boxes:
            out |= box_cells(grid, box)
        shape = np.array(grid.shape, dtype=np.int64)
        for mesh, closed in self.solids:
            out |= voxelize.legofy(mesh, cell=grid.cell, origin=grid.origin, shape=shape,
                                   closed=closed).filled
        return out & np.asarray(grid.filled, dtype=bool)

    def moved(self, transform) -> "Regions":
        """These regions moved by the 4x4 rigid ``transform``: a box stays a box when the
        rotation maps axes onto axes, otherwise it becomes a solid."""
        m = np.asarray(transform, dtype=np.float64)
        rot, shift = m[:3, :3], m[:3, 3]
        axis_aligned = np.allclose(np.abs(rot), np.round(np.abs(rot)), atol=1e-9)
        boxes, solids = [], []
        for box in self.boxes:
            if axis_aligned:
                corners = np.asarray(box) @ rot.T + shift
                boxes.append(np.stack([corners.min(axis=0), corners.max(axis=0)]))
            else:
                solids.append((trimesh.creation.box(bounds=box).apply_transform(m), True))
        for mesh, closed in self.solids:
            solids.append((mesh.copy().apply_transform(m), closed))
        return Regions(tuple(boxes), tuple(solids))


def anchor(grid: Grid, cells: np.ndarray) -> np.ndarray:
    """The marked ``cells`` plus *anchor tabs*: cells that let every marked region clamp.

    LEGO holds only vertically: a marked region that touches unmarked bricks
    only side by side (a screw seat standing on the floor through every
    layer, say) would be a loose piece.  For each such region (6-connected
    marked cells with no unmarked filled cell directly above or below any
    of them) this adds up to four tab cells (:func:`_tabs`: one on each side)
    next to it in one layer, each an unmarked filled cell with an unmarked
    filled cell directly above (the region's lowest such layer) or, failing
    that, directly below (its highest); the printed part then reaches under
    (or over) its LEGO neighbours and clamps there through its connectors
    (:mod:`core.parts.connectors`).  Regions with a vertical contact, and regions
    no tab can anchor, are left as they are.  Returns a new bool array.
    """
    filled = np.asarray(grid.filled, dtype=bool)
    marked = np.asarray(cells, dtype=bool) & filled
    free = filled & ~marked
    above = np.zeros_like(free)
    above[:, :, :-1] = free[:, :, 1:]
    below = np.zeros_like(free)
    below[:, :, 1:] = free[:, :, :-1]
    labels, count = ndimage.label(marked, structure=ndimage.generate_binary_structure(3, 1))
    out = marked.copy()
    for r, box in enumerate(ndimage.find_objects(labels), start=1):
        region = labels == r
        if (region & (above | below)).any():
            continue
        for support in (above, below):
            layers = range(box[2].start, box[2].stop)
            for k in (layers if support is above else reversed(layers)):
                flat = region[:, :, k]
                if not flat.any():
                    continue
                tab = _tabs(flat, free[:, :, k] & support[:, :, k])
                if tab.any():
                    out[:, :, k] |= tab
                    break
            else:
                continue
            break
    return out


def _tabs(flat: np.ndarray, allowed: np.ndarray) -> np.ndarray:
    """Per side (-x, +x, -y, +y) of the 2-D region ``flat``, the first ``allowed``
    cell just outside it on that side (in index order): at most four cells."""
    out = np.zeros_like(flat)
    for axis in (0, 1):
        for step in (-1, 1):
            side = np.zeros_like(flat)
            src = [slice(None)] * 2
            dst = [slice(None)] * 2
            src[axis] = slice(None, -1) if step == 1 else slice(1, None)
            dst[axis] = slice(1, None) if step == 1 else slice(None, -1)
            side[tuple(dst)] = flat[tuple(src)]
            hits = np.argwhere(side & ~flat & allowed)
            if len(hits):
                out[tuple(hits[len(hits) // 2])] = True
    return out


def touched_bricks(layout: Layout, cells: np.ndarray) -> list[int]:
    """Ids of the bricks that have at least one cell in ``cells`` (sorted)."""
    lab = layout.labels()
    hit = np.unique(lab[np.asarray(cells, dtype=bool) & (lab >= 0)])
    return sorted(layout.bricks[int(n)].id for n in hit)


def check_ids(layout: Layout, brick_ids) -> list[int]:
    """``brick_ids`` as a sorted list without repeats; InputError for an id not in the layout."""
    known = {b.id for b in layout.bricks}
    ids = sorted({int(i) for i in brick_ids})
    unknown = [i for i in ids if i not in known]
    if unknown:
        raise InputError(f"brick id(s) {unknown[:5]} are not in the layout")
    return ids


def adjacency(layout: Layout) -> sparse.csr_matrix:
    """Symmetric 0/1 matrix over ``layout.bricks`` indices: bricks touching face to face."""
    lab = layout.labels()
    n = len(layout.bricks)
    rows, cols = [], []
    for axis in range(3):
        a = np.moveaxis(lab, axis, 0)
        lower, upper = a[:-1].ravel(), a[1:].ravel()
        touch = (lower >= 0) & (upper >= 0) & (lower != upper)
        rows += [lower[touch], upper[touch]]
        cols += [upper[touch], lower[touch]]
    rows_a = np.concatenate(rows) if rows else np.zeros(0, np.int64)
    cols_a = np.concatenate(cols) if cols else np.zeros(0, np.int64)
    graph = sparse.csr_matrix((np.ones(rows_a.size, dtype=np.int8), (rows_a, cols_a)), shape=(n, n))
    graph.sum_duplicates()
    graph.data[:] = 1
    return graph


def lego_beside(layout: Layout, brick_ids) -> list[int]:
    """Sorted ids of the LEGO bricks touching the bricks ``brick_ids`` face to face (those
    bricks themselves left out)."""
    graph = adjacency(layout)
    index = {b.id: n for n, b in enumerate(layout.bricks)}
    given = set(brick_ids)
    beside = {int(j) for i in given for j in graph[index[i]].indices}
    return sorted(layout.bricks[j].id for j in beside
                  if layout.bricks[j].kind == "lego" and layout.bricks[j].id not in given)


def groups(layout: Layout, brick_ids) -> list[list[int]]:
    """The connected groups of the given bricks (face-to-face contact), each a sorted id list.

    Groups are ordered by their lowest, then most -y, then most -x brick
    (the order the printed part ids P1, P2, ... follow).
    """
    ids = check_ids(layout, brick_ids)
    if not ids:
        return []
    index = {b.id: n for n, b in enumerate(layout.bricks)}
    sel = np.array([index[i] for i in ids], dtype=np.int64)
    sub = adjacency(layout)[sel][:, sel]
    _, comp = connected_components(sub, directed=False)
    out: dict[int, list[int]] = {}
    for brick_id, c in zip(ids, comp):
        out.setdefault(int(c), []).append(brick_id)

    def key(group):
        cells = [layout.bricks[index[i]].cell for i in group]
        return min((c[2], c[1], c[0]) for c in cells)

    return sorted(out.values(), key=key)


def is_connected(layout: Layout, brick_ids) -> bool:
    """True when the given bricks form one face-to-face connected group."""
    return len(groups(layout, brick_ids)) <= 1
