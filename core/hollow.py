"""Hollow stage: keep a shell of a legofied part, plus the pillars that hold its roof.

A big solid object is mostly interior that nobody sees.  :func:`hollow` returns a new
:class:`~core.model.Grid` with the cells to keep:

* the **shell**: the filled cells that are not *interior*, a cell being interior when the
  whole box ``i +- studs, j +- studs, k +- layers`` around it is filled (a box erosion;
  cells beyond the grid count as empty), with ``layers = ceil(studs * 8 / 3.2)`` so that
  walls, floor and roof are about equally thick in mm (2 studs: 16 mm walls, 5 layers =
  16 mm floor and roof);
* **pillars**: the interior cells of the columns ``(i, j)`` with ``i mod PILLAR_PITCH <
  PILLAR_STUDS`` and ``j mod PILLAR_PITCH < PILLAR_STUDS`` (2 x 2-stud pillars on a
  12-stud lattice), from the floor shell to the roof shell of every hollow: a closed
  shell's roof has nothing under it but air, so they carry it, at most 10 studs (80 mm)
  apart, and keep it joined to the floor where the walls are far;
* every cell of ``keep`` (the high-res regions: printed from the model, they stay solid).

Every interior cell has its whole neighbourhood box filled, so the cells right under and
over a column's interior are shell cells: each pillar stands on the shell and carries it.
The shell surrounds every removed cell, so removing them never separates it: the kept cells
form as many 6-connected regions as the part.

:func:`decide` applies the request's setting: ``-1`` (automatic) proposes a 2-stud shell for
a part of at least :data:`AUTO_MIN_CELLS` cells when it keeps at most two thirds of them,
``0`` keeps the part solid, ``n >= 1`` hollows with an ``n``-stud shell.  Fewer cells need
not mean fewer bricks (an uneven part's shell is made of small bricks, a solid interior is
mostly the largest brick), so the driver keeps an automatic shell only when its greedy
layout has fewer than two thirds of the solid part's bricks: surely so below two thirds of
the solid part's lower bound (:func:`surely_saves`), else by laying out the solid part too
(:func:`compared`; :func:`solid_layout_wanted` says when, and for the report).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from core.errors import InputError
from core.model import Grid

#: Default shell thickness in studs.
SHELL_STUDS = 2
#: Pillar footprint (studs per side) and the pitch (studs) of their lattice.
PILLAR_STUDS = 2
PILLAR_PITCH = 12
#: Automatic hollowing needs at least this many filled cells (about a 25 cm cube)...
AUTO_MIN_CELLS = 50_000
#: ...and must keep at most this share of them (save more than a third).
AUTO_KEEP_SHARE = 2.0 / 3.0
#: Largest shell thickness accepted (studs).
MAX_STUDS = 64
#: Most cells of a solid part the driver lays out beside its shell only for the report
#: (:func:`solid_layout_wanted`): beyond, its layout would take much of the minute a 1 m
#: part is given, and its lower bound, reported instead, is close anyway (a big block's
#: interior is mostly the largest brick).
SOLID_LAYOUT_MAX_CELLS = 2_000_000


@dataclass(frozen=True)
class Hollowing:
    """What the hollow stage did: the ``grid`` of kept cells and the figures of the report.

    ``setting`` is the request's value (-1 automatic, 0 solid, n studs),
    ``studs`` the shell thickness used (0 when kept solid), ``layers`` the
    roof and floor thickness in plate layers; ``solid_cells`` the part's
    filled cells, ``kept_cells`` those kept, ``pillar_cells`` and
    ``kept_solid_cells`` (high-res cells kept although interior) among them;
    ``why`` a sentence for the report and the terminal.
    """

    grid: Grid
    setting: int
    studs: int
    layers: int
    solid_cells: int
    kept_cells: int
    pillar_cells: int
    kept_solid_cells: int
    why: str
    bricks_hollow: int | None = None
    bricks_solid: int | None = None

    @property
    def on(self) -> bool:
        return self.studs > 0

    def to_json(self) -> dict:
        return {"setting": "auto" if self.setting < 0 else self.setting, "on": self.on,
                "shell_studs": self.studs, "shell_layers": self.layers,
                "pillar_studs": PILLAR_STUDS if self.on else 0,
                "pillar_pitch_studs": PILLAR_PITCH if self.on else 0,
                "cells_solid": self.solid_cells, "cells_kept": self.kept_cells,
                "cells_pillars": self.pillar_cells, "cells_kept_high_res": self.kept_solid_cells,
                "why": self.why,
                **({} if self.bricks_solid is None else
                   {"laid_out_both": {"hollow_bricks": self.bricks_hollow,
                                      "solid_bricks": self.bricks_solid}})}


def check_setting(value) -> int:
    """``value`` as a hollow setting (-1 automatic, 0 solid, 1..MAX_STUDS studs); InputError otherwise."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) \
            or not -1 <= int(value) <= MAX_STUDS:
        raise InputError(f"--hollow {value!r} must be a whole number of studs from 0 (solid) to "
                         f"{MAX_STUDS}, or -1 (automatic)")
    return int(value)


def layers_for(studs: int, cell) -> int:
    """Plate layers as thick as ``studs`` studs (rounded up)."""
    return int(math.ceil(studs * float(cell[0]) / float(cell[2]) - 1e-9))


def interior(filled: np.ndarray, studs: int, layers: int) -> np.ndarray:
    """Filled cells whose box ``+-studs`` (x, y) ``+-layers`` (z) of cells is all filled
    (cells beyond the array count as empty)."""
    size = (2 * studs + 1, 2 * studs + 1, 2 * layers + 1)
    return ndimage.minimum_filter(filled.view(np.uint8), size=size, mode="constant",
                                  cval=0).view(bool) & filled


def pillar_columns(shape, phase=(0, 0)) -> np.ndarray:
    """(nx, ny) bool: the columns of the pillar lattice, whose first column is at index
    ``-phase`` (a grid cropped from a bigger one by ``phase`` cells keeps its pillars)."""
    i = (np.arange(shape[0]) + int(phase[0])) % PILLAR_PITCH < PILLAR_STUDS
    j = (np.arange(shape[1]) + int(phase[1])) % PILLAR_PITCH < PILLAR_STUDS
    return i[:, None] & j[None, :]


def hollow(grid: Grid, studs: int = SHELL_STUDS, keep: np.ndarray | None = None,
           phase=(0, 0)) -> tuple[Grid, int, int]:
    """The grid of the cells to keep with a ``studs``-thick shell (see the module
    docstring), with the number of pillar cells and of ``keep`` cells kept that
    would otherwise go; ``phase`` as :func:`pillar_columns`.  ``grid`` is not changed."""
    filled = np.asarray(grid.filled, dtype=bool)
    inner = interior(filled, studs, layers_for(studs, grid.cell))
    pillars = inner & pillar_columns(filled.shape, phase)[:, :, None]
    gone = inner & ~pillars
    kept_solid = 0
    if keep is not None:
        keep = np.asarray(keep, dtype=bool)
        kept_solid = int(np.count_nonzero(gone & keep))
        gone &= ~keep
    out = Grid(origin=np.array(grid.origin, dtype=float), cell=np.array(grid.cell, dtype=float),
               filled=filled & ~gone)
    return out, int(np.count_nonzero(pillars)), kept_solid


def decide(grid: Grid, setting: int = -1, keep: np.ndarray | None = None,
           phase=(0, 0), how: str | None = None) -> Hollowing:
    """Apply the hollow ``setting`` to ``grid`` (``keep``: cells that stay solid; ``phase``
    of the pillars as :func:`pillar_columns`; ``how`` it was asked for, in the report's
    sentence: by default "automatically" or "as asked").

    -1: hollow with a :data:`SHELL_STUDS` shell when the part has at least
    :data:`AUTO_MIN_CELLS` cells and that keeps at most :data:`AUTO_KEEP_SHARE`
    of them; 0: solid; n: hollow with an n-stud shell.  InputError for
    another setting.  ``grid`` is not changed.
    """
    setting = check_setting(setting)
    solid = grid.count
    studs = SHELL_STUDS if setting < 0 else setting
    if setting == 0:
        return Hollowing(grid, 0, 0, 0, solid, solid, 0, 0, "kept solid (--hollow=0)")
    if setting < 0 and solid < AUTO_MIN_CELLS:
        return Hollowing(grid, setting, 0, 0, solid, solid, 0, 0,
                         f"kept solid: {solid:,} cells, automatic hollowing starts at "
                         f"{AUTO_MIN_CELLS:,}")
    out, pillars, kept_solid = hollow(grid, studs, keep, phase)
    kept = out.count
    layers = layers_for(studs, grid.cell)
    share = kept / max(solid, 1)
    if setting < 0 and share > AUTO_KEEP_SHARE:
        return Hollowing(grid, setting, 0, 0, solid, solid, 0, 0,
                         f"kept solid: a {studs}-stud shell would keep {share:.0%} of the "
                         f"{solid:,} cells (automatic hollowing needs it to save more than a third)")
    how = how or ("automatically" if setting < 0 else "as asked")
    why = (f"hollowed {how}: a {studs}-stud shell ({layers} layers top and bottom) with "
           f"{PILLAR_STUDS}x{PILLAR_STUDS}-stud pillars every {PILLAR_PITCH} studs keeps "
           f"{kept:,} of {solid:,} cells ({share:.0%}); --hollow=0 builds it solid")
    return Hollowing(out, setting, studs, layers, solid, kept, pillars, kept_solid, why)


def surely_saves(h: Hollowing, bricks: int, largest_cells: int) -> bool:
    """Whether the hollow layout of ``bricks`` bricks surely saves more than a third of
    the bricks of the solid part: no part covers more than ``largest_cells`` cells, so
    the solid part needs at least ``solid_cells / largest_cells`` bricks."""
    return bricks < AUTO_KEEP_SHARE * math.ceil(h.solid_cells / largest_cells)


def judged(h: Hollowing, bricks: int, largest_cells: int) -> Hollowing | None:
    """An automatic shell of ``bricks`` bricks kept because it :func:`surely_saves` a third of
    the bricks (its ``why`` says so), or None when only a solid layout can tell."""
    if not surely_saves(h, bricks, largest_cells):
        return None
    least = math.ceil(h.solid_cells / largest_cells)
    return dataclasses.replace(h, bricks_hollow=bricks, why=h.why + (
        f"; it saves more than a third of the bricks ({bricks:,}, where solid needs at least "
        f"{least:,}: no part covers more than {largest_cells} cells)"))


def solid_layout_wanted(h: Hollowing, bricks: int, largest_cells: int) -> bool:
    """Whether the driver lays out the solid part too, beside the shell ``h`` laid out in
    ``bricks`` bricks (then :func:`compared`): for an automatic shell that does not
    :func:`surely_saves` a third of the bricks, since only the solid layout can tell, and
    for any shell whose solid part has at most :data:`SOLID_LAYOUT_MAX_CELLS` cells, so that
    the report gives its bricks.  Never for a part kept solid."""
    if not h.on:
        return False
    return h.solid_cells <= SOLID_LAYOUT_MAX_CELLS or (
        h.setting < 0 and not surely_saves(h, bricks, largest_cells))


def compared(h: Hollowing, solid: Grid, bricks_hollow: int, bricks_solid: int) -> Hollowing:
    """The shell ``h`` once both the shell and the ``solid`` part were laid out, in
    ``bricks_hollow`` and ``bricks_solid`` bricks: a shell asked for stays, holding both
    counts; an automatic one only when ``bricks_hollow`` are fewer than two thirds of
    ``bricks_solid``, else the part is kept solid."""
    if h.setting > 0:
        return dataclasses.replace(h, bricks_hollow=bricks_hollow, bricks_solid=bricks_solid)
    if bricks_hollow < AUTO_KEEP_SHARE * bricks_solid:
        return dataclasses.replace(h, bricks_hollow=bricks_hollow, bricks_solid=bricks_solid,
                                   why=h.why + f"; it saves more than a third of the bricks: "
                                   f"{bricks_hollow:,} instead of {bricks_solid:,} solid")
    return Hollowing(solid, h.setting, 0, 0, h.solid_cells, h.solid_cells, 0, 0,
                     f"kept solid: hollow it would take {bricks_hollow:,} bricks, solid "
                     f"{bricks_solid:,} (automatic hollowing needs it to save more than a third; "
                     f"a shell of an uneven part is all small bricks); --hollow builds it hollow",
                     bricks_hollow, bricks_solid)


def as_before(grid: Grid, studs: int, setting: int, keep: np.ndarray | None,
              phase) -> Hollowing:
    """A new version of a part hollowed as its previous version was: its ``studs``-thick
    shell (0: solid), unless the request's ``setting`` asks otherwise (0 solid, n studs;
    -1 keeps the previous thickness).  The pillars keep the previous lattice (``phase``:
    previous index = index + phase), so that unchanged cells stay unchanged."""
    if check_setting(setting) >= 0:
        return decide(grid, setting, keep, phase)
    if studs == 0:
        return Hollowing(grid, -1, 0, 0, grid.count, grid.count, 0, 0,
                         "kept solid, as the previous version")
    return dataclasses.replace(decide(grid, studs, keep, phase, "as the previous version"),
                               setting=-1)
