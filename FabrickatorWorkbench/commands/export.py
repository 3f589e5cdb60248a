"""Export: the printed parts (STL, STEP, a 3MF plate) and the instructions into a folder."""

from __future__ import annotations

from PySide import QtCore, QtGui

from core.errors import InputError
from FabrickatorWorkbench import log, make
from FabrickatorWorkbench.commands.base import Command, file_dialog, selected_fabrication


class Export(Command):
    NAME = "Fabrickator_Export"
    ICON = "Export"
    MENU = "&Export printed parts"
    TIP = ("Write the printed parts (STL and STEP each, one 3MF plate), the layout, the report "
           "and the assembly instructions of the selected Fabrication into a folder")

    def IsActive(self):
        return selected_fabrication() is not None

    def run(self):
        fab = selected_fabrication()
        folder = ask_folder(f"Export {fab.Label} to a folder")
        if folder:
            export_to(fab, folder)


def export_to(fab, folder: str) -> list[str]:
    """Export ``fab`` into ``folder`` with a wait cursor; the file names ([] on failure)."""
    QtGui.QApplication.setOverrideCursor(QtCore.Qt.WaitCursor)
    try:
        return make.export(fab, folder)
    except (InputError, ValueError) as exc:
        log.failure(f"{fab.Label}: export", exc)
        return []
    except Exception as exc:  # noqa: BLE001 - a bug: its traceback goes to the Report view
        log.bug(f"{fab.Label}: export", exc)
        return []
    finally:
        QtGui.QApplication.restoreOverrideCursor()


def ask_folder(title: str) -> str:
    """A folder chosen in a dialog ('' when cancelled)."""
    dialog = file_dialog(title, "FabrickatorChooseFolder")
    dialog.setFileMode(QtGui.QFileDialog.Directory)
    dialog.setOption(QtGui.QFileDialog.ShowDirsOnly, True)
    chosen = dialog.selectedFiles() if dialog.exec_() else []
    return chosen[0] if chosen else ""
