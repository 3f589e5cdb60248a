"""Printed parts: marked LEGO bricks intersected exactly with the user's part.

The paper's central idea ("Converting Lego bricks into 3D printable
bricks", "Merging and splitting", "Detecting the completeness of knobs and
tubes"):

* **Envelope.**  The bricks of one part are merged by
  :func:`core.brick_solids.merged_solid` the paper's way, by removing
  faces, not by a Boolean union: each brick is built with the sides it
  shares with another brick of the part *flush* (on the cell boundary, no
  play), without studs where a brick of the part stands on it and with a
  solid underside where it stands on one, and with its faces split along
  every rectangle where it touches another brick, so the two bricks have
  one exactly coincident, tagged face there.  Those faces are dropped, the
  rest is sewn into one closed solid and ``ShapeUpgrade_UnifySameDomain``
  merges the coplanar pieces of the outer faces: a merged part has no
  internal faces and no internal voids, and its volume is that of the
  union of the bricks.  A Boolean fuse of the same brick solids is only the
  fallback when sewing does not give one valid solid
  (``PrintedPart.merge_method`` says which).  Splitting a part rebuilds
  each piece from its own bricks, so the faces along the split come back.
* **Intersection.**  Printed part = envelope ∩ model.  For B-rep input
  (STEP, FCStd) this is ``BRepAlgoAPI_Common`` with the model's solid.  For
  mesh input it is a manifold3d Boolean: the model mesh (converted to a
  Manifold once per model, :func:`model_solid`) is first cropped to the
  envelope's box, then intersected with the envelope's tessellation; the
  result is exact with respect to the model mesh.
* **Completeness.**  Studs, tubes, pins and cavities are *exposed* when no
  brick of the same part covers them (a stud with a part brick above is
  internal).  An exposed feature is complete when the intersection left it
  whole.  With OCC this is read from the Common's history: the feature's
  tagged faces (carried through the merge) must be neither modified (split)
  nor deleted.  With manifold3d it is the equivalent from manifold's
  provenance tracking: the triangles of the result that come from the
  envelope (by mesh run / original id) are assigned to features by
  position, and a feature is complete when it kept its whole area.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field

import cadquery as cq
import manifold3d as m3
import numpy as np
import trimesh
from OCP.BRepAlgoAPI import BRepAlgoAPI_Common, BRepAlgoAPI_Cut
from OCP.BRepBuilderAPI import BRepBuilderAPI_Copy
from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox
from OCP.gp import gp_Pnt
from OCP.ShapeUpgrade import ShapeUpgrade_UnifySameDomain
from OCP.BRepClass3d import BRepClass3d_SolidClassifier
from OCP.TopAbs import TopAbs_IN, TopAbs_SOLID
from OCP.TopExp import TopExp_Explorer
from OCP.TopoDS import TopoDS_Shape

from core import high_res
from core.brick_solids import (SIDE_TAGS, BooleanFailed, BrickGeometry, merged_solid, part_contacts,
                               run_boolean, to_trimesh)
from core.errors import InputError
from core.mesh_io import LoadedModel
from core.model import Brick, Layout

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
#: The font of the id (DejaVu Sans Bold, Debian fonts-dejavu-core).
ENGRAVE_FONT = "/usr/share/fonts/truetype/dejavu/DejaVuSans-Bold.ttf"
#: The system's fontconfig configuration, given to OpenCascade's bundled fontconfig.
SYSTEM_FONTS_CONF = "/etc/fonts/fonts.conf"
#: Tolerance (mm) when assigning mesh triangles to studs, tubes and cavities.
FEATURE_TOL_MM = 0.02
#: Relative area a mesh feature may lose to rounding and still count as whole.
AREA_RTOL = 1e-6


@dataclass
class ModelSolid:
    """The model as the intersection sees it: an OCC solid or a manifold3d Manifold."""

    brep: TopoDS_Shape | None = None
    manifold: m3.Manifold | None = None

    @property
    def kind(self) -> str:
        return "brep" if self.brep is not None else "mesh"


@dataclass
class PrintedPart:
    """One printed part: marked bricks merged and intersected with the model.

    ``bricks`` are layout brick ids, ``cells`` the number of 1x1 plate cells
    they cover; ``solid`` the OCC shape (B-rep input; None for mesh input,
    whose exact result is ``mesh``); ``mesh`` a watertight tessellation in
    model mm; ``studs`` / ``tubes`` map feature names (``"<brick>:stud:a,b"``,
    ``"<brick>:tube:a,b"``, ``"<brick>:pin:a"``, ``"<brick>:cavity"``) of the
    exposed features to True when complete.  ``top_ok`` / ``bottom_ok`` map a
    grid cell (i, j, k) of a brick's top / bottom layer to whether a brick
    above / below can clamp there.  ``engraved`` says whether the id is cut
    into a side; ``engraving`` is then a dict saying where (brick, side,
    centre, outward normal, text size, font size, depth), else the reason
    why not.  ``merge_method`` says how the bricks' envelope was merged
    (:attr:`core.brick_solids.MergedSolid.method`: "single brick", "face
    removal", or "fuse (...)" when face removal failed).  ``stl``, ``step``,
    ``pose`` (the print orientation chosen by :func:`core.export.print_pose`)
    and ``print_s`` are filled by export and print time.
    """

    id: str
    bricks: list[int]
    cells: int
    solid: object | None
    mesh: trimesh.Trimesh
    volume_mm3: float
    studs: dict[str, bool] = field(default_factory=dict)
    tubes: dict[str, bool] = field(default_factory=dict)
    top_ok: dict[tuple[int, int, int], bool] = field(default_factory=dict)
    bottom_ok: dict[tuple[int, int, int], bool] = field(default_factory=dict)
    pieces: int = 1
    merge_method: str = "single brick"
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
    def complete_tubes(self) -> list[str]:
        return sorted(k for k, v in self.tubes.items() if v)

    @property
    def incomplete_tubes(self) -> list[str]:
        return sorted(k for k, v in self.tubes.items() if not v)

    def to_json(self) -> dict:
        return {
            "id": self.id, "bricks": list(self.bricks), "cells": self.cells,
            "volume_mm3": round(self.volume_mm3, 3), "pieces": self.pieces,
            "merge": self.merge_method,
            "stl": self.stl, "step": self.step,
            "print_s": None if self.print_s is None else round(self.print_s, 1),
            "complete_studs": len(self.complete_studs),
            "incomplete_studs": self.incomplete_studs,
            "incomplete_tubes": self.incomplete_tubes,
            "engraved": self.engraved,
            "engraving": self.engraving,
            "print_pose": self.pose,
        }


def model_solid(model: LoadedModel) -> ModelSolid:
    """The model as a Boolean operand: its B-rep when it has one, else its mesh as a Manifold.

    Raises :class:`InputError` when a mesh model is not a closed oriented
    2-manifold (an open or self-touching mesh cannot be intersected exactly).
    """
    if model.brep is not None:
        return ModelSolid(brep=model.brep)
    manifold = _manifold(model.mesh)
    if manifold.status() != m3.Error.NoError or manifold.is_empty():
        raise InputError(f"{model.path}: the mesh is not a closed manifold solid "
                         f"({manifold.status().name}), so printed parts cannot be cut from it")
    return ModelSolid(manifold=manifold)


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


def build_parts(layout: Layout, groups: list[list[int]], source: ModelSolid,
                geometry: BrickGeometry = BrickGeometry(), engrave: bool = True) -> list[PrintedPart]:
    """One :class:`PrintedPart` per group of brick ids, named P1, P2, ... in group order.

    Every group must be face-to-face connected (InputError otherwise), and
    no brick may be in two groups.  Does not change ``layout``; see
    :func:`apply`.
    """
    seen: set[int] = set()
    for g in groups:
        if seen & set(g):
            raise InputError(f"brick(s) {sorted(seen & set(g))[:5]} are in two printed parts")
        seen |= set(g)
        high_res.check_ids(layout, g)
        if not high_res.is_connected(layout, g):
            raise InputError(f"bricks {sorted(g)[:8]} do not touch face to face; "
                             "a merged printed part must be one piece")
    by_id = {b.id: b for b in layout.bricks}
    source = _settled(source)
    return [build_part(f"P{n + 1}", [by_id[i] for i in sorted(g)], layout, source, geometry, engrave)
            for n, g in enumerate(groups)]


def _settled(source: ModelSolid) -> ModelSolid:
    """``source`` with a mesh model evaluated into a plain Manifold of its own.

    manifold3d evaluates Booleans lazily; a model that is itself an
    unevaluated Boolean (the model united with connector boxes) shared by
    the intersections of several parts crashed manifold3d 3.0.1 (a
    segmentation fault in ``to_mesh64``, the model relativty_hmd_body with
    four parts), the crash manifold's issue #1378 describes.  Rebuilding
    the model once from its evaluated mesh gives every part a leaf operand.
    """
    if source.kind != "mesh":
        return source
    return ModelSolid(manifold=m3.Manifold(source.manifold.to_mesh64()))


def apply(layout: Layout, parts: list[PrintedPart]) -> None:
    """Mark the bricks of ``parts`` in ``layout`` as printed (kind and printed_part)."""
    owner = {b: p.id for p in parts for b in p.bricks}
    for b in layout.bricks:
        if b.id in owner:
            b.kind, b.printed_part = "printed", owner[b.id]


def clamp_masks(layout: Layout, parts: list[PrintedPart]) -> tuple[np.ndarray, np.ndarray]:
    """Grid-shaped bool arrays (studs_ok, bottom_ok) for :func:`core.stability.brick_graph`.

    ``studs_ok`` is False at the top-layer cells of printed bricks whose stud
    there is incomplete; ``bottom_ok`` False at bottom-layer cells of printed
    bricks whose cavity or neighbouring tube/pin is cut; True elsewhere.
    """
    studs_ok = np.ones(layout.grid.shape, dtype=bool)
    bottom_ok = np.ones(layout.grid.shape, dtype=bool)
    for p in parts:
        for cell, ok in p.top_ok.items():
            studs_ok[cell] = ok
        for cell, ok in p.bottom_ok.items():
            bottom_ok[cell] = ok
    return studs_ok, bottom_ok


@dataclass
class _Member:
    """One brick of a part, with its solid and what of it is exposed."""

    brick: Brick
    origin: np.ndarray
    flush: tuple[str, ...]
    studs: list[tuple[int, int]]
    tubes: list[str]
    cavity: bool
    open_sides: dict[str, float]


def build_part(part_id: str, bricks: list[Brick], layout: Layout, source: ModelSolid,
               geometry: BrickGeometry = BrickGeometry(), engrave: bool = True) -> PrintedPart:
    """The printed part made of ``bricks`` (one connected group of the layout): envelope ∩ model.

    Promises: the result lies inside both the envelope and the model; its
    mesh is watertight; ``studs``/``tubes`` say which exposed features are
    complete; ``engraved`` says whether the id was cut into a side.  Raises
    :class:`InputError` when nothing of the model lies in the bricks.
    """
    grid = layout.grid
    if not np.allclose(grid.cell[:2], geometry.pitch) or not math.isclose(grid.cell[2], geometry.plate_height):
        raise InputError("brick geometry pitch and plate height must match the grid cell size")
    members = _members(bricks, layout, geometry)
    merged = merged_solid([b.cell for b in bricks], [b.size for b in bricks], geometry, grid.origin,
                          names=[b.id for b in bricks])
    envelope, tagged = merged.shape, merged.tagged
    if source.kind == "brep":
        common = BRepAlgoAPI_Common()
        result = _run(common, envelope, [source.brep])
        cut = {}
        for face, tag in tagged:
            hit = common.IsDeleted(face) or common.Modified(face).Size() > 0
            cut[tag] = cut.get(tag, False) or hit
        solid = _unify(BRepBuilderAPI_Copy(result).Shape())
        if _count_solids(solid) == 0:
            raise InputError(f"printed part {part_id}: the model does not reach into its bricks")
        mesh = to_trimesh(solid)
    else:
        solid = None
        mesh, cut = _mesh_common(envelope, members, source.manifold, geometry)
    part = _assemble(part_id, members, solid, mesh, cut)
    part.merge_method = merged.method
    if engrave:
        _engrave(part, members, geometry)
    return part


def _members(bricks: list[Brick], layout: Layout, geometry: BrickGeometry) -> list[_Member]:
    """Flush sides and exposed features of each brick of one part."""
    grid = layout.grid
    ids = {b.id for b in bricks}
    lab = layout.labels()
    id_of = np.array([b.id for b in layout.bricks] + [-1], dtype=np.int64)
    part_of = np.isin(id_of[lab], list(ids))
    nz = grid.shape[2]
    out = []
    contacts = part_contacts([b.cell for b in bricks], [b.size for b in bricks], geometry, grid.origin)
    for b, contact in zip(bricks, contacts):
        i, j, k = b.cell
        sx, sy, sz = b.size
        above = part_of[i:i + sx, j:j + sy, k + sz] if k + sz < nz else np.zeros((sx, sy), bool)
        below = part_of[i:i + sx, j:j + sy, k - 1] if k > 0 else np.zeros((sx, sy), bool)
        studs = [(a, c) for a in range(sx) for c in range(sy) if not above[a, c]]
        tubes = []
        if sx >= 2 and sy >= 2:
            tubes = [f"tube:{a},{c}" for a in range(sx - 1) for c in range(sy - 1)
                     if not below[a:a + 2, c:c + 2].any()]
        elif max(sx, sy) >= 2:
            line = below.ravel()
            tubes = [f"pin:{a}" for a in range(max(sx, sy) - 1) if not line[a:a + 2].any()]
        origin = grid.origin + np.array(b.cell) * grid.cell
        out.append(_Member(b, origin, contact.flush, studs, tubes,
                           not below.all(), _open_sides(grid.filled, b)))
    return out


def _open_sides(filled: np.ndarray, b: Brick) -> dict[str, float]:
    """Per outer side of brick ``b``, the fraction of the cells just across it that are
    empty (1.0 at the grid's border): how visible that side is on the finished model."""
    i, j, k = b.cell
    sx, sy, sz = b.size
    padded = np.pad(np.asarray(filled, dtype=bool), 1)
    i, j, k = i + 1, j + 1, k + 1
    across = {"side-x": padded[i - 1, j:j + sy, k:k + sz], "side+x": padded[i + sx, j:j + sy, k:k + sz],
              "side-y": padded[i:i + sx, j - 1, k:k + sz], "side+y": padded[i:i + sx, j + sy, k:k + sz]}
    return {side: float(1.0 - cells.mean()) for side, cells in across.items()}


def _run(op, argument, tools, tagged: list | None = None, parallel: bool = True):
    """:func:`core.brick_solids.run_boolean` for a printed part; a failure is bad input."""
    try:
        return run_boolean(op, argument, tools, tagged, parallel)
    except BooleanFailed:
        raise InputError("OpenCascade could not compute a printed part (Boolean failed)") from None


def _unify(shape: TopoDS_Shape) -> TopoDS_Shape:
    """``shape`` with coplanar / co-cylindrical neighbouring faces merged into one."""
    unify = ShapeUpgrade_UnifySameDomain(shape, True, True, False)
    unify.Build()
    return unify.Shape()


def _count_solids(shape: TopoDS_Shape) -> int:
    explorer = TopExp_Explorer(shape, TopAbs_SOLID)
    n = 0
    while explorer.More():
        n += 1
        explorer.Next()
    return n


def _mesh_common(envelope: TopoDS_Shape, members: list[_Member], model: m3.Manifold,
                 geometry: BrickGeometry) -> tuple[trimesh.Trimesh, dict[str, bool]]:
    """Envelope ∩ model with manifold3d, the model cropped to the envelope's box first;
    the result mesh and, per feature tag, whether it was cut (lost area)."""
    env_mesh = to_trimesh(envelope)
    env = _manifold(env_mesh).as_original()
    if env.status() != m3.Error.NoError:
        raise InputError("the printed part's brick envelope could not be meshed as a solid")
    lo, hi = env_mesh.bounds
    crop = m3.Manifold.cube(list(hi - lo + 2.0)).translate(list(lo - 1.0))
    result = env ^ (model ^ crop)
    out = result.to_mesh64()
    vertices = np.asarray(out.vert_properties, dtype=np.float64)[:, :3]
    faces = np.asarray(out.tri_verts, dtype=np.int64)
    if len(faces) == 0:
        return trimesh.Trimesh(), {}
    runs = np.asarray(out.run_index, dtype=np.int64) // 3
    origin_ids = np.asarray(out.run_original_id, dtype=np.int64)
    source = np.repeat(origin_ids, np.diff(runs))
    from_env = source == env.original_id()
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    tags = _feature_tags(env_mesh.triangles_center, members, geometry)
    before = _area_by_tag(tags, env_mesh.area_faces)
    tags_after = _feature_tags(mesh.triangles_center[from_env], members, geometry)
    after = _area_by_tag(tags_after, mesh.area_faces[from_env])
    cut = {t: after.get(t, 0.0) < area * (1 - AREA_RTOL) - 1e-9 for t, area in before.items()}
    mesh.merge_vertices()
    return mesh, cut


def _area_by_tag(tags: np.ndarray, areas: np.ndarray) -> dict[str, float]:
    names, inverse = np.unique(tags, return_inverse=True)
    sums = np.bincount(inverse, weights=areas, minlength=len(names))
    return {str(n): float(s) for n, s in zip(names, sums) if n}


def _feature_tags(centres: np.ndarray, members: list[_Member], geometry: BrickGeometry) -> np.ndarray:
    """Feature tag of each triangle (by its centre): ``"<brick>:stud:a,b"``, tube, pin,
    cavity, or "" for the rest (outer sides, top, bottom rim, fillers)."""
    g, tol = geometry, FEATURE_TOL_MM
    out = np.full(len(centres), "", dtype=object)
    x, y, z = centres.T
    for m in members:
        b, (ox, oy, oz) = m.brick, m.origin
        sx, sy, sz = b.size
        ztop = oz + sz * g.plate_height
        ceiling = ztop - g.top
        inside = (x > ox - tol) & (x < ox + sx * g.pitch + tol) & (y > oy - tol) & (y < oy + sy * g.pitch + tol)
        u, v = (x - ox) / g.pitch, (y - oy) / g.pitch
        a, c = np.floor(u).astype(np.int64), np.floor(v).astype(np.int64)
        near = np.hypot((u - a - 0.5) * g.pitch, (v - c - 0.5) * g.pitch) < g.printed_stud_diameter / 2 + tol
        stud = inside & near & (z > ztop + tol) & (z < ztop + g.stud_height + tol)
        for i in np.flatnonzero(stud):
            out[i] = f"{b.id}:stud:{a[i]},{c[i]}"
        low = inside & (z > oz - tol) & (z < ceiling - tol)
        wall = g.play + g.printed_wall
        cavity = low & (z > oz + tol) & (x > ox + wall - tol) & (x < ox + sx * g.pitch - wall + tol) \
            & (y > oy + wall - tol) & (y < oy + sy * g.pitch - wall + tol)
        if sx >= 2 and sy >= 2:
            na, nc = np.rint(u).astype(np.int64), np.rint(v).astype(np.int64)
            tube = low & (np.hypot((u - na) * g.pitch, (v - nc) * g.pitch) < g.printed_tube_outer / 2 + tol) \
                & (na >= 1) & (na < sx) & (nc >= 1) & (nc < sy)
            names = np.array([f"{b.id}:tube:{p},{q}" for p, q in zip(na - 1, nc - 1)], dtype=object)
        elif max(sx, sy) >= 2:
            along = u if sx > 1 else v
            across = v if sx > 1 else u
            na = np.rint(along).astype(np.int64)
            tube = low & (np.hypot((along - na) * g.pitch, (across - 0.5) * g.pitch)
                          < g.printed_pin_diameter / 2 + tol) & (na >= 1) & (na < max(sx, sy))
            names = np.array([f"{b.id}:pin:{p}" for p in na - 1], dtype=object)
        else:
            tube = np.zeros(len(centres), bool)
            names = np.zeros(len(centres), dtype=object)
        out[cavity & ~tube] = f"{b.id}:cavity"
        out[tube] = names[tube]
    return out


def _assemble(part_id: str, members: list[_Member], solid, mesh: trimesh.Trimesh,
              cut: dict[str, bool]) -> PrintedPart:
    """The PrintedPart from the Boolean's result and the per-tag cut flags."""
    studs: dict[str, bool] = {}
    tubes: dict[str, bool] = {}
    top_ok: dict[tuple[int, int, int], bool] = {}
    bottom_ok: dict[tuple[int, int, int], bool] = {}
    for m in members:
        b = m.brick
        i, j, k = b.cell
        sx, sy, sz = b.size
        for a, c in m.studs:
            name = f"{b.id}:stud:{a},{c}"
            studs[name] = not cut.get(name, True)
            top_ok[(i + a, j + c, k + sz - 1)] = studs[name]
        for t in m.tubes:
            tubes[f"{b.id}:{t}"] = not cut.get(f"{b.id}:{t}", True)
        cavity_ok = not cut.get(f"{b.id}:cavity", False) if m.cavity else True
        if m.cavity:
            tubes[f"{b.id}:cavity"] = cavity_ok
        for a in range(sx):
            for c in range(sy):
                near = [t for t in m.tubes if _tube_touches(t, a, c)]
                bottom_ok[(i + a, j + c, k)] = cavity_ok and all(tubes[f"{b.id}:{t}"] for t in near)
    volume = float(cq.Shape.cast(solid).Volume()) if solid is not None else float(mesh.volume)
    pieces = _count_solids(solid) if solid is not None else int(mesh.body_count)
    return PrintedPart(id=part_id, bricks=sorted(m.brick.id for m in members),
                       cells=int(sum(np.prod(m.brick.size) for m in members)), solid=solid,
                       mesh=mesh, volume_mm3=volume, studs=studs, tubes=tubes,
                       top_ok=top_ok, bottom_ok=bottom_ok, pieces=pieces)


def _tube_touches(tag: str, a: int, c: int) -> bool:
    """True when the tube/pin ``tag`` stands at a corner of footprint cell (a, c)."""
    kind, _, where = tag.partition(":")
    if kind == "tube":
        p, q = (int(v) for v in where.split(","))
        return p <= a <= p + 1 and q <= c <= q + 1
    p = int(where)
    return p <= max(a, c) <= p + 1


def _engrave(part: PrintedPart, members: list[_Member], geometry: BrickGeometry) -> None:
    """Cut the part id ENGRAVE_DEPTH_MM deep into an outer flat side where it fits.

    Candidates are the non-flush outer sides of the part's bricks: those that
    take the largest text first, then those on the outside of the model (no
    filled cells across them), then the largest.  For each, the biggest of
    ENGRAVE_FONT_SIZES whose text (plus ENGRAVE_MARGIN_MM) fits the side is
    placed centred on it, and the side is
    taken only when the slab behind the text, ENGRAVE_DEPTH_MM +
    ENGRAVE_KEEP_MM deep, lies wholly inside the part: then the part still
    has the flat side there (the intersection did not cut it away) and at
    least ENGRAVE_KEEP_MM of wall stays behind the letters.  Sets
    ``engraved``, ``engraving`` (where, or why not) and updates the part's
    solid, mesh and volume.
    """
    g = geometry
    if ENGRAVE_DEPTH_MM + ENGRAVE_KEEP_MM > g.printed_wall + 1e-9:
        part.engraving = (f"not engraved: walls of {g.printed_wall:.2f} mm are too thin for "
                          f"{ENGRAVE_DEPTH_MM} mm deep text")
        return
    if part.solid is None and _manifold(part.mesh).status() != m3.Error.NoError:
        part.engraving = "not engraved: the part's mesh is not a closed manifold"
        return
    sizes = {f: _text_size(part.id, f) for f in ENGRAVE_FONT_SIZES}
    candidates = []
    for m in members:
        for side in SIDE_TAGS:
            if side in m.flush:
                continue
            face = _side_face(m, side, g)
            fits = [f for f in ENGRAVE_FONT_SIZES
                    if sizes[f][0] + 2 * ENGRAVE_MARGIN_MM <= face["width"]
                    and sizes[f][1] + 2 * ENGRAVE_MARGIN_MM <= face["height"]]
            if fits:
                candidates.append((-max(fits), -m.open_sides[side], -face["width"] * face["height"],
                                   m.brick.id, SIDE_TAGS.index(side), face, max(fits)))
    candidates.sort(key=lambda c: c[:5])
    inside = _inside_test(part)
    for *_, face, font in candidates:
        width, height = sizes[font]
        behind = ENGRAVE_DEPTH_MM + ENGRAVE_KEEP_MM
        if not inside(_slab(face, width + 2 * ENGRAVE_MARGIN_MM, height + 2 * ENGRAVE_MARGIN_MM, behind)):
            continue
        text = _text_solid(part.id, font, face)
        if part.solid is not None:
            solid = _unify(_run(BRepAlgoAPI_Cut(), part.solid, [text]))
            part.solid, part.mesh = solid, to_trimesh(solid)
            part.volume_mm3 = float(cq.Shape.cast(solid).Volume())
            part.pieces = _count_solids(solid)
        else:
            cut = _manifold(part.mesh) - _manifold(to_trimesh(text))
            out = cut.to_mesh64()
            mesh = trimesh.Trimesh(np.asarray(out.vert_properties, np.float64)[:, :3],
                                   np.asarray(out.tri_verts, np.int64), process=False)
            mesh.merge_vertices()
            part.mesh, part.volume_mm3, part.pieces = mesh, float(cut.volume()), int(mesh.body_count)
        part.engraved = True
        part.engraving = {"brick": face["brick"], "side": face["side"],
                          "centre_mm": [round(float(v), 4) for v in face["centre"]],
                          "normal": [float(v) for v in face["normal"]],
                          "text_mm": [round(width, 3), round(height, 3)],
                          "font_size_mm": font, "depth_mm": ENGRAVE_DEPTH_MM}
        return
    part.engraving = ("not engraved: no outer flat side large enough for the id"
                      if not candidates else
                      "not engraved: no outer side large enough stays whole after the intersection")


def _side_face(m: _Member, side: str, g: BrickGeometry) -> dict:
    """The outer side ``side`` of member ``m``: centre, outward normal, horizontal
    reading direction, width and height (mm) of its flat body (studs excluded)."""
    b, (ox, oy, oz) = m.brick, m.origin
    sx, sy, sz = b.size
    axis = 0 if side[-1] == "x" else 1
    sign = 1.0 if side[-2] == "+" else -1.0
    lo = np.array([ox + g.play, oy + g.play, oz])
    hi = np.array([ox + sx * g.pitch - g.play, oy + sy * g.pitch - g.play, oz + sz * g.plate_height])
    centre = (lo + hi) / 2
    centre[axis] = hi[axis] if sign > 0 else lo[axis]
    normal = np.zeros(3)
    normal[axis] = sign
    return {"brick": b.id, "side": side, "centre": centre, "normal": normal,
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
    on any other machine the first text shape printed "Fontconfig error:
    Cannot load default config file" on stderr.  Fontconfig reads
    ``FONTCONFIG_FILE`` when OpenCascade's font manager first initialises
    it, so setting it before the first text shape is enough.  Nothing
    changes when ``FONTCONFIG_FILE`` or ``FONTCONFIG_PATH`` is already set
    or the system has no :data:`SYSTEM_FONTS_CONF`.
    """
    if not {"FONTCONFIG_FILE", "FONTCONFIG_PATH"} & set(os.environ) and os.path.exists(SYSTEM_FONTS_CONF):
        os.environ["FONTCONFIG_FILE"] = SYSTEM_FONTS_CONF


def _text_shape(text: str, font: float, plane: cq.Plane, distance: float) -> cq.Shape:
    """``text`` at ``font`` size centred at the plane's origin, extruded ``distance``
    along the plane's normal (negative: into the part)."""
    _use_system_fontconfig()
    kwargs = {"fontPath": _font_path()} if _font_path() else {}
    return cq.Workplane(plane).text(text, font, distance, combine=False, halign="center",
                                    valign="center", kind="bold", **kwargs).val()


def _text_size(text: str, font: float) -> tuple[float, float]:
    """Width and height (mm) of ``text`` set at ``font`` size."""
    box = _text_shape(text, font, cq.Plane.XY(), 1.0).BoundingBox()
    return float(box.xlen), float(box.ylen)


def _text_solid(text: str, font: float, face: dict) -> TopoDS_Shape:
    """The cutting tool of the engraving: ``text`` centred on ``face``, from
    ENGRAVE_OVERSHOOT_MM outside it to ENGRAVE_DEPTH_MM into the part."""
    start = face["centre"] + ENGRAVE_OVERSHOOT_MM * face["normal"]
    shape = _text_shape(text, font, cq.Plane(origin=tuple(start), xDir=tuple(face["right"]),
                                             normal=tuple(face["normal"])),
                        -(ENGRAVE_DEPTH_MM + ENGRAVE_OVERSHOOT_MM))
    box = shape.BoundingBox()
    shift = face["centre"] - np.array([box.center.x, box.center.y, box.center.z])
    shift -= np.dot(shift, face["normal"]) * face["normal"]
    return shape.translate(cq.Vector(*shift)).wrapped


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
    tool = BRepPrimAPI_MakeBox(gp_Pnt(*box[0]), gp_Pnt(*box[1])).Shape()
    outside = BRepAlgoAPI_Cut(tool, shape)
    if not outside.IsDone():
        return False
    return float(cq.Shape.cast(outside.Shape()).Volume()) <= 1e-6 * np.prod(box[1] - box[0])


def _manifold(mesh: trimesh.Trimesh) -> m3.Manifold:
    """``mesh`` (closed) as a manifold3d Manifold."""
    return m3.Manifold(m3.Mesh64(vert_properties=np.ascontiguousarray(mesh.vertices, np.float64),
                                 tri_verts=np.ascontiguousarray(mesh.faces, np.uint64)))
