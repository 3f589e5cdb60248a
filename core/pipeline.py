"""The main job: a model file in, a LEGO layout and its report out.

:func:`run` chains the stages and returns plain data; :func:`fabricate`
also writes the output folder of the headless contract (DESIGN.md):
``report.json``, ``layout.json`` and ``layout.png``.  The folder is
written to a temporary sibling and renamed into place only when complete,
so a failed run never leaves a folder that looks finished.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from core import build_order, catalog, connectors as connectors_stage, grid_fit, high_res as high_res_stage, layout as layout_stage, mesh_io, printed as printed_stage
from core.interfaces import Fit
from core import print_time as print_time_stage, stability as stability_stage, voxelize
from core.errors import InputError
from core.model import CELL_MM, Grid, Layout

Progress = Callable[[float, str], None]

#: Default assembly estimate: seconds to place one LEGO brick, and to find,
#: turn and press on one printed part (:func:`core.build_order.assembly_seconds`).
SECONDS_PER_BRICK = build_order.SECONDS_PER_BRICK
SECONDS_PER_PART = build_order.SECONDS_PER_PART

#: Files that mark a folder as an output of ours (and so safe to replace).
OUTPUT_MARKERS = ("report.json", "layout.json")


@dataclass
class Fabrication:
    """Everything one run produced, stage by stage."""

    model: mesh_io.LoadedModel
    parts: tuple[catalog.Part, ...]
    grid: Grid
    layout: Layout
    stability: stability_stage.Stability
    seed: int
    timings_s: dict[str, float] = field(default_factory=dict)
    printed: list[printed_stage.PrintedPart] = field(default_factory=list)
    print_full: print_time_stage.PrintEstimate | None = None
    print_parts: print_time_stage.PrintEstimate | None = None
    seconds_per_brick: float = SECONDS_PER_BRICK
    connectors: connectors_stage.Connectors | None = None
    seconds_per_part: float = SECONDS_PER_PART
    interface: Fit = field(default_factory=Fit)
    iteration: object | None = None
    profile: str | None = None
    marks: dict = field(default_factory=dict)
    fit: grid_fit.GridFit | None = None
    plates: list | None = None

    @property
    def to_print(self) -> list[printed_stage.PrintedPart]:
        """The printed parts to print now: all of them, or after an iteration
        (``--previous``) only those it must reprint."""
        if self.iteration is None:
            return list(self.printed)
        again = set(self.iteration.reprinted)
        return [p for p in self.printed if p.id in again]


def _noop(fraction: float, message: str) -> None:
    """Progress sink that ignores everything."""


def run(path: str | os.PathLike, units: str = "mm", scale: float = 1.0, seed: int = 0,
        parts: str | None = None, progress: Progress | None = None, high_res=(),
        high_res_solids=(), high_res_bricks=(), stud_fit: float = Fit.stud_fit,
        socket_fit: float = Fit.socket_fit,
        seconds_per_brick: float = SECONDS_PER_BRICK, slice_parts: bool = True,
        connectors: bool = True, seconds_per_part: float = SECONDS_PER_PART,
        previous: str | os.PathLike | None = None, part_edits=(),
        profile: str | os.PathLike | None = None, fit_grid: bool = True) -> Fabrication:
    """Load, repair, legofy and lay out the model at ``path``; make the printed parts.

    ``parts`` restricts the brick set (see :func:`core.catalog.select`).
    ``high_res`` are boxes (``"X0,Y0,Z0,X1,Y1,Z1"`` strings or (2, 3)
    arrays, model mm), ``high_res_solids`` region solid files (in ``units``),
    ``high_res_bricks`` brick ids: every brick they touch becomes printed,
    one printed part per connected group; boxes and solids are marked before
    the layout, which then keeps its bricks inside or outside the marked
    cells (:func:`core.high_res.lay_out_around`; brick ids refer to that
    layout) (:mod:`core.high_res`,
    :mod:`core.printed`); unless ``fit_grid`` is False the grid is first
    shifted in x and y so that the boxes and solids mark the least of the
    model (:func:`core.grid_fit.fit`); unless
    ``connectors`` is False, a printed part gets a stud or a socket wherever it
    meets another brick directly above or below (:mod:`core.connectors`,
    :mod:`core.interfaces`; printed studs are 4.8 + ``stud_fit`` mm across,
    sockets 4.8 + ``socket_fit`` mm between their walls) and anchor tabs
    added to regions that would touch LEGO only sideways
    (:func:`core.high_res.anchor`).  With
    printed parts and ``slice_parts``, the whole model and the plate of all
    printed parts are print-timed (:func:`core.print_time.print_time`); the
    print times stay None without printed parts, so a plain run slices
    nothing.  ``previous`` is an earlier output folder of the same object:
    the model is then an iteration on it (:func:`core.iterate.iterate`:
    aligned, diffed on the previous grid, the old layout kept where nothing
    changed, only changed printed parts reprinted and print-timed; high-res
    boxes in the new file's coordinates add to the earlier marks).
    ``part_edits`` change how the printed bricks group into parts, in order:
    each a dict ``{"op": "merge" | "split", "boxes": [...], "bricks": [...]}``
    whose boxes (model mm) and brick ids name bricks; ``merge`` makes the
    parts holding them one, ``split`` gives each its own part
    (:func:`core.printed.merge`, :func:`core.printed.split`).  ``profile`` is
    a PrusaSlicer ini to slice with instead of the bundled one.
    Raises :class:`~core.errors.InputError` for bad input; otherwise returns
    a :class:`Fabrication` whose layout covers every filled cell once.
    """
    progress = progress or _noop
    chosen = catalog.select(parts)
    timings: dict[str, float] = {}

    def timed(name: str, fraction: float, fn, *args, **kwargs):
        progress(fraction, name)
        start = time.perf_counter()
        value = fn(*args, **kwargs)
        timings[name] = round(time.perf_counter() - start, 4)
        return value

    model = timed("load", 0.0, mesh_io.load_model, path, units=units, scale=scale)
    interface = Fit(stud_fit=stud_fit, socket_fit=socket_fit).check()
    for flag, value in (("--seconds-per-brick", seconds_per_brick), ("--seconds-per-part", seconds_per_part)):
        if isinstance(value, bool) or not (isinstance(value, (int, float)) and 0 <= value < 1e6):
            raise InputError(f"{flag} {value!r} must be a number of seconds >= 0")
    if previous is not None:
        return _iterate(previous, model, chosen, seed, timed, timings, progress, high_res=high_res,
                        high_res_solids=high_res_solids, units=units, scale=scale,
                        fit=interface, connectors=connectors,
                        seconds_per_brick=float(seconds_per_brick),
                        seconds_per_part=float(seconds_per_part), slice_parts=slice_parts,
                        profile=profile)
    boxes = [high_res_stage.as_box(b) for b in high_res]
    regions = [high_res_stage.load_region(p, units=units, scale=scale) for p in high_res_solids]
    fit = None
    if fit_grid and (boxes or regions):
        fit = timed("grid_fit", 0.1, grid_fit.fit, model.mesh, boxes, regions, units=units,
                    scale=scale, closed=model.watertight)
    origin, shape = voxelize.grid_frame(model.mesh.bounds) if fit is None else (fit.origin, fit.shape)
    grid = timed("legofy", 0.2, voxelize.legofy,
                 voxelize.snap_to_lattice(model.mesh, origin, np.asarray(CELL_MM)),
                 origin=origin, shape=shape, closed=model.watertight)
    if grid.count == 0:
        raise InputError(f"{Path(path).name}: the part fills no cell of the "
                         f"{CELL_MM[0]:g} x {CELL_MM[1]:g} x {CELL_MM[2]:g} mm grid")
    marked = timed("high_res", 0.3, high_res_stage.marked_cells, grid, boxes, regions,
                   units=units, scale=scale)
    cells = high_res_stage.anchor(grid, marked) if connectors else marked
    if cells.any():
        layout = timed("layout", 0.4, high_res_stage.lay_out_around, grid, cells, chosen, seed=seed)
    else:
        layout = timed("layout", 0.4, layout_stage.lay_out, grid, chosen, seed=seed)
    made: list[printed_stage.PrintedPart] = []
    clamp, links = None, None
    if cells.any() or high_res_bricks:
        ids = high_res_stage.touched_bricks(layout, cells) + high_res_stage.check_ids(layout, high_res_bricks)
        groups = _edited(layout, high_res_stage.groups(layout, ids), part_edits)
        if groups:
            source = timed("model_solid", 0.6, printed_stage.model_solid, model)
            contacts = connectors_stage.find(layout, groups)
            made = timed("printed_parts", 0.65, printed_stage.build_parts, layout, groups,
                         source, interface, connectors, links=contacts)
            links = contacts if connectors else connectors_stage.find(layout, [])
            layout = printed_stage.apply(layout, made)
            clamp = printed_stage.clamp_masks(layout, made)
    stab = timed("stability", 0.8, stability_stage.analyse, layout, clamp)
    fab = Fabrication(model, chosen, grid, layout, stab, seed, timings, made,
                      seconds_per_brick=float(seconds_per_brick), connectors=links,
                      seconds_per_part=float(seconds_per_part), interface=interface,
                      profile=None if profile is None else str(profile),
                      marks={"marked_cells": int(np.count_nonzero(marked)),
                             "anchor_cells": int(np.count_nonzero(cells & ~marked))}, fit=fit)
    if made and slice_parts:
        timed("print_time", 0.85, print_times, fab)
    return fab


def _iterate(previous, model, chosen, seed, timed, timings: dict, progress, slice_parts: bool,
             seconds_per_brick: float, seconds_per_part: float, profile, **marks) -> Fabrication:
    """:func:`run` with ``previous``: the iteration stage, as a Fabrication."""
    from core import iterate as iterate_stage
    before = timed("previous", 0.05, iterate_stage.load_previous, previous)
    it = iterate_stage.iterate(before, model, chosen, seed, progress=progress, **marks)
    fab = iterate_stage.to_fabrication(it, seconds_per_brick)
    fab.seconds_per_part, fab.interface, fab.iteration = seconds_per_part, marks["fit"], it
    fab.profile = None if profile is None else str(profile)
    if fab.printed and slice_parts:
        timed("print_time", 0.85, print_times, fab)
    fab.timings_s = {**timings, **it.timings_s}
    return fab


def _edited(layout: Layout, groups: list[list[int]], part_edits) -> list[list[int]]:
    """``groups`` after the merge/split ``part_edits`` of :func:`run`; InputError for a bad edit."""
    for edit in part_edits or ():
        op = edit.get("op") if isinstance(edit, dict) else None
        if op not in ("merge", "split"):
            raise InputError(f"part edit {edit!r}: op must be 'merge' or 'split'")
        boxes = [high_res_stage.as_box(b) for b in edit.get("boxes", ())]
        cells = high_res_stage.marked_cells(layout.grid, boxes)
        ids = set(high_res_stage.touched_bricks(layout, cells))
        ids |= set(high_res_stage.check_ids(layout, edit.get("bricks", ())))
        if op == "merge":
            groups = printed_stage.merge(groups, ids)
        else:
            printed_ids = {b for g in groups for b in g}
            groups = printed_stage.split(groups, ids & printed_ids)
    return groups


def print_times(fab: Fabrication) -> None:
    """Slice the whole model (the baseline) and the plates of the printed parts
    to print (:func:`core.export.plates`: one plate unless they do not fit the
    bed), the slicer runs two at a time; the parts' time is the plates' sum.

    The plates are kept in ``fab.plates`` (for :func:`write_outputs`, which
    writes them as they were timed).  The whole model is posed and timed first (its pose search already
    slices two poses at a time), then the plates, two at a time.  A part's
    own ``print_s`` is its plate's time shared out in proportion to the
    parts' own sliced times in their poses (their calibrated estimates
    without a slicer), so the parts' times add up to the plates'.
    """
    from concurrent.futures import ThreadPoolExecutor

    from core.export import plates
    printing = fab.to_print
    beds = fab.plates = plates(printing, profile=fab.profile)
    profile = {} if fab.profile is None else {"profile": fab.profile}
    with tempfile.TemporaryDirectory(prefix="fabrickator-slice-") as work:
        fab.print_full = print_time_stage.print_time([fab.model.mesh], work, **profile)
        with ThreadPoolExecutor(max_workers=2) as pool:
            results = list(pool.map(lambda items: print_time_stage.print_time(
                [m for _, m, _ in items], work, **profile), beds))
    methods = sorted({r.method for r in results})
    fab.print_parts = print_time_stage.PrintEstimate(
        sum(r.seconds for r in results),
        "; ".join(methods) if methods else "nothing to print: no printed part changed", None)
    for items, result in zip(beds, results):
        weights = [pose.slicer_s or print_time_stage.estimate_seconds([m]) for _, m, pose in items]
        total = sum(weights) or 1.0
        for (index, _, _), w in zip(items, weights):
            printing[index].print_s = result.seconds * w / total


def assembly_split(fab: Fabrication) -> tuple[float, float]:
    """The assembly estimate as (LEGO building, printed-part insertion) seconds.

    LEGO building is ``seconds_per_brick`` per LEGO brick, insertion is
    ``seconds_per_part`` per printed part.  After an iteration
    (``--previous``) it is the rework only: each LEGO brick to take off or
    add, each reprinted part to insert.
    """
    if fab.iteration is None:
        return (build_order.assembly_seconds(fab.layout, fab.seconds_per_brick, 0.0),
                build_order.assembly_seconds(fab.layout, 0.0, fab.seconds_per_part))
    ch = fab.iteration.changes
    moves = sum(1 for b in ch["take_off"] + ch["add"] if b.get("kind", "lego") == "lego")
    return fab.seconds_per_brick * moves, fab.seconds_per_part * len(fab.iteration.reprinted)


def assembly_seconds(fab: Fabrication) -> float:
    """Assembly estimate: LEGO building plus printed-part insertion (:func:`assembly_split`)."""
    return sum(assembly_split(fab))


def fabrication_seconds(fab: Fabrication) -> float | None:
    """Wall-clock time of the faBrickated object, or None before slicing.

    As in the paper's walkthrough, the user builds the LEGO part while the
    printer prints ("the overall fabrication time was thus still bound by
    the 3D printer"), then presses the printed parts on:
    max(parts print, LEGO building) + part insertion.
    """
    if fab.print_parts is None:
        return None
    lego, insert = assembly_split(fab)
    return max(fab.print_parts.seconds, lego) + insert


def speedups(fab: Fabrication) -> dict[str, float] | None:
    """The speed-ups over printing the whole model, or None before slicing.

    - ``fabrication``: full print / :func:`fabrication_seconds` (LEGO built
      while the printer prints), the paper's headline figure;
    - ``printing``: full print / parts print, the paper's "improvement for
      3D printing time" of its Validation (2.44x on average there);
    - ``sequential``: full print / (parts print + whole assembly), for one
      who only starts building once the print is done.

    After an iteration these compare printing the new version whole with
    reprinting the changed parts and the rework (the paper's "faster
    iteration").
    """
    if fab.print_full is None or fab.print_parts is None:
        return None
    full, parts = fab.print_full.seconds, fab.print_parts.seconds
    return {"fabrication": full / max(fabrication_seconds(fab), 1e-9),
            "printing": full / max(parts, 1e-9) if parts > 0 else float("inf"),
            "sequential": full / max(parts + assembly_seconds(fab), 1e-9)}


def report(fab: Fabrication) -> dict:
    """The ``report.json`` document for a fabrication (DESIGN.md contract)."""
    by_part: dict[str, int] = {}
    for b in fab.layout.bricks:
        by_part[b.part] = by_part.get(b.part, 0) + 1
    lego = sum(1 for b in fab.layout.bricks if b.kind == "lego")
    m, st = fab.model, fab.stability
    incomplete = sum(len(p.incomplete_studs) for p in fab.printed)
    full, plate = fab.print_full, fab.print_parts
    gains = speedups(fab)
    making = fabrication_seconds(fab)
    lego_s, insert_s = assembly_split(fab)
    bounds = m.mesh.bounds
    return {
        "model": {
            "path": str(m.path),
            "format": m.format,
            "triangles": int(m.triangles),
            "watertight": bool(m.watertight),
            "repaired": list(m.repaired),
            "warnings": list(m.warnings),
            "bbox_mm": [round(float(v), 4) for v in (bounds[1] - bounds[0])],
            "bounds_mm": [[round(float(v), 4) for v in row] for row in bounds],
        },
        "grid": {
            "origin_mm": [round(float(v), 6) for v in fab.grid.origin],
            "shape": list(fab.grid.shape),
            "cell_mm": [float(c) for c in fab.grid.cell],
            "alignment": "z from the part's lowest point; x and y centred on the part's bounding box"
            if fab.fit is None or fab.fit.shift_mm == (0.0, 0.0) else
            "z from the part's lowest point; x and y shifted from centred on the part's bounding "
            "box so that the high-res regions mark the least of the model",
            **({} if fab.fit is None else {"fit": fab.fit.to_json()}),
        },
        "plates": fab.grid.count,
        "bricks": {
            "total": len(fab.layout.bricks),
            "lego": lego,
            "printed": len(fab.layout.bricks) - lego,
            "by_part": dict(sorted(by_part.items())),
            "per_cell": round(len(fab.layout.bricks) / max(fab.grid.count, 1), 4),
        },
        "brick_set": [p.number for p in fab.parts],
        "seed": fab.seed,
        "stability": {
            "regions": st.regions,
            "components": st.components,
            "weak_points": len(st.weak_points),
            "weak_point_bricks": list(st.weak_points),
            "weak_points_holding_only_leaf_bricks": len(st.leaf_supports),
            "unconnectable": list(st.unconnectable),
            "incomplete_studs": incomplete,
        },
        "high_res": dict(fab.marks),
        "printed_parts": [p.to_json() for p in fab.printed],
        "print_time_s": None if full is None else {
            "full_model": round(full.seconds, 1),
            "printed_parts": round(plate.seconds, 1),
            "full_model_pose": full.pose, "full_model_supports": bool(full.supports),
            "method": full.method if full.method == plate.method
            else f"full model: {full.method}; printed parts: {plate.method}",
        },
        "assembly_s": round(assembly_seconds(fab), 1),
        "assembly_split_s": {"lego": round(lego_s, 1), "insert_printed_parts": round(insert_s, 1)},
        "fabrication_s": None if making is None else round(making, 1),
        "seconds_per_brick": fab.seconds_per_brick,
        "seconds_per_part": fab.seconds_per_part,
        "speedup": None if gains is None else round(gains["fabrication"], 3),
        "speedups": None if gains is None else {
            "definition": "fabrication: full print / (max(parts print, LEGO building) + inserting "
                          "the printed parts); printing: full print / parts print; sequential: "
                          "full print / (parts print + all assembly)",
            **{k: (None if v == float("inf") else round(v, 3)) for k, v in gains.items()}},
        "timings_s": dict(fab.timings_s),
        **({} if fab.iteration is None else {"changes": fab.iteration.changes}),
    }


def _prepare_out(out: Path) -> None:
    """Refuse an ``out`` that exists and is not an (empty or earlier) output folder."""
    if out.exists() and not out.is_dir():
        raise InputError(f"--out {out} exists and is not a folder")
    if out.is_dir() and any(out.iterdir()) and not any((out / f).exists() for f in OUTPUT_MARKERS):
        raise InputError(f"--out {out} is a folder with other files in it; "
                         "choose an empty or new folder")


def write_outputs(fab: Fabrication, out: str | os.PathLike, picture: bool = True,
                  progress: Progress | None = None) -> dict:
    """Write ``report.json``, ``layout.json`` (and ``layout.png``), the printed
    parts (``parts/``) and the builder's files (``instructions.html``,
    ``assembly.mpd``, ``bom.csv``, ``bricklink.xml``, :mod:`core.instructions`,
    which also numbers every brick's assembly step) into ``out``.

    Everything is written into a temporary sibling folder first and moved
    into place at the end, replacing an earlier output; returns the report.
    """
    progress = progress or _noop
    out = Path(out)
    _prepare_out(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    tmp.chmod(0o755)
    try:
        start = time.perf_counter()
        if fab.printed:
            from core import export
            progress(0.9, "export")
            export.export_parts(fab.printed, tmp / "parts", profile=fab.profile,
                                slicer="none" if fab.print_full is None else "auto",
                                beds=fab.plates if fab.iteration is None else None)
        progress(0.92, "instructions")
        from core import instructions
        assembly = instructions.write_assembly(
            fab.layout, fab.printed, tmp, title=Path(fab.model.path).name,
            seconds_per_brick=fab.seconds_per_brick, seconds_per_part=fab.seconds_per_part)
        (tmp / "layout.json").write_text(json.dumps(fab.layout.to_json()))
        if picture:
            progress(0.95, "picture")
            from core import render
            render.render_layout(fab.layout, tmp / "layout.png",
                                 title=f"{Path(fab.model.path).name}: "
                                       f"{len(fab.layout.bricks)} bricks")
        fab.timings_s["write"] = round(time.perf_counter() - start, 4)
        from core import iterate as iterate_stage
        iterate_stage.snapshot(fab, tmp, fit=fab.interface)
        if fab.iteration is not None:
            iterate_stage.changes_page(fab.iteration, tmp / "changes.html")
        doc = report(fab)
        doc["assembly"] = assembly
        doc["outputs"] = sorted(p.name for p in tmp.iterdir()) + ["report.json"]
        (tmp / "report.json").write_text(json.dumps(doc, indent=2))
        if out.exists():
            shutil.rmtree(out)
        os.replace(tmp, out)
        progress(1.0, "done")
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
    return doc


def fabricate(path: str | os.PathLike, out: str | os.PathLike, units: str = "mm",
              scale: float = 1.0, seed: int = 0, parts: str | None = None,
              picture: bool = True, progress: Progress | None = None, **printing) -> dict:
    """Run the pipeline on ``path`` and write its outputs into ``out``; returns the report.

    ``printing`` are the high-res and iteration keywords of :func:`run` (``previous``, ``high_res``,
    ``high_res_solids``, ``high_res_bricks``, ``stud_fit``, ``socket_fit``,
    ``seconds_per_brick``, ``seconds_per_part``, ``slice_parts``, ``connectors``,
    ``part_edits``, ``profile``, ``fit_grid``).
    """
    _prepare_out(Path(out))
    fab = run(path, units=units, scale=scale, seed=seed, parts=parts, progress=progress, **printing)
    return write_outputs(fab, out, picture=picture, progress=progress)
