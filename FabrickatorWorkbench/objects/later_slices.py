"""Print times that fill in after the recompute, in the GUI.

With SlicePrintTimes on and the GUI up, a recompute does not wait for PrusaSlicer: the core
runs with the calibrated estimate, the tree shows the result at once (its Status says the
times are estimates and are being sliced), and :func:`start` sets
:func:`core.pipeline.sliced_later` going in a background thread.  A timer of the GUI's event
loop takes the answer when it comes and writes the sliced times into the Fabrication: its
report, speed-up and iteration snapshot, and each printed part's PrintTime and
PrintTimeMethod.  Nothing of this makes the objects touched or adds an undo step.  An answer
for a Fabrication that was recomputed again, or removed, meanwhile is dropped; a slice that
fails leaves the estimates, and the Report view says why.
"""

from __future__ import annotations

import json
import os
import shutil

import FreeCAD as App

from FabrickatorWorkbench import bridge, log
from FabrickatorWorkbench.objects import tree

#: Milliseconds between two looks at a slice running in the background.
POLL_MS = 250

#: What the Status of a Fabrication ends with while its times are being sliced.
SLICING = "; print times estimated, slicing in the background"


class LaterSlice:
    """The background slice of one recompute of Fabrication ``fab`` (the core's result
    ``result``, :class:`~FabrickatorWorkbench.objects.fabricate.Result`) with ``slicer``.
    ``done`` is set once its answer was written (or dropped)."""

    def __init__(self, fab, result, slicer: str | None):
        from core import pipeline

        self.fab, self.result, self.done = fab, result, False
        self.name, self.document = fab.Name, fab.Document.Name
        self.future = pipeline.sliced_later(result.fab, slicer)
        self.outcome = ""

    def current(self) -> bool:
        """Whether the Fabrication still exists and this is its latest slice."""
        doc = App.listDocuments().get(self.document)
        obj = doc.getObject(self.name) if doc is not None else None
        proxy = getattr(getattr(obj, "ViewObject", None), "Proxy", None)
        return obj is self.fab and getattr(proxy, "later_slice", None) is self

    def poll(self) -> None:
        """Write the answer when it is there, else look again in :data:`POLL_MS`."""
        from PySide import QtCore

        if self.done:
            return
        if not self.current():
            self.done, self.outcome = True, "dropped"
            return
        if not self.future.done():
            QtCore.QTimer.singleShot(POLL_MS, self.poll)
            return
        self.done = True
        try:
            sliced = self.future.result()
        except Exception as exc:  # noqa: BLE001 - the estimates stay, and the user is told why
            self.outcome = "failed"
            self.fab.Status = self.fab.Status.replace(SLICING, "; print times estimated (slicing failed)")
            self.fab.purgeTouched()
            log.warning(f"{self.fab.Label}: the print times could not be sliced "
                        f"({str(exc).splitlines()[0] if str(exc) else type(exc).__name__}); "
                        f"the estimates stay")
            return
        self.outcome = "sliced"
        write(self.fab, self.result, sliced)


def start(fab, result, slicer: str | None) -> LaterSlice:
    """Slice ``result``'s print times in the background for Fabrication ``fab``; its view
    provider keeps the slice as ``later_slice`` (a later recompute replaces it)."""
    from PySide import QtCore

    job = LaterSlice(fab, result, slicer)
    fab.ViewObject.Proxy.later_slice = job
    fab.Status = fab.Status + SLICING
    fab.purgeTouched()
    QtCore.QTimer.singleShot(POLL_MS, job.poll)
    return job


def write(fab, result, sliced) -> None:
    """The sliced times of ``sliced`` (the core's Fabrication) into ``fab`` and its printed parts."""
    from core import report as reporting

    report = reporting.document(sliced)
    report["model"]["path"] = result.report["model"]["path"]
    fab.ReportJson = json.dumps(report)
    fab.SpeedUp = float(report["speedup"] or 0.0)
    seconds = {p.id: float(p.print_s or 0.0) for p in sliced.printed}
    method = sliced.print_parts.method if sliced.print_parts is not None else ""
    again = {p.id for p in sliced.to_print}
    for part in tree.printed_parts(fab):
        if part.PartId in again:
            part.PrintTime = seconds[part.PartId]
            part.PrintTimeMethod = method
            part.purgeTouched()
    snapshot = bridge.snapshot(sliced)
    fab.IterationState = snapshot
    shutil.rmtree(os.path.dirname(snapshot), ignore_errors=True)
    fab.Status = fab.Status.replace(SLICING, "")
    fab.purgeTouched()
    log.message(f"{fab.Label}: print times sliced: parts {reporting.duration_words(sliced.print_parts.seconds)}"
                f", speed-up {fab.SpeedUp:.1f}x")
