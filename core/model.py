"""Plain data passed between the pipeline stages.

A stage is a function from these types to these types; none of them holds
behaviour beyond small derived views.  Units are millimetres; cell indices
are ``(i, j, k)`` along ``(x, y, z)``, ``k`` counting plate layers from the
bottom of the grid.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: Size of one 1x1 plate cell in mm: stud pitch x stud pitch x plate height.
CELL_MM = (8.0, 8.0, 3.2)
#: Unit names a model file's coordinates may be in, and their size in mm.
UNITS = {"mm": 1.0, "cm": 10.0, "m": 1000.0, "in": 25.4}
#: The model axis that points up -> the rotation (rows: the turned x, y, z) that turns it to
#: +z: a quarter turn about x for y and -y, about y for x and -x, a half turn for -z.
#: Meshes are often y-up (OBJ scans such as the Stanford bunny); a build stands on z = 0.
UP_AXES = {"z": ((1, 0, 0), (0, 1, 0), (0, 0, 1)), "y": ((1, 0, 0), (0, 0, -1), (0, 1, 0)),
           "-y": ((1, 0, 0), (0, 0, 1), (0, -1, 0)), "x": ((0, 0, -1), (0, 1, 0), (1, 0, 0)),
           "-x": ((0, 0, 1), (0, 1, 0), (-1, 0, 0)), "-z": ((1, 0, 0), (0, -1, 0), (0, 0, -1))}


@dataclass(frozen=True)
class Grid:
    """A legofied model: which 1x1 plate cells are filled.

    ``origin`` is the min corner of cell ``(0, 0, 0)`` in model mm, ``cell``
    the cell size in mm, ``filled`` a boolean array of shape ``(nx, ny, nz)``.
    Cell ``(i, j, k)`` spans ``origin + (i, j, k) * cell`` to
    ``origin + (i + 1, j + 1, k + 1) * cell``.
    """

    origin: np.ndarray
    cell: np.ndarray
    filled: np.ndarray

    @property
    def shape(self) -> tuple[int, int, int]:
        return tuple(int(n) for n in self.filled.shape)

    @property
    def count(self) -> int:
        """Number of filled cells (1x1 plates)."""
        return int(np.count_nonzero(self.filled))

    def corner_mm(self, cell) -> np.ndarray:
        """The min corner (mm) of cell ``(i, j, k)``: ``origin + cell * self.cell``.

        Cells outside the grid's shape are fine (the grid extends the same way).
        """
        return np.asarray(self.origin, dtype=float) + np.asarray(cell, dtype=float) * self.cell

    def box_mm(self, cell, size=(1, 1, 1)) -> tuple[np.ndarray, np.ndarray]:
        """The box (min corner, max corner, mm) of the ``size`` cells from ``cell`` on,
        e.g. a brick's box: ``grid.box_mm(brick.cell, brick.size)``."""
        lo = self.corner_mm(cell)
        return lo, lo + np.asarray(size, dtype=float) * self.cell

    def nearest_cell(self, point_mm) -> tuple[int, int, int]:
        """The cell whose min corner is nearest to ``point_mm``: the inverse of
        :meth:`corner_mm` for a point on the grid's lattice, rounding off the floating
        error (a corner of another grid with the same cell size lands on its cell)."""
        at = (np.asarray(point_mm, dtype=float) - self.origin) / self.cell
        return tuple(int(v) for v in np.rint(at))


@dataclass
class Brick:
    """One placed catalog part.

    ``size`` is the extent in cells along x, y, z after orientation (a 2x4
    brick turned by 90° has size ``(4, 2, 3)``), ``cell`` its min corner.
    ``kind`` is ``"lego"`` or ``"printed"``; a printed brick names its
    printed part in ``printed_part``.  ``step`` is the assembly step, or
    None before instructions are made.  ``load_g`` is an extra mass in grams
    resting on the brick (a lens, a battery), which the force check carries.
    """

    id: int
    part: str
    size: tuple[int, int, int]
    cell: tuple[int, int, int]
    kind: str = "lego"
    printed_part: str | None = None
    step: int | None = None
    load_g: float = 0.0

    def slices(self) -> tuple[slice, slice, slice]:
        """Index of the brick's cells in a grid-shaped array."""
        return tuple(slice(c, c + s) for c, s in zip(self.cell, self.size))

    def to_json(self) -> dict:
        out = {
            "id": self.id,
            "part": self.part,
            "size": list(self.size),
            "cell": list(self.cell),
            "kind": self.kind,
            "printed_part": self.printed_part,
            "step": self.step,
        }
        if self.load_g:
            out["load_g"] = self.load_g
        return out


@dataclass
class Layout:
    """Bricks that cover the filled cells of ``grid``, each cell once."""

    grid: Grid
    bricks: list[Brick] = field(default_factory=list)

    def labels(self) -> np.ndarray:
        """Grid-shaped int array: the index into ``bricks`` per cell, -1 if empty."""
        lab = np.full(self.grid.shape, -1, dtype=np.int64)
        for n, b in enumerate(self.bricks):
            lab[b.slices()] = n
        return lab

    def boxes_mm(self) -> tuple[np.ndarray, np.ndarray]:
        """The bricks' boxes in mm as two ``(len(bricks), 3)`` arrays, min and max
        corners, in the order of ``bricks`` (each :meth:`Grid.box_mm` of a brick)."""
        cells = np.array([b.cell for b in self.bricks], dtype=float).reshape(-1, 3)
        sizes = np.array([b.size for b in self.bricks], dtype=float).reshape(-1, 3)
        lo = np.asarray(self.grid.origin, dtype=float) + cells * self.grid.cell
        return lo, lo + sizes * self.grid.cell

    @classmethod
    def from_json(cls, data: dict) -> "Layout":
        """The layout of a ``layout.json`` document (:meth:`to_json`): its grid's
        filled cells are the bricks' cells, steps as stored.  Raises KeyError,
        TypeError or ValueError for a document that is not one."""
        bricks = [Brick(int(b["id"]), str(b["part"]), tuple(int(v) for v in b["size"]),
                        tuple(int(v) for v in b["cell"]), b["kind"], b["printed_part"],
                        b.get("step"), float(b.get("load_g", 0.0))) for b in data["bricks"]]
        filled = np.zeros(tuple(int(v) for v in data["shape"]), dtype=bool)
        for b in bricks:
            filled[b.slices()] = True
        grid = Grid(origin=np.array(data["origin_mm"], dtype=np.float64),
                    cell=np.array(data["cell_mm"], dtype=np.float64), filled=filled)
        return cls(grid, bricks)

    def to_json(self) -> dict:
        return {
            "cell_mm": [float(c) for c in self.grid.cell],
            "origin_mm": [float(o) for o in self.grid.origin],
            "shape": list(self.grid.shape),
            "bricks": [b.to_json() for b in self.bricks],
        }


@dataclass(frozen=True)
class Load:
    """A mass of ``grams`` resting on the bricks the box ``lo``-``hi`` (model mm) touches."""

    lo: tuple[float, float, float]
    hi: tuple[float, float, float]
    grams: float

    def to_json(self) -> dict:
        return {"box_mm": [list(self.lo), list(self.hi)], "grams": self.grams}
