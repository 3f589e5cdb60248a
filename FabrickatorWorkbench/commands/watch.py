"""Watch folder: legofy model files as they appear in a folder (e.g. exported by Blender).

A new file (STL, OBJ, PLY, 3MF, STEP) is imported and legofied; a new
version of a model already legofied in the document (the same file written
again, or a versioned name: ``part_v2.stl`` after ``part.stl``, by the rule
the CLI's ``watch`` follows too, :func:`core.watch.same_model`) replaces
its Source's geometry, so its Fabrication recomputes as the next iteration
(keeping the layout where nothing changed, highlighting what changed).
Imported objects remember their file (``ModelFile``), so this also works
after the document was saved and reopened.  Files are taken once completely written (:mod:`core.watch`).
The watcher polls on a Qt timer and lives as a child of FreeCAD's main
window; running the command again stops it.
"""

from __future__ import annotations

import os
from pathlib import Path

import FreeCAD as App
import FreeCADGui as Gui
from PySide import QtCore, QtGui

from core.errors import InputError
from core.watch import FolderWatcher
from FabrickatorWorkbench import log, make
from FabrickatorWorkbench.commands.base import Command, recompute_or_fail, transaction
from FabrickatorWorkbench.commands.export import ask_folder

#: Object name of the watcher under the main window.
WATCHER_NAME = "FabrickatorWatcher"
#: Milliseconds between two scans of the folder.
POLL_MS = 500


class WatchFolder(Command):
    NAME = "Fabrickator_WatchFolder"
    ICON = "WatchFolder"
    MENU = "&Watch folder"
    TIP = ("Legofy model files as they appear in a folder (e.g. exported from Blender); a file "
           "written again updates its Fabrication.  Run again to stop watching")

    def run(self):
        running = running_watcher()
        if running is not None:
            answer = QtGui.QMessageBox.question(
                Gui.getMainWindow(), "Watch folder", f"Stop watching {running.folder}?",
                QtGui.QMessageBox.Yes | QtGui.QMessageBox.No)
            if answer == QtGui.QMessageBox.Yes:
                running.stop()
            return
        folder = ask_folder("Watch a folder for model files")
        if folder:
            start_watching(folder)


def running_watcher():
    """The running watcher, or None."""
    found = Gui.getMainWindow().findChild(QtCore.QObject, WATCHER_NAME)
    return getattr(found, "fabrickator", None) if found is not None else None


def start_watching(folder: str, doc=None):
    """Start watching ``folder`` for the document ``doc`` (the active one, or a new one)."""
    doc = doc or App.ActiveDocument or App.newDocument("Watched")
    try:
        watcher = FolderWatch(folder, doc)
    except InputError as exc:
        log.failure("Watch folder", exc)
        return None
    log.message(f"watching {folder}: model files that appear or change there are legofied "
                f"into {doc.Label} (run Watch folder again to stop)")
    return watcher


class FolderWatch:
    """Polls a folder (:class:`core.watch.FolderWatcher`) and legofies what appears."""

    def __init__(self, folder: str, doc):
        self.folder = folder
        self.doc_name = doc.Name
        self.watcher = FolderWatcher(Path(folder))
        self.timer = QtCore.QTimer(Gui.getMainWindow())
        self.timer.setObjectName(WATCHER_NAME)
        self.timer.fabrickator = self
        self.timer.setInterval(POLL_MS)
        self.timer.timeout.connect(self.poll)
        self.timer.start()

    def poll(self) -> None:
        """One scan: take every file that became complete."""
        if self.doc_name not in App.listDocuments():
            log.message(f"stopped watching {self.folder}: its document was closed")
            self.stop()
            return
        for path in self.watcher.poll():
            self.take(str(path))

    def take(self, path: str) -> None:
        """Legofy a new model, or feed a new version of a known one (the same file written
        again, or a versioned name like ``part_v2.stl``) to its Fabrication as an
        iteration (:func:`FabrickatorWorkbench.make.feed_file`)."""
        doc = App.getDocument(self.doc_name)
        name = os.path.basename(path)
        with transaction(doc, f"Watch folder: {name}"):
            source, fabs, new = make.feed_file(path, doc)
            recompute_or_fail(*fabs)
            what = "appeared" if new else f"is a new version of {source.Label}"
            log.message(f"{name} {what}: {', '.join(f.Label + ' ' + f.Status for f in fabs)}")
        if App.GuiUp and Gui.ActiveDocument is not None:
            Gui.SendMsgToActiveView("ViewFit")

    def stop(self) -> None:
        self.timer.stop()
        self.timer.setObjectName("")
        self.timer.deleteLater()
        log.message(f"stopped watching {self.folder}")
