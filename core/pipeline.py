"""The main job: a model file in, a LEGO layout and its report out.

:func:`run` chains the stages and returns plain data; :func:`fabricate`
also writes the output folder of the headless contract (DESIGN.md):
``report.json``, ``layout.json`` and ``layout.png``.  The folder is
written to a temporary sibling and renamed into place only when complete,
so a failed run never leaves a folder that looks finished
(:class:`core.io.output_dir.OutputFolder`: the place is checked and locked
before the run starts).
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from core import catalog, colours, forces as forces_stage, grid_fit
from core import high_res as high_res_stage, hollow as hollow_stage
from core import inventory as inventory_stage, iterate as iterate_stage
from core import report as reporting, result, stability as stability_stage
from core import suggest as suggest_stage, voxelize
from core.errors import InputError
from core.instructions import build_order, changes_page
from core.io import meshes as mesh_io, output_dir
from core.layout import greedy as layout_stage, reinforce as reinforce_stage
from core.layout import search as improve_stage
from core.model import CELL_MM, Grid, Layout
from core.parts import connectors as connectors_stage, printed as printed_stage
from core.parts.interfaces import Fit
from core.parts.printed_part import PrintedPart
from core.printing import print_time as print_time_stage, printers
from core.printing.estimate import PrintEstimate, estimate_seconds
from core.printing.plate import build_volume
from core.request import UNITS, Request, request as request_of

Progress = Callable[[float, str], None]


@dataclass(frozen=True)
class LayoutReady:
    """The bricks of a run, told once they are decided, before the printed parts are cut and
    the forces and the build order checked: the ``layout`` (its bricks' steps not yet
    numbered), the ids of its bricks that become printed parts (``printed``) and the seconds
    since the run began."""

    layout: Layout
    printed: frozenset[int]
    seconds: float


@dataclass
class Fabrication:
    """Everything one run produced, stage by stage, and the :class:`Request` it was made for.

    ``regions`` are the high-res regions in the layout's frame (what the
    snapshot records for a later iteration); ``order`` the build order,
    whose step numbers the layout's bricks carry; ``iteration`` what the
    iteration branch added (None for a fresh run); ``warnings`` what the
    user should look at (a high-res region that marks no cell).
    """

    request: Request
    model: mesh_io.LoadedModel
    parts: tuple[catalog.Part, ...]
    grid: Grid
    layout: Layout
    stability: stability_stage.Stability
    order: build_order.BuildOrder
    timings_s: dict[str, float] = field(default_factory=dict)
    printed: list[PrintedPart] = field(default_factory=list)
    connectors: connectors_stage.Connectors | None = None
    regions: high_res_stage.Regions = field(default_factory=high_res_stage.Regions)
    marks: dict = field(default_factory=dict)
    fit: grid_fit.GridFit | None = None
    iteration: iterate_stage.Iteration | None = None
    notes: list[str] = field(default_factory=list)
    print_full: PrintEstimate | None = None
    print_parts: PrintEstimate | None = None
    plates: list | None = None
    forces: forces_stage.Forces | None = None
    reinforced: reinforce_stage.Reinforced | None = None
    warnings: list[str] = field(default_factory=list)
    hollowing: hollow_stage.Hollowing | None = None
    layout_quality: dict = field(default_factory=dict)
    inventory: inventory_stage.Inventory | None = None
    colouring: dict | None = None

    @property
    def seed(self) -> int:
        return self.request.seed

    @property
    def interface(self) -> Fit:
        """The stud and socket fit the printed parts were made with."""
        return self.request.fit

    @property
    def seconds_per_brick(self) -> float:
        return self.request.seconds_per_brick

    @property
    def seconds_per_part(self) -> float:
        return self.request.seconds_per_part

    @property
    def profile(self) -> str | dict | None:
        """What the parts are sliced with (:func:`core.printing.printers.profile`)."""
        return printers.profile(self.request)

    @property
    def printer(self) -> printers.Printer | None:
        """The printer the request chose (:func:`core.printing.printers.chosen`), None for the default."""
        return printers.chosen(self.request)

    @property
    def to_print(self) -> list[PrintedPart]:
        """The printed parts to print now: all of them, or after an iteration
        (``--previous``) only those it must reprint."""
        if self.iteration is None:
            return list(self.printed)
        again = set(self.iteration.reprinted)
        return [p for p in self.printed if p.id in again]


def _noop(fraction: float, message: str) -> None:
    """Progress sink that ignores everything."""


def as_request(job, **settings) -> Request:
    """``job`` as a checked :class:`Request`: a Request (``settings`` change it) or a model path."""
    if isinstance(job, Request):
        return job.replace(**settings).checked()
    return request_of(job, **settings)


def run(job, progress: Progress | None = None,
        on_layout: Callable[[LayoutReady], None] | None = None, **settings) -> Fabrication:
    """The driver: run every stage for ``job`` (a :class:`Request`, or a model path with
    ``settings`` as Request fields) and return the :class:`Fabrication`.  ``on_layout`` is
    called once with the :class:`LayoutReady` as soon as the bricks are decided (after
    stage 4, the groups of stage 5 known), so that a user sees the layout before the rest.

    The stages, in order (each returns new data):

    1. **load** the model (:func:`core.io.meshes.load_model`); with
       ``previous``, load that result (:func:`core.result.load_previous`) and
       align the model onto it (:func:`core.iterate.align_to`).  The run is
       then an *iteration*, unless the previous result cannot be reused
       (:func:`core.iterate.reusable`) or the model moved and
       ``iterate_moved`` is off: then it is a fresh run and ``notes`` say why.
    2. **legofy**: fresh, on a grid centred on the part or shifted so that
       the regions mark the least (:func:`core.grid_fit.fit`); iterating,
       on the previous lattice, diffed with it (:func:`core.iterate.legofy_on`).
       Fresh, the grid's size is checked before (:func:`core.voxelize.check_size`),
       and then **hollow** keeps a shell, its pillars and the high-res cells
       (:func:`core.hollow.decide`, the request's ``hollow``; when iterating, as the
       previous version was, :func:`core.hollow.as_before`).
    3. **high_res**: the regions mark cells (:meth:`core.high_res.Regions.cells`;
       iterating, the previous run's regions too when ``previous_regions``),
       and unless ``connectors`` is off, anchor tabs are added
       (:func:`core.high_res.anchor`).
    4. **layout**: fresh, marked and other cells laid out apart
       (:func:`core.layout.greedy.lay_out_around`), and beside a shell the solid part
       too when :func:`core.hollow.solid_layout_wanted` (an automatic shell is
       then kept only if it saves a third of the bricks, :func:`core.hollow.compared`);
       iterating, the previous bricks
       kept where they still fit and the rest laid out anew
       (:func:`core.iterate.lay_out`); then **improve**d window by window
       as hard as ``effort`` says (:func:`core.layout.search.improve`; iterating,
       the kept bricks stay; ``best`` on a fresh layout also starts from the brick layers
       of the exact cover's relaxation where that is cheap,
       :func:`core.layout.greedy.relaxed_brick_groups`) and measured (:func:`core.layout.search.layout_quality`,
       with the exact lower bound on request or when it is cheap).  A fresh
       layout is then re-merged around the joints the forces find failing or
       loaded (:func:`core.layout.reinforce.reinforce`).
    5. **printed_parts**: the bricks touching marked cells (and
       ``high_res_bricks``), grouped (:func:`core.high_res.groups`), edited
       by ``part_edits``, on a chosen printer (:func:`core.printing.printers.chosen`) cut
       at layer seams where a group fits it in no pose (:func:`core.parts.printed.fitting_groups`),
       become printed parts (:func:`core.parts.printed.build_parts`;
       iterating, kept parts stay and only changed ones are cut again,
       :func:`core.iterate.printed_parts`).
    6. **stability**: the brick graph (:func:`core.stability.analyse`) and the
       forces on ``ground`` with ``loads`` (:func:`core.forces.analyse`), 7. **build order**
       (:func:`core.instructions.build_order.plan`; the layout's bricks get their steps),
       8. with an iteration, the **changes** (:func:`core.iterate.changes`),
       9. with printed parts and ``slice_parts``, **print times**
       (:func:`print_times`) on the chosen printer's beds.

    Raises :class:`~core.errors.InputError` for bad input; otherwise the
    layout covers every filled cell once.
    """
    req = as_request(job, **settings)
    with output_dir.scratch("slice") as scratch:
        return _stages(req, progress or _noop, os.path.join(scratch, "run"), on_layout)


# One function on purpose: the one driver's whole sequence of stages, read top to bottom,
# is where the data flow between them is decided and seen.
def _stages(req: Request, progress: Progress, work: str,
            on_layout: Callable[[LayoutReady], None] | None = None) -> Fabrication:
    """:func:`run`'s stages for ``req`` (``on_layout`` as there); what is sliced in the
    background is sliced under ``work``, a folder made when first sliced into, in a scratch
    folder the caller removes after the run however it ends (a slice still running then
    fails, and makes neither again)."""
    timings: dict[str, float] = {}
    began = time.perf_counter()

    def timed(name: str, fraction: float, fn, *args, **kwargs):
        progress(fraction, name)
        start = time.perf_counter()
        value = fn(*args, **kwargs)
        timings[name] = round(time.perf_counter() - start, 4)
        return value

    chosen = catalog.select(req.parts)
    printers.chosen(req)                    # a bad printer or config ends the run before any work
    owned = timed("inventory", 0.0, inventory_stage.read, req.inventory) if req.inventory else None
    stock = None if owned is None else inventory_stage.Stock(owned.owned(chosen),
                                                             buy=not req.inventory_only)
    laying = chosen if stock is None or stock.buy else inventory_stage.usable(chosen, stock)
    model = timed("load", 0.0, mesh_io.load_model, req.model, units=req.units, scale=req.scale,
                  up=req.up)
    loaded = [high_res_stage.load_region(p, units=req.units, scale=req.scale, up=req.up)
              for p in req.high_res_solids]
    regions = high_res_stage.Regions.of(req.high_res, loaded)
    if any(model.offset_mm):
        shift = np.asarray(model.offset_mm)
        loaded = [dataclasses.replace(r, mesh=r.mesh.copy().apply_translation(shift)) for r in loaded]
        regions = (high_res_stage.Regions.of(req.high_res).moved(_translation(shift))
                   + high_res_stage.Regions.of((), loaded))
    suggested = suggested_regions = None
    if req.suggest:
        suggested = timed("suggest", 0.02, suggest_stage.suggest, model, req.suggest_tolerance,
                          min_speedup=req.suggest_speedup)
        suggested_regions = high_res_stage.Regions.of(suggested.boxes)
        regions = regions + suggested_regions
    notes: list[str] = []
    before = alignment = None
    if req.previous is not None:
        before = timed("previous", 0.03, result.load_previous, req.previous)
        why = iterate_stage.reusable(before, req.units, req.scale, req.seed, req.up)
        if why is None:
            alignment, aligned = timed("align", 0.05, iterate_stage.align_to, before, model)
            if iterate_moved_out(req, alignment):
                why = "the new version is moved or turned against the previous one"
            else:
                model, regions = aligned, regions.moved(alignment.transform)
                if suggested_regions is not None:
                    suggested_regions = suggested_regions.moved(alignment.transform)
        if why is not None:
            notes.append(f"laid out anew where it stands: {why}")
            before = alignment = None

    slicing = _Slicing.start(req, model.mesh, bool(regions or req.high_res_bricks), work)
    given = regions
    fit = diff = hollowing = None
    if before is None:
        voxelize.check_size(model.mesh, req.units, Path(req.model).name, unit_mm=UNITS)
        voxelize.check_volume(model.mesh, model.watertight, req.hollow)
        if req.fit_grid and regions:
            fit = timed("grid_fit", 0.1, grid_fit.fit, model.mesh, regions.boxes, loaded,
                        closed=model.watertight)
        origin, shape = voxelize.grid_frame(model.mesh.bounds) if fit is None else (fit.origin, fit.shape)
        grid = timed("legofy", 0.2, voxelize.legofy,
                     voxelize.snap_to_lattice(model.mesh, origin, np.asarray(CELL_MM)),
                     origin=origin, shape=shape, closed=model.watertight)
        if grid.count == 0:
            raise InputError(f"{Path(req.model).name}: the part fills no cell of the "
                             f"{CELL_MM[0]:g} x {CELL_MM[1]:g} x {CELL_MM[2]:g} mm grid")
        solid = grid
        hollowing = timed("hollow", 0.25, hollow_stage.decide, grid, req.hollow,
                          regions.cells(grid) if regions else None)
        grid = hollowing.grid
        voxelize.check_cells(grid.count, req.hollow)
    else:
        if req.previous_regions:
            regions = iterate_stage.previous_regions(before) + regions
        diff, hollowing = timed("legofy", 0.2, iterate_stage.legofy_on, before, model, req.hollow,
                                regions)
        grid = diff.grid

    def fresh_layout(grid_: Grid, name: str, span=(0.4, 0.6)):
        marked_ = timed("high_res", 0.3, regions.cells, grid_)
        cells_ = high_res_stage.anchor(grid_, marked_) if req.connectors else marked_
        lay = layout_stage.lay_out_around if cells_.any() else layout_stage.lay_out
        extra = (cells_,) if cells_.any() else ()
        laid = timed(name, span[0], lay, grid_, *extra, laying, seed=req.seed,
                     progress=within(progress, *span))
        if stock is not None:
            laid = timed(name + "_stock", span[1], layout_stage.fit_stock, laid, chosen, stock)
        return marked_, cells_, laid

    plan = rings = None
    if before is not None:
        marked = timed("high_res", 0.3, regions.cells, grid)
        cells = high_res_stage.anchor(grid, marked) if req.connectors else marked
        (layout, plan, rings) = timed("layout", 0.4, iterate_stage.lay_out, before, diff, cells,
                                      laying, req.seed)
        if stock is not None:
            layout = timed("layout_stock", 0.45, layout_stage.fit_stock, layout, chosen, stock,
                           plan.kept)
    else:
        marked, cells, layout = fresh_layout(grid, "layout")
        largest = max(p.footprint[0] * p.footprint[1] * p.layers for p in chosen)
        if hollow_stage.solid_layout_wanted(hollowing, len(layout.bricks), largest):
            solid_marked, solid_cells, solid_layout = fresh_layout(solid, "layout_solid", (0.6, 0.78))
            hollowing = hollow_stage.compared(hollowing, solid, len(layout.bricks),
                                              len(solid_layout.bricks))
            if not hollowing.on:
                grid, marked, cells, layout = solid, solid_marked, solid_cells, solid_layout
        elif hollowing.on and hollowing.setting < 0:
            hollowing = hollow_stage.judged(hollowing, len(layout.bricks), largest)
    greedy = layout
    others = ()
    if before is None and stock is None and improve_stage.EFFORT_LEVELS[req.effort].relaxed_start:
        relaxed = timed("layout_relaxed", 0.77, layout_stage.relaxed_layout, grid, cells, chosen,
                        req.seed)
        others = () if relaxed is None else (relaxed,)
    bound = timed("early_bound", 0.78, improve_stage.early_bound, grid, laying)
    layout = timed("improve", 0.78, improve_stage.improve, layout, laying, req.effort, req.seed,
                   within(progress, 0.78, 0.8),
                   frozen=None if plan is None else plan.kept, apart=cells,
                   next_id=None if plan is None else plan.next_id, others=others, bound=bound,
                   stock=stock)
    quality = improve_stage.layout_quality(greedy, layout, laying, timings, req.lower_bound,
                                           bound=bound)
    warnings = _unmarked(given, grid, req, marked.any()) + list(suggested.warnings if suggested else ())
    reinforced = None
    if before is None:
        reinforced = timed("reinforce", 0.8, reinforce_stage.reinforce, layout, laying, req.ground,
                           req.loads, req.clutch_n, cells, req.seed,
                           checked_again=bool(cells.any() or req.high_res_bricks), effort=req.effort)
        if stock is None or inventory_stage.fits(reinforced.layout, stock):
            layout = reinforced.layout

    ids = high_res_stage.touched_bricks(layout, cells) + high_res_stage.check_ids(layout, req.high_res_bricks)
    if req.high_res_bricks:
        regions = regions + high_res_stage.Regions.of_bricks(layout, req.high_res_bricks)
    groups = _edited(layout, high_res_stage.groups(layout, ids), req.part_edits)
    if on_layout is not None:
        on_layout(LayoutReady(layout, frozenset(i for g in groups for i in g),
                              round(time.perf_counter() - began, 4)))
    printer = printers.chosen(req)
    if groups and before is None and printer is not None:
        groups, cut = printed_stage.fitting_groups(
            layout, groups, build_volume(printer.config), req.fit)
        notes += [f"a printed part of {' x '.join(f'{v:g}' for v in box)} mm fits the "
                  f"{printer.printer} in no pose: split along brick seams into {n} parts that "
                  f"each fit, joined by their own studs and sockets" for box, n in cut]
    made: list[PrintedPart] = []
    clamp = links = reprint = None
    if groups and before is not None:
        made, reprint, links, layout = timed(
            "printed_parts", 0.6, iterate_stage.printed_parts, before, layout, plan, groups,
            model, alignment, req.fit, req.connectors)
        links = links if req.connectors else connectors_stage.find(layout, [])
    elif groups:
        source = timed("model_solid", 0.6, printed_stage.model_solid, model)
        contacts = connectors_stage.find(layout, groups)
        made = timed("printed_parts", 0.65, printed_stage.build_parts, layout, groups,
                     source, req.fit, req.connectors, links=contacts)
        links = contacts if req.connectors else connectors_stage.find(layout, [])
        layout = printed_stage.apply(layout, made)
    if made:
        clamp = printed_stage.clamp_masks(layout, made)
        again = None if reprint is None else {r["id"] for r in reprint if r["reprint"]}
        slicing = slicing.with_parts([p for p in made if again is None or p.id in again])
    stab = timed("stability", 0.8, stability_stage.analyse, layout, clamp)
    settings = _slicer_settings(req) if made else None
    if reinforced is not None and reinforced.forces is not None and not made and reinforced.layout is layout:
        force = reinforced.forces            # the same check of this very layout, made there
    else:
        force = timed("forces", 0.81, forces_stage.analyse, layout, req.ground, req.loads, made,
                      clamp, req.clutch_n, settings)
    order = timed("build_order", 0.82, build_order.plan, layout)
    if forces_stage.build_unchecked(force) is None:
        checker = forces_stage.BuildChecker(layout, req.ground, made, clamp, req.clutch_n, settings)
        order = timed("build_stability", 0.83, build_order.standing, layout, order, checker.stands,
                      props=True, ground=req.ground)
        order = dataclasses.replace(order, graph_only_why=checker.why or "")
        if order.props:
            final = forces_stage.BuildChecker(layout, req.ground, made, clamp, req.clutch_n, settings,
                                              loads=req.loads)
            order = dataclasses.replace(order, finished=timed(
                "finished_with_props", 0.84, build_order.finished_with_props, layout, order, final.stands))
    layout = build_order.numbered(layout, order)
    colouring = None if owned is None else inventory_stage.colour(
        layout, owned, colours.by_name(req.colour), _kept_colours(before, plan))
    iteration = None
    if before is not None:
        reprint = reprint or []
        changes = iterate_stage.changes(before, alignment, diff, layout, plan, made, reprint, rings)
        iteration = iterate_stage.Iteration(before, alignment, diff,
                                            [r["id"] for r in reprint if r["reprint"]], changes, rings)
    fab = Fabrication(req, model, chosen, grid, layout, stab, order, timings, made,
                      connectors=links, regions=regions,
                      marks={"marked_cells": int(np.count_nonzero(marked)),
                             "anchor_cells": int(np.count_nonzero(cells & ~marked)),
                             **_suggested_marks(suggested, suggested_regions, grid, model)},
                      fit=fit, iteration=iteration, notes=notes, warnings=warnings,
                      forces=force, reinforced=reinforced, hollowing=hollowing,
                      layout_quality=quality, inventory=owned, colouring=colouring)
    if fab.to_print and req.slice_parts:
        fab = timed("print_time", 0.85, print_times, fab, slicing)
        fab.timings_s.update(timings)
    return fab


def _kept_colours(before, plan) -> dict | None:
    """Brick id -> LDraw colour of the bricks an iteration keeps, as the previous output's
    ``layout.json`` coloured them (None: not an iteration, or no colours there)."""
    path = None if before is None or plan is None else Path(before.folder) / "layout.json"
    if path is None or not path.is_file():
        return None
    try:
        known = inventory_stage.colouring_of(json.loads(path.read_text()))
    except (ValueError, KeyError, TypeError):
        return None
    kept = set(plan.kept)
    return {i: c for i, (c, _) in (known or {}).items() if i in kept} or None


def _slicer_settings(req: Request) -> dict[str, str]:
    """The slicer settings printed parts are made with (their walls, infill and filament
    weigh them in the force check); the committed profile when they cannot be read."""
    try:
        return print_time_stage.load_profile(printers.profile(req),
                                             print_time_stage.requested(req.slicer))
    except InputError:
        return print_time_stage.load_profile(print_time_stage.FALLBACK_PROFILE)


def _suggested_marks(suggested, marks, grid: Grid, model) -> dict:
    """The report's ``high_res.suggested`` with ``--suggest`` (nothing without): the regions
    (boxes in the frame of --high-res), those dropped, and on ``grid`` (the one laid out)
    the share of the model's volume in the cells the regions (``marks``, in ``grid``'s
    frame) touch and the share of ``grid``'s cells."""
    if suggested is None:
        return {}
    doc = suggested.to_json(model.offset_mm)
    weight = suggest_stage.volume_per_cell(model.mesh, grid.origin, grid.shape, model.watertight)
    volume, cells = suggest_stage.shares(grid, marks, weight)
    doc["share_of_volume"], doc["share_of_cells"] = round(volume, 4), round(cells, 4)
    return {"suggested": doc}


def _translation(shift) -> np.ndarray:
    """The 4x4 matrix that moves by the vector ``shift``."""
    m = np.eye(4)
    m[:3, 3] = shift
    return m


def _unmarked(regions: high_res_stage.Regions, grid: Grid, req: Request, any_marked: bool) -> list[str]:
    """One warning per high-res box of ``req`` that marks no filled cell of ``grid``, and per
    region solid when no region marks any (``regions``: the request's own, in the grid's
    frame, boxes first; ``any_marked``: whether all regions together mark a cell)."""
    lo = grid.origin
    hi = grid.origin + np.asarray(grid.shape) * grid.cell
    span = " to ".join(",".join(f"{v:g}" for v in np.round(c, 1)) for c in (lo, hi))
    boxes = [(f"high-res box {b}" if isinstance(b, str) else f"high-res box {n + 1}", box)
             for n, (b, box) in enumerate(zip(req.high_res, regions.boxes))]
    unmarked = [name for name, box in boxes
                if not (high_res_stage.box_cells(grid, box) & grid.filled).any()]
    if not any_marked:
        unmarked += [f"high-res region {Path(p).name}" for p in req.high_res_solids]
    return [f"{name} marks no cell of the part (its grid spans {span} mm): nothing is printed "
            f"for it" for name in unmarked]


def within(progress: Progress, lo: float, hi: float, step: float = 0.05,
           every_s: float = 5.0) -> Progress:
    """``progress`` for a stage that runs from ``lo`` to ``hi`` of the whole run: the
    stage's fraction mapped into that range, passed on only when it moved by ``step``
    of the stage or ``every_s`` seconds passed (a stage may report thousands of times)."""
    last = {"fraction": -1.0, "time": 0.0}

    def report(fraction: float, message: str) -> None:
        now = time.perf_counter()
        if fraction - last["fraction"] >= step or now - last["time"] >= every_s:
            last.update(fraction=fraction, time=now)
            progress(lo + (hi - lo) * min(max(fraction, 0.0), 1.0), message)

    return report


def iterate_moved_out(req: Request, alignment) -> bool:
    """Whether ``req`` lays a moved new version out anew instead of iterating on it."""
    return not req.iterate_moved and iterate_stage.moved(alignment)


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


@dataclass(frozen=True)
class _Slicing:
    """The slices :func:`run` started early, in the background: the whole model's time
    (``full``) and the printed parts' plates with their times (``parts``), each a Future
    or None when not started.  ``slicer`` is the binary they were started with, ``work``
    the folder they slice under."""

    slicer: str | None = None
    profile: str | None = None
    work: str | None = None
    full: object = None
    parts: object = None

    @classmethod
    def start(cls, req: Request, mesh, likely: bool, work: str) -> "_Slicing":
        """The whole model's slicing started now under ``work``, when ``req`` slices, a
        slicer (the request's choice) is installed and printed parts are ``likely``
        (regions are marked)."""
        binary = print_time_stage.slicer_path(req.slicer) if req.slice_parts and likely else None
        if binary is None:
            return cls(work=work)
        profile = printers.profile(req)
        return cls(binary, profile, work,
                   print_time_stage.in_background(_full_time, mesh.copy(), profile, binary, work,
                                                  printers.chosen(req) is not None))

    def with_parts(self, printing: list) -> "_Slicing":
        """This, with the plates of the parts ``printing`` being posed and sliced too."""
        if self.slicer is None or not printing:
            return self
        return dataclasses.replace(self, parts=print_time_stage.in_background(
            _plates_time, printing, self.profile, self.slicer, self.work))


def _sliced_under(work: str | None):
    """``work`` for a ``with`` block, or a scratch folder of its own when None."""
    return contextlib.nullcontext(work) if work is not None else output_dir.scratch("slice")


def _full_time(mesh, profile, slicer, work: str | None = None,
               chosen: bool = False) -> PrintEstimate:
    """The whole model's print time in its fastest pose (the speed-up's baseline),
    sliced under ``work`` (a scratch folder when None); on a ``chosen`` printer, as if
    its bed were large enough where the model does not fit it
    (:func:`core.printing.printers.reference_time`)."""
    with _sliced_under(work) as folder:
        if chosen:
            return printers.reference_time(mesh, folder, profile=profile, slicer=slicer)
        return print_time_stage.print_time([mesh], folder, profile=profile, slicer=slicer)


def _plates_time(printing: list, profile, slicer, work: str | None = None) -> tuple[list, list]:
    """The plates of the printed parts ``printing`` (:func:`core.printing.export.plates`) and
    each plate's print time, two plates at a time, sliced under ``work`` (a scratch
    folder when None)."""
    from core.printing.export import plates
    with _sliced_under(work) as folder:
        beds = plates(printing, profile=profile, slicer=slicer, workdir=folder)
        results = print_time_stage.in_parallel(lambda items: print_time_stage.print_time(
            [m for _, m, _ in items], folder, profile=profile, slicer=slicer), beds, 2)
    return beds, results


def print_times(fab: Fabrication, started: _Slicing | None = None) -> Fabrication:
    """``fab`` with print times: the whole model (the baseline) and the plates of the
    printed parts to print (:func:`core.printing.export.plates`: one plate unless they do not
    fit the bed) sliced with the request's ``slicer``, two at a time; the parts' time is the
    plates' sum.
    ``started`` holds what :func:`run` already set slicing in the background (the
    same slices, begun while the other stages ran); the rest is sliced now.

    The returned Fabrication keeps the plates in ``plates`` (for
    :func:`write_outputs`, which writes them as they were timed).  A part's
    own ``print_s`` is its plate's time shared out in proportion to the
    parts' own sliced times in their poses (their calibrated estimates
    without a slicer), so the parts' times add up to the plates'.  ``fab``
    itself is not changed.
    """
    started = started or _Slicing()
    printing = fab.to_print
    slicer = started.slicer or print_time_stage.requested(fab.request.slicer)
    full = started.full or print_time_stage.in_background(_full_time, fab.model.mesh, fab.profile,
                                                          slicer, started.work, fab.printer is not None)
    beds, results = (started.parts.result() if started.parts is not None
                     else _plates_time(printing, fab.profile, slicer, started.work))
    printers.check_plates(fab.printer, beds, [p.id for p in printing])
    full = full.result()
    methods = sorted({r.method for r in results})
    parts = PrintEstimate(
        sum(r.seconds for r in results),
        "; ".join(methods) if methods else "nothing to print: no printed part changed", None)
    seconds: dict[str, float] = {}
    for items, sliced in zip(beds, results):
        weights = [pose.slicer_s or estimate_seconds([m]) for _, m, pose in items]
        total = sum(weights) or 1.0
        for (index, _, _), w in zip(items, weights):
            seconds[printing[index].id] = sliced.seconds * w / total
    printed = [dataclasses.replace(p, print_s=seconds[p.id]) if p.id in seconds else p
               for p in fab.printed]
    return dataclasses.replace(fab, printed=printed, print_full=full, print_parts=parts,
                               plates=beds, timings_s=dict(fab.timings_s))




def sliced_later(fab: Fabrication, slicer: str | None):
    """A Future of ``fab`` with its print times sliced by ``slicer`` (:func:`print_times`; None:
    the one installed), sliced in a background thread while the caller shows ``fab`` with its
    estimates.  ``fab`` itself is not changed."""
    job = dataclasses.replace(fab, request=fab.request.replace(slicer=slicer))
    return print_time_stage.in_background(print_times, job)


def stored(folder: str | os.PathLike, doc: dict) -> Fabrication:
    """The Fabrication of a stored result: the iteration snapshot in ``folder`` (an output
    folder, or what the workbench keeps of one) and its report ``doc``.

    It holds what :func:`write_outputs` writes (layout with its steps, the build
    order the run checked (planned afresh for a snapshot older than that),
    printed parts, model, regions, settings); the report is ``doc`` itself,
    so :func:`write_outputs` called with ``report=doc`` writes the same
    files a run writes.  Raises InputError when the snapshot cannot be read.
    """
    before = result.load_previous(folder)
    state = before.state
    settings = state.get("settings") or {}
    fit = state.get("fit") or {}
    req = Request(model=str(doc["model"]["path"]), units=settings.get("units", "mm"),
                  scale=float(settings.get("scale", 1.0)), up=settings.get("up", "z"),
                  seed=int(state.get("seed", 0)),
                  stud_fit=float(fit.get("stud_fit", Fit.stud_fit)),
                  socket_fit=float(fit.get("socket_fit", Fit.socket_fit)),
                  seconds_per_brick=float(doc.get("seconds_per_brick", Request.seconds_per_brick)),
                  seconds_per_part=float(doc.get("seconds_per_part", Request.seconds_per_part)))
    m = doc["model"]
    model = mesh_io.LoadedModel(before.mesh, str(m["path"]), m.get("format", ""),
                                int(m.get("triangles", 0)), before.watertight,
                                list(m.get("repaired", ())), list(m.get("warnings", ())), before.brep)
    st = doc["stability"]
    stab = stability_stage.Stability(int(st["regions"]), int(st["components"]),
                                     list(st.get("weak_point_bricks", ())),
                                     list(st.get("unconnectable", ())))
    chosen = tuple(catalog.BY_NUMBER[n] for n in state["brick_set"] if n in catalog.BY_NUMBER)
    printed = [before.parts[p["id"]] for p in doc.get("printed_parts", ()) if p["id"] in before.parts]
    order = (build_order.BuildOrder.from_json(state["order"]) if "order" in state
             else build_order.plan(before.layout))
    box = doc.get("inventory")
    owned = None if not box else inventory_stage.Inventory(
        {(r["part"], int(r["ldraw_color"])): int(r["count"]) for r in box.get("owned", ())},
        tuple(box.get("ignored", ())))
    if box:
        req = req.replace(colour=box.get("bought_colour", req.colour),
                          inventory_only=bool(box.get("inventory_only", False)))
    return Fabrication(req, model, chosen, before.grid, before.layout, stab,
                       order, dict(doc.get("timings_s", {})), printed,
                       regions=before.regions or high_res_stage.Regions(),
                       marks=dict(doc.get("high_res", {})), inventory=owned,
                       colouring=inventory_stage.colouring_of(state["layout"]) if box else None)


def write_outputs(fab: Fabrication, out: str | os.PathLike,
                  progress: Progress | None = None, report_doc: dict | None = None) -> dict:
    """Write ``report.json``, ``layout.json`` (and ``layout.png`` unless the request
    says no picture), the printed parts (``parts/``), the builder's files
    (``instructions.html``, ``assembly.mpd``, ``bom.csv``, ``bricklink.xml``,
    :mod:`core.instructions.page`, in the run's build order), the iteration
    snapshot (``iteration/``) and after an iteration ``changes.html`` into
    ``out``; returns the report.  Reads ``fab`` only.

    Everything is written into a temporary sibling folder first and moved
    into place at the end, replacing an earlier output atomically
    (:class:`core.io.output_dir.OutputFolder`; ``out`` may be one already open,
    as :func:`fabricate` opens it before the run).  ``report_doc`` is
    the report to write instead of :func:`core.report.document`'s (a stored result's,
    :func:`stored`), with its ``changes`` page written too.  Raises
    InputError for a place that cannot take the output (refused before
    anything is written) or that fails while writing (a full disk: the
    unfinished output is removed).
    """
    if not isinstance(out, output_dir.OutputFolder):
        with output_dir.OutputFolder(out, inputs=_inputs(fab.request)) as folder:
            return write_outputs(fab, folder, progress, report_doc)
    progress = progress or _noop
    folder, tmp = out, out.temp
    title = Path(fab.model.path).name.encode("utf-8", "surrogateescape").decode("utf-8", "replace")
    start = time.perf_counter()
    placed = {}
    if fab.printed:
        from core.printing import export
        progress(0.9, "export")
        _, parts = export.export_parts(fab.printed, tmp / "parts", profile=fab.profile,
                                       slicer="none" if fab.print_full is None
                                       else print_time_stage.requested(fab.request.slicer),
                                       beds=fab.plates if fab.iteration is None else None)
        placed = {p.id: p for p in parts}
    progress(0.92, "instructions")
    from core.instructions import page as instructions
    assembly = instructions.write_assembly(
        fab.layout, fab.printed, tmp, title=title, seconds_per_brick=fab.seconds_per_brick,
        seconds_per_part=fab.seconds_per_part, order=fab.order, colouring=fab.colouring,
        inventory=fab.inventory, bought=colours.by_name(fab.request.colour),
        printed_on=printers.described(fab.request).label)
    (tmp / "layout.json").write_text(json.dumps(
        inventory_stage.with_colours(fab.layout.to_json(), fab.colouring)))
    if fab.request.picture:
        progress(0.95, "picture")
        from core.instructions import render
        drawn: dict = {}                         # both pictures draw the same polygons
        render.render_layout(fab.layout, tmp / "layout.png",
                             title=f"{title}: {len(fab.layout.bricks)} bricks",
                             palette=fab.request.palette,
                             colours=None if fab.colouring is None or fab.request.palette != "bom"
                             else colours.brick_colours(fab.layout, colouring=fab.colouring),
                             cache=drawn)
        if fab.forces is not None and fab.forces.utilisation:
            render.render_layout(fab.layout, tmp / "stress.png", title=reporting.stress_title(fab),
                                 colours=colours.stress_rgb(
                                     [fab.forces.utilisation.get(b.id, 0.0) for b in fab.layout.bricks]),
                                 cache=drawn)
    result.snapshot(fab, tmp)
    doc = reporting.document(fab) if report_doc is None else json.loads(json.dumps(report_doc))
    for entry in doc["printed_parts"]:
        if entry["id"] in placed:
            p = placed[entry["id"]]
            entry.update(stl=p.stl, step=p.step, pose=p.pose)
    if doc.get("changes"):
        changes_page.changes_page(doc["changes"], fab.layout, tmp / "changes.html", title)
    doc.setdefault("timings_s", {})["write"] = round(time.perf_counter() - start, 4)
    doc["assembly"] = assembly
    doc["outputs"] = sorted(p.name for p in tmp.iterdir()) + ["report.json"]
    (tmp / "report.json").write_text(json.dumps(doc, indent=2))
    folder.install()
    progress(1.0, "done")
    if folder.notes:
        doc["notes"] = list(doc.get("notes", ())) + folder.notes
    return doc


def _inputs(req: Request) -> list[str]:
    """The files a run of ``req`` reads (an output folder must not hold them)."""
    return [req.model, *req.high_res_solids, *([req.profile] if req.profile else []),
            *([req.slicer_config] if req.slicer_config else []), *req.inventory]


def fabricate(job, out: str | os.PathLike, progress: Progress | None = None, **settings) -> dict:
    """Run the driver on ``job`` (a :class:`Request`, or a model path with ``settings``
    as Request fields) and write its outputs into ``out``; returns the report.

    The output place is checked and locked before the run starts
    (:class:`core.io.output_dir.OutputFolder`): InputError in one line for one
    that cannot be written, holds an input or other files, or another run
    is writing."""
    req = as_request(job, **settings)
    with output_dir.OutputFolder(out, inputs=_inputs(req)) as folder:
        return write_outputs(run(req, progress=progress), folder, progress=progress)
