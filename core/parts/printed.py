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

* **B-rep models** (STEP, FCStd) are cut with OpenCascade, **meshes** with manifold3d
  (:mod:`core.parts.booleans`).  A model of several solids or shells is first made one
  solid (:func:`model_solid`).  The result is a :class:`~core.parts.printed_part.PrintedPart`,
  its id engraved where it fits (:mod:`core.parts.engraving`).
* **Studs and sockets are complete by construction**: they are added after
  the intersection, so the model cannot cut them.  Without connectors
  (``connectors=False``) the same cells are listed as missing, so the stability
  check knows the part does not clamp there.
* **One solid.**  When the model inside the envelope falls into several
  pieces, each loose piece is joined to the rest by the shortest bar that
  stays inside the envelope (:data:`BAR_MM` square, reported in
  ``joins``); when no such bar exists the part is refused in one line.
"""

from __future__ import annotations

import dataclasses
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
from core.parts.booleans import (CRUMB_MM3, Brep, InvalidSolid, Mesh, as_manifold, cube, finished,
                                 occ_solids, unified)
from core.parts.engraving import engrave_id
from core.parts.interfaces import Fit
from core.parts.printed_part import ModelSolid, PrintedPart

if TYPE_CHECKING:  # OpenCascade is imported where B-rep parts are made
    from OCP.TopoDS import TopoDS_Shape


#: Side (mm) of the square bar that joins a loose piece of a part to the rest.
BAR_MM = 2.0


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
        solids = occ_solids(model.brep)
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
        return unified(run_boolean(BRepAlgoAPI_Fuse(), solids[0], list(solids[1:]), None, True))
    except BooleanFailed:
        raise InputError(f"{path}: OpenCascade could not fuse its {len(solids)} solids into one, "
                         "so printed parts cannot be cut from it") from None


def _union_of_shells(mesh: trimesh.Trimesh) -> m3.Manifold:
    """The closed ``mesh`` as one Manifold: its shells united, inward-facing shells subtracted."""
    whole = as_manifold(mesh)
    if whole.status() != m3.Error.NoError:
        return whole
    shells = mesh.split(only_watertight=False)
    if len(shells) <= 1:
        return whole
    outward = [as_manifold(s) for s in shells if s.volume > 0]
    inward = []
    for shell in (s.copy() for s in shells if s.volume < 0):
        shell.invert()
        inward.append(as_manifold(shell))
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
    near = source.manifold ^ cube(lo_all - 1.0, hi_all + 1.0)
    layout_plan = interfaces.plan(grid.origin, grid.cell, mine, other,
                                  [(b.cell, b.size) for b in bricks],
                                  top if connectors else np.zeros((0, 3), int),
                                  bottom if connectors else np.zeros((0, 3), int),
                                  lambda lo, hi: _extent(near, lo, hi), fit)
    method = "OpenCascade (exact B-rep)" if source.kind == "brep" else "manifold3d (mesh)"
    engine = Brep(source.brep) if source.kind == "brep" else Mesh(source.manifold)
    try:
        shape, mesh, envelope, kept_mm3, joins = _cut(part_id, engine, layout_plan, lo_all, hi_all, grid,
                                                mine, fit)
    except InvalidSolid as why:
        if isinstance(engine, Mesh):
            raise RuntimeError(f"printed part {part_id} came out as {why}") from None
        method = f"manifold3d on the model's mesh (the B-rep result was {why})"
        engine = Mesh(source.manifold)
        try:
            shape, mesh, envelope, kept_mm3, joins = _cut(part_id, engine, layout_plan, lo_all, hi_all,
                                                    grid, mine, fit)
        except InvalidSolid as again:
            raise RuntimeError(f"printed part {part_id} came out as {again}") from None
    names = {tuple(c): ",".join(map(str, c)) for c in np.concatenate([top, bottom]).tolist()}
    studs = {names[tuple(c)]: connectors for c in top.tolist()}
    sockets = {names[tuple(c)]: connectors for c in bottom.tolist()}
    part = PrintedPart(id=part_id, bricks=sorted(ids),
                       cells=int(sum(np.prod(b.size) for b in bricks)),
                       solid=shape if isinstance(engine, Brep) else None, method=method,
                       mesh=mesh, volume_mm3=engine.volume(shape),
                       studs=studs, sockets=sockets,
                       top_ok={tuple(c): connectors for c in top.tolist()},
                       bottom_ok={tuple(c): connectors for c in bottom.tolist()},
                       pieces=1, kept_mm3=kept_mm3,
                       envelope_mm3=engine.volume(envelope), joins=joins)
    if engrave:
        engrave_id(part, bricks, grid, mine, other, fit, engine)
    if thin:
        part.thin = thickness.thin_features(part.mesh)
    return part


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
    return (*finished(engine, shape, part_id), envelope, kept_mm3, joins)


def _extent(model: m3.Manifold, lo, hi) -> tuple[np.ndarray, np.ndarray] | None:
    """The bounding box (min, max corner) of ``model`` inside the box (lo, hi), None
    where it has no volume there."""
    inside = model ^ cube(lo, hi)
    if inside.is_empty() or inside.volume() <= CRUMB_MM3:
        return None
    box = np.asarray(inside.bounding_box(), dtype=float)
    return box[:3], box[3:]


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
