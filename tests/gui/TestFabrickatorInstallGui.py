"""The Addon Manager's install in the FreeCAD GUI: a clone of this repository in a clean
FreeCAD user folder, first started with no virtual environment.

Each case runs its own ``freecad`` (on this test's virtual screen) with a throw-away user
folder (:class:`TestFabrickatorInstall.UserFolder`, shared with the headless tests), and a
script in it answers the dialogs by their object names as a user would:

* installing: activating the workbench offers the install, *Install* shows the progress
  dialog fed by pip, the packages are then in use in that same FreeCAD, the toolbar gets
  the commands and the example fabricates;
* after a restart on the same user folder, with FreeCAD 1.0's start workbench PartDesign (which
  loads numpy at start-up), the packages are in use from the start and the example fabricates;
* declining: *Not now* leaves only *Install Python packages...* and FreeCAD working, the
  offer comes back at the next activation; without a package index the install ends in
  one message with the command to run by hand; *Cancel* in the progress dialog stops it
  and the offer comes back; *Do not ask again* stops the offer.

The installing and the declining FreeCAD run at once (the install is mostly waiting for pip);
both start in the Part workbench, which loads no numpy.  A FreeCAD that already loaded its own
numpy (1.0's default start workbench PartDesign does) cannot use the packages before a restart:
that message is tested in tests/core/test_deps.py.  Screenshots of the
dialogs go to tests/gui/artifacts/install_*.png.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
import unittest
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
ARTIFACTS = ROOT / "tests" / "gui" / "artifacts"
sys.path.insert(0, str(ROOT / "tests" / "app"))
from TestFabrickatorInstall import INSTALL_TIMEOUT_S, UserFolder  # noqa: E402

#: Run inside the child FreeCAD as a macro, after PLAN, REPORT and ARTIFACTS are set.
CHILD = r'''
import json, os, sys, time, traceback
import FreeCAD as App, FreeCADGui as Gui
from PySide import QtCore, QtGui

out = {"numpy_at_start": "numpy" in sys.modules, "start_workbench": Gui.activeWorkbench().name(), "dialogs": []}


def settle(seconds):
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        QtGui.QApplication.processEvents()
        time.sleep(0.02)


def shot(widget, name):
    os.makedirs(ARTIFACTS, exist_ok=True)
    widget.grab().save(os.path.join(ARTIFACTS, name + ".png"))


def answer(name, button, shot_as=None, tick=False):
    """When the modal dialog ``name`` opens: record it, click ``button``; any other is rejected."""
    timer = QtCore.QTimer(Gui.getMainWindow())

    def poll():
        widget = QtGui.QApplication.activeModalWidget()
        if widget is None:
            return
        timer.stop()
        out["dialogs"].append([widget.objectName(), widget.text() if hasattr(widget, "text") else "",
                               widget.informativeText() if hasattr(widget, "informativeText") else ""])
        if widget.objectName() != name:
            widget.reject()
            return
        if tick:
            widget.checkBox().setChecked(True)
        settle(0.3)
        if shot_as:
            shot(widget, shot_as)
        [b for b in widget.buttons() if b.text().replace("&", "") == button][0].click()

    timer.timeout.connect(poll)
    timer.start(100)
    return timer


def dialogs_within(seconds):
    """The modal dialogs that open within ``seconds`` (each rejected)."""
    seen, end = [], time.monotonic() + seconds
    while time.monotonic() < end:
        widget = QtGui.QApplication.activeModalWidget()
        if widget is not None:
            seen.append(widget.objectName())
            widget.reject()
        settle(0.1)
    return seen


def toolbar():
    return Gui.getWorkbench("FabrickatorWorkbench").getToolbarItems().get("Fabrickator", [])


def switch_away():
    Gui.activateWorkbench("PartWorkbench")
    settle(0.5)


def install_plan():
    from FabrickatorWorkbench import install
    answer("FabrickatorInstallOffer", "Install", "install_offer")
    Gui.activateWorkbench("FabrickatorWorkbench")
    settle(0.5)
    installer = install.running_installer()
    out["installer"] = installer is not None
    out["progress_modal"] = installer.dialog.isModal()
    out["labels"], out["values"], shot_taken = [], [], False
    answer("FabrickatorInstallDone", "OK", "install_done")
    deadline = time.monotonic() + INSTALL_TIMEOUT_S
    while installer.result is None and time.monotonic() < deadline:
        settle(0.2)
        if installer.running:
            label, value = installer.dialog.labelText(), installer.dialog.value()
            if not out["labels"] or out["labels"][-1] != label:
                out["labels"].append(label)
                out["values"].append(value if installer.dialog.maximum() else None)
            if not shot_taken and installer.dialog.maximum() and value > 20:
                shot(installer.dialog, "install_progress")
                shot_taken = True
    settle(1.0)
    out["result"] = installer.result and [installer.result.ok, installer.result.message]
    out["toolbar"] = toolbar()
    import numpy
    out["numpy"] = numpy.__file__
    from FabrickatorWorkbench import deps
    out["needs_after"] = deps.needs_install()
    out["command_active"] = install.InstallPackages().IsActive()
    sys.path.insert(0, os.path.join(deps.ROOT, "examples"))
    import hmd
    hmd.build_hmd().val().exportStep(REPORT + ".step")
    from FabrickatorWorkbench import example
    f = example.open_example(REPORT + ".step")
    out["status"] = f.Status
    settle(1.0)
    Gui.ActiveDocument.ActiveView.saveImage(os.path.join(ARTIFACTS, "install_example.png"), 800, 600, "White")
    shot(Gui.getMainWindow(), "install_window")


def decline_plan():
    from FabrickatorWorkbench import install
    answer("FabrickatorInstallOffer", "Not now", "install_offer_declined")
    Gui.activateWorkbench("FabrickatorWorkbench")
    settle(0.5)
    out["toolbar_declined"] = toolbar()
    out["numpy_after_decline"] = "numpy" in sys.modules
    out["command_active"] = install.InstallPackages().IsActive()
    switch_away()
    doc = App.newDocument("StillFine")
    box = doc.addObject("Part::Box", "Box")
    doc.recompute()
    out["part_box_volume"] = box.Shape.Volume
    answer("FabrickatorInstallOffer", "Install")
    Gui.activateWorkbench("FabrickatorWorkbench")
    settle(0.5)
    installer = install.running_installer()
    answer("FabrickatorInstallFailed", "OK", "install_failed")
    deadline = time.monotonic() + 300
    while installer is not None and installer.result is None and time.monotonic() < deadline:
        settle(0.2)
    settle(1.0)
    out["failed"] = installer.result and [installer.result.ok, installer.result.message]
    switch_away()
    answer("FabrickatorInstallOffer", "Install")
    Gui.activateWorkbench("FabrickatorWorkbench")
    installer = install.running_installer()
    [b for b in installer.dialog.findChildren(QtGui.QPushButton) if b.text().replace("&", "") == "Cancel"][0].click()
    deadline = time.monotonic() + 60
    while installer.result is None and time.monotonic() < deadline:
        settle(0.1)
    out["cancelled"] = installer.result and [installer.result.ok, installer.result.message]
    out["progress_visible_after_cancel"] = installer.dialog.isVisible()
    switch_away()
    answer("FabrickatorInstallOffer", "Not now", tick=True)
    Gui.activateWorkbench("FabrickatorWorkbench")
    settle(0.5)
    out["asking"] = install.asking()
    switch_away()
    Gui.activateWorkbench("FabrickatorWorkbench")
    out["dialogs_after_never"] = dialogs_within(2.0)
    out["toolbar_end"] = toolbar()


def restarted_plan():
    out["numpy_file_at_start"] = sys.modules["numpy"].__file__ if "numpy" in sys.modules else None
    Gui.activateWorkbench("FabrickatorWorkbench")
    out["dialogs_on_activation"] = dialogs_within(1.0)
    out["toolbar"] = toolbar()
    from FabrickatorWorkbench import deps, example
    out["needs_after"] = deps.needs_install()
    sys.path.insert(0, os.path.join(deps.ROOT, "examples"))
    import hmd
    hmd.build_hmd().val().exportStep(REPORT + ".step")
    f = example.open_example(REPORT + ".step")
    out["status"], out["bricks"] = f.Status, f.Bricks


def run():
    try:
        {"install": install_plan, "decline": decline_plan, "restarted": restarted_plan}[PLAN]()
    except Exception:
        out["error"] = traceback.format_exc()
    with open(REPORT, "w") as report:
        json.dump(out, report, indent=1)
    os._exit(0)


QtCore.QTimer.singleShot(1500, run)
'''


class GuiUser(UserFolder):
    """A throw-away user folder whose FreeCAD GUI runs a :data:`CHILD` plan."""

    def start(self, plan: str, start_workbench: str, **env) -> tuple[subprocess.Popen, Path]:
        """Start FreeCAD on ``plan`` with a fresh user.cfg whose start workbench is ``start_workbench``."""
        self.write_config(start_workbench)
        report = self.home / f"{plan}.json"
        script = self.home / f"{plan}.py"
        script.write_text(f"PLAN = {plan!r}\nREPORT = {str(report)!r}\nARTIFACTS = {str(ARTIFACTS)!r}\n"
                          f"INSTALL_TIMEOUT_S = {INSTALL_TIMEOUT_S}\n" + CHILD)
        freecad = shutil.which("freecad") or shutil.which("FreeCAD")
        process = subprocess.Popen([freecad, "-u", str(self.cfg), str(script)], stdout=subprocess.PIPE,
                                   stderr=subprocess.STDOUT, text=True, stdin=subprocess.DEVNULL,
                                   env={**self.env, "QTWEBENGINE_DISABLE_SANDBOX": "1", **env}, cwd=self.home)
        return process, report


class TestInstallInTheGui(unittest.TestCase):
    """First activation of an Addon Manager clone in the FreeCAD GUI."""

    @classmethod
    def setUpClass(cls):
        cls.started = time.monotonic()
        cls.base = Path(tempfile.mkdtemp(prefix="fabrickator-gui-install-"))
        installing, declining = GuiUser(cls.base, "install"), GuiUser(cls.base, "decline")
        cls.clones = {"install": installing.mod, "decline": declining.mod}
        # Part as the start workbench: it loads no numpy, so the install can be in use at once
        started = {"install": installing.start("install", "PartWorkbench"),
                   "decline": declining.start("decline", "PartWorkbench", PIP_NO_INDEX="1",
                                              PIP_FIND_LINKS=str(cls.base / "no-such-folder"))}
        cls.reports, cls.outputs = {}, {}
        cls.finish(started, "install")
        # FreeCAD again on the same user folder, with FreeCAD 1.0's start workbench PartDesign,
        # which loads numpy at start-up (its shaft wizard)
        started["restarted"] = installing.start("restarted", "PartDesignWorkbench")
        cls.finish(started, "decline")
        cls.finish(started, "restarted")

    @classmethod
    def finish(cls, started: dict, plan: str) -> None:
        """Wait for the FreeCAD running ``plan`` and read its report."""
        process, report = started[plan]
        try:
            cls.outputs[plan], _ = process.communicate(timeout=INSTALL_TIMEOUT_S + 300)
        except subprocess.TimeoutExpired:
            process.kill()
            cls.outputs[plan], _ = process.communicate()
        cls.reports[plan] = json.loads(report.read_text()) if report.exists() else None
        sys.__stderr__.write(f"(the {plan} FreeCAD ended {time.monotonic() - cls.started:.0f} s into the install "
                             f"tests, exit {process.returncode})\n")
        sys.__stderr__.flush()

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.base, ignore_errors=True)

    def report(self, plan: str) -> dict:
        report = self.reports[plan]
        self.assertIsNotNone(report, f"the {plan} FreeCAD did not report: {self.outputs[plan][-3000:]}")
        self.assertNotIn("error", report, report.get("error"))
        return report

    def test_install_from_the_offer_then_the_workbench_works_without_a_restart(self):
        report = self.report("install")
        self.assertEqual(report["start_workbench"], "PartWorkbench")
        self.assertFalse(report["numpy_at_start"])
        self.assertIn(f"They go into a folder of their own, {self.clones['install'] / '.venv'}", report["dialogs"][0][2])
        self.assertNotIn("restart FreeCAD", report["dialogs"][0][2])
        self.assertEqual(report["dialogs"][0][0], "FabrickatorInstallOffer")
        self.assertIn("Install them now?", report["dialogs"][0][1])
        self.assertTrue(report["installer"])
        # the install's own result first: when it failed, its message and pip's last lines say why
        self.assertEqual(report["result"], [True, "Fabrickator's Python packages are installed and in use: "
                                                  "the workbench is ready."], report["labels"][-8:])
        self.assertFalse(report["progress_modal"], "the progress dialog must leave FreeCAD usable")
        # pip's lines as they came (sampled): the bar grows with them, then is busy while pip unpacks
        values = [v for v in report["values"] if v is not None]
        self.assertEqual(values, sorted(values))
        self.assertGreater(len(set(values)), 5, report["values"])
        self.assertGreaterEqual(max(values), 55)
        self.assertTrue(any(label.startswith(("Collecting ", "Downloading ", "Processing "))
                            for label in report["labels"]), report["labels"][:10])
        installing = [v for label, v in zip(report["labels"], report["values"]) if label.startswith("Installing ")]
        self.assertTrue(installing and installing[0] is None, report["labels"][-5:])
        self.assertEqual([d[0] for d in report["dialogs"]], ["FabrickatorInstallOffer", "FabrickatorInstallDone"])
        self.assertIn("Fabrickator_Legofy", report["toolbar"])
        self.assertTrue(report["numpy"].startswith(str(self.clones["install"] / ".venv")), report["numpy"])
        self.assertIsNone(report["needs_after"])
        self.assertFalse(report["command_active"])
        self.assertTrue(report["status"].startswith("ok"), report["status"])
        for name in ("install_offer", "install_progress", "install_done", "install_example"):
            self.assertTrue((ARTIFACTS / f"{name}.png").is_file(), name)

    def test_a_restart_puts_the_packages_first_before_the_start_workbench_loads_numpy(self):
        self.report("install")
        report = self.report("restarted")
        self.assertEqual(report["start_workbench"], "PartDesignWorkbench")
        # PartDesign loaded numpy before this FreeCAD ran the test: the venv's, as Init.py put it first
        self.assertTrue(report["numpy_at_start"])
        self.assertTrue(report["numpy_file_at_start"].startswith(str(self.clones["install"] / ".venv")),
                        report["numpy_file_at_start"])
        self.assertEqual(report["dialogs_on_activation"], [])
        self.assertIn("Fabrickator_Legofy", report["toolbar"])
        self.assertIsNone(report["needs_after"])
        self.assertTrue(report["status"].startswith("ok"), report["status"])
        self.assertGreater(report["bricks"], 100)

    def test_declining_keeps_freecad_working_and_the_offer_comes_back(self):
        report = self.report("decline")
        self.assertFalse(report["numpy_at_start"])
        self.assertEqual(report["toolbar_declined"], ["Fabrickator_InstallPackages"])
        self.assertFalse(report["numpy_after_decline"])
        self.assertTrue(report["command_active"])
        self.assertAlmostEqual(report["part_box_volume"], 1000.0)
        names = [d[0] for d in report["dialogs"]]
        self.assertEqual(names, ["FabrickatorInstallOffer", "FabrickatorInstallOffer", "FabrickatorInstallFailed",
                                 "FabrickatorInstallOffer", "FabrickatorInstallOffer"])
        self.assertFalse(report["asking"])
        self.assertEqual(report["dialogs_after_never"], [])
        self.assertEqual(report["toolbar_end"], ["Fabrickator_InstallPackages"])

    def test_cancel_stops_the_install_and_the_offer_comes_back(self):
        report = self.report("decline")
        self.assertEqual(report["cancelled"], [False, "Fabrickator: the install of its Python packages was "
                                                      "cancelled; the workbench offers it again when you "
                                                      "activate it"])
        self.assertFalse(report["progress_visible_after_cancel"])
        # no message box for a cancel; the next activation asked again (then Do not ask again)
        self.assertEqual([d[0] for d in report["dialogs"]][3:], ["FabrickatorInstallOffer"] * 2)

    def test_no_package_index_ends_in_one_message_with_the_command(self):
        report = self.report("decline")
        ok, message = report["failed"]
        self.assertFalse(ok)
        self.assertIn("could not download its Python packages: no network", message)
        clone = self.clones["decline"]
        venv = clone / ".venv"
        self.assertIn("run in a terminal: ", message)
        self.assertTrue(message.endswith(f" -m venv --clear {venv} && {venv}/bin/python -m pip install "
                                         f"--disable-pip-version-check --progress-bar off -r "
                                         f"{clone}/requirements.txt"), message)
        shown = [d[1] for d in report["dialogs"] if d[0] == "FabrickatorInstallFailed"][0]
        self.assertIn(f"-m venv --clear {venv}", shown)
        self.assertTrue((ARTIFACTS / "install_failed.png").is_file())
