"""Connectors: the cells where a printed part meets another brick directly above or below.

A printed part clamps onto LEGO only through studs and sockets
(:mod:`core.parts.interfaces`).  A part gets one wherever the geometry allows:
a **stud** on every cell of its top layer that carries a brick of another
part (LEGO or printed), a **socket** in every cell of its bottom layer
that stands on one.  Bricks side by side do not clamp (LEGO does not), so
they get neither.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from core.model import Layout


@dataclass(frozen=True)
class Connectors:
    """Connector cells of the printed parts: ``top`` (studs) and ``bottom`` (sockets)
    are (n, 3) int arrays of grid cells (i, j, k) of printed bricks."""

    top: np.ndarray
    bottom: np.ndarray

    def count_for(self, cells: set[tuple[int, int, int]]) -> tuple[int, int]:
        """How many top and bottom connectors lie in ``cells``."""
        top = sum(1 for c in map(tuple, self.top.tolist()) if c in cells)
        bottom = sum(1 for c in map(tuple, self.bottom.tolist()) if c in cells)
        return top, bottom


def find(layout: Layout, groups: list[list[int]]) -> Connectors:
    """The connector cells of the bricks in ``groups`` (each group one printed part).

    A top connector is a cell of a group's brick whose cell above belongs to
    a brick outside that group; a bottom connector likewise below.  Every
    such cell is one, in (i, j, k) order.
    """
    lab = layout.labels()
    part = np.full(len(layout.bricks) + 1, -1, dtype=np.int64)
    index = {b.id: n for n, b in enumerate(layout.bricks)}
    for g, ids in enumerate(groups):
        part[[index[i] for i in ids]] = g
    owner = np.where(lab >= 0, part[lab], -1)
    filled = lab >= 0
    below, above = owner[:, :, :-1], owner[:, :, 1:]
    differ = filled[:, :, :-1] & filled[:, :, 1:] & (below != above)
    top_mask = np.zeros(lab.shape, dtype=bool)
    bottom_mask = np.zeros(lab.shape, dtype=bool)
    top_mask[:, :, :-1] = differ & (below >= 0)
    bottom_mask[:, :, 1:] = differ & (above >= 0)
    return Connectors(np.argwhere(top_mask), np.argwhere(bottom_mask))
