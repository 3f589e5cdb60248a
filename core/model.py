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


@dataclass
class Brick:
    """One placed catalog part.

    ``size`` is the extent in cells along x, y, z after orientation (a 2x4
    brick turned by 90° has size ``(4, 2, 3)``), ``cell`` its min corner.
    ``kind`` is ``"lego"`` or ``"printed"``; a printed brick names its
    printed part in ``printed_part``.  ``step`` is the assembly step, or
    None before instructions are made.
    """

    id: int
    part: str
    size: tuple[int, int, int]
    cell: tuple[int, int, int]
    kind: str = "lego"
    printed_part: str | None = None
    step: int | None = None

    def slices(self) -> tuple[slice, slice, slice]:
        """Index of the brick's cells in a grid-shaped array."""
        return tuple(slice(c, c + s) for c, s in zip(self.cell, self.size))

    def to_json(self) -> dict:
        return {
            "id": self.id,
            "part": self.part,
            "size": list(self.size),
            "cell": list(self.cell),
            "kind": self.kind,
            "printed_part": self.printed_part,
            "step": self.step,
        }


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

    def to_json(self) -> dict:
        return {
            "cell_mm": [float(c) for c in self.grid.cell],
            "origin_mm": [float(o) for o in self.grid.origin],
            "shape": list(self.grid.shape),
            "bricks": [b.to_json() for b in self.bricks],
        }
