"""What the commands share: resources, the selected Fabrication, transactions, dialogs."""

from __future__ import annotations

from contextlib import contextmanager

import FreeCAD as App
import FreeCADGui as Gui
from PySide import QtGui

from FabrickatorWorkbench import deps, log
from FabrickatorWorkbench.make import fabrication_of
from FabrickatorWorkbench.objects.fabrication import is_fabrication
from FabrickatorWorkbench.viewproviders import icon

translate = App.Qt.translate


class Command:
    """Base of the toolbar commands: subclasses set NAME, ICON, MENU, TIP and ``run``."""

    NAME = ""
    ICON = "Fabrickator"
    MENU = ""
    TIP = ""

    def GetResources(self):
        # NoTransaction: each command opens its own, single undo transaction
        return {"Pixmap": icon(self.ICON), "MenuText": translate("Fabrickator", self.MENU),
                "ToolTip": translate("Fabrickator", self.TIP), "CmdType": "NoTransaction"}

    def IsActive(self):
        return True

    def Activated(self):
        if deps.check(self.MENU.replace("&", "")):
            self.run()

    def run(self):
        raise NotImplementedError


def fabrications(doc=None) -> list:
    """The Fabrications of ``doc`` (the active document by default), cheaply."""
    doc = doc or App.ActiveDocument
    if doc is None:
        return []
    return [o for o in doc.findObjects("App::FeaturePython") if is_fabrication(o)]


def selected_fabrication(computed: bool = True):
    """The Fabrication the selection belongs to, else the document's only one, else None.

    With ``computed``, only a Fabrication that has a result counts.
    """
    found = None
    for obj in Gui.Selection.getSelection():
        found = fabrication_of(obj)
        if found is not None:
            break
    if found is None:
        every = fabrications()
        found = every[0] if len(every) == 1 else None
    if found is not None and computed and not found.LayoutJson:
        return None
    return found


class Reported(Exception):
    """A failure already written to the Report view."""


def no_task_dialog() -> bool:
    """True when no task panel is open (the brush and assembly panels are exclusive)."""
    return not Gui.Control.activeDialog()


@contextmanager
def transaction(doc, name: str):
    """One undo transaction: committed when the block ends, aborted (the document back
    as it was, the reason in the Report view) when it raises."""
    doc.openTransaction(name)
    try:
        yield
    except Reported:
        doc.abortTransaction()
        return
    except Exception as exc:
        doc.abortTransaction()
        log.failure(name, exc)
        return
    doc.commitTransaction()


def recompute_or_fail(*fabs) -> None:
    """Recompute the document; raise :class:`Reported` when one of ``fabs`` failed
    (the recompute has said why in the Report view)."""
    for fab in fabs:
        fab.touch()
    fabs[0].Document.recompute()
    if any(not fab.Status.startswith("ok") for fab in fabs):
        raise Reported()


def main_window():
    """FreeCAD's main window."""
    return Gui.getMainWindow()


def file_dialog(title: str, object_name: str):
    """A QFileDialog that follows FreeCAD's "use the native dialog" preference."""
    dialog = QtGui.QFileDialog(Gui.getMainWindow(), title)
    dialog.setObjectName(object_name)
    native = not App.ParamGet("User parameter:BaseApp/Preferences/Dialog").GetBool(
        "DontUseNativeDialog", True)
    dialog.setOption(QtGui.QFileDialog.DontUseNativeDialog, not native)
    return dialog
