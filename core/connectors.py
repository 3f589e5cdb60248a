"""Connectors: where a printed part meets LEGO, it keeps the brick's studs and underside.

A printed brick is the brick solid intersected with the part (paper,
"Converting Lego bricks into 3D printable bricks").  Where the part is
thinner than a brick (a 3 mm wall in an 8 mm cell, a lens plate), that
intersection cuts every stud and tube, so the printed part cannot clamp
onto the LEGO bricks above or below it and the structure falls apart.

Connectors fix this the way a designer would: in every cell where a
printed brick touches a brick of another part (LEGO or another printed
part) *vertically*, the intersection also keeps the brick's own geometry
in a thin band at that face:

* **top connector** (a brick of another part sits on this cell): the
  stud, the brick's top skin and the upper :data:`TOP_BAND_MM` of its
  walls, so the stud stands on a supported plate;
* **bottom connector** (this cell sits on a brick of another part): the
  lower :data:`BOTTOM_BAND_MM` of the walls and of the tube or pin, the
  socket that grips the studs below.

Technically the model is united with one box per connector cell before
the intersection (:func:`with_connectors`), so the printed brick is
``brick ∩ (model ∪ boxes)``: it never leaves its brick, it equals the exact
intersection everywhere except in those bands, and inside the bands it is
the brick itself, so the studs and the sockets' grip there are whole
(:func:`mark_grip`), which the stability check uses.  Cells touching other bricks only side by side get
no connector (LEGO does not clamp sideways).
"""

from __future__ import annotations

from dataclasses import dataclass

import manifold3d as m3
import numpy as np
from OCP.BRepAlgoAPI import BRepAlgoAPI_Fuse
from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox
from OCP.gp import gp_Pnt

from core.brick_solids import BrickGeometry, run_boolean
from core.model import Layout
from core.printed import ModelSolid

#: Depth (mm) of a top connector below the brick's top: skin plus upper walls.
TOP_BAND_MM = 2.9
#: Height (mm) of a bottom connector above the brick's bottom: the socket.
BOTTOM_BAND_MM = 2.9
#: Connectors per pair of touching bricks: two studs hold a LEGO joint
#: against turning; more only add material that the exact shape did not have.
PER_CONTACT = 2
#: How far (mm) a connector box reaches past the faces it must cover, so that
#: its faces never coincide with the brick's (studs, bottom face, sides).
OVERSHOOT_MM = 0.35


@dataclass(frozen=True)
class Connectors:
    """Connector cells of the printed bricks: ``top`` and ``bottom`` are (n, 3) int
    arrays of grid cells (i, j, k) of printed bricks; ``boxes`` the (m, 2, 3)
    min/max corners in model mm of the boxes united with the model."""

    top: np.ndarray
    bottom: np.ndarray
    boxes: np.ndarray

    def count_for(self, cells: set[tuple[int, int, int]]) -> tuple[int, int]:
        """How many top and bottom connectors lie in ``cells``."""
        top = sum(1 for c in map(tuple, self.top.tolist()) if c in cells)
        bottom = sum(1 for c in map(tuple, self.bottom.tolist()) if c in cells)
        return top, bottom


def find(layout: Layout, groups: list[list[int]],
         geometry: BrickGeometry = BrickGeometry()) -> Connectors:
    """The connector cells of the bricks in ``groups`` (each group one printed part).

    A top connector is a top-layer cell of a group's brick whose cell above
    belongs to a brick outside that group; a bottom connector likewise below;
    of the cells two bricks share, at most :data:`PER_CONTACT` (the contact's
    two far ends) become connectors.
    """
    lab = layout.labels()
    part = np.full(len(layout.bricks) + 1, -1, dtype=np.int64)
    index = {b.id: n for n, b in enumerate(layout.bricks)}
    for g, ids in enumerate(groups):
        part[[index[i] for i in ids]] = g
    owner = np.where(lab >= 0, part[lab], -1)
    other = (lab >= 0)
    below, above = owner[:, :, :-1], owner[:, :, 1:]
    top_mask = np.zeros(lab.shape, dtype=bool)
    bottom_mask = np.zeros(lab.shape, dtype=bool)
    brick_below, brick_above = lab[:, :, :-1], lab[:, :, 1:]
    differ = other[:, :, :-1] & other[:, :, 1:] & (brick_below != brick_above) & (below != above)
    top_mask[:, :, :-1] = differ & (below >= 0)
    bottom_mask[:, :, 1:] = differ & (above >= 0)
    top = _fewest(np.argwhere(top_mask), lab, 1)
    bottom = _fewest(np.argwhere(bottom_mask), lab, -1)
    grid = layout.grid
    origin, cell = np.asarray(grid.origin, float), np.asarray(grid.cell, float)
    boxes = []
    for cells, upper in ((top, True), (bottom, False)):
        lo = origin + cells * cell
        hi = lo + cell
        box = np.stack([lo, hi], axis=1) if len(cells) else np.zeros((0, 2, 3))
        box[:, 0, :2] -= OVERSHOOT_MM
        box[:, 1, :2] += OVERSHOOT_MM
        if upper:
            box[:, 0, 2] = hi[:, 2] - TOP_BAND_MM
            box[:, 1, 2] = hi[:, 2] + geometry.stud_height + OVERSHOOT_MM
        else:
            box[:, 0, 2] = lo[:, 2] - OVERSHOOT_MM
            box[:, 1, 2] = lo[:, 2] + BOTTOM_BAND_MM
        boxes.append(box)
    return Connectors(top, bottom, np.concatenate(boxes) if boxes else np.zeros((0, 2, 3)))


def _fewest(cells: np.ndarray, lab: np.ndarray, step: int) -> np.ndarray:
    """Of the contact ``cells`` (printed cell, neighbour at ``k + step``), at most
    :data:`PER_CONTACT` per pair of bricks: the first and last in (i, j) order,
    the contact's two far ends, which hold the pair against turning."""
    if len(cells) == 0:
        return cells
    mine = lab[cells[:, 0], cells[:, 1], cells[:, 2]]
    theirs = lab[cells[:, 0], cells[:, 1], cells[:, 2] + step]
    order = np.lexsort((cells[:, 1], cells[:, 0], theirs, mine))
    cells, mine, theirs = cells[order], mine[order], theirs[order]
    first = np.r_[True, (mine[1:] != mine[:-1]) | (theirs[1:] != theirs[:-1])]
    last = np.r_[first[1:], True]
    keep = first | last if PER_CONTACT >= 2 else first
    return cells[keep]


def with_connectors(source: ModelSolid, connectors: Connectors) -> ModelSolid:
    """The model united with the connector boxes, as the intersection's operand.

    B-rep models get one OpenCascade fuse with all the boxes; mesh
    models one manifold3d union.  With no connectors, ``source`` itself.
    """
    boxes = connectors.boxes
    if len(boxes) == 0:
        return source
    if source.kind == "brep":
        tools = [BRepPrimAPI_MakeBox(gp_Pnt(*map(float, lo)), gp_Pnt(*map(float, hi))).Shape()
                 for lo, hi in boxes]
        return ModelSolid(brep=run_boolean(BRepAlgoAPI_Fuse(), source.brep, tools, parallel=True))
    cubes = [m3.Manifold.cube(list(map(float, hi - lo))).translate(list(map(float, lo)))
             for lo, hi in boxes]
    union = m3.Manifold.batch_boolean([source.manifold, *cubes], m3.OpType.Add)
    # Evaluated here, once: a lazy Boolean shared by several parts' intersections
    # crashes manifold3d 3.0.1 (its issue #1378).
    return ModelSolid(manifold=union.as_original())


def mark_grip(parts, connectors: Connectors) -> None:
    """Set the clamp flags of the printed ``parts`` in their connector cells to True.

    This holds by construction, not by measurement: a part is
    ``brick ∩ (model ∪ boxes)``, which contains ``brick ∩ box`` and lies in
    the brick, so inside a connector box it *is* the brick: the stud (top)
    and the walls, tube and pin sections over the stud height (bottom) are
    whole there, even when the feature as a whole, reaching above the band,
    was cut (``studs``/``tubes`` still report the whole features).
    """
    for cells, attr in ((connectors.top, "top_ok"), (connectors.bottom, "bottom_ok")):
        for cell in map(tuple, cells.tolist()):
            for p in parts:
                flags = getattr(p, attr)
                if cell in flags:
                    flags[cell] = True
