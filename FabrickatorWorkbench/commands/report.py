"""Report: brick counts, the bill of materials (with an inventory: owned and to buy), printed
parts, print times, assembly time and speed-up, the force check, in words; its failing bricks, weak points and incomplete studs are listed and a click
selects them in the 3D view."""

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


def summary(fab) -> list[str]:
    """The headline numbers of ``fab``'s last result, one short line each, in words."""
    from core import report as reporting  # loads the stages whose words it uses

    return reporting.headlines(make.report(fab), fab.Steps)


def items(fab) -> list[dict]:
    """What the report points at in the model, each ``{"kind", "title", "text", "bricks",
    "parts"}``: every failing brick of the force check (its brick, or its printed part),
    every weak point (its brick) and every printed part with incomplete studs (the
    part), with the core's explanation."""
    st = make.report(fab)["stability"]
    out = force_items(st.get("force"))
    details = {d["brick"]: d for d in st.get("weak_point_details", ())}
    for brick in st.get("weak_point_bricks", ()):
        d = details.get(brick)
        if d is None:
            out.append({"kind": "weak", "title": f"Weak point: brick {brick}",
                        "text": "recompute the Fabrication to see where it is and what hangs on it",
                        "bricks": [brick], "parts": []})
            continue
        where = (f"printed part {d['printed_part']}" if d["kind"] == "printed" else f"LEGO {d['part']}")
        out.append({"kind": "weak",
                    "title": f"Weak point: {where}, layer {d['layer']}, cell {d['cell'][0]}, {d['cell'][1]}",
                    "text": d["why"], "bricks": [brick],
                    "parts": [d["printed_part"]] if d["kind"] == "printed" else []})
    for entry in st.get("incomplete_stud_parts", ()):
        out.append({"kind": "studs",
                    "title": f"Incomplete studs: printed part {entry['part']}, {entry['count']} "
                             f"in layer(s) {', '.join(map(str, entry['layers']))}",
                    "text": entry["why"], "bricks": [], "parts": [entry["part"]]})
    return out


def force_items(force: dict | None) -> list[dict]:
    """One report item per failure of the force check (report.json ``stability.force``
    ``failures``): where the brick is, how hard it works and the core's ``why``."""
    out = []
    for f in (force or {}).get("failures", ()):
        printed = f.get("printed_part")
        where = f"printed part {printed}" if printed else f"LEGO {f.get('part', '')}".rstrip()
        u = f.get("utilisation")
        how = "unsupported" if u is None else f"utilisation {u:.2f}"
        out.append({"kind": "force",
                    "title": f"Fails: {where}, layer {f['layer']}, cell {f['cell'][0]}, "
                             f"{f['cell'][1]} ({how})",
                    "text": f["why"], "bricks": [int(f["brick"])],
                    "parts": [printed] if printed else []})
    return out


def select(fab, item: dict) -> list:
    """Select in the 3D view (Gui.Selection) exactly the objects ``item`` names: its
    bricks (by BrickId) and printed parts (by PartId); returns them."""
    wanted_bricks, wanted_parts = set(item["bricks"]), set(item["parts"])
    objects = [b for b in make.bricks(fab) if b.BrickId in wanted_bricks and not wanted_parts]
    objects += [p for p in make.printed_parts(fab) if p.PartId in wanted_parts]
    Gui.Selection.clearSelection()
    for obj in objects:
        Gui.Selection.addSelection(obj.Document.Name, obj.Name)
    return objects


def report_html(fab) -> str:
    """The report of ``fab`` as a small HTML page: the numbers, what they mean and the tables."""
    from core import report as reporting  # loads the stages whose words it uses

    doc = make.report(fab)
    esc = html.escape
    st = doc["stability"]
    explain = st.get("explain", {})
    lego = make.bom(fab)
    counted = any(r.owned is not None for r in lego)
    rows = "".join(f"<tr><td>{esc(r.part)}</td><td>{esc(r.name)}</td><td>{esc(r.color)}</td>"
                   f"<td align='right'>{r.count}</td>"
                   + (f"<td align='right'>{r.owned}</td><td align='right'>{r.count - r.owned}</td>"
                      if counted else "") + "</tr>" for r in lego)
    columns = "<th>part</th><th>name</th><th>colour</th><th>count</th>" + (
        "<th>owned</th><th>to buy</th>" if counted else "")
    parts = "".join(
        f"<tr><td><b>{esc(p.PartId)}</b></td><td align='right'>{p.Cells}</td>"
        f"<td align='right'>{p.VolumeMm3 / 1000:.1f}</td>"
        f"<td align='right'>{reporting.duration_words(p.PrintTime)}</td>"
        f"<td align='right'>{p.CompleteStuds}</td><td align='right'>{len(p.IncompleteStuds)}</td>"
        f"<td align='right'>{p.Step}</td></tr>" for p in make.printed_parts(fab))
    lines = "".join(f"<li>{esc(line)}</li>" for line in summary(fab))
    meaning = ""
    if st["weak_points"] and explain.get("weak_point"):
        meaning += f"<p><b>Weak points.</b> {esc(explain['weak_point'])}</p>"
    if st["incomplete_studs"] and explain.get("incomplete_stud"):
        meaning += f"<p><b>Incomplete studs.</b> {esc(explain['incomplete_stud'])}</p>"
    force = st.get("force") or {}
    if force.get("failing_bricks") and force.get("explain"):
        meaning += (f"<p><b>Failing bricks.</b> {esc(force['explain'])} The Stress display mode "
                    f"of the Fabrication draws them white.</p>")
    if meaning:
        meaning += "<p>Click one in the list below to select it in the 3D view.</p>"
    times = doc.get("print_time_s") or {}
    how = times.get("method_words")
    timing = f"<p><b>Print times.</b> {esc(how)}</p>" if how else ""
    return (f"<h2>{esc(fab.Label)}</h2><ul>{lines}</ul>{meaning}{timing}"
            f"<h3>LEGO bricks by design and colour</h3><table border='1' cellpadding='3'>"
            f"<tr>{columns}</tr>{rows}</table>"
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
    """The report in a dialog: the numbers and what they mean, a list of the weak points
    and incomplete studs (a click selects them in the 3D view), and a button that slices
    the print times."""

    def __init__(self, fab):
        self.fab = fab
        self.dialog = QtGui.QDialog(Gui.getMainWindow())
        self.dialog.setObjectName("FabrickatorReportDialog")
        self.dialog.setWindowTitle(f"Fabrickator report: {fab.Label}")
        self.dialog.resize(680, 640)
        layout = QtGui.QVBoxLayout(self.dialog)
        self.text = QtGui.QTextBrowser()
        self.text.setObjectName("FabrickatorReportText")
        layout.addWidget(self.text, 3)
        self.list = QtGui.QTreeWidget()
        self.list.setObjectName("FabrickatorReportItems")
        self.list.setHeaderLabels(["In the model", "Why it matters"])
        self.list.setRootIsDecorated(False)
        self.list.setWordWrap(True)
        self.list.itemClicked.connect(lambda item, _column: self.on_select())
        layout.addWidget(self.list, 2)
        self.detail = QtGui.QLabel()
        self.detail.setObjectName("FabrickatorReportDetail")
        self.detail.setWordWrap(True)
        layout.addWidget(self.detail)
        buttons = QtGui.QDialogButtonBox(QtGui.QDialogButtonBox.Close)
        self.select_button = buttons.addButton("Select in 3D view", QtGui.QDialogButtonBox.ActionRole)
        self.select_button.setObjectName("FabrickatorReportSelect")
        self.select_button.setToolTip("Select the brick or printed part of the chosen line in the 3D view")
        self.select_button.clicked.connect(self.on_select)
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
        self.list.clear()
        self.items = items(self.fab)
        for item in self.items:
            row = QtGui.QTreeWidgetItem([item["title"], item["text"]])
            row.setToolTip(0, item["text"])
            row.setToolTip(1, item["text"])
            self.list.addTopLevelItem(row)
        self.list.setVisible(bool(self.items))
        self.select_button.setEnabled(bool(self.items))
        self.list.resizeColumnToContents(0)

    def on_select(self) -> list:
        """Select the chosen line's bricks or printed part in the 3D view."""
        row = self.list.currentItem()
        if row is None:
            return []
        item = self.items[self.list.indexOfTopLevelItem(row)]
        self.detail.setText(f"<b>{html.escape(item['title'])}</b>: {html.escape(item['text'])}")
        return select(self.fab, item)

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
