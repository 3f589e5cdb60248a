"""Where a printed part meets LEGO: the studs and sockets it gets, and their fit.

A printed part is the model inside its bricks' envelopes, kept whole (:mod:`core.parts.printed`).
Brick geometry is *added* only where the part meets a brick of another part directly above
or below it:

* a **socket** in every cell of the part's bottom layer that stands on another brick: a
  square hole :attr:`Fit.socket_width` wide (its four flat walls touch a real stud at the
  real 4.8 mm spacing, as the walls of a real 1x1 brick do) and :attr:`Fit.socket_depth`
  deep, cut into a solid band of the cell's footprint with a :attr:`Fit.roof` above it;
* a **stud** on every cell of the part's top layer that carries another brick: a cylinder
  of :attr:`Fit.stud_diameter` and 1.7 mm height on a :attr:`Fit.skin` of the footprint.

Where the model is thinner than that band or skin (a 2 mm lens plate in a 9.6 mm brick),
it is grown inside the cell's column until it reaches :attr:`Fit.overlap` into the model,
the least material that joins the connector to the part.  Nowhere else is anything cut
from the model.

**The fit.**  FDM prints outer surfaces slightly large and holes slightly small, so printed
studs and sockets have separate, signed settings.  ``stud_fit``: printed stud diameter =
4.8 + ``stud_fit``; default +0.05 (Ø4.85: printed LEGO-compatible designs known to clamp
use Ø4.85–5.0, e.g. LEGO.scad by cfinke; MachineBlocks and Brickify's calibration strips
reach 4.9–5.0 on printers that print small).  ``socket_fit``: distance between opposite
socket walls = 4.8 + ``socket_fit``; default 0, the real spacing, which a real stud enters
with the slight interference of a hole printed a little small.  Negative tightens the fit,
positive loosens it.  ``python -m core calibration-strip`` prints a strip of studs and
sockets in steps of 0.05 mm to find a printer's values.  All dimensions are in mm.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, fields

import numpy as np

from core.errors import InputError

#: LEGO's stud diameter and the distance between the walls a stud touches (mm).
LEGO_STUD_DIAMETER = 4.8
#: Cell pitch and plate height of the grid (mm).
PITCH = 8.0
PLATE = 3.2


@dataclass(frozen=True)
class Fit:
    """The printed studs and sockets: the one table of their defaults.

    ``stud_fit`` and ``socket_fit`` are the signed fit settings of the
    module docstring; ``stud_height`` is the printed stud's height,
    ``socket_depth`` how deep a socket takes a real stud (its 1.7 mm plus
    0.3 mm so that the brick seats on its top face), ``roof`` the material
    kept above a socket, ``skin`` the material kept under a stud, ``play``
    how far a printed part's side stays back from a LEGO brick beside it
    (LEGO's own 0.1 mm), ``min_wall`` the thinnest wall the added geometry
    may leave (two 0.4 mm perimeters), ``overlap`` how far added material
    reaches into the model so that the two join with volume, not along a
    face.
    """

    stud_fit: float = 0.05
    socket_fit: float = 0.0
    stud_height: float = 1.7
    socket_depth: float = 2.0
    roof: float = 1.0
    skin: float = 1.0
    play: float = 0.1
    min_wall: float = 0.8
    overlap: float = 0.5

    @property
    def stud_diameter(self) -> float:
        """Diameter of a printed stud: 4.8 + ``stud_fit``."""
        return LEGO_STUD_DIAMETER + self.stud_fit

    @property
    def socket_width(self) -> float:
        """Width of a printed socket between opposite walls: 4.8 + ``socket_fit``."""
        return LEGO_STUD_DIAMETER + self.socket_fit

    def check(self) -> "Fit":
        """``self`` when every setting is a finite number in its range, else InputError
        naming the first setting that is not."""
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(value):
                raise InputError(f"{f.name.replace('_', '-')} {value!r} must be a finite number of mm")
        limits = (
            ("stud_fit", -0.8, 0.8), ("socket_fit", -0.8, 0.8),
            ("stud_height", 0.5, 3.0), ("socket_depth", 0.5, PLATE - 0.5),
            ("roof", 0.4, PLATE), ("skin", 0.4, PLATE), ("play", 0.0, 0.5),
            ("min_wall", 0.2, 2.0), ("overlap", 0.05, 2.0),
        )
        for name, lo, hi in limits:
            value = getattr(self, name)
            if not lo <= value <= hi:
                raise InputError(f"{name.replace('_', '-')} {value:g} mm is outside {lo:g} .. {hi:g} mm")
        if self.socket_depth + self.roof > PLATE + 1e-9:
            raise InputError(f"socket-depth {self.socket_depth:g} + roof {self.roof:g} mm "
                             f"must fit one plate ({PLATE:g} mm)")
        if (PITCH - self.socket_width) / 2 - self.play < self.min_wall:
            raise InputError(f"socket width {self.socket_width:g} mm leaves walls thinner than "
                             f"{self.min_wall:g} mm in an {PITCH:g} mm cell")
        return self


@dataclass(frozen=True)
class Plan:
    """The solids that make one printed part, as axis-aligned boxes and studs (model mm).

    The part is ``((model ∩ (∪ envelope − ∪ play)) ∪ ∪ fills ∪ ∪ studs) − ∪ holes``:

    * ``envelope`` (n, 2, 3): min/max corners of boxes whose union is the
      part's cells;
    * ``play`` (m, 2, 3): slabs :attr:`Fit.play` thick on the sides that face
      a brick of another part in the same layer;
    * ``fills`` (f, 2, 3): the solid bands under studs and around sockets;
    * ``tapers`` (t, 4, 3): under a stud's skin that overhangs the model, a
      45° taper from the skin's footprint (rows 0, 1: min and max corner of
      a flat rectangle) down to the model's extent below it (rows 2, 3), so
      that an upright print needs no support under the skin;
    * ``studs`` (s, 4): centre x, y, bottom z and top z of each stud
      cylinder, diameter :attr:`Fit.stud_diameter`;
    * ``holes`` (t, 2, 3): the socket holes;
    * ``stud_cells`` / ``socket_cells``: the grid cells (i, j, k) of the
      part that carry each stud / socket, in the order of ``studs`` / ``holes``.
    """

    envelope: np.ndarray
    play: np.ndarray
    fills: np.ndarray
    tapers: np.ndarray
    studs: np.ndarray
    holes: np.ndarray
    stud_cells: np.ndarray
    socket_cells: np.ndarray


def _boxes(rows) -> np.ndarray:
    return np.asarray(rows, dtype=float).reshape(-1, 2, 3)


def plan(origin, cell, mine: np.ndarray, other: np.ndarray, bricks, top_cells, bottom_cells,
         model_extent, fit: Fit = Fit()) -> Plan:
    """The :class:`Plan` of one printed part.

    ``origin``/``cell``: the grid's origin and cell size (mm); ``mine``: bool
    grid of the part's cells; ``other``: bool grid of the cells of every
    other brick (LEGO or another printed part); ``bricks``: ((i, j, k), (sx,
    sy, sz)) of the part's bricks; ``top_cells`` / ``bottom_cells``: (n, 3)
    cells of the part that get a stud / a socket (:func:`core.parts.connectors.find`);
    ``model_extent(lo, hi)``: the (min corner, max corner) of the model's
    bounding box inside the box (lo, hi), or None where the model is absent.

    Promises: every box and stud of the plan lies in the part's cells
    (studs excepted, which stand :attr:`Fit.stud_height` above its top);
    fills leave at least ``(8 - socket_width) / 2 - play`` mm of wall around
    each hole; a fill reaches :attr:`Fit.overlap` into the model in its
    column, or the whole column when the model is absent from it.
    """
    origin, cell = np.asarray(origin, float), np.asarray(cell, float)
    nx, ny, nz = mine.shape
    envelope = [(origin + np.asarray(c) * cell, origin + (np.asarray(c) + np.asarray(s)) * cell)
                for c, s in bricks]
    play = []
    for axis in (0, 1):
        for sign in (-1, 1):
            step = np.zeros(3, dtype=int)
            step[axis] = sign
            across = np.zeros_like(mine)
            src = [slice(None)] * 3
            dst = [slice(None)] * 3
            if sign > 0:
                src[axis], dst[axis] = slice(1, None), slice(None, -1)
            else:
                src[axis], dst[axis] = slice(None, -1), slice(1, None)
            across[tuple(dst)] = other[tuple(src)]
            for i, j, k0, k1 in _z_runs(mine & across):
                lo = origin + np.array([i, j, k0]) * cell
                hi = origin + np.array([i + 1, j + 1, k1]) * cell
                if sign > 0:
                    lo[axis] = hi[axis] - fit.play
                    hi[axis] += fit.overlap
                else:
                    hi[axis] = lo[axis] + fit.play
                    lo[axis] -= fit.overlap
                play.append((lo, hi))
    fills, tapers, studs, holes = [], [], [], []
    top_cells = np.asarray(top_cells, dtype=int).reshape(-1, 3)
    bottom_cells = np.asarray(bottom_cells, dtype=int).reshape(-1, 3)
    for i, j, k in top_cells:
        k0 = k
        while k0 > 0 and mine[i, j, k0 - 1]:
            k0 -= 1
        lo, hi = _footprint(origin, cell, other, i, j, k0, k, fit)
        z_top = origin[2] + (k + 1) * cell[2]
        z_bottom = origin[2] + k0 * cell[2]
        extent = model_extent(np.r_[lo, z_bottom], np.r_[hi, z_top])
        z_lo = z_top - fit.skin
        z_lo = z_bottom if extent is None else max(z_bottom, min(z_lo, extent[1][2] - fit.overlap))
        fills.append((np.r_[lo, z_lo], np.r_[hi, z_top]))
        below = model_extent(np.r_[lo, max(z_bottom, z_lo - fit.overlap)], np.r_[hi, z_lo + fit.overlap]) \
            if z_lo > z_bottom else None
        if below is not None:
            taper = _taper(lo, hi, below[0][:2], below[1][:2], z_lo, z_bottom, fit)
            if taper is not None:
                tapers.append(taper)
        centre = origin[:2] + (np.array([i, j]) + 0.5) * cell[:2]
        studs.append((*centre, z_top - min(fit.skin, fit.overlap) / 2, z_top + fit.stud_height))
    for i, j, k in bottom_cells:
        k1 = k
        while k1 + 1 < nz and mine[i, j, k1 + 1]:
            k1 += 1
        lo, hi = _footprint(origin, cell, other, i, j, k, k1, fit)
        z0 = origin[2] + k * cell[2]
        z_column = origin[2] + (k1 + 1) * cell[2]
        extent = model_extent(np.r_[lo, z0], np.r_[hi, z_column])
        z_hi = z0 + fit.socket_depth + fit.roof
        z_hi = z_column if extent is None else min(z_column, max(z_hi, extent[0][2] + fit.overlap))
        fills.append((np.r_[lo, z0], np.r_[hi, z_hi]))
        centre = origin[:2] + (np.array([i, j]) + 0.5) * cell[:2]
        half = fit.socket_width / 2
        holes.append((np.r_[centre - half, z0 - fit.overlap], np.r_[centre + half, z0 + fit.socket_depth]))
    return Plan(_boxes(envelope), _boxes(play), _boxes(fills),
                np.asarray(tapers, dtype=float).reshape(-1, 4, 3),
                np.asarray(studs, dtype=float).reshape(-1, 4), _boxes(holes), top_cells, bottom_cells)


def _taper(lo, hi, support_lo, support_hi, z_top: float, z_floor: float, fit: Fit):
    """The 45° taper under a skin of footprint (lo, hi) at ``z_top`` down to the
    model's footprint (support_lo, support_hi), cut off at ``z_floor``; None when
    the skin overhangs the model by less than :attr:`Fit.min_wall`."""
    s_lo = np.clip(support_lo, lo, hi)
    s_hi = np.clip(support_hi, lo, hi)
    reach = float(max(np.max(s_lo - lo), np.max(hi - s_hi)))
    if reach < fit.min_wall or np.any(s_hi <= s_lo):
        return None
    depth = min(reach, z_top - z_floor)
    t = depth / reach
    b_lo, b_hi = lo + (s_lo - lo) * t, hi + (s_hi - hi) * t
    return (np.r_[lo, z_top], np.r_[hi, z_top], np.r_[b_lo, z_top - depth], np.r_[b_hi, z_top - depth])


def _footprint(origin, cell, other, i, j, k0, k1, fit: Fit) -> tuple[np.ndarray, np.ndarray]:
    """The (x, y) min/max of cell column (i, j) from layer k0 to k1, held back by
    :attr:`Fit.play` on every side where a layer of it has another brick beside it."""
    lo = origin[:2] + np.array([i, j]) * cell[:2]
    hi = lo + cell[:2]
    nx, ny = other.shape[:2]
    layers = slice(k0, k1 + 1)
    if i > 0 and other[i - 1, j, layers].any():
        lo[0] += fit.play
    if i + 1 < nx and other[i + 1, j, layers].any():
        hi[0] -= fit.play
    if j > 0 and other[i, j - 1, layers].any():
        lo[1] += fit.play
    if j + 1 < ny and other[i, j + 1, layers].any():
        hi[1] -= fit.play
    return lo, hi


def _z_runs(mask: np.ndarray) -> list[tuple[int, int, int, int]]:
    """The vertical runs of True in ``mask``: (i, j, k_first, k_end) with k_end exclusive."""
    out = []
    padded = np.concatenate([np.zeros(mask.shape[:2] + (1,), bool), mask,
                             np.zeros(mask.shape[:2] + (1,), bool)], axis=2)
    change = np.diff(padded.astype(np.int8), axis=2)
    starts = np.argwhere(change == 1)
    ends = np.argwhere(change == -1)
    order_s = np.lexsort((starts[:, 2], starts[:, 1], starts[:, 0]))
    order_e = np.lexsort((ends[:, 2], ends[:, 1], ends[:, 0]))
    for (i, j, k0), (_, _, k1) in zip(starts[order_s], ends[order_e]):
        out.append((int(i), int(j), int(k0), int(k1)))
    return out
