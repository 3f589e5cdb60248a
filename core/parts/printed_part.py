"""What a printed part is: the record of one part, and the model as the operand it is cut from.

:class:`PrintedPart` holds one part's bricks, its solid and watertight mesh, its studs and
sockets by cell (and whether each is there), what it kept of the model, the bars that join
loose pieces, its thin features and engraving, and what export and print time add (files,
pose, print time); :meth:`PrintedPart.to_json` is its report.json entry.  :class:`ModelSolid`
is the model as a Boolean operand: always a manifold3d Manifold, and the OpenCascade solid
for B-rep input.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import manifold3d as m3
import trimesh

if TYPE_CHECKING:  # OpenCascade is imported where B-rep parts are made
    from OCP.TopoDS import TopoDS_Shape


@dataclass
class ModelSolid:
    """The model as a Boolean operand: an OCC solid (B-rep input) and always a
    manifold3d Manifold of its closed mesh (to measure where the model is)."""

    manifold: m3.Manifold
    brep: TopoDS_Shape | None = None

    @property
    def kind(self) -> str:
        return "brep" if self.brep is not None else "mesh"


@dataclass
class PrintedPart:
    """One printed part: the model inside its bricks, with studs and sockets where it meets LEGO.

    ``bricks`` are layout brick ids, ``cells`` the number of 1x1 plate cells
    they cover; ``solid`` the OCC shape (B-rep input; None for mesh input,
    whose exact result is ``mesh``); ``mesh`` a watertight tessellation in
    model mm.  ``studs`` / ``sockets`` map ``"i,j,k"`` of each cell where
    the part meets another brick above / below to True when a stud /
    socket is there (False with connectors switched off).  ``top_ok`` /
    ``bottom_ok`` map those grid cells (i, j, k) to the same, for the
    stability check.  ``kept_mm3`` is the model's volume inside the
    envelope (before studs and sockets), ``envelope_mm3`` the part's cells'
    volume; ``joins`` the bars that join loose pieces; ``method`` which
    Booleans made it; ``thin`` where the printed part is thinner than a
    0.4 mm nozzle prints (:func:`core.parts.thickness.thin_features`).  ``engraved`` says
    whether the id is cut into a side; ``engraving`` is then a dict saying
    where (brick, side, centre, outward normal, text size, font size,
    depth), else the reason why not.  ``stl``, ``step``, ``pose`` and
    ``print_s`` are filled by export and print time.
    """

    id: str
    bricks: list[int]
    cells: int
    solid: object | None
    mesh: trimesh.Trimesh
    volume_mm3: float
    studs: dict[str, bool] = field(default_factory=dict)
    sockets: dict[str, bool] = field(default_factory=dict)
    top_ok: dict[tuple[int, int, int], bool] = field(default_factory=dict)
    bottom_ok: dict[tuple[int, int, int], bool] = field(default_factory=dict)
    pieces: int = 1
    kept_mm3: float = 0.0
    envelope_mm3: float = 0.0
    joins: list = field(default_factory=list)
    method: str = ""
    thin: dict = field(default_factory=dict)
    engraved: bool = False
    engraving: dict | str = "not engraved: engraving switched off"
    stl: str | None = None
    step: str | None = None
    print_s: float | None = None
    pose: dict | None = None

    @property
    def complete_studs(self) -> list[str]:
        return sorted(k for k, v in self.studs.items() if v)

    @property
    def incomplete_studs(self) -> list[str]:
        return sorted(k for k, v in self.studs.items() if not v)

    @property
    def complete_sockets(self) -> list[str]:
        return sorted(k for k, v in self.sockets.items() if v)

    @property
    def incomplete_sockets(self) -> list[str]:
        return sorted(k for k, v in self.sockets.items() if not v)

    @property
    def engaged(self) -> dict:
        """Studs and sockets engaged with the bricks above and below, and whether
        that is enough to hold the part (two or more), with the reason when not."""
        studs = sum(self.studs.values())
        sockets = sum(self.sockets.values())
        out = {"studs": int(studs), "sockets": int(sockets)}
        if studs + sockets >= 2:
            return {**out, "clamps": True}
        if not self.studs and not self.sockets:
            why = "no brick of another part lies directly above or below it (it touches them only sideways, or not at all)"
        elif studs + sockets < len(self.studs) + len(self.sockets):
            why = "studs and sockets are switched off (--no-connectors)"
        else:
            why = "it meets another brick above or below in only one cell"
        return {**out, "clamps": False, "why": f"fewer than two studs and sockets engaged: {why}"}

    def to_json(self) -> dict:
        return {
            "id": self.id, "bricks": list(self.bricks), "cells": self.cells,
            "volume_mm3": round(self.volume_mm3, 3), "pieces": self.pieces,
            "kept_mm3": round(self.kept_mm3, 3), "envelope_mm3": round(self.envelope_mm3, 3),
            "joins": list(self.joins), "method": self.method,
            "thin_features": dict(self.thin),
            "stl": self.stl, "step": self.step,
            "print_s": None if self.print_s is None else round(self.print_s, 1),
            "engaged": self.engaged,
            "complete_studs": len(self.complete_studs),
            "incomplete_studs": self.incomplete_studs,
            "engraved": self.engraved,
            "engraving": self.engraving,
            "print_pose": self.pose,
        }
