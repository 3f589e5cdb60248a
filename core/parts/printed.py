"""Printed parts: the model inside the marked bricks, kept whole, plus studs and sockets.

The paper printed each marked brick as the LEGO brick solid intersected
with the model, which carves the brick's hollow underside into exactly the
geometry the user marked as exact.  Here a printed part is

    ((model ∩ envelope) ∪ connector material) − socket holes

where the envelope is the part's cells (held back by LEGO's 0.1 mm play
only on the sides that face a brick of another part), and the connector
material, the studs and the socket holes exist only where the part meets a
brick of another part directly above or below it (:mod:`core.parts.connectors`
finds those cells, :func:`core.parts.interfaces.plan` lays the solids out).  No
cavity anywhere else: over air, on the grid's bottom and over other bricks
of the same part the model is kept exactly.

* **B-rep models** (STEP, FCStd) are cut with OpenCascade (the part is an
  exact solid: its STEP has true cylinders for the studs); **meshes** with
  manifold3d.  A model of several solids or shells is first made one solid
  (their union, :func:`model_solid`).
* **Studs and sockets are complete by construction**: they are added after
  the intersection, so the model cannot cut them.  ``studs`` / ``sockets``
  of a part list them by cell; without connectors (``connectors=False``)
  the same cells are listed as missing, so the stability check knows the
  part does not clamp there.
* **One solid.**  When the model inside the envelope falls into several
  pieces, each loose piece is joined to the rest by the shortest bar that
  stays inside the envelope (:data:`BAR_MM` square, reported in
  ``joins``); when no such bar exists the part is refused in one line.
"""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import manifold3d as m3
import numpy as np
import trimesh
from scipy.spatial import cKDTree

from core import high_res
from core.errors import InputError
from core.io.meshes import LoadedModel
from core.model import Brick, Layout
from core.parts import connectors as connectors_stage, interfaces, thickness
from core.parts.interfaces import Fit

if TYPE_CHECKING:  # OpenCascade and cadquery are imported where B-rep parts are made
    import cadquery as cq
    from OCP.TopoDS import TopoDS_Shape

#: Depth (mm) of the engraved part id.
ENGRAVE_DEPTH_MM = 0.5
#: Wall (mm) that must stay behind the engraved letters.
ENGRAVE_KEEP_MM = 0.4
#: Free border (mm) around the text on its side face.
ENGRAVE_MARGIN_MM = 0.4
#: Font sizes (mm) tried for the id, largest first.
ENGRAVE_FONT_SIZES = (5.0, 4.0, 3.0, 2.5)
#: How far (mm) the cutting text starts outside the face (no coplanar Boolean faces).
ENGRAVE_OVERSHOOT_MM = 0.2
#: Steps (mm) in which the id is moved along a side when its centre is covered or not whole.
ENGRAVE_STEP_MM = 4.0
#: Free space (mm) the engraved side must have in front of it (else the side is covered).
ENGRAVE_CLEAR_MM = 1.0
#: The font of the id (DejaVu Sans Bold, Debian fonts-dejavu-core).
ENGRAVE_FONT = "/usr/share/fonts/truetype/dejavu/DejaVuSans-Bold.ttf"
#: The system's fontconfig configuration, given to OpenCascade's bundled fontconfig.
SYSTEM_FONTS_CONF = "/etc/fonts/fonts.conf"
#: Side (mm) of the square bar that joins a loose piece of a part to the rest.
BAR_MM = 2.0
#: Segments of a stud's circle in a mesh part (the B-rep part has a true cylinder).
STUD_SEGMENTS = 96
#: Tessellation of a B-rep part's STL: linear (mm) and angular (rad) deflection, fine
#: enough that a stud's flats are within 0.01 mm of its diameter.
MESH_TOL_MM = 0.01
MESH_ANGLE_RAD = 0.1
#: Fuzzy tolerance (mm) of the part's OpenCascade Booleans.
FUZZY_MM = 1e-5
#: Thickness (mm) of the weld that fills an edge where a part touches itself.
WELD_MM = 0.4
#: A piece of a part smaller than this (mm³) is a Boolean crumb, dropped.
CRUMB_MM3 = 1e-3


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


def model_solid(model: LoadedModel) -> ModelSolid:
    """The model as one Boolean operand: the union of its solids (B-rep) or shells (mesh).

    A mesh of several closed shells becomes their union (a shell inside
    another that faces inward stays a cavity); a B-rep of several solids is
    fused into one.  Raises :class:`InputError` when a mesh model is not a
    closed oriented 2-manifold (an open or self-touching mesh cannot be
    intersected exactly), a B-rep model has no solid or its solids cannot
    be fused.
    """
    manifold = _union_of_shells(model.mesh)
    if manifold.status() != m3.Error.NoError or manifold.is_empty():
        raise InputError(f"{model.path}: the mesh is not a closed manifold solid "
                         f"({manifold.status().name}), so printed parts cannot be cut from it")
    brep = None
    if model.brep is not None:
        solids = _solids(model.brep)
        if not solids:
            raise InputError(f"{model.path}: the file has no solid to cut printed parts from")
        brep = solids[0] if len(solids) == 1 else _fused(solids, model.path)
    return ModelSolid(manifold=manifold, brep=brep)


def _fused(solids: list, path) -> TopoDS_Shape:
    """The union of the model's B-rep ``solids``; InputError naming ``path`` when
    OpenCascade cannot fuse them (the model's geometry defeats the Boolean)."""
    from OCP.BRepAlgoAPI import BRepAlgoAPI_Fuse

    from core.parts.brick_solids import BooleanFailed, run_boolean
    try:
        return _unify(run_boolean(BRepAlgoAPI_Fuse(), solids[0], list(solids[1:]), None, True))
    except BooleanFailed:
        raise InputError(f"{path}: OpenCascade could not fuse its {len(solids)} solids into one, "
                         "so printed parts cannot be cut from it") from None


def _union_of_shells(mesh: trimesh.Trimesh) -> m3.Manifold:
    """The closed ``mesh`` as one Manifold: its shells united, inward-facing shells subtracted."""
    whole = _manifold(mesh)
    if whole.status() != m3.Error.NoError:
        return whole
    shells = mesh.split(only_watertight=False)
    if len(shells) <= 1:
        return whole
    outward = [_manifold(s) for s in shells if s.volume > 0]
    inward = []
    for shell in (s.copy() for s in shells if s.volume < 0):
        shell.invert()
        inward.append(_manifold(shell))
    if not outward or any(m.status() != m3.Error.NoError for m in outward + inward):
        return whole
    union = m3.Manifold.batch_boolean(outward, m3.OpType.Add) if len(outward) > 1 else outward[0]
    if inward:
        union = union - m3.Manifold.batch_boolean(inward, m3.OpType.Add)
    return m3.Manifold(union.to_mesh64())


def merge(groups: list[list[int]], brick_ids) -> list[list[int]]:
    """Groups with every group holding any of ``brick_ids`` (and those bricks) made one."""
    ids = {int(i) for i in brick_ids}
    joined = sorted(ids.union(*[g for g in groups if ids & set(g)]))
    rest = [list(g) for g in groups if not ids & set(g)]
    return rest + ([joined] if joined else [])


def split(groups: list[list[int]], brick_ids) -> list[list[int]]:
    """Groups with each of ``brick_ids`` taken out into a part of its own."""
    ids = {int(i) for i in brick_ids}
    out = [[b for b in g if b not in ids] for g in groups]
    return [g for g in out if g] + [[i] for i in sorted(ids)]


def fitting_groups(layout: Layout, groups: list[list[int]], volume,
                   fit: Fit = Fit()) -> tuple[list[list[int]], list[tuple[list[float], int]]]:
    """``groups`` with each one whose box (its bricks' cells and a stud on top) fits the
    printer's build ``volume`` (x, y, z mm) in no orientation cut along layer seams (levels
    no brick of it crosses) into slabs as tall as ``volume`` allows standing, each slab's
    connected pieces (:func:`core.high_res.groups`) a group of its own; pieces stacked
    this way clamp each other with their own studs and sockets (:func:`build_parts`).
    A group whose every layer is wider than the bed stays whole.  Returns the groups and,
    per group that was cut, (its box in mm, how many groups it became)."""
    by_id = {b.id: b for b in layout.bricks}
    cell = np.asarray(layout.grid.cell, dtype=float)
    room = np.sort(np.asarray(volume, dtype=float)) + 1e-6
    layers = int((float(volume[2]) - fit.stud_height) // cell[2])
    out: list[list[int]] = []
    cut: list[tuple[list[float], int]] = []
    for group in groups:
        bricks = [by_id[i] for i in group]
        lo = np.min([b.cell for b in bricks], axis=0)
        hi = np.max([np.add(b.cell, b.size) for b in bricks], axis=0)
        box = (hi - lo) * cell + (0.0, 0.0, fit.stud_height)
        if np.all(np.sort(box) <= room) or layers < 1 or hi[2] - lo[2] <= layers:
            out.append(list(group))
            continue
        crossed = {z for b in bricks for z in range(b.cell[2] + 1, b.cell[2] + b.size[2])}
        start, slabs = int(lo[2]), []
        while start < hi[2]:
            seams = [z for z in range(start + 1, min(start + layers, int(hi[2])) + 1) if z not in crossed]
            end = max(seams) if seams else int(hi[2])
            slabs.append([b.id for b in bricks if start <= b.cell[2] < end])
            start = end
        pieces = [piece for slab in slabs if slab for piece in high_res.groups(layout, slab)]
        out += pieces
        cut.append(([round(float(v), 1) for v in box], len(pieces)))
    return out, cut


def build_parts(layout: Layout, groups: list[list[int]], source: ModelSolid, fit: Fit = Fit(),
                connectors: bool = True, engrave: bool = True,
                links: connectors_stage.Connectors | None = None) -> list[PrintedPart]:
    """One :class:`PrintedPart` per group of brick ids, named P1, P2, ... in group order.

    Every group must be face-to-face connected (InputError otherwise: a
    merge brush joined parts that do not touch), and no brick may be in two
    groups (ValueError: the caller's groups are wrong).  With ``connectors``
    every cell where a part meets a brick of another group or a LEGO brick
    directly above or below gets a stud or a socket; ``links`` are those
    cells when the caller already has them (:func:`core.parts.connectors.find` of
    ``groups``).  Does not change ``layout``; see :func:`apply`.
    """
    seen: set[int] = set()
    for g in groups:
        if seen & set(g):
            raise ValueError(f"brick(s) {sorted(seen & set(g))[:5]} are in two printed parts")
        seen |= set(g)
        high_res.check_ids(layout, g)
        if not high_res.is_connected(layout, g):
            raise InputError(f"bricks {sorted(g)[:8]} do not touch face to face; "
                             "a merged printed part must be one piece")
    fit.check()
    by_id = {b.id: b for b in layout.bricks}
    links = connectors_stage.find(layout, groups) if links is None else links
    return [build_part(f"P{n + 1}", [by_id[i] for i in sorted(g)], layout, source, fit, links,
                       connectors, engrave)
            for n, g in enumerate(groups)]


def apply(layout: Layout, parts: list[PrintedPart]) -> Layout:
    """A new layout: ``layout`` with the bricks of ``parts`` marked printed (kind and
    printed_part); ``layout`` itself is not changed."""
    owner = {b: p.id for p in parts for b in p.bricks}
    return Layout(layout.grid, [dataclasses.replace(b, kind="printed", printed_part=owner[b.id])
                                if b.id in owner else b for b in layout.bricks])


def clamp_masks(layout: Layout, parts: list[PrintedPart]) -> tuple[np.ndarray, np.ndarray]:
    """Grid-shaped bool arrays (studs_ok, bottom_ok) for :func:`core.stability.brick_graph`.

    ``studs_ok`` is False at the top-layer cells of printed parts that meet
    a brick above without a stud; ``bottom_ok`` False at bottom-layer cells
    that stand on a brick without a socket; True elsewhere.
    """
    studs_ok = np.ones(layout.grid.shape, dtype=bool)
    bottom_ok = np.ones(layout.grid.shape, dtype=bool)
    for p in parts:
        for cell, ok in p.top_ok.items():
            studs_ok[cell] = ok
        for cell, ok in p.bottom_ok.items():
            bottom_ok[cell] = ok
    return studs_ok, bottom_ok


def build_part(part_id: str, bricks: list[Brick], layout: Layout, source: ModelSolid,
               fit: Fit = Fit(), links: connectors_stage.Connectors | None = None,
               connectors: bool = True, engrave: bool = True, thin: bool = True) -> PrintedPart:
    """The printed part made of ``bricks`` (one connected group of the layout).

    ``links`` are the connector cells of the layout's printed parts
    (:func:`core.parts.connectors.find`; found for ``bricks`` alone when None).
    Without ``engrave`` the id is not cut in; without ``thin`` its thin features
    are not looked for (``thin`` stays empty).
    Promises: the result is one valid closed solid (its mesh watertight)
    that equals the model inside the envelope except for the studs, the
    sockets and the material that carries them (:func:`core.parts.interfaces.plan`)
    and the bars that join loose pieces; it lies inside the bricks' cells
    but for the studs on top.  Raises :class:`InputError` when nothing of
    the model lies in the bricks, or its pieces cannot be joined inside them.
    """
    grid = layout.grid
    ids = {b.id for b in bricks}
    lab = layout.labels()
    id_of = np.array([b.id for b in layout.bricks] + [-1], dtype=np.int64)
    mine = np.isin(id_of[lab], list(ids)) & (lab >= 0)
    other = (lab >= 0) & ~mine
    if links is None:
        links = connectors_stage.find(layout, [sorted(ids)])
    top = np.array([c for c in links.top.tolist() if mine[tuple(c)]], dtype=int).reshape(-1, 3)
    bottom = np.array([c for c in links.bottom.tolist() if mine[tuple(c)]], dtype=int).reshape(-1, 3)
    lo_all = grid.origin + np.min([b.cell for b in bricks], axis=0) * grid.cell
    hi_all = grid.origin + np.max([np.add(b.cell, b.size) for b in bricks], axis=0) * grid.cell
    near = source.manifold ^ _cube(lo_all - 1.0, hi_all + 1.0)
    layout_plan = interfaces.plan(grid.origin, grid.cell, mine, other,
                                  [(b.cell, b.size) for b in bricks],
                                  top if connectors else np.zeros((0, 3), int),
                                  bottom if connectors else np.zeros((0, 3), int),
                                  lambda lo, hi: _extent(near, lo, hi), fit)
    method = "OpenCascade (exact B-rep)" if source.kind == "brep" else "manifold3d (mesh)"
    engine = _Brep(source.brep) if source.kind == "brep" else _Mesh(source.manifold)
    try:
        shape, mesh, envelope, kept_mm3, joins = _cut(part_id, engine, layout_plan, lo_all, hi_all, grid,
                                                mine, fit)
    except _InvalidSolid as why:
        if isinstance(engine, _Mesh):
            raise RuntimeError(f"printed part {part_id} came out as {why}") from None
        method = f"manifold3d on the model's mesh (the B-rep result was {why})"
        engine = _Mesh(source.manifold)
        try:
            shape, mesh, envelope, kept_mm3, joins = _cut(part_id, engine, layout_plan, lo_all, hi_all,
                                                    grid, mine, fit)
        except _InvalidSolid as again:
            raise RuntimeError(f"printed part {part_id} came out as {again}") from None
    names = {tuple(c): ",".join(map(str, c)) for c in np.concatenate([top, bottom]).tolist()}
    studs = {names[tuple(c)]: connectors for c in top.tolist()}
    sockets = {names[tuple(c)]: connectors for c in bottom.tolist()}
    part = PrintedPart(id=part_id, bricks=sorted(ids),
                       cells=int(sum(np.prod(b.size) for b in bricks)),
                       solid=shape if isinstance(engine, _Brep) else None, method=method,
                       mesh=mesh, volume_mm3=engine.volume(shape),
                       studs=studs, sockets=sockets,
                       top_ok={tuple(c): connectors for c in top.tolist()},
                       bottom_ok={tuple(c): connectors for c in bottom.tolist()},
                       pieces=1, kept_mm3=kept_mm3,
                       envelope_mm3=engine.volume(envelope), joins=joins)
    if engrave:
        _engrave(part, bricks, grid, mine, other, fit, engine)
    if thin:
        part.thin = thickness.thin_features(part.mesh)
    return part


class _InvalidSolid(Exception):
    """The B-rep Booleans gave a shape that is not one valid solid; the message says how."""


def _cut(part_id: str, engine, layout_plan, lo_all, hi_all, grid, mine, fit: Fit):
    """The part's solid from its :class:`core.parts.interfaces.Plan` with ``engine``:
    (solid, its mesh, envelope, model volume kept in the envelope, joins)."""
    envelope = engine.cut(engine.union([engine.box(lo, hi) for lo, hi in layout_plan.envelope]),
                          [engine.box(lo, hi) for lo, hi in layout_plan.play])
    kept = engine.common(envelope, lo_all - 1.0, hi_all + 1.0)
    kept_mm3 = engine.volume(kept)
    if kept_mm3 <= CRUMB_MM3:
        raise InputError(f"printed part {part_id}: the model does not reach into its bricks")
    kept, joins = _joined(part_id, engine, kept, envelope, grid, mine)
    shape = engine.union([kept]
                         + [engine.box(lo, hi) for lo, hi in layout_plan.fills]
                         + [engine.taper(t) for t in layout_plan.tapers]
                         + [engine.cylinder(x, y, z0, z1, fit.stud_diameter / 2)
                            for x, y, z0, z1 in layout_plan.studs])
    shape = engine.cut(shape, [engine.box(lo, hi) for lo, hi in layout_plan.holes])
    return (*_finished(engine, shape, part_id), envelope, kept_mm3, joins)


def _finished(engine, shape, part_id: str, rounds: int = 3):
    """``shape`` as one solid (:meth:`only_solid`) and its watertight mesh, tessellated
    once per round: every edge where it touches itself (four faces on one edge, as where
    a model edge meets a socket's corner exactly) is filled by a box :data:`WELD_MM`
    thick round the edge, up to ``rounds`` times, so that its STL is a 2-manifold.
    Raises :class:`_InvalidSolid` when the mesh is still not watertight."""
    for n in range(rounds + 1):
        solid = engine.only_solid(shape, part_id)
        mesh = engine.mesh(solid)
        edges, counts = np.unique(mesh.edges_sorted, axis=0, return_counts=True)
        touching = edges[counts > 2]
        if len(touching) == 0 or n == rounds:
            break
        ends = mesh.vertices[touching]
        shape = engine.union([solid] + [engine.box(e.min(axis=0) - WELD_MM / 2, e.max(axis=0) + WELD_MM / 2)
                                        for e in ends])
    if not mesh.is_watertight:
        raise _InvalidSolid("a solid whose tessellation is not watertight")
    return solid, mesh


def _extent(model: m3.Manifold, lo, hi) -> tuple[np.ndarray, np.ndarray] | None:
    """The bounding box (min, max corner) of ``model`` inside the box (lo, hi), None
    where it has no volume there."""
    inside = model ^ _cube(lo, hi)
    if inside.is_empty() or inside.volume() <= CRUMB_MM3:
        return None
    box = np.asarray(inside.bounding_box(), dtype=float)
    return box[:3], box[3:]


def _cube(lo, hi) -> m3.Manifold:
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    return m3.Manifold.cube(list(hi - lo)).translate(list(lo))


def _joined(part_id: str, engine, kept, envelope, grid, mine: np.ndarray):
    """``kept`` with every loose piece joined to the largest by :data:`BAR_MM` bars
    clipped to ``envelope``; the bars as JSON.

    Joins the pieces one at a time, the piece nearest to the growing whole
    first: by the straight bar between their nearest points when that joins
    them inside the envelope, else by a bar from the piece through the
    centres of the part's cells (``mine``, face-adjacent, fewest cells) to
    the whole.  Raises InputError when neither joins them."""
    pieces = engine.pieces(kept)
    if len(pieces) <= 1:
        return kept, []
    pieces.sort(key=engine.volume, reverse=True)
    whole, rest, joins = pieces[0], pieces[1:], []
    while rest:
        target = _surface_points(engine.mesh(whole))
        tree = cKDTree(target)
        best = None
        for n, piece in enumerate(rest):
            points = _surface_points(engine.mesh(piece))
            dist, idx = tree.query(points)
            m = int(np.argmin(dist))
            if best is None or dist[m] < best[0]:
                best = (float(dist[m]), n, points[m], target[idx[m]])
        gap, n, a, b = best
        piece = rest.pop(n)
        joined = None
        for route in ([a, b], _cell_route(a, b, grid, mine)):
            if route is None:
                continue
            bars = engine.union([engine.bar(p, q, BAR_MM) for p, q in zip(route[:-1], route[1:])])
            candidate = engine.union([whole, piece, engine.intersect(bars, envelope)])
            if len(engine.pieces(candidate)) == 1:
                joined = (candidate, route)
                break
        if joined is None:
            raise InputError(f"printed part {part_id}: the model inside its bricks is "
                             f"{len(pieces)} loose pieces that cannot be joined inside them; "
                             f"mark a region that holds them together, or split the part")
        whole, route = joined
        joins.append({"path_mm": [[round(float(v), 3) for v in p] for p in route],
                      "length_mm": round(float(sum(np.linalg.norm(np.subtract(q, p))
                                                   for p, q in zip(route[:-1], route[1:]))), 3),
                      "bar_mm": BAR_MM})
    return whole, joins


def _cell_route(a, b, grid, mine: np.ndarray) -> list | None:
    """Points from ``a`` through the centres of the fewest face-adjacent cells of
    ``mine`` to ``b``, or None when their cells are not connected in ``mine``."""
    import networkx as nx
    cell = np.asarray(grid.cell, float)
    origin = np.asarray(grid.origin, float)

    def cell_of(point):
        c = np.floor((np.asarray(point) - origin) / cell).astype(int)
        return tuple(np.clip(c, 0, np.array(mine.shape) - 1))

    graph = nx.Graph()
    cells = [tuple(map(int, c)) for c in np.argwhere(mine)]
    graph.add_nodes_from(cells)
    members = set(cells)
    for c in cells:
        for axis in range(3):
            n = list(c)
            n[axis] += 1
            if tuple(n) in members:
                graph.add_edge(c, tuple(n))
    start, end = cell_of(a), cell_of(b)
    if start not in members or end not in members:
        return None
    try:
        path = nx.shortest_path(graph, start, end)
    except nx.NetworkXNoPath:
        return None
    return [np.asarray(a, float)] + [origin + (np.array(c) + 0.5) * cell for c in path] + [np.asarray(b, float)]


def _surface_points(mesh: trimesh.Trimesh, count: int = 4000) -> np.ndarray:
    """Vertices and evenly spread surface samples of ``mesh`` (deterministic)."""
    samples = trimesh.sample.sample_surface_even(mesh, count, seed=0)[0] if len(mesh.faces) else np.zeros((0, 3))
    return np.concatenate([np.asarray(mesh.vertices), samples])


class _Mesh:
    """The part's Booleans on manifold3d Manifolds (mesh models)."""

    def __init__(self, model: m3.Manifold):
        self.model = model

    def box(self, lo, hi) -> m3.Manifold:
        return _cube(lo, hi)

    def cylinder(self, x, y, z0, z1, r) -> m3.Manifold:
        return m3.Manifold.cylinder(float(z1 - z0), float(r), -1.0, STUD_SEGMENTS).translate([x, y, z0])

    def bar(self, a, b, side) -> m3.Manifold:
        return _bar_hull(np.asarray(a), np.asarray(b), side)

    def taper(self, rects) -> m3.Manifold:
        return m3.Manifold.hull_points(_rect_corners(rects).reshape(-1, 3).tolist())

    def union(self, shapes):
        return shapes[0] if len(shapes) == 1 else m3.Manifold.batch_boolean(shapes, m3.OpType.Add)

    def cut(self, shape, tools):
        return shape if not tools else shape - self.union(tools)

    def intersect(self, a, b):
        return a ^ b

    def common(self, envelope, lo, hi):
        return m3.Manifold(((self.model ^ _cube(lo, hi)) ^ envelope).to_mesh64())

    def volume(self, shape) -> float:
        return float(shape.volume())

    def pieces(self, shape) -> list:
        return [p for p in shape.decompose() if p.volume() > CRUMB_MM3]

    def only_solid(self, shape, part_id: str):
        pieces = self.pieces(shape)
        if len(pieces) != 1:
            raise _InvalidSolid(f"{len(pieces)} pieces")
        return m3.Manifold(pieces[0].to_mesh64())

    def mesh(self, shape) -> trimesh.Trimesh:
        out = shape.to_mesh64()
        mesh = trimesh.Trimesh(np.asarray(out.vert_properties, np.float64)[:, :3],
                               np.asarray(out.tri_verts, np.int64), process=False)
        mesh.merge_vertices()
        return mesh


def _bar_hull(a: np.ndarray, b: np.ndarray, side: float) -> m3.Manifold:
    """The convex hull of two axis-aligned cubes of ``side`` centred on ``a`` and ``b``."""
    corners = np.array(np.meshgrid(*[[-side / 2, side / 2]] * 3, indexing="ij")).reshape(3, -1).T
    return m3.Manifold.hull_points(np.concatenate([a + corners, b + corners]).tolist())


def _rect_corners(rects: np.ndarray) -> np.ndarray:
    """(2, 4, 3): the corners, in order round, of the two flat rectangles of a taper."""
    out = []
    for lo, hi in (rects[:2], rects[2:]):
        z = lo[2]
        out.append([[lo[0], lo[1], z], [hi[0], lo[1], z], [hi[0], hi[1], z], [lo[0], hi[1], z]])
    return np.asarray(out, dtype=float)


class _Brep:
    """The part's Booleans on OpenCascade shapes (B-rep models)."""

    def __init__(self, model: TopoDS_Shape):
        self.model = model

    def box(self, lo, hi) -> TopoDS_Shape:
        from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox
        from OCP.gp import gp_Pnt
        return BRepPrimAPI_MakeBox(gp_Pnt(*map(float, lo)), gp_Pnt(*map(float, hi))).Shape()

    def cylinder(self, x, y, z0, z1, r) -> TopoDS_Shape:
        from OCP.BRepPrimAPI import BRepPrimAPI_MakeCylinder
        from OCP.gp import gp_Ax2, gp_Dir, gp_Pnt
        axis = gp_Ax2(gp_Pnt(float(x), float(y), float(z0)), gp_Dir(0, 0, 1))
        return BRepPrimAPI_MakeCylinder(axis, float(r), float(z1 - z0)).Shape()

    def bar(self, a, b, side) -> TopoDS_Shape:
        from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox
        from OCP.gp import gp_Ax2, gp_Dir, gp_Pnt
        a, b = np.asarray(a, float), np.asarray(b, float)
        axis = b - a
        length = float(np.linalg.norm(axis))
        direction = axis / length if length > 1e-9 else np.array([0.0, 0.0, 1.0])
        frame = gp_Ax2(gp_Pnt(0, 0, 0), gp_Dir(*direction))
        x, y = (np.array([v.X(), v.Y(), v.Z()]) for v in (frame.XDirection(), frame.YDirection()))
        corner = a - direction * side / 2 - (x + y) * side / 2
        return BRepPrimAPI_MakeBox(gp_Ax2(gp_Pnt(*corner), gp_Dir(*direction), gp_Dir(*x)),
                                   side, side, length + side).Shape()

    def taper(self, rects) -> TopoDS_Shape:
        from OCP.BRepBuilderAPI import BRepBuilderAPI_MakePolygon
        from OCP.BRepOffsetAPI import BRepOffsetAPI_ThruSections
        from OCP.gp import gp_Pnt
        loft = BRepOffsetAPI_ThruSections(True, True)
        for corners in _rect_corners(rects):
            loft.AddWire(BRepBuilderAPI_MakePolygon(*[gp_Pnt(*map(float, c)) for c in corners], True).Wire())
        loft.Build()
        return loft.Shape()

    def union(self, shapes):
        from OCP.BRepAlgoAPI import BRepAlgoAPI_Fuse
        return shapes[0] if len(shapes) == 1 else _unify(_occ(BRepAlgoAPI_Fuse(), shapes[0], shapes[1:]))

    def cut(self, shape, tools):
        from OCP.BRepAlgoAPI import BRepAlgoAPI_Cut
        return shape if not tools else _unify(_occ(BRepAlgoAPI_Cut(), shape, tools))

    def intersect(self, a, b):
        from OCP.BRepAlgoAPI import BRepAlgoAPI_Common
        return _unify(_occ(BRepAlgoAPI_Common(), a, [b]))

    def common(self, envelope, lo, hi):
        from OCP.BRepAlgoAPI import BRepAlgoAPI_Common
        return _unify(_occ(BRepAlgoAPI_Common(), self.model, [envelope]))

    def volume(self, shape) -> float:
        return _volume(shape) if _solids(shape) else 0.0

    def pieces(self, shape) -> list:
        return [s for s in _solids(shape) if _volume(s) > CRUMB_MM3]

    def only_solid(self, shape, part_id: str):
        from OCP.BRepCheck import BRepCheck_Analyzer
        from OCP.ShapeFix import ShapeFix_Shape
        pieces = self.pieces(shape)
        if len(pieces) != 1:
            raise _InvalidSolid(f"{len(pieces)} pieces")
        solid = pieces[0]
        if not BRepCheck_Analyzer(solid).IsValid():
            fix = ShapeFix_Shape(solid)
            fix.Perform()
            solid = fix.Shape()
            if len(_solids(solid)) != 1 or not BRepCheck_Analyzer(solid).IsValid():
                raise _InvalidSolid("not a valid solid")
        return _solids(solid)[0]

    def mesh(self, shape) -> trimesh.Trimesh:
        from core.parts.brick_solids import to_trimesh
        return to_trimesh(shape, MESH_TOL_MM, MESH_ANGLE_RAD)


def _solids(shape: TopoDS_Shape) -> list[TopoDS_Shape]:
    from OCP.TopAbs import TopAbs_SOLID

    from core.parts.brick_solids import sub_shapes
    return sub_shapes(shape, TopAbs_SOLID)


def _volume(shape: TopoDS_Shape) -> float:
    """The volume (mm³) of the OCC ``shape``."""
    import cadquery as cq
    return float(cq.Shape.cast(shape).Volume())


def _occ(op, argument, tools):
    """:func:`core.parts.brick_solids.run_boolean` inside a part's construction: a failure
    makes the part on the mesh instead (:class:`_InvalidSolid`).  Faces closer than
    :data:`FUZZY_MM` count as one (a model aligned onto an earlier version lies a
    rounding error off the cell planes)."""
    from core.parts.brick_solids import BooleanFailed, run_boolean
    op.SetFuzzyValue(FUZZY_MM)
    try:
        return run_boolean(op, argument, list(tools), None, True)
    except BooleanFailed:
        raise _InvalidSolid("an OpenCascade Boolean that failed") from None


def _unify(shape: TopoDS_Shape) -> TopoDS_Shape:
    """``shape`` with coplanar / co-cylindrical neighbouring faces merged into one."""
    from OCP.ShapeUpgrade import ShapeUpgrade_UnifySameDomain
    unify = ShapeUpgrade_UnifySameDomain(shape, True, True, False)
    unify.Build()
    return unify.Shape()


def _engrave(part: PrintedPart, bricks: list[Brick], grid, mine: np.ndarray, other: np.ndarray,
             fit: Fit, engine) -> None:
    """Cut the part id ENGRAVE_DEPTH_MM deep into a flat vertical side where it fits.

    Candidates are the outer sides of the part's bricks (sides that do not
    face another brick of the part): those that take the largest text
    first, then those that face other bricks (a face the envelope cut, not
    one the designer drew; hidden once built), then the largest.  For each,
    the biggest of ENGRAVE_FONT_SIZES whose text (plus ENGRAVE_MARGIN_MM)
    fits the side is placed centred on it (else moved along it, then to its
    top or bottom: :func:`_positions`), and a place is taken only when
    the slab behind the text, ENGRAVE_DEPTH_MM + ENGRAVE_KEEP_MM deep, lies
    wholly inside the part and the slab ENGRAVE_CLEAR_MM in front of it
    holds nothing of the part: then the part has a flat, uncovered side
    there and at least ENGRAVE_KEEP_MM of wall stays behind the letters.  The side is
    vertical, so in an upright print it faces sideways.  Sets ``engraved``,
    ``engraving`` (where, or why not) and updates the part's solid, mesh and
    volume.
    """
    from core.parts.brick_solids import SIDE_TAGS, to_trimesh
    sizes = {f: _text_size(part.id, f) for f in ENGRAVE_FONT_SIZES}
    candidates = []
    for b in bricks:
        for side in SIDE_TAGS:
            face = _side_face(b, side, grid, mine, other, fit)
            if face is None:
                continue
            fits = [f for f in ENGRAVE_FONT_SIZES
                    if sizes[f][0] + 2 * ENGRAVE_MARGIN_MM <= face["width"]
                    and sizes[f][1] + 2 * ENGRAVE_MARGIN_MM <= face["height"]]
            if fits:
                candidates.append((-max(fits), -face["hidden"], -face["width"] * face["height"],
                                   b.id, SIDE_TAGS.index(side), face, max(fits)))
    candidates.sort(key=lambda c: c[:5])
    inside = _inside_test(part)
    body = _manifold(part.mesh)
    for *_, side, font in candidates:
        width, height = sizes[font]
        behind = ENGRAVE_DEPTH_MM + ENGRAVE_KEEP_MM
        for face in _positions(side, width + 2 * ENGRAVE_MARGIN_MM, height + 2 * ENGRAVE_MARGIN_MM):
            if not inside(_slab(face, width + 2 * ENGRAVE_MARGIN_MM, height + 2 * ENGRAVE_MARGIN_MM, behind)):
                continue
            front = _slab(face, width + 2 * ENGRAVE_MARGIN_MM, height + 2 * ENGRAVE_MARGIN_MM, -ENGRAVE_CLEAR_MM)
            if (body ^ _cube(*front)).volume() <= 1e-6 * np.prod(front[1] - front[0]):
                break
        else:
            continue
        text = _text_solid(part.id, font, face)
        try:
            body = part.solid if part.solid is not None else _manifold(part.mesh)
            tool = text if part.solid is not None else _manifold(to_trimesh(text))
            solid, mesh = _finished(engine, engine.cut(body, [tool]), part.id, rounds=0)
            if part.solid is not None:
                part.solid = solid
            part.mesh, part.volume_mm3 = mesh, engine.volume(solid)
        except _InvalidSolid:
            continue
        part.engraved = True
        part.engraving = {"brick": face["brick"], "side": face["side"],
                          "centre_mm": [round(float(v), 4) for v in face["centre"]],
                          "normal": [float(v) for v in face["normal"]],
                          "text_mm": [round(width, 3), round(height, 3)],
                          "font_size_mm": font, "depth_mm": ENGRAVE_DEPTH_MM}
        return
    part.engraving = ("not engraved: no outer flat side large enough for the id"
                      if not candidates else
                      "not engraved: no outer side large enough stays whole")


def _side_face(b: Brick, side: str, grid, mine: np.ndarray, other: np.ndarray, fit: Fit) -> dict | None:
    """The outer side ``side`` of brick ``b`` as a plane rectangle: centre, outward
    normal, horizontal reading direction, width and height (mm), and ``hidden``,
    the fraction of the cells across it that other bricks fill; None when
    every cell across belongs to the part."""
    i, j, k = b.cell
    sx, sy, sz = b.size
    axis = 0 if side[-1] == "x" else 1
    sign = 1 if side[-2] == "+" else -1
    nx, ny, _ = mine.shape
    if axis == 0:
        at = i + sx if sign > 0 else i - 1
        span = (slice(at, at + 1), slice(j, j + sy), slice(k, k + sz)) if 0 <= at < nx else None
    else:
        at = j + sy if sign > 0 else j - 1
        span = (slice(i, i + sx), slice(at, at + 1), slice(k, k + sz)) if 0 <= at < ny else None
    if span is not None and mine[span].all():
        return None
    hidden = float(other[span].mean()) if span is not None else 0.0
    lo = np.asarray(grid.origin) + np.array(b.cell) * grid.cell
    hi = lo + np.array(b.size) * grid.cell
    lo[:2] += fit.play
    hi[:2] -= fit.play
    centre = (lo + hi) / 2
    boundary = (hi[axis] + fit.play) if sign > 0 else (lo[axis] - fit.play)
    centre[axis] = boundary - sign * (fit.play if hidden > 0 else 0.0)
    normal = np.zeros(3)
    normal[axis] = sign
    return {"brick": b.id, "side": side, "centre": centre, "normal": normal, "hidden": hidden,
            "right": np.cross([0.0, 0.0, 1.0], normal),
            "width": float(hi[1 - axis] - lo[1 - axis]), "height": float(hi[2] - lo[2])}


def _font_path() -> str | None:
    """The bundled-with-Debian DejaVu Sans Bold font when present (else cadquery's default)."""
    return ENGRAVE_FONT if os.path.exists(ENGRAVE_FONT) else None


def _use_system_fontconfig() -> None:
    """Point OpenCascade's fontconfig at the system's ``fonts.conf`` unless the user set one.

    The fontconfig library bundled with the cadquery-ocp wheel was built
    with its configuration folder inside the build machine's conda
    environment (``/usr/share/miniconda3/envs/cadquery-ocp/etc/fonts``), so
    on any other machine the first text shape prints "Fontconfig error:
    Cannot load default config file" on stderr.  Fontconfig reads
    ``FONTCONFIG_FILE`` when OpenCascade's font manager first initialises
    it, so setting it before the first text shape is enough.  Nothing
    changes when ``FONTCONFIG_FILE`` or ``FONTCONFIG_PATH`` is already set
    or the system has no :data:`SYSTEM_FONTS_CONF`.
    """
    if not {"FONTCONFIG_FILE", "FONTCONFIG_PATH"} & set(os.environ) and os.path.exists(SYSTEM_FONTS_CONF):
        os.environ["FONTCONFIG_FILE"] = SYSTEM_FONTS_CONF


def text_shape(text: str, font: float, plane: cq.Plane, distance: float) -> cq.Shape:
    """``text`` at ``font`` size, DejaVu Sans Bold, centred at the plane's origin,
    extruded ``distance`` along the plane's normal (negative: into the part)."""
    import cadquery as cq
    _use_system_fontconfig()
    kwargs = {"fontPath": _font_path()} if _font_path() else {}
    return cq.Workplane(plane).text(text, font, distance, combine=False, halign="center",
                                    valign="center", kind="bold", **kwargs).val()


def _text_size(text: str, font: float) -> tuple[float, float]:
    """Width and height (mm) of ``text`` set at ``font`` size."""
    import cadquery as cq
    box = text_shape(text, font, cq.Plane.XY(), 1.0).BoundingBox()
    return float(box.xlen), float(box.ylen)


def _text_solid(text: str, font: float, face: dict) -> TopoDS_Shape:
    """The cutting tool of the engraving: ``text`` centred on ``face``, from
    ENGRAVE_OVERSHOOT_MM outside it to ENGRAVE_DEPTH_MM into the part."""
    import cadquery as cq
    start = face["centre"] + ENGRAVE_OVERSHOOT_MM * face["normal"]
    shape = text_shape(text, font, cq.Plane(origin=tuple(start), xDir=tuple(face["right"]),
                                             normal=tuple(face["normal"])),
                        -(ENGRAVE_DEPTH_MM + ENGRAVE_OVERSHOOT_MM))
    box = shape.BoundingBox()
    shift = face["centre"] - np.array([box.center.x, box.center.y, box.center.z])
    shift -= np.dot(shift, face["normal"]) * face["normal"]
    return shape.translate(cq.Vector(*shift)).wrapped


def _positions(face: dict, width: float, height: float):
    """``face`` with its centre moved to where a ``width`` x ``height`` text box may sit on
    it: the centre first, then along the side in steps of :data:`ENGRAVE_STEP_MM` (and to
    the ends), then also to its top and bottom; the box always stays on the side."""
    along = max((face["width"] - width) / 2, 0.0)
    up = max((face["height"] - height) / 2, 0.0)
    shifts = np.unique(np.round(np.concatenate(
        [np.arange(0.0, along, ENGRAVE_STEP_MM), [along]]), 6))
    offsets = sorted({(sign * a, v) for a in shifts for sign in (1, -1) for v in (0.0, up, -up)},
                     key=lambda o: (o[1] != 0.0, abs(o[0]), o[0] < 0, o[1] < 0))
    right = np.abs(face["right"])
    for a, v in offsets:
        yield dict(face, centre=face["centre"] + right * a + np.array([0.0, 0.0, v]))


def _slab(face: dict, width: float, height: float, depth: float) -> np.ndarray:
    """(2, 3) min/max corners of the box of ``width`` x ``height`` centred on ``face``,
    reaching ``depth`` behind it into the part."""
    right, normal = np.abs(face["right"]), face["normal"]
    half = right * width / 2 + np.array([0.0, 0.0, height / 2])
    a = face["centre"] - half
    b = face["centre"] + half - normal * depth
    return np.stack([np.minimum(a, b), np.maximum(a, b)])


def _inside_test(part: PrintedPart):
    """A function telling whether a box ((2, 3) corners) lies wholly inside the part.

    Mesh parts: a manifold3d difference (milliseconds).  B-rep parts: a
    grid of points in the box is classified first (a cheap rejection) and a
    box that passes is confirmed with an OCC Boolean on the exact solid.
    """
    if part.solid is None:
        solid = _manifold(part.mesh)

        def inside_mesh(box: np.ndarray) -> bool:
            tool = m3.Manifold.cube(list(box[1] - box[0])).translate(list(box[0]))
            return (tool - solid).volume() <= 1e-6 * np.prod(box[1] - box[0])
        return inside_mesh
    from OCP.BRepClass3d import BRepClass3d_SolidClassifier
    from OCP.gp import gp_Pnt
    from OCP.TopAbs import TopAbs_IN
    classifier = BRepClass3d_SolidClassifier(part.solid)

    def inside_brep(box: np.ndarray) -> bool:
        inset = np.minimum(0.05, (box[1] - box[0]) / 4)
        axes = [np.linspace(a, b, 4) for a, b in zip(box[0] + inset, box[1] - inset)]
        for point in np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3):
            classifier.Perform(gp_Pnt(*point), 1e-6)
            if classifier.State() != TopAbs_IN:
                return False
        return _inside_brep(part.solid, box)
    return inside_brep


def _inside_brep(shape: TopoDS_Shape, box: np.ndarray) -> bool:
    """True when the box ((2, 3) corners) lies wholly inside the OCC solid ``shape``."""
    from OCP.BRepAlgoAPI import BRepAlgoAPI_Cut
    from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox
    from OCP.gp import gp_Pnt
    tool = BRepPrimAPI_MakeBox(gp_Pnt(*box[0]), gp_Pnt(*box[1])).Shape()
    outside = BRepAlgoAPI_Cut(tool, shape)
    if not outside.IsDone():
        return False
    return _volume(outside.Shape()) <= 1e-6 * np.prod(box[1] - box[0])


def _manifold(mesh: trimesh.Trimesh) -> m3.Manifold:
    """``mesh`` (closed) as a manifold3d Manifold."""
    return m3.Manifold(m3.Mesh64(vert_properties=np.ascontiguousarray(mesh.vertices, np.float64),
                                 tri_verts=np.ascontiguousarray(mesh.faces, np.uint64)))
