"""Design iteration: a new version of the part against an earlier output folder.

The paper's second key benefit ("Faster iteration through localized
changes", "Calculating changes between design iterations"): the user edits
the part, and only what changed is rebuilt and reprinted.

* :func:`snapshot` writes into an output folder (``iteration/``) what a
  later iteration needs: the model mesh (``model.ply``) and B-rep
  (``model.brep``, binary OpenCascade), each printed part's mesh and B-rep,
  and ``state.json`` (layout, stability, printed-part records).
* :func:`load_previous` reads it back as a :class:`Previous`.
* The stages of the iteration branch of the driver (:func:`core.pipeline.run`
  runs them, in the same order as a fresh run's):

  1. **Align** (:func:`align_to`, :mod:`core.align`) the new version onto
     the previous one.
  2. **Legofy** it on the previous grid's lattice and **diff** the cells
     (:func:`legofy_on`, :mod:`core.diff`).
  3. **High-res marks** are made as in a fresh run, from the regions: the
     request's (moved into the previous frame) and, unless the request says
     otherwise, the previous run's (:func:`previous_regions`).  So a marked
     box prints what it touches in the new version, exactly as a fresh run
     with the same regions would: cells the edit added outside every region
     are LEGO.  Anchor tabs are added as in a fresh run.
  4. **Keep** (:func:`lay_out`) every previous brick whose cells are all still filled and
     whose kind (LEGO / printed) still fits the marks; a printed part is
     kept whole or not at all (not when a freed marked cell touches it).
     The rest (*freed* cells: added cells and the cells of bricks not
     kept) is laid out anew with :func:`core.layout.lay_out`, LEGO and
     marked cells separately.  :func:`core.stability.analyse` then checks
     the joined layout; while it has more extra components than the
     previous layout or new weak points that carry more than single leaf
     bricks (a brick standing alone on one brick is a leaf), one ring of
     LEGO bricks around the freed cells (bricks touching them face to face,
     also above and below) is freed too and the neighbourhood laid out
     again, at most :data:`MAX_RINGS` times; the best attempt (extra
     components, new weak points, new leaf-only weak points, bricks placed)
     wins.
  5. **Printed parts** (:func:`printed_parts`): a kept part whose surroundings changed (changed
     surface near it, :func:`core.diff.changed_boxes`, or other connector
     cells) and every new group of printed bricks is cut from the aligned
     model (:func:`core.printed.build_part`).  A new group takes the id of
     the previous part it overlaps most.  A part is *reprinted* when it is
     new or its symmetric difference with the previous print exceeds
     :func:`core.diff.reprint_threshold`; otherwise the old print still
     fits.
  6. The ``changes`` document (:func:`changes`): transform, cells added/removed, bricks
     kept/added/taken off, parts reprinted, and the instructions diff.

* :func:`changes_page` writes the self-contained HTML page of the
  instructions diff: what to take off, what to add, what to reprint.

Brick ids are stable: a kept brick keeps its id, new bricks get ids above
the previous largest, so "take off brick 17" means the brick 17 of the
previous instructions.  The new version is expressed in the *previous*
frame: ``changes["transform"]["matrix"]`` maps the new file's coordinates
into it.
"""

from __future__ import annotations

import dataclasses
import html
import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh
from scipy import ndimage

from core import align as align_stage
from core import connectors as connectors_stage
from core import diff as diff_stage
from core import high_res, layout as layout_stage, mesh_io, printed as printed_stage
from core import stability as stability_stage
from core.interfaces import Fit
from core.catalog import BY_NUMBER, Part
from core.connectivity import FACE_STRUCTURE
from core.errors import InputError
from core.model import Brick, Grid, Layout

#: Folder inside an output folder that holds the iteration snapshot.
SNAPSHOT_DIR = "iteration"
#: Version of the snapshot format (2 records the high-res regions and the settings).
SNAPSHOT_VERSION = 2
#: Older snapshot versions that can still be read.
READABLE_VERSIONS = (1, 2)
#: Rings of LEGO bricks the re-laid-out neighbourhood may grow by.
MAX_RINGS = 4
#: Margin (mm) around a printed part's bricks within which a changed surface
#: makes it be cut again (its studs stand above the bricks).
PART_MARGIN_MM = 0.5
#: Distance (mm) within which triangles / faces of the two versions are the same.
SAME_SURFACE_MM = diff_stage.SAME_SURFACE_MM


# --------------------------------------------------------------------------- snapshot


def snapshot(fab, folder: str | os.PathLike) -> Path:
    """Write what a later iteration needs into ``folder/iteration/``; returns that folder.

    ``fab`` is a :class:`core.pipeline.Fabrication`.  Written: ``model.ply``
    (the repaired model mesh, mm), ``model.brep`` for B-rep input,
    ``parts/<id>.ply`` (and ``.brep``) per printed part, ``regions/<n>.ply``
    per high-res region solid, and ``state.json`` with the layout, its
    stability, the brick set, seed, units and scale, the stud and socket fit,
    the high-res region boxes and every printed part's record (bricks,
    studs, tubes, clamp cells, engraving).  Reads ``fab`` only.
    """
    out = Path(folder) / SNAPSHOT_DIR
    (out / "parts").mkdir(parents=True, exist_ok=True)
    (out / "regions").mkdir(exist_ok=True)
    model = fab.model
    model.mesh.export(out / "model.ply", file_type="ply")
    if model.brep is not None:
        _write_brep(model.brep, out / "model.brep")
    records = []
    for p in fab.printed:
        p.mesh.export(out / "parts" / f"{p.id}.ply", file_type="ply")
        if p.solid is not None:
            _write_brep(p.solid, out / "parts" / f"{p.id}.brep")
        records.append(_part_record(p))
    for n, (mesh, _) in enumerate(fab.regions.solids):
        mesh.export(out / "regions" / f"{n}.ply", file_type="ply")
    st = fab.stability
    req = fab.request
    state = {
        "version": SNAPSHOT_VERSION,
        "model": {"path": str(model.path), "format": model.format,
                  "watertight": bool(model.watertight), "brep": model.brep is not None},
        "layout": fab.layout.to_json(),
        "stability": {"regions": st.regions, "components": st.components,
                      "weak_points": list(st.weak_points)},
        "brick_set": [p.number for p in fab.parts],
        "seed": fab.seed,
        "settings": {"units": req.units, "scale": float(req.scale), "seed": int(req.seed)},
        "fit": dataclasses.asdict(req.fit),
        "regions": {"boxes": [np.asarray(b, dtype=float).tolist() for b in fab.regions.boxes],
                    "solids_closed": [bool(c) for _, c in fab.regions.solids]},
        "printed": records,
    }
    (out / "state.json").write_text(json.dumps(state))
    return out


def _write_brep(shape, path: Path) -> None:
    from OCP.BinTools import BinTools
    BinTools.Write_s(shape, str(path))


def _read_brep(path: Path):
    from OCP.BinTools import BinTools
    from OCP.TopoDS import TopoDS_Shape
    shape = TopoDS_Shape()
    BinTools.Read_s(shape, str(path))
    return shape


#: PrintedPart fields kept as grid-cell maps; they are stored as [i, j, k, value] rows.
_CELL_MAPS = ("top_ok", "bottom_ok")


def _part_record(p: printed_stage.PrintedPart) -> dict:
    """A printed part as JSON: every field but its geometry (``solid``, ``mesh``)."""
    out = {}
    for f in dataclasses.fields(p):
        value = getattr(p, f.name)
        if f.name in ("solid", "mesh"):
            continue
        if f.name in _CELL_MAPS:
            value = [[*map(int, c), bool(v)] for c, v in value.items()]
        out[f.name] = value
    return out


@dataclass
class Previous:
    """An earlier output folder as the iteration sees it.

    ``grid`` and ``layout`` as that run made them; ``mesh`` / ``brep`` its
    model (mm, its frame); ``parts`` its printed parts by id (cells in its
    grid); ``state`` the raw ``state.json``; ``regions`` its high-res
    regions in its frame (None for a snapshot of version 1, which did not
    record them).
    """

    folder: Path
    grid: Grid
    layout: Layout
    mesh: trimesh.Trimesh
    brep: object | None
    watertight: bool
    parts: dict[str, printed_stage.PrintedPart]
    state: dict
    regions: high_res.Regions | None = None

    @property
    def weak_points(self) -> set[int]:
        return set(self.state["stability"]["weak_points"])

    @property
    def extra_components(self) -> int:
        st = self.state["stability"]
        return max(0, int(st["components"]) - int(st["regions"]))


def load_previous(folder: str | os.PathLike) -> Previous:
    """Read the snapshot of an earlier output folder (``--previous DIR``).

    Raises :class:`InputError` when ``folder`` is missing, is not an output
    folder, or was written without a snapshot (then it must be made again).
    """
    folder = Path(folder)
    state_file = folder / SNAPSHOT_DIR / "state.json"
    if not folder.is_dir():
        raise InputError(f"--previous {folder}: no such folder")
    if not state_file.is_file():
        raise InputError(f"--previous {folder}: not an output folder with an iteration snapshot "
                         f"({SNAPSHOT_DIR}/state.json is missing); fabricate that version again")
    try:
        state = json.loads(state_file.read_text())
        if state.get("version") not in READABLE_VERSIONS:
            raise InputError(f"--previous {folder}: snapshot version {state.get('version')} "
                             f"is not {SNAPSHOT_VERSION}; fabricate that version again")
        layout = Layout.from_json(state["layout"])
        snap = folder / SNAPSHOT_DIR
        mesh = trimesh.load(snap / "model.ply", file_type="ply", process=False, force="mesh")
        brep = _read_brep(snap / "model.brep") if state["model"]["brep"] else None
        parts = {}
        for rec in state["printed"]:
            part_mesh = trimesh.load(snap / "parts" / f"{rec['id']}.ply", file_type="ply",
                                     process=False, force="mesh")
            brep_file = snap / "parts" / f"{rec['id']}.brep"
            parts[rec["id"]] = _part_from_record(rec, part_mesh,
                                                 _read_brep(brep_file) if brep_file.exists() else None)
        regions = _read_regions(state.get("regions"), snap)
    except InputError:
        raise
    except (OSError, ValueError, KeyError, TypeError, IndexError) as err:
        raise InputError(f"--previous {folder}: the iteration snapshot cannot be read "
                         f"({type(err).__name__}: {str(err).splitlines()[0] if str(err) else ''})") from None
    return Previous(folder, layout.grid, layout, mesh, brep,
                    bool(state["model"]["watertight"]), parts, state, regions)


def _read_regions(record: dict | None, snap: Path) -> high_res.Regions | None:
    """The regions of a snapshot's ``state["regions"]`` (None when it has none)."""
    if record is None:
        return None
    boxes = tuple(np.asarray(b, dtype=np.float64).reshape(2, 3) for b in record["boxes"])
    solids = tuple((trimesh.load(snap / "regions" / f"{n}.ply", file_type="ply", process=False,
                                 force="mesh"), bool(closed))
                   for n, closed in enumerate(record["solids_closed"]))
    return high_res.Regions(boxes, solids)


def _part_from_record(rec: dict, mesh: trimesh.Trimesh, solid) -> printed_stage.PrintedPart:
    """The :class:`~core.printed.PrintedPart` of a record and its geometry (fields
    the record lacks keep their defaults; fields it has that the class lacks are dropped)."""
    names = {f.name for f in dataclasses.fields(printed_stage.PrintedPart)} - {"solid", "mesh"}
    values = {k: v for k, v in rec.items() if k in names}
    for key in _CELL_MAPS:
        if key in values:
            values[key] = {tuple(int(v) for v in c[:3]): bool(c[3]) for c in values[key]}
    values["bricks"] = [int(i) for i in values.get("bricks", [])]
    return printed_stage.PrintedPart(solid=solid, mesh=mesh, **values)


def _shifted_part(part: printed_stage.PrintedPart, shift) -> printed_stage.PrintedPart:
    """A copy of ``part`` with its clamp cells moved by ``shift`` cells."""
    s = tuple(int(v) for v in shift)

    def move(cells: dict) -> dict:
        return {(c[0] + s[0], c[1] + s[1], c[2] + s[2]): v for c, v in cells.items()}

    return dataclasses.replace(part, top_ok=move(part.top_ok), bottom_ok=move(part.bottom_ok),
                               stl=None, step=None)


# --------------------------------------------------------------------------- iterate


@dataclass(frozen=True)
class Iteration:
    """What the iteration branch of the driver (:func:`core.pipeline.run`) adds to a run.

    ``previous`` is the earlier result, ``alignment`` how the new version
    was placed onto it (the run's model, grid and layout are in the
    previous frame; ``diff.offset``: previous index = index + offset),
    ``reprinted`` the ids of the printed parts to print now, ``changes`` the
    report's ``changes`` document, ``rings`` how far the re-laid-out
    neighbourhood grew.
    """

    previous: Previous
    alignment: align_stage.Alignment
    diff: diff_stage.CellDiff
    reprinted: list[str]
    changes: dict
    rings: int


def reusable(previous: Previous, units: str, scale: float, seed: int) -> str | None:
    """Why the run (``units``, ``scale``, ``seed``) cannot be an iteration on
    ``previous``, or None when it can.

    A different seed asks for a different layout, different units or scale
    for a different object; a snapshot that does not record them (an older
    version) can always be iterated on.
    """
    settings = previous.state.get("settings") or {}
    for name, value in (("units", units), ("scale", float(scale)), ("seed", int(seed))):
        if name in settings and settings[name] != value:
            return f"the {name} changed from {settings[name]!r} to {value!r}"
    return None


def align_to(previous: Previous, model: mesh_io.LoadedModel
             ) -> tuple[align_stage.Alignment, mesh_io.LoadedModel]:
    """Step 1: the alignment of ``model`` onto ``previous`` and the model moved into its frame."""
    alignment = align_stage.align(model.mesh, previous.mesh, model.brep, previous.brep,
                                  model.watertight, previous.watertight)
    return alignment, align_stage.transform_model(model, alignment.transform)


def moved(alignment: align_stage.Alignment) -> bool:
    """Whether the alignment moves or turns the new version (more than 1e-6 mm / rad)."""
    return not np.allclose(alignment.transform, np.eye(4), atol=1e-6)


def legofy_on(previous: Previous, model: mesh_io.LoadedModel) -> diff_stage.CellDiff:
    """Step 2: the aligned ``model`` legofied on the previous lattice, diffed on the cells."""
    grid, offset = diff_stage.legofy_on(previous.grid, model.mesh, model.watertight)
    return diff_stage.cell_diff(previous.grid, grid, offset)


def previous_regions(previous: Previous) -> high_res.Regions:
    """The high-res regions of the previous run, in its frame.

    A snapshot written before regions were recorded gives the boxes of its
    printed bricks instead (what it printed, tabs included).
    """
    recorded = previous.regions
    if recorded is not None:
        return recorded
    printed = [b.id for b in previous.layout.bricks if b.kind == "printed"]
    return high_res.Regions.of_bricks(previous.layout, printed)


@dataclass
class _Plan:
    """Which previous bricks stay: shifted copies by id, and the kept printed parts."""

    shifted: dict[int, Brick]
    kept: set[int]
    kept_parts: set[str]
    next_id: int
    offset: np.ndarray


def _keep(previous: Previous, cells: diff_stage.CellDiff, marked: np.ndarray,
          allowed: set[str]) -> _Plan:
    """Decide which previous bricks are kept (module docstring, step 4)."""
    grid = cells.grid
    shape = np.array(grid.shape)
    filled = np.asarray(grid.filled, dtype=bool)
    shifted: dict[int, Brick] = {}
    fits: dict[int, bool] = {}
    for b in previous.layout.bricks:
        c = np.array(b.cell) - cells.offset
        s = dataclasses.replace(b, cell=tuple(int(v) for v in c), step=None)
        shifted[b.id] = s
        inside = bool(np.all(c >= 0) and np.all(c + np.array(b.size) <= shape))
        ok = inside and bool(filled[s.slices()].all())
        if ok and b.kind == "printed":
            ok = bool(marked[s.slices()].all())
        elif ok:
            ok = not marked[s.slices()].any() and b.part in allowed
        fits[b.id] = ok
    by_part: dict[str, list[int]] = {}
    for b in previous.layout.bricks:
        if b.kind == "printed" and b.printed_part is not None:
            by_part.setdefault(b.printed_part, []).append(b.id)
    kept_parts = {pid for pid, ids in by_part.items() if all(fits[i] for i in ids)}
    while True:
        covered = np.zeros(grid.shape, dtype=bool)
        for pid in kept_parts:
            for i in by_part[pid]:
                covered[shifted[i].slices()] = True
        free_marks = ndimage.binary_dilation(marked & ~covered,
                                             structure=FACE_STRUCTURE)
        drop = {pid for pid in kept_parts
                if any(free_marks[shifted[i].slices()].any() for i in by_part[pid])}
        if not drop:
            break
        kept_parts -= drop
    kept = {b.id for b in previous.layout.bricks
            if fits[b.id] and (b.kind != "printed" or b.printed_part in kept_parts)}
    next_id = max((b.id for b in previous.layout.bricks), default=-1) + 1
    return _Plan(shifted, kept, kept_parts, next_id, np.asarray(cells.offset, dtype=np.int64))


def _lay_out_mask(grid: Grid, mask: np.ndarray, parts: tuple[Part, ...], seed: int) -> list[Brick]:
    """Bricks covering the cells of ``mask`` (laid out on the mask's bounding box alone)."""
    if not mask.any():
        return []
    idx = np.argwhere(mask)
    a, b = idx.min(axis=0), idx.max(axis=0) + 1
    sub = np.ascontiguousarray(mask[a[0]:b[0], a[1]:b[1], a[2]:b[2]])
    part = layout_stage.lay_out(Grid(origin=grid.origin + a * grid.cell, cell=grid.cell, filled=sub),
                                parts, seed=seed)
    return [dataclasses.replace(x, cell=tuple(int(v) for v in np.array(x.cell) + a)) for x in part.bricks]


def lay_out(previous: Previous, cells: diff_stage.CellDiff, marked: np.ndarray,
            parts: tuple[Part, ...], seed: int) -> tuple[Layout, _Plan, int]:
    """Step 4: which previous bricks stay (:func:`_keep`), then the kept bricks plus the
    freed neighbourhood laid out anew (:func:`_relayout`), as (layout, plan, rings).

    ``marked`` are the cells to print (tabs included); the layout's new
    bricks lie wholly inside or wholly outside them and are all LEGO until
    the printed parts are made.
    """
    plan = _keep(previous, cells, marked, {p.number for p in parts})
    layout, rings = _relayout(previous, cells.grid, plan, marked, parts, seed)
    return _same_again(layout, plan) + (rings,)


def _same_again(layout: Layout, plan: _Plan) -> tuple[Layout, _Plan]:
    """A new brick that is a previous brick the re-layout freed, laid again as it was
    (same part, size and cell; LEGO or printed), is that brick: it gets its id back and
    counts as kept, so the builder is not told to take it off and put it back.  Returns the
    layout and plan with those ids (new objects; the inputs are not changed)."""
    present = {b.id for b in layout.bricks}
    old = {(b.part, tuple(b.size), tuple(b.cell)): i for i, b in plan.shifted.items()
           if i not in present}
    reused: set[int] = set()
    bricks = []
    for b in layout.bricks:
        key = (b.part, tuple(b.size), tuple(b.cell))
        if b.id >= plan.next_id and old.get(key) not in (None, *reused):
            reused.add(old[key])
            b = dataclasses.replace(b, id=old[key])
        bricks.append(b)
    if not reused:
        return layout, plan
    return Layout(layout.grid, bricks), dataclasses.replace(plan, kept=plan.kept | reused)


def _relayout(previous: Previous, grid: Grid, plan: _Plan, marked: np.ndarray,
              parts: tuple[Part, ...], seed: int) -> tuple[Layout, int]:
    """Kept bricks plus the freed neighbourhood laid out anew, grown ring by ring
    while the joined layout is less stable than the previous one (step 4)."""
    filled = np.asarray(grid.filled, dtype=bool)
    kept_cells = np.zeros(grid.shape, dtype=bool)
    for i in plan.kept:
        kept_cells[plan.shifted[i].slices()] = True
    free = filled & ~kept_cells
    kept = [plan.shifted[b.id] for b in previous.layout.bricks if b.id in plan.kept]
    if not free.any():
        return Layout(grid, kept), 0
    lego_kept = {b.id for b in kept if b.kind != "printed"}
    label = np.full(grid.shape, -1, dtype=np.int64)
    for b in kept:
        label[b.slices()] = b.id
    clamp = _kept_clamp(previous, plan, grid)
    best = None
    freed: set[int] = set()
    for ring in range(MAX_RINGS + 1):
        if ring:
            near = ndimage.binary_dilation(free, structure=FACE_STRUCTURE)
            grow = {int(i) for i in np.unique(label[near & ~free]) if i in lego_kept} - freed
            if not grow:
                break
            freed |= grow
            for i in grow:
                free[plan.shifted[i].slices()] = True
        new = _lay_out_mask(grid, free & ~marked, parts, seed) + _lay_out_mask(grid, free & marked, parts, seed)
        new = [dataclasses.replace(b, id=plan.next_id + n, kind="lego", printed_part=None, step=None)
               for n, b in enumerate(new)]
        bricks = [b for b in kept if b.id not in freed] + new
        joined = Layout(grid, bricks)
        st = stability_stage.analyse(joined, clamp)
        extra = max(0, st.components - st.regions - previous.extra_components)
        weak = set(st.weak_points) - previous.weak_points
        leaf = weak & set(st.leaf_supports)
        key = (extra, len(weak - leaf), len(leaf), len(new))
        if best is None or key < best[0]:
            best = (key, joined, ring)
        if key[:2] == (0, 0):
            break
    return best[1], best[2]


def _kept_clamp(previous: Previous, plan: _Plan, grid: Grid) -> tuple[np.ndarray, np.ndarray] | None:
    """Clamp masks of the kept printed parts in the new grid (None without any)."""
    if not plan.kept_parts:
        return None
    kept = [_shifted_part(previous.parts[p], -plan.offset) for p in sorted(plan.kept_parts)
            if p in previous.parts]
    return printed_stage.clamp_masks(Layout(grid, []), kept)


def _part_region(grid: Grid, bricks: list[Brick], fit: Fit) -> np.ndarray:
    """Boxes (n, 2, 3) mm around each brick of a printed part, its studs and a margin."""
    out = []
    for b in bricks:
        lo = grid.origin + np.array(b.cell) * grid.cell - PART_MARGIN_MM
        hi = grid.origin + (np.array(b.cell) + np.array(b.size)) * grid.cell + PART_MARGIN_MM
        hi[2] += fit.stud_height
        out.append([lo, hi])
    return np.array(out, dtype=np.float64).reshape(-1, 2, 3)


def printed_parts(previous: Previous, layout: Layout, plan: _Plan, groups: list[list[int]],
                  model: mesh_io.LoadedModel, alignment: align_stage.Alignment, fit: Fit,
                  connectors: bool):
    """Step 5: the printed parts of the groups of printed bricks ``groups``: kept, rebuilt or new.

    A group that is exactly a kept previous part's bricks is that part:
    its old print stands unless the model's surface changed at it, its
    connector cells or the fit changed (then it is cut again and compared).
    Every other group is new and takes the id of the previous part it
    overlaps most (:func:`_name_groups`).  Returns (parts, one reprint
    record per part, connectors of all parts, the layout with their bricks
    marked printed: a new one, ``layout`` is not changed).
    """
    index = {b.id: b for b in layout.bricks}
    kept_parts = {frozenset(i for i in plan.kept if plan.shifted[i].printed_part == pid): pid
                  for pid in sorted(plan.kept_parts)}
    kept_groups = {kept_parts[frozenset(g)]: sorted(g) for g in groups if frozenset(g) in kept_parts}
    new_groups = [g for g in groups if frozenset(g) not in kept_parts]
    named = _name_groups(previous, new_groups, index, plan.offset, set(kept_groups))
    all_groups = list(kept_groups.values()) + [g for _, g in named]
    if not all_groups:
        return [], [], None, layout
    changed = np.zeros((0, 2, 3))
    if kept_groups:
        tol = SAME_SURFACE_MM + 4.0 * min(alignment.residual_mm, 1.0)
        changed = diff_stage.changed_boxes(previous.mesh, model.mesh, previous.brep, model.brep, tol)
    links = connectors_stage.find(layout, all_groups if connectors else [])
    rebuild: list[tuple[str, list[int], str | None]] = []
    made: dict[str, printed_stage.PrintedPart] = {}
    shift = -plan.offset
    for pid, group in kept_groups.items():
        old = previous.parts.get(pid)
        bricks = [index[i] for i in group]
        why = None
        if old is None:
            why = "no previous print on record"
        elif diff_stage.boxes_meet(changed, _part_region(layout.grid, bricks, fit)):
            why = "the model's surface changed at the part"
        elif connectors and (_connector_cells(layout, group)
                             != _connector_cells(previous.layout, group, shift)):
            why = "bricks above or below it changed, so its connectors change"
        elif previous.state.get("fit") != dataclasses.asdict(fit):
            why = ("the stud and socket fit changed" if previous.state.get("fit")
                   else "printed before its studs and sockets were made to fit (an earlier version)")
        if why is None:
            made[pid] = _shifted_part(old, shift)
        else:
            rebuild.append((pid, group, why))
    rebuild += [(pid, group, None) for pid, group in named]
    records = {pid: {"id": pid, "reprint": False, "reason": "unchanged", "replaces": pid,
                     "symmetric_difference_mm3": 0.0} for pid in made}
    if rebuild:
        source = printed_stage.model_solid(model)
        for pid, group, why in rebuild:
            part = printed_stage.build_part(pid, [index[i] for i in group], layout, source, fit,
                                            links=None, connectors=connectors)
            made[pid] = part
            records[pid] = _compare(previous.parts.get(pid), part, why)
    order = sorted(made, key=_id_key)
    return ([made[p] for p in order], [records[p] for p in order], links,
            printed_stage.apply(layout, list(made.values())))


def _connector_cells(layout: Layout, group: list[int],
                     shift=(0, 0, 0)) -> tuple[frozenset, frozenset]:
    """The top and bottom connector cells of one printed group, moved by ``shift``."""
    found = connectors_stage.find(layout, [group])
    s = np.asarray(shift, dtype=np.int64)
    return (frozenset(map(tuple, (found.top + s).tolist())),
            frozenset(map(tuple, (found.bottom + s).tolist())))


def _name_groups(previous: Previous, groups: list[list[int]], index: dict[int, Brick],
                 offset: np.ndarray, taken: set[str]) -> list[tuple[str, list[int]]]:
    """Ids for new printed groups: the previous part overlapping a group most
    (not yet taken), else the next free ``P<n>``."""
    owner: dict[tuple[int, int, int], str] = {}
    for b in previous.layout.bricks:
        if b.kind == "printed" and b.printed_part:
            for c in np.ndindex(*b.size):
                owner[tuple(int(v) for v in np.array(b.cell) + c)] = b.printed_part
    used = set(taken)
    numbers = [_id_key(p)[0] for p in list(previous.parts) + list(taken)]
    fresh = max([n for n in numbers if n >= 0], default=0) + 1
    out = []
    for g in groups:
        votes: dict[str, int] = {}
        for i in g:
            b = index[i]
            for c in np.ndindex(*b.size):
                key = tuple(int(v) for v in np.array(b.cell) + c + offset)
                if key in owner:
                    votes[owner[key]] = votes.get(owner[key], 0) + 1
        choice = max((p for p in votes if p not in used), key=lambda p: (votes[p], p), default=None)
        if choice is None:
            choice = f"P{fresh}"
            fresh += 1
        used.add(choice)
        out.append((choice, g))
    return out


def _id_key(pid: str) -> tuple[int, str]:
    """Sort key of part ids: P2 before P10."""
    digits = pid[1:] if pid[:1] == "P" else ""
    return (int(digits), pid) if digits.isdigit() else (-1, pid)


def _compare(old: printed_stage.PrintedPart | None, new: printed_stage.PrintedPart,
             why: str | None) -> dict:
    """Reprint record of a part cut again: new, or compared with its previous print."""
    if old is None:
        return {"id": new.id, "reprint": True, "reason": why or "new printed part",
                "replaces": None, "symmetric_difference_mm3": None}
    volume = diff_stage.symmetric_difference_volume(old.mesh, new.mesh)
    limit = diff_stage.reprint_threshold(old.volume_mm3)
    changed = volume > limit
    reason = (f"{why or 'its bricks changed'}: {volume:.1f} mm³ differ (threshold {limit:.1f} mm³)"
              if changed else f"cut again ({why or 'its bricks changed'}) but only "
                              f"{volume:.2f} mm³ differ (threshold {limit:.1f} mm³): the old print fits")
    return {"id": new.id, "reprint": bool(changed), "reason": reason, "replaces": old.id,
            "symmetric_difference_mm3": round(volume, 3), "threshold_mm3": round(limit, 3)}


def _brick_entry(b: Brick, offset: np.ndarray) -> dict:
    """A brick of the instructions diff: part, name, size, cell in both frames."""
    part = BY_NUMBER.get(b.part)
    return {"id": b.id, "part": b.part, "name": part.name if part else b.part,
            "size": list(b.size), "cell": list(b.cell),
            "cell_previous": [int(v) for v in np.array(b.cell) + offset],
            "kind": b.kind, "printed_part": b.printed_part}


def changes(previous: Previous, alignment: align_stage.Alignment, cells: diff_stage.CellDiff,
             layout: Layout, plan: _Plan, made: list[printed_stage.PrintedPart],
             reprint: list[dict], rings: int) -> dict:
    """Step 6: the report's ``changes`` document with the instructions diff.

    ``take_off`` / ``add`` list every brick (LEGO or printed) that leaves or
    enters the layout, ``add`` entries with the previous bricks whose cells
    they take (``replaces``).  ``parts_out`` are the previous prints to take
    out (reprinted or no longer used), ``parts_in`` the prints to insert,
    each with the previous part and LEGO bricks it replaces.
    """
    offset = cells.offset
    present = {b.id for b in layout.bricks}
    kept = sorted(i for i in plan.kept if i in present)
    taken = [plan.shifted[b.id] for b in previous.layout.bricks if b.id not in present]
    added = [b for b in layout.bricks if b.id >= plan.next_id]
    old_label = np.full(previous.grid.shape, -1, dtype=np.int64)
    for b in previous.layout.bricks:
        old_label[b.slices()] = b.id
    old_kind = {b.id: b.kind for b in previous.layout.bricks}
    add = []
    for b in added:
        entry = _brick_entry(b, offset)
        idx = np.argwhere(np.ones(b.size, dtype=bool)) + np.array(b.cell) + offset
        inside = np.all((idx >= 0) & (idx < np.array(previous.grid.shape)), axis=1)
        hit = old_label[tuple(idx[inside].T)]
        entry["replaces"] = sorted(int(i) for i in np.unique(hit[hit >= 0]))
        add.append(entry)
    parts_now = {p.id for p in made}
    removed = sorted((p for p in previous.parts if p not in parts_now), key=_id_key)
    printing = [r for r in reprint if r["reprint"]]
    parts_in = []
    for r in printing:
        bricks = [e for e in add if e["printed_part"] == r["id"]]
        lego = sorted({i for e in bricks for i in e["replaces"] if old_kind.get(i) == "lego"})
        parts_in.append({"id": r["id"], "replaces_part": r["replaces"], "replaces_bricks": lego})
    parts_out = sorted({r["replaces"] for r in printing if r["replaces"]} | set(removed), key=_id_key)
    return {
        "transform": alignment.to_json(),
        "grid_offset": [int(v) for v in offset],
        "cells_added": cells.cells_added,
        "cells_removed": cells.cells_removed,
        "bricks_changed": len(added),
        "bricks_removed": len(taken),
        "bricks_kept": len(kept),
        "neighbourhood_rings": rings,
        "first_new_id": int(plan.next_id),
        "parts_reprinted": [r["id"] for r in printing],
        "parts_kept": [r["id"] for r in reprint if not r["reprint"]],
        "parts_removed": removed,
        "parts_out": parts_out,
        "parts_in": parts_in,
        "take_off": [_brick_entry(b, offset) for b in taken],
        "add": add,
        "reprint": reprint,
    }


# --------------------------------------------------------------------------- page


_PAGE_STYLE = """
body{font-family:sans-serif;margin:1.5em;color:#222;max-width:70em}
h1{font-size:1.4em}h2{font-size:1.15em;margin-top:1.6em}
table{border-collapse:collapse;margin:.4em 0}td,th{border:1px solid #bbb;padding:.2em .5em;text-align:left}
th{background:#eee}.off{color:#b00020}.on{color:#00703c}.print{color:#0050b0}
.layers{display:flex;flex-wrap:wrap;gap:1em}.layer{border:1px solid #ccc;padding:.4em}
.note{color:#555;font-size:.9em}
"""


def changes_page(changes: dict, layout: Layout, path: str | os.PathLike, title: str) -> Path:
    """Write the instructions diff as one self-contained HTML file at ``path``.

    Sections: what changed (alignment, cells); 1. take off: LEGO bricks (by
    previous id, part, layer and stud position in the previous build, top
    down) and printed parts to take out; 2. add: LEGO bricks (bottom up)
    and printed parts to insert, with the bricks they replace; 3. print:
    every printed part, whether it must be printed and why; then a top view
    of every layer that changes (kept bricks grey, taken off red dashed,
    added green, printed blue).  Returns the path written.
    """
    ch = changes
    tr = ch["transform"]
    name = f"{title}: changes since the previous version"
    e = html.escape
    rows = [f"<h1>{e(name)}</h1>",
            f"<p>{e(tr['message'])}. Rotation {tr['rotation_deg']:.3g}°, translation "
            f"{', '.join(f'{v:.3g}' for v in tr['translation_mm'])} mm.</p>",
            f"<p>Cells: <span class='on'>+{ch['cells_added']}</span>, "
            f"<span class='off'>-{ch['cells_removed']}</span>. Bricks: {ch['bricks_kept']} kept, "
            f"<span class='off'>{ch['bricks_removed']} to take off</span>, "
            f"<span class='on'>{ch['bricks_changed']} to add</span>; "
            f"<span class='print'>{len(ch['parts_reprinted'])} part(s) to print</span>.</p>",
            "<p class='note'>Layers count plate heights (3.2 mm) from the base; positions are "
            "studs from the corner of the previous build (x, y).</p>"]
    lego_off = [b for b in ch["take_off"] if b["kind"] != "printed"]
    lego_on = [b for b in ch["add"] if b["kind"] != "printed"]
    rows.append("<h2 class='off'>1. Take off</h2>")
    rows.append(_brick_table(sorted(lego_off, key=lambda b: (-b["cell_previous"][2], b["id"])),
                             "no LEGO bricks to take off", replaces=False))
    if ch["parts_out"]:
        rows.append(f"<p>Take out printed part(s): <b>{e(', '.join(ch['parts_out']))}</b>.</p>")
    rows.append("<h2 class='on'>2. Add (bottom up)</h2>")
    rows.append(_brick_table(sorted(lego_on, key=lambda b: (b["cell_previous"][2], b["id"])),
                             "no LEGO bricks to add", replaces=True))
    for p in ch["parts_in"]:
        what = []
        if p["replaces_part"]:
            what.append(f"the old print of {p['replaces_part']}" if p["replaces_part"] == p["id"]
                        else f"printed part {p['replaces_part']}")
        if p["replaces_bricks"]:
            what.append("LEGO brick(s) " + ", ".join(map(str, p["replaces_bricks"])))
        rows.append(f"<p>Insert printed part <b>{e(p['id'])}</b>"
                    + (f" in place of {e(' and '.join(what))}" if what else "") + ".</p>")
    rows.append("<h2 class='print'>3. Print</h2>")
    if ch["reprint"]:
        rows.append("<table><tr><th>part</th><th>print</th><th>why</th></tr>")
        for r in ch["reprint"]:
            rows.append(f"<tr><td>{e(r['id'])}</td><td>{'yes' if r['reprint'] else 'no, keep'}</td>"
                        f"<td>{e(r['reason'])}</td></tr>")
        rows.append("</table>")
    else:
        rows.append("<p>no printed parts</p>")
    if ch["parts_removed"]:
        rows.append(f"<p>Printed part(s) no longer used: {e(', '.join(ch['parts_removed']))}.</p>")
    rows.append("<h2>Layers that change</h2><div class='layers'>")
    rows += _layer_views(changes, layout)
    rows.append("</div>")
    text = ("<!DOCTYPE html><html><head><meta charset='utf-8'><title>" + e(name) + "</title><style>"
            + _PAGE_STYLE + "</style></head><body>" + "\n".join(rows) + "</body></html>\n")
    path = Path(path)
    path.write_text(text, encoding="utf-8")
    return path


def _brick_table(entries: list[dict], empty: str, replaces: bool) -> str:
    """An HTML table of instruction-diff LEGO bricks."""
    if not entries:
        return f"<p>{html.escape(empty)}</p>"
    head = "<tr><th>brick</th><th>part</th><th>layer</th><th>at (x, y)</th><th>size</th>"
    head += "<th>replaces</th></tr>" if replaces else "</tr>"
    out = ["<table>", head]
    for b in entries:
        x, y, k = b["cell_previous"]
        row = (f"<tr><td>{b['id']}</td><td>{html.escape(b['part'] + ' ' + b['name'])}</td>"
               f"<td>{k}</td><td>{x}, {y}</td>"
               f"<td>{b['size'][0]} x {b['size'][1]} x {b['size'][2]}</td>")
        if replaces:
            row += f"<td>{', '.join(map(str, b['replaces'])) or '-'}</td>"
        out.append(row + "</tr>")
    out.append("</table>")
    return "\n".join(out)


def _layer_views(changes: dict, layout: Layout, px: int = 14) -> list[str]:
    """One small SVG top view per changed layer, in previous-build coordinates:
    kept bricks grey, taken off red (dashed), added LEGO green, added printed blue."""
    ch = changes
    offset = np.asarray(ch["grid_offset"])
    first_new = ch["first_new_id"]
    boxes = [(np.array(b.cell) + offset, b.size, "#ccc") for b in layout.bricks
             if b.id < first_new]
    boxes += [(b["cell_previous"], b["size"], "#d33") for b in ch["take_off"]]
    boxes += [(b["cell_previous"], b["size"], "#36c" if b["kind"] == "printed" else "#2a2")
              for b in ch["add"]]
    layers = sorted({k for c, s, colour in boxes if colour != "#ccc" for k in range(c[2], c[2] + s[2])})
    if not layers:
        return ["<p>no layer changes</p>"]
    lo = np.min([np.asarray(c[:2]) for c, _, _ in boxes], axis=0)
    hi = np.max([np.asarray(c[:2]) + np.asarray(s[:2]) for c, s, _ in boxes], axis=0)
    w, h = (hi - lo) * px
    out = []
    for k in layers:
        shapes = []
        for c, s, colour in boxes:
            if not c[2] <= k < c[2] + s[2]:
                continue
            x, y = (c[0] - lo[0]) * px, (hi[1] - c[1] - s[1]) * px
            style = "fill-opacity:0.25;stroke-dasharray:3,2" if colour == "#d33" else "fill-opacity:0.85"
            shapes.append(f"<rect x='{x}' y='{y}' width='{s[0] * px}' height='{s[1] * px}' "
                          f"style='fill:{colour};stroke:#333;stroke-width:1;{style}'/>")
        out.append(f"<div class='layer'>layer {k}<br><svg xmlns='http://www.w3.org/2000/svg' "
                   f"width='{w}' height='{h}' viewBox='0 0 {w} {h}'>{''.join(shapes)}</svg></div>")
    return out
