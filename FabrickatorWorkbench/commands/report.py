"""Report: brick counts, printed parts, print times, assembly time and speed-up."""

from __future__ import annotations

import html

import FreeCADGui as Gui
from PySide import QtCore, QtGui

from FabrickatorWorkbench import log, make
from FabrickatorWorkbench.commands.base import (Command, recompute_or_fail, selected_fabrication,
                                                transaction)


class Report(Command):
    NAME = "Fabrickator_Report"
    ICON = "Report"
    MENU = "&Report"
    TIP = ("Show the selected Fabrication's numbers: bricks by part, printed parts, print times "
           "(whole part vs printed parts), assembly estimate and speed-up")

    def IsActive(self):
        return selected_fabrication() is not None

    def run(self):
        fab = selected_fabrication()
        for line in summary(fab):
            log.message(f"{fab.Label}: {line}")
        ReportDialog(fab).exec_()


def _time(seconds) -> str:
    if seconds is None:
        return "-"
    minutes = int(round(float(seconds) / 60.0))
    return f"{minutes // 60} h {minutes % 60:02d} min" if minutes >= 60 else f"{minutes} min"


def summary(fab) -> list[str]:
    """The headline numbers of ``fab``'s last result, one short line each."""
    doc = make.report(fab)
    bricks, st = doc["bricks"], doc["stability"]
    lines = [f"{bricks['total']} bricks ({bricks['lego']} LEGO, {bricks['printed']} printed) "
             f"from {doc['plates']} plates; {fab.Steps} assembly steps",
             f"{st['components']} component(s), {st['weak_points']} weak point(s), "
             f"{st['incomplete_studs']} incomplete stud(s)"]
    times = doc.get("print_time_s")
    if times:
        lines.append(f"print time: whole part {_time(times['full_model'])}, printed parts "
                     f"{_time(times['printed_parts'])} + assembly {_time(doc['assembly_s'])} "
                     f"({times['method']})")
    if doc.get("speedup"):
        gains = doc["speedups"]
        printing = f"{gains['printing']:.2f}x" if gains.get("printing") else "nothing to print"
        lines.append(f"speed-up {doc['speedup']:.2f}x over printing the whole part, building the "
                     f"LEGO while the parts print (printing alone {printing}; building after "
                     f"printing {gains['sequential']:.2f}x)")
    return lines


def report_html(fab) -> str:
    """The report of ``fab`` as a small HTML page."""
    doc = make.report(fab)
    esc = html.escape
    rows = "".join(f"<tr><td>{esc(part)}</td><td align='right'>{n}</td></tr>"
                   for part, n in doc["bricks"]["by_part"].items())
    parts = "".join(
        f"<tr><td><b>{esc(p.PartId)}</b></td><td align='right'>{p.Cells}</td>"
        f"<td align='right'>{p.VolumeMm3 / 1000:.1f}</td><td align='right'>{_time(p.PrintTime)}</td>"
        f"<td align='right'>{p.CompleteStuds}</td><td align='right'>{len(p.IncompleteStuds)}</td>"
        f"<td align='right'>{p.Step}</td></tr>" for p in make.printed_parts(fab))
    lines = "".join(f"<li>{esc(line)}</li>" for line in summary(fab))
    return (f"<h2>{esc(fab.Label)}</h2><ul>{lines}</ul>"
            f"<h3>Bricks by LEGO design number</h3><table border='1' cellpadding='3'>"
            f"<tr><th>part</th><th>count</th></tr>{rows}</table>"
            f"<h3>Printed parts</h3><table border='1' cellpadding='3'><tr><th>ID</th><th>cells</th>"
            f"<th>cm&sup3;</th><th>print time</th><th>complete studs</th><th>incomplete studs</th>"
            f"<th>step</th></tr>{parts}</table>")


def slice_print_times(fab) -> bool:
    """Recompute ``fab`` with slicer print times (one transaction); True on success."""
    done = False
    with transaction(fab.Document, "Slice print times"):
        fab.SlicePrintTimes = True
        recompute_or_fail(fab)
        done = True
    return done


class ReportDialog:
    """The report in a dialog, with a button that slices the print times."""

    def __init__(self, fab):
        self.fab = fab
        self.dialog = QtGui.QDialog(Gui.getMainWindow())
        self.dialog.setObjectName("FabrickatorReportDialog")
        self.dialog.setWindowTitle(f"Fabrickator report: {fab.Label}")
        self.dialog.resize(640, 560)
        layout = QtGui.QVBoxLayout(self.dialog)
        self.text = QtGui.QTextBrowser()
        self.text.setObjectName("FabrickatorReportText")
        layout.addWidget(self.text)
        buttons = QtGui.QDialogButtonBox(QtGui.QDialogButtonBox.Close)
        self.slice = buttons.addButton("Slice print times", QtGui.QDialogButtonBox.ActionRole)
        self.slice.setToolTip("Slice the whole part and the printed parts with PrusaSlicer "
                              "(instead of the estimate) and recompute")
        self.slice.setEnabled(not fab.SlicePrintTimes)
        self.slice.clicked.connect(self.on_slice)
        buttons.rejected.connect(self.dialog.reject)
        layout.addWidget(buttons)
        self.refresh()

    def refresh(self) -> None:
        self.text.setHtml(report_html(self.fab))

    def on_slice(self) -> None:
        QtGui.QApplication.setOverrideCursor(QtCore.Qt.WaitCursor)
        try:
            slice_print_times(self.fab)
        finally:
            QtGui.QApplication.restoreOverrideCursor()
        self.slice.setEnabled(not self.fab.SlicePrintTimes)
        self.refresh()

    def exec_(self) -> int:
        return self.dialog.exec_()
