"""Which brick is under a point: picking and brushing bricks of a layout, in mm.

A pick in a 3D view gives a point on a drawn surface (a brick, a printed
part, a preview).  The brick under it is the brick whose *box* (its cells,
:meth:`core.model.Layout.boxes_mm`) is nearest to the point, when that is
within :data:`PICK_TOLERANCE_MM`: a LEGO brick's faces lie 0.1 mm inside its
box and a printed part's surface inside its bricks' boxes, so a picked point
is in or on its brick's box up to the float error of the view's pick.  A
brush of a radius takes every brick whose box comes within the radius of the
point.  Coordinates are the layout's (the grid's origin and cell size), the
same as the document's where the bricks are shown.
"""

from __future__ import annotations

import numpy as np

from core.model import Layout

#: A picked point this close (mm) to a brick's box is on that brick: the float
#: error of a pick in a 3D view, far below the 0.1 mm play between two bricks.
PICK_TOLERANCE_MM = 0.05


def box_distances(layout: Layout, point) -> np.ndarray:
    """The distance (mm) from ``point`` to each brick's box, in the order of
    ``layout.bricks``: 0 for a point inside or on the box."""
    lo, hi = layout.boxes_mm()
    p = np.asarray(point, dtype=float)
    return np.linalg.norm(np.maximum(np.maximum(lo - p, p - hi), 0.0), axis=1)


def brick_at(layout: Layout, point, tolerance: float = PICK_TOLERANCE_MM,
             among=None) -> int | None:
    """The id of the brick under ``point`` (mm), or None when no brick's box is within
    ``tolerance`` of it.

    The brick is the one whose box is nearest (0 inside); of boxes equally near
    (a point on a face two bricks share) the one whose box centre is nearest,
    then the lowest id.  ``among`` (brick ids) restricts the choice, e.g. to the
    bricks of the printed part that was picked.
    """
    if not layout.bricks:
        return None
    distance = box_distances(layout, point)
    lo, hi = layout.boxes_mm()
    centre = np.linalg.norm((lo + hi) / 2.0 - np.asarray(point, dtype=float), axis=1)
    ids = np.array([b.id for b in layout.bricks])
    allowed = distance <= tolerance
    if among is not None:
        allowed &= np.isin(ids, np.array(list(among), dtype=ids.dtype))
    if not allowed.any():
        return None
    order = np.lexsort((ids, centre, distance))
    return int(ids[next(n for n in order if allowed[n])])


def bricks_within(layout: Layout, point, radius: float) -> list[int]:
    """The ids (ascending) of the bricks whose box comes within ``radius`` mm of
    ``point``: what a brush of that radius paints there."""
    distance = box_distances(layout, point)
    return sorted(b.id for b, d in zip(layout.bricks, distance) if d <= radius)
