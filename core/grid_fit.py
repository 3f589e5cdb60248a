"""Fitting the grid to the high-res regions: print as little as the regions need.

Every brick cell a high-res mark touches is printed whole (as far as the
model fills it), so where the grid's cell boundaries fall decides how much
is printed: a 16 mm deep lens plate fills two 8 mm cells when a boundary
lies on its face and three when it does not.  Before laying out,
:func:`fit` tries every shift of the grid in x and y by whole
:data:`STEP_MM` within one stud pitch and keeps the one whose touched cells
hold the least of the model.  z is not shifted: the grid starts at the
part's lowest point, so the part stands on its bottom layer.

The measure is sampled, not exact: the model is legofied
(:func:`core.voxelize.legofy`) on a fine grid of :data:`FINE_MM` cells
around the regions, whose boundaries include every candidate's cell
boundaries, so each fine cell lies in exactly one cell of each candidate.
A candidate's cost is the fine model cells inside the cells it marks (boxes
as :func:`core.high_res.box_range` marks them; region solids legofied on
the same fine grid, a cell marked when it holds one of their fine cells).
The shift from the centred frame (:func:`core.voxelize.grid_frame`) is
kept unless another saves more than :data:`MIN_GAIN` of its cost.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh

from core import voxelize
from core.high_res import as_box, box_range, load_region
from core.model import CELL_MM

#: Shift step in x and y (mm); every shift 0, 1, ..., 7 mm of the 8 mm pitch is tried.
STEP_MM = 1.0
#: Fine cell of the volume measure (mm); x and y equal the step, z a quarter plate.
FINE_MM = (STEP_MM, STEP_MM, CELL_MM[2] / 4)
#: A shift replaces the centred frame only when it prints this much less (fraction).
MIN_GAIN = 0.02


@dataclass
class GridFit:
    """The grid frame chosen for the regions.

    ``origin`` and ``shape`` are the grid to legofy on; ``shift_mm`` how far
    the origin moved from the centred frame (x, y; both <= 0);
    ``centred_mm3`` and ``fitted_mm3`` the sampled model volume in the
    marked cells of the centred and the chosen frame.
    """

    origin: np.ndarray
    shape: tuple[int, int, int]
    shift_mm: tuple[float, float]
    centred_mm3: float
    fitted_mm3: float

    def to_json(self) -> dict:
        """The report's ``grid.fit`` entry."""
        return {"shift_mm": [round(float(v), 3) for v in self.shift_mm],
                "marked_model_mm3": {"centred": round(self.centred_mm3, 1),
                                     "fitted": round(self.fitted_mm3, 1)}}


def frame(bounds: np.ndarray, origin: np.ndarray, cell=CELL_MM) -> tuple[int, int, int]:
    """The grid shape from ``origin`` that covers ``bounds`` (whole cells, at least one)."""
    c = np.asarray(cell, dtype=np.float64)
    reach = np.asarray(bounds, dtype=np.float64)[1] - origin
    counts = np.maximum(1, np.ceil((reach - voxelize.WHOLE_CELL_TOL_MM) / c)).astype(np.int64)
    return tuple(int(n) for n in counts)


def fit(mesh: trimesh.Trimesh, boxes=(), solids=(), units: str = "mm", scale: float = 1.0,
        closed: bool | None = None, cell=CELL_MM) -> GridFit:
    """The grid frame whose high-res cells hold the least of the model (module docstring).

    ``boxes`` are (2, 3) arrays or "X0,..,Z1" strings (model mm), ``solids``
    region files or loaded regions (:func:`core.high_res.load_region`).  With no
    region, or none near the model, it is the centred frame.  Raises
    InputError for a bad box or an unreadable region file.
    """
    c = np.asarray(cell, dtype=np.float64)
    base, base_shape = voxelize.grid_frame(mesh.bounds, c)
    boxes = [as_box(b) for b in boxes]
    regions = [load_region(p, units=units, scale=scale) for p in solids]
    extents = boxes + [r.mesh.bounds for r in regions]
    centred = GridFit(base, base_shape, (0.0, 0.0), 0.0, 0.0)
    if not extents:
        return centred
    fine = np.asarray(FINE_MM)
    steps = int(round(c[0] / STEP_MM))
    lo = np.min([e[0] for e in extents], axis=0) - c
    hi = np.max([e[1] for e in extents], axis=0) + c
    lo, hi = np.maximum(lo, base - c), np.minimum(hi, mesh.bounds[1])
    if np.any(hi <= lo):
        return centred
    first = np.floor((lo - base) / fine).astype(np.int64)
    fine_origin = base + first * fine
    fine_shape = np.maximum(1, np.ceil((hi - fine_origin) / fine).astype(np.int64))
    model_cells = voxelize.legofy(mesh, cell=fine, origin=fine_origin, shape=fine_shape,
                                  closed=closed).filled
    region_cells = np.zeros_like(model_cells)
    for region in regions:
        region_cells |= voxelize.legofy(region.mesh, cell=fine, origin=fine_origin,
                                        shape=fine_shape, closed=region.watertight).filled
    index = np.nonzero(model_cells)
    marked_fine = np.nonzero(region_cells)
    centres = [fine_origin[a] + (np.arange(fine_shape[a]) + 0.5) * fine[a] for a in range(3)]
    costs = np.zeros((steps, steps))
    for i in range(steps):
        for j in range(steps):
            origin = base - np.array([i * STEP_MM, j * STEP_MM, 0.0])
            costs[i, j] = _marked_volume(origin, c, boxes, centres, index, marked_fine, fine)
    best = np.unravel_index(np.argmin(costs), costs.shape)
    if costs[best] >= costs[0, 0] * (1.0 - MIN_GAIN):
        best = (0, 0)
    origin = base - np.array([best[0] * STEP_MM, best[1] * STEP_MM, 0.0])
    return GridFit(origin, frame(mesh.bounds, origin, c),
                   (-best[0] * STEP_MM, -best[1] * STEP_MM), float(costs[0, 0]), float(costs[best]))


def _marked_volume(origin: np.ndarray, cell: np.ndarray, boxes, centres, index, marked_fine,
                   fine: np.ndarray) -> float:
    """Volume (mm³) of the fine model cells ``index`` inside the cells, of the grid at ``origin``,
    that the ``boxes`` or the fine region cells ``marked_fine`` touch."""
    coarse = [np.floor((centres[a] - origin[a]) / cell[a]).astype(np.int64) for a in range(3)]
    keys = np.stack([coarse[a][index[a]] for a in range(3)], axis=1)
    hit = np.zeros(len(keys), dtype=bool)
    for box in boxes:
        first, stop = box_range(origin, cell, box)
        hit |= np.all((keys >= first) & (keys < stop), axis=1)
    if len(marked_fine[0]):
        touched = np.unique(np.stack([coarse[a][marked_fine[a]] for a in range(3)], axis=1), axis=0)
        hit |= _rows_in(keys, touched)
    return float(np.count_nonzero(hit) * np.prod(fine))


def _rows_in(rows: np.ndarray, table: np.ndarray) -> np.ndarray:
    """Which of the integer ``rows`` (N, 3) occur in ``table`` (M, 3)."""
    shift = np.minimum(rows.min(axis=0), table.min(axis=0))
    span = np.maximum(rows.max(axis=0), table.max(axis=0)) - shift + 1
    def flat(a):
        return np.ravel_multi_index((a - shift).T, span)
    return np.isin(flat(rows), flat(table))
