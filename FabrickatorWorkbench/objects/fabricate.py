"""Recompute of a Fabrication: its inputs to the core, the core's result to the document.

:func:`recompute` is the Fabrication's ``execute``.  It writes the Source to
a temporary file (:mod:`FabrickatorWorkbench.bridge`), gathers the high-res
regions into a :class:`core.request.Request`, runs the core's one driver
(:func:`core.pipeline.run`), and only when that succeeded changes the document
(:func:`FabrickatorWorkbench.objects.tree.sync`).  A failure (bad input,
a Source without a solid, a cancelled run) leaves every object as it was,
puts the parameters back to the last values that worked, and says why in
one line in the Report view and in the ``Status`` property.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from contextlib import contextmanager
from dataclasses import dataclass

import FreeCAD as App

from core import request as core_request
from core.errors import InputError, memory_shortage
from core.model import CELL_MM
from core.parts.interfaces import Fit
from FabrickatorWorkbench import bridge, deps, log, preferences
from FabrickatorWorkbench.objects import high_res_region, later_slices, load, tree
from FabrickatorWorkbench.viewproviders.layout_preview import LayoutPreview

#: Inputs of a Fabrication the user edits; the last values that recomputed fine are
#: kept in ``LastGood`` and put back when a recompute fails.
PARAMETERS = ("BrickSet", "StudFit", "SocketFit", "Seed", "Scale", "Effort", "LowerBound",
              "SecondsPerBrick", "SecondsPerPart", "SlicePrintTimes", "FitGrid", "Ground",
              "Clutch", "Hollow", "Inventory", "InventoryOnly", "BuyColour")


#: Milliseconds the status bar says that a recompute was stopped with Esc.
CANCELLED_MESSAGE_MS = 10000


class Cancelled(Exception):
    """The user cancelled the recompute (Esc)."""


@dataclass
class Result:
    """What one core run gave: the Fabrication (core), its steps and report, the inputs
    it was made from and a zip of the core's iteration snapshot (a temporary file)."""

    fab: object
    order: object
    report: dict
    inputs: dict
    snapshot: str | None = None
    #: Whether the run was an iteration on the last result: then the tree marks what
    #: changed (new bricks highlighted, removed ones as ghosts).
    marks: bool = True
    #: Whether the print times are estimates to be sliced after the recompute (with
    #: ``slicer``, :mod:`.later_slices`).
    later: bool = False
    slicer: str | None = None


def cell_size() -> App.Vector:
    """The core's cell size (one 1x1 plate), mm."""
    return App.Vector(*CELL_MM)


def fit(obj):
    """The :class:`core.parts.interfaces.Fit` of Fabrication ``obj``: its StudFit and SocketFit,
    the rest Fit's defaults; raises InputError naming a setting out of range."""
    return Fit(stud_fit=float(obj.StudFit.Value), socket_fit=float(obj.SocketFit.Value)).check()


def parameters(obj) -> dict:
    """The user-editable parameters of a Fabrication as plain values."""
    out = {}
    for name in PARAMETERS:
        value = getattr(obj, name)
        out[name] = float(value.Value) if hasattr(value, "Value") else value
    return out


def edits(obj) -> list[dict]:
    """The merge/split brush edits: [{"op": "merge"|"split", "boxes": [[x0..z1], ...]}]."""
    try:
        value = json.loads(obj.PartEdits or "[]")
    except ValueError:
        return []
    return value if isinstance(value, list) else []


def recompute(obj) -> bool:
    """Run the core for Fabrication ``obj`` and update the document; True on success.

    Never raises: for bad input (:class:`core.errors.InputError`), memory
    the system refused (:func:`core.errors.memory_shortage`) or a cancelled
    run the Report view and ``obj.Status`` say what failed in one line; any other exception is a bug, and the Report view shows its
    traceback.  Either way the document keeps the previous result and the
    parameters go back to the last values that worked.
    """
    if not deps.check(f"recomputing {obj.Label}"):
        obj.Status = "failed: Fabrickator's Python packages are missing (see the Report view)"
        return False
    try:
        result = run_core(obj)
    except (InputError, Cancelled) as exc:
        reason = log.failure(f"{obj.Label}: recompute", exc)
        _restore_parameters(obj)
        obj.Status = f"failed, previous result kept: {reason.split('failed: ', 1)[-1]}"
        return False
    except Exception as exc:  # noqa: BLE001 - a bug: shown with its traceback, document kept
        shortage = memory_shortage(exc)
        if shortage is not None:                 # the system refused memory: not a bug
            log.error(f"{obj.Label}: recompute failed: {shortage}")
            _restore_parameters(obj)
            obj.Status = f"failed, previous result kept: {shortage}"
            return False
        log.bug(f"{obj.Label}: recompute", exc)
        _restore_parameters(obj)
        obj.Status = (f"failed by a bug, previous result kept: {type(exc).__name__} "
                      f"(the traceback is in the Report view)")
        return False
    obj.Status = "failed while updating the tree (see the Report view)"
    first = not obj.LayoutJson
    kept, changed = tree.sync(obj, result)
    _store(obj, result, kept, changed)
    obj.Changes = change_lines(obj, first, result.marks)
    for line in obj.Changes:
        log.message(f"{obj.Label}: {line}")
    proxy = getattr(getattr(obj, "ViewObject", None), "Proxy", None) if App.GuiUp else None
    if proxy is not None:
        proxy.later_slice = None
        if result.later and result.fab.to_print:
            later_slices.start(obj, result, result.slicer)
    return True


def change_lines(obj, first: bool, marks: bool = True) -> list[str]:
    """What the last recompute of Fabrication ``obj`` changed, one line per category:
    bricks to take off (the ghosts), bricks to add (the highlighted ones), printed
    parts to reprint, and what stays.  Without ``marks`` (not an iteration: the
    seed or scale changed, the Source moved, or KeepLayout is off) one line says
    the layout was made anew."""
    parts = tree.printed_parts(obj)
    printing = [p.PartId for p in parts if p.Reprint]
    if first or not marks:
        return [("first layout" if first else "laid out anew (not an iteration on the previous "
                 "layout)") + f": {obj.Bricks} brick(s) to place"
                + (f", print {', '.join(printing)}" if printing else "")]
    changes = json.loads(obj.ReportJson).get("changes") if obj.ReportJson else None
    how = "iteration on the previous layout" if changes is not None else "laid out anew"
    added = sorted(b.BrickId for b in tree.bricks(obj) if b.Changed)
    removed = sorted(g.BrickId for g in tree.ghosts(obj))
    unchanged = [p.PartId for p in parts if not p.Reprint]
    return [f"take off: {_ids(removed)}",
            f"add: {_ids(added)}",
            f"reprint: {', '.join(printing) if printing else 'no printed part'}",
            f"keep: {obj.BricksKept} brick(s)"
            + (f", printed part(s) {', '.join(unchanged)} as printed" if unchanged else "")
            + f" ({how})"]


def _ids(ids: list[int], shown: int = 12) -> str:
    """'3 brick(s): 4, 9, 12' (at most ``shown`` ids listed), or 'no brick'."""
    if not ids:
        return "no brick"
    listed = ", ".join(str(i) for i in ids[:shown]) + (", ..." if len(ids) > shown else "")
    return f"{len(ids)} brick(s): {listed}"


def request(obj, path: str, boxes, solids, previous: str | None = None):
    """The :class:`core.request.Request` of Fabrication ``obj`` for its Source written at
    ``path``: its properties, the preferences' slicer profile, the regions (``boxes``,
    ``solids``) and brush edits, its Ground, Clutch and Loads (:func:`load_texts`);
    ``previous`` an unpacked snapshot to iterate on.  Its slicer is ``"none"`` (the core's
    estimate) with SlicePrintTimes off, else the preferences' SlicerPath when set.

    The workbench sends all of its regions every time (``previous_regions``
    off) and lays a moved Source out anew where it stands (``iterate_moved``
    off), because its bricks stand at the Source.
    """
    scale = float(obj.Scale)
    return core_request.Request(
        model=path, scale=scale, seed=int(obj.Seed), parts=obj.BrickSet.strip() or None,
        high_res=tuple(boxes), high_res_solids=tuple(solids),
        part_edits=tuple({"op": e["op"], "boxes": [_scaled_box(b, scale) for b in e["boxes"]]}
                         for e in edits(obj)),
        stud_fit=float(obj.StudFit.Value), socket_fit=float(obj.SocketFit.Value),
        fit_source="the Fabrication's StudFit and SocketFit",
        seconds_per_brick=float(obj.SecondsPerBrick),
        seconds_per_part=float(obj.SecondsPerPart), fit_grid=bool(obj.FitGrid),
        hollow=int(obj.Hollow),
        effort=str(obj.Effort), lower_bound=bool(obj.LowerBound),
        profile=preferences.get("SlicerProfile") or None, previous=previous,
        slicer=("none" if not obj.SlicePrintTimes
                else (preferences.get("SlicerPath") or "").strip() or None),
        printer=(getattr(obj, "Printer", "") or preferences.get("Printer") or "").strip() or None,
        previous_regions=False, iterate_moved=False, ground=str(obj.Ground),
        clutch_n=float(obj.Clutch.getValueAs("N")), loads=load_texts(obj, scale),
        inventory=tuple(str(p) for p in obj.Inventory if str(p).strip()),
        inventory_only=bool(obj.InventoryOnly), colour=str(obj.BuyColour)).checked()


def load_texts(obj, scale: float) -> tuple[str, ...]:
    """The Loads of Fabrication ``obj`` as ``Request.loads`` ("X0,Y0,Z0,X1,Y1,Z1:GRAMS" in the
    core's model mm: the Source's mm times ``scale``)."""
    return tuple(load.request_text(x, scale) for x in obj.Loads if load.is_load(x))


def run_core(obj) -> Result:
    """The core's result for Fabrication ``obj`` (changes nothing in the document).

    One run of the core's driver (:func:`core.pipeline.run`) on the
    Fabrication's :func:`request`.  With ``KeepLayout`` on, the stored
    snapshot is the request's ``previous`` and the core decides whether the
    run is an iteration (:func:`core.iterate.reusable`: not when the seed or
    the scale changed, nor when the Source was moved): then it keeps the old
    layout wherever the part and the regions did not change, as the command
    line's ``--previous`` does.  Raises InputError for unusable inputs and
    :class:`Cancelled` when the user stops it.
    """
    source = obj.Source
    if source is None:
        raise InputError("no Source: link the part to build in the Source property")
    if bridge.source_kind(source) is None:
        raise InputError(f"the Source {source.Label} has no solid and no mesh")
    from core import pipeline
    from core import report as reporting

    inputs = {"parameters": parameters(obj), "regions": region_signature(obj),
              "loads": list(load_texts(obj, 1.0))}
    title = f"Fabrickator: {obj.Label}"
    with tempfile.TemporaryDirectory(prefix="fabrickator-fc-") as work, \
            _progress(title, obj.Document) as progress, _preview(obj, title) as preview:
        path = bridge.write_source(source, work)
        boxes, solids = region_inputs(obj, work, float(obj.Scale))
        previous = _previous(obj, work) if obj.KeepLayout else None
        job = request(obj, path, boxes, solids, previous)
        later = slices_later(obj)
        fab = pipeline.run(job.replace(slicer="none") if later else job, progress=progress,
                           on_layout=None if preview is None else preview.show)
        for note in fab.notes:
            log.message(f"{obj.Label}: {note}")
        if not fab.layout.bricks:
            raise InputError("the layout has no bricks")
        report = reporting.document(fab)
        report["model"]["path"] = f"{source.Document.Name}#{source.Name} ({source.Label})"
        state = bridge.snapshot(fab)
    return Result(fab, fab.order, report, inputs, state, fab.iteration is not None,
                  later, job.slicer)


def slices_later(obj) -> bool:
    """Whether Fabrication ``obj``'s recompute leaves slicing to the background
    (:mod:`.later_slices`): with SlicePrintTimes on, in the GUI."""
    return bool(App.GuiUp and obj.SlicePrintTimes
                and getattr(getattr(obj, "ViewObject", None), "Proxy", None) is not None)


def region_signature(obj) -> str:
    """A text that changes whenever the regions or the merge/split edits change."""
    regions = []
    for r in obj.Regions:
        solid = r.RegionSolid
        regions.append({"mode": r.Mode, "boxes": list(r.Boxes),
                        "solid": None if solid is None else [solid.Name,
                                                             solid.Shape.exportBrepToString()
                                                             if bridge.source_kind(solid) == "shape"
                                                             else solid.Mesh.CountFacets],
                        "faces": [[o.Name, list(names)] for o, names in r.Faces]})
    return json.dumps({"regions": regions, "edits": edits(obj)}, sort_keys=True)


def _last_inputs(obj) -> dict | None:
    try:
        return json.loads(obj.LastGood) if obj.LastGood else None
    except ValueError:
        return None


def _previous(obj, work: str) -> str | None:
    """The stored snapshot of ``obj`` unpacked into ``work`` (a folder the core reads as
    ``previous``), or None when there is none or it cannot be read (then, said in the
    Report view, the layout is made anew)."""
    from core import result

    if not obj.IterationState:
        return None
    folder = os.path.join(work, "previous")
    try:
        shutil.unpack_archive(obj.IterationState, folder, "zip")
        result.snapshot_state(folder)
    except (OSError, ValueError, InputError) as exc:
        log.warning(f"{obj.Label}: the stored previous result cannot be read "
                    f"({str(exc).splitlines()[0] if str(exc) else type(exc).__name__}); laying out anew")
        return None
    return folder


def region_inputs(obj, work: str, scale: float) -> tuple[list[str], list[str]]:
    """High-res boxes ("X0,Y0,Z0,X1,Y1,Z1" in scaled model mm) and region solid files.

    Boxes of Bricks-mode regions are passed as boxes; Solid and Faces
    regions are written into ``work`` as BREP (or STL for a mesh solid).
    """
    boxes, solids = [], []
    for n, region in enumerate(obj.Regions):
        if region.Mode == "Bricks":
            boxes += [",".join(f"{v:.6f}" for v in _scaled_box(b, scale))
                      for b in high_res_region.boxes(region)]
            continue
        if region.Mode == "Solid" and bridge.source_kind(region.RegionSolid) == "mesh":
            folder = os.path.join(work, f"region{n}")
            os.makedirs(folder)
            solids.append(bridge.write_source(region.RegionSolid, folder))
            continue
        shape = high_res_region.region_shape(region)
        if shape.isNull() or not shape.Solids:
            log.warning(f"{region.Label}: the region is empty and marks nothing")
            continue
        path = os.path.join(work, f"region{n}.brep")
        shape.exportBrep(path)
        solids.append(path)
    return boxes, solids


def _scaled_box(box, scale: float) -> list[float]:
    """A Source-coordinate box in the core's (scaled) model mm."""
    return [float(v) * scale for v in box]


@contextmanager
def _preview(obj, title: str):
    """The :class:`~FabrickatorWorkbench.viewproviders.layout_preview.LayoutPreview` of
    Fabrication ``obj``'s run (None without the GUI), removed when the run ends however it
    ends; its view provider keeps it as ``last_preview`` (when the layout was shown)."""
    if not App.GuiUp:
        yield None
        return
    preview = LayoutPreview(obj, title)
    try:
        yield preview
    finally:
        preview.close()
        proxy = getattr(getattr(obj, "ViewObject", None), "Proxy", None)
        if proxy is not None:
            proxy.last_preview = preview


@contextmanager
def _progress(title: str, document):
    """A core progress callback for the GUI (None without it): the status bar shows the
    stage and how far the run is, and Esc cancels it (the callback raises
    :class:`Cancelled`) at the next stage the core starts; after a cancelled run the
    status bar says so, once ``document`` finished recomputing.

    A document recompute runs FreeCAD's own sequencer ("Recompute...", one step
    per object), and FreeCAD ignores a ``Base.ProgressIndicator`` started
    inside it (only the outermost sequencer counts), so Esc is checked with
    ``FreeCAD.checkAbort()``, which asks whichever sequencer runs: it lets the
    GUI handle its events (the Esc key among them) at most every 0.5 s and,
    once Esc was pressed, asks FreeCAD's "Do you really want to abort the
    operation?" and raises ``Base.FreeCADAbort`` on Yes.  Between those
    moments the GUI paints nothing (a run shorter than 0.5 s gets no events at
    all), so the status bar is repainted at once at every stage.  Outside a
    recompute (a macro calling :func:`run_core`) the indicator started here is
    the outermost one and drives the progress bar.
    """
    if not App.GuiUp:
        yield None
        return
    import FreeCADGui as Gui

    status = Gui.getMainWindow().statusBar()
    bar = App.Base.ProgressIndicator()
    bar.start(title, 100)
    done = [0]

    def progress(fraction: float, message: str) -> None:
        target = min(int(fraction * 100), 99)
        status.showMessage(f"{title}: {message.replace('_', ' ')} ({target} %)")
        status.repaint()
        try:
            while done[0] < target:
                bar.next(True)
                done[0] += 1
            # the first call lets the GUI see a pressed Esc (at most every 0.5 s), the
            # second asks the user about it at once
            App.checkAbort()
            App.checkAbort()
        except (RuntimeError, App.Base.FreeCADAbort):
            raise Cancelled("stopped with Esc") from None

    cancelled = False
    try:
        yield progress
    except Cancelled:
        cancelled = True
        raise
    finally:
        bar.stop()
        status.clearMessage()
        if cancelled:
            _say_when_recomputed(document, status,
                                 f"{title}: stopped with Esc, the previous result is kept")


def _say_when_recomputed(document, status, text: str) -> None:
    """Show ``text`` in the status bar for :data:`CANCELLED_MESSAGE_MS` once ``document``
    is no longer recomputing (FreeCAD clears the status bar when its recompute ends)."""
    from PySide import QtCore

    def say():
        try:
            recomputing = bool(document.Recomputing)
        except (AttributeError, ReferenceError, RuntimeError):   # FreeCAD without it, or closed
            recomputing = False
        if recomputing:
            QtCore.QTimer.singleShot(100, say)
        else:
            status.showMessage(text, CANCELLED_MESSAGE_MS)

    QtCore.QTimer.singleShot(0, say)


def _restore_parameters(obj) -> None:
    """Put the parameters back to the last values that recomputed fine."""
    good = (_last_inputs(obj) or {}).get("parameters", {})
    now = parameters(obj)
    for name, value in good.items():
        if name in now and now[name] != value:
            setattr(obj, name, value)
            log.warning(f"{obj.Label}: {name} put back to {value!r}, the last value that worked")


def _store_forces(obj, force: dict | None, build: dict | None = None) -> None:
    """The force check's verdict into Stands, FailingBricks and Forces (words, with what
    the props left in do: ``build``, the report's ``stability.build``); the Report view
    says it when the build does not stand."""
    obj.Stands = bool(force and force["stable"])
    obj.FailingBricks = len(force["failing_bricks"]) if force else 0
    from core import report as reporting

    obj.Forces = reporting.force_line(force, build)
    if force and force.get("checked", True) and not force["stable"]:
        log.warning(f"{obj.Label}: {obj.Forces} (the Report lists them; the Stress display "
                    f"mode shows them white)")


def _store(obj, result: Result, kept: int, changed: int) -> None:
    """Write the result's numbers and JSON into the Fabrication's properties."""
    from core import inventory  # loads scipy
    fab, report = result.fab, result.report
    layout = fab.layout
    obj.LayoutJson = json.dumps(inventory.with_colours(layout.to_json(), fab.colouring))
    obj.ReportJson = json.dumps(report)
    from core import report as reporting

    obj.StepsJson = json.dumps(reporting.steps_record(result.order, layout))
    obj.Plates = int(report["plates"])
    obj.Bricks = int(report["bricks"]["total"])
    obj.LegoBricks = int(report["bricks"]["lego"])
    obj.PrintedParts = len(fab.printed)
    obj.Steps = len(result.order.steps)
    obj.Components = int(report["stability"]["components"])
    obj.WeakPoints = int(report["stability"]["weak_points"])
    obj.SpeedUp = float(report["speedup"] or 0.0)
    _store_forces(obj, report["stability"].get("force"), report["stability"].get("build"))
    obj.BricksKept, obj.BricksChanged = kept, changed
    obj.GridOrigin = bridge.vector(fab.grid.origin)
    obj.CellSize = bridge.vector(fab.grid.cell)
    obj.LastGood = json.dumps(result.inputs)
    if result.snapshot is not None:
        obj.IterationState = result.snapshot
        shutil.rmtree(os.path.dirname(result.snapshot), ignore_errors=True)
    lines = list(report["model"]["warnings"]) + list(report.get("warnings", ()))
    warnings = len(lines)
    obj.Status = (f"ok: {obj.Bricks} bricks ({obj.LegoBricks} LEGO), {obj.PrintedParts} printed "
                  f"part(s), {obj.Steps} steps" + (f"; {warnings} warning(s)" if warnings else ""))
    for line in lines:
        log.warning(f"{obj.Label}: {line}")
