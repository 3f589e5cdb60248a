"""Design iteration: a new version of the part against an earlier output folder.

The paper's second key benefit ("Faster iteration through localized changes"): the user
edits the part, and only what changed is rebuilt and reprinted.  A previous result is read
back by :func:`core.result.load_previous`; :func:`core.pipeline.run` runs the stages of the
iteration, in the same order as a fresh run's:

1. **Align** (:func:`align_to`, :mod:`core.align`) the new version onto the previous one.
2. **Legofy** it on the previous grid's lattice and **diff** the cells (:func:`legofy_on`,
   :mod:`core.diff`).
3. **High-res marks** as in a fresh run, from the request's regions (moved into the
   previous frame) and, unless the request says otherwise, the previous run's
   (:func:`previous_regions`): a marked box prints what it touches in the new version,
   exactly as a fresh run with the same regions would.  Anchor tabs as in a fresh run.
4. **Keep** (:func:`lay_out`) every previous brick whose cells are all still filled and
   whose kind (LEGO / printed) still fits the marks; a printed part is kept whole or not at
   all.  The rest (the *freed* cells) is laid out anew, the neighbourhood grown ring by
   ring while the joined layout is less stable than the previous one (:func:`_relayout`).
5. **Printed parts** (:func:`printed_parts`): a kept part whose surroundings changed, and
   every new group of printed bricks, is cut from the aligned model; a part is *reprinted*
   when it is new or differs from its previous print by more than
   :func:`core.diff.reprint_threshold`.
6. The ``changes`` document (:func:`changes`): transform, cells added/removed, bricks
   kept/added/taken off, parts reprinted, and the instructions diff, which
   :func:`core.instructions.changes_page.changes_page` writes as a self-contained HTML page.

Brick ids are stable: a kept brick keeps its id, new bricks get ids above the previous
largest, so "take off brick 17" means the brick 17 of the previous instructions.  The new
version is expressed in the *previous* frame: ``changes["transform"]["matrix"]`` maps the
new file's coordinates into it.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from core import align as align_stage, diff as diff_stage, high_res, hollow as hollow_stage
from core import stability as stability_stage
from core.catalog import BY_NUMBER, Part
from core.connectivity import FACE_STRUCTURE
from core.io import meshes as mesh_io
from core.layout import greedy as layout_stage
from core.model import Brick, Grid, Layout
from core.parts import connectors as connectors_stage, printed as printed_stage
from core.parts.interfaces import Fit
from core.parts.printed_part import PrintedPart
from core.result import Previous

#: Rings of LEGO bricks the re-laid-out neighbourhood may grow by.
MAX_RINGS = 4
#: Margin (mm) around a printed part's bricks within which a changed surface
#: makes it be cut again (its studs stand above the bricks).
PART_MARGIN_MM = 0.5
#: Distance (mm) within which triangles / faces of the two versions are the same.
SAME_SURFACE_MM = diff_stage.SAME_SURFACE_MM


def _shifted_part(part: PrintedPart, shift) -> PrintedPart:
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


def reusable(previous: Previous, units: str, scale: float, seed: int, up: str = "z") -> str | None:
    """Why the run (``units``, ``scale``, ``seed``, ``up``) cannot be an iteration on
    ``previous``, or None when it can.

    A different seed asks for a different layout, different units or scale
    for a different object, a different up axis for the object built on another
    side; a snapshot that does not record them (an older version) can always be
    iterated on.
    """
    settings = previous.state.get("settings") or {}
    for name, value in (("units", units), ("scale", float(scale)), ("seed", int(seed)), ("up", up)):
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


def legofy_on(previous: Previous, model: mesh_io.LoadedModel, hollow_setting: int = -1,
              regions: high_res.Regions | None = None
              ) -> tuple[diff_stage.CellDiff, hollow_stage.Hollowing]:
    """Step 2: the aligned ``model`` legofied on the previous lattice, hollowed as the
    previous version was (:func:`core.hollow.as_before`: ``hollow_setting`` is the
    request's, the cells of ``regions`` stay solid), diffed on the cells."""
    grid, offset = diff_stage.legofy_on(previous.grid, model.mesh, model.watertight)
    keep = regions.cells(grid) if regions else None
    hollowing = hollow_stage.as_before(grid, previous.shell_studs, hollow_setting, keep,
                                       offset[:2])
    return diff_stage.cell_diff(previous.grid, hollowing.grid, offset), hollowing


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
    """Decide which previous bricks are kept (module docstring, step 4): those whose cells
    are all still filled and whose kind still fits the marks; a printed part whole or not at
    all, and not when a freed marked cell touches it."""
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
    while the joined layout is less stable than the previous one (step 4).

    LEGO and marked cells are laid out separately (:func:`core.layout.greedy.lay_out`).  While the
    joined layout has more extra components than the previous layout, or new weak points
    that carry more than single leaf bricks (a brick standing alone on one brick), one ring
    of LEGO bricks around the freed cells (touching them face to face, also above and
    below) is freed too, at most :data:`MAX_RINGS` times; the best attempt (extra
    components, new weak points, new leaf-only weak points, bricks placed) wins.
    Returns the layout and the rings grown."""
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
    made: dict[str, PrintedPart] = {}
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


def _compare(old: PrintedPart | None, new: PrintedPart,
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
             layout: Layout, plan: _Plan, made: list[PrintedPart],
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

