"""First run in the FreeCAD GUI: offer to install Fabrickator's Python packages, and install them.

An Addon Manager install is a clone of the repository in FreeCAD's user
``Mod`` folder, without the virtual environment the core needs
(:mod:`.deps`).  Until it exists the workbench shows only the command
*Install Python packages...* (:data:`COMMAND`), and each activation of the
workbench asks once (:func:`offer`): *Install* builds the venv with
FreeCAD's own interpreter and pip (:class:`Installer`: ``deps.install_commands``
run in a QProcess, pip's lines feeding a progress dialog that can be
cancelled, FreeCAD usable meanwhile); *Not now* leaves FreeCAD as it was and
the question comes back at the next activation, unless the user ticked
*Do not ask again* (the preference ASK under PARAMETERS; the menu command
stays).  A failed install (no network, no ``python3-venv``) ends in one
message that says what to do and gives the exact command to run by hand.
Once installed, the packages are put to use in the running FreeCAD
(:func:`.deps.activate`) and the workbench gets its commands; when that is
impossible (FreeCAD already loaded its own numpy: FreeCAD 1.0's start
workbench PartDesign does) the message says to restart FreeCAD, the offer
does not come back, and at the next start ``Init.py`` puts the packages
first before any workbench loads numpy.

This module imports nothing from :mod:`core` or the commands (they need
the packages it installs).
"""

from __future__ import annotations

import html
import os

import FreeCAD as App
import FreeCADGui as Gui
from PySide import QtCore, QtGui

from FabrickatorWorkbench import deps

#: Parameter group of Fabrickator's preferences.
PARAMETERS = "User parameter:BaseApp/Preferences/Mod/Fabrickator"

#: Boolean preference: ask on activation when the packages are missing (default True).
ASK = "AskToInstallPackages"

#: Name of the menu and toolbar command that installs the packages.
COMMAND = "Fabrickator_InstallPackages"

#: Object names of the dialogs (tests answer them by name).
OFFER_DIALOG = "FabrickatorInstallOffer"
PROGRESS_DIALOG = "FabrickatorInstallProgress"
DONE_DIALOG = "FabrickatorInstallDone"
FAILED_DIALOG = "FabrickatorInstallFailed"
INSTALLER = "FabrickatorInstaller"

ICON = os.path.join(os.path.dirname(os.path.abspath(__file__)), "resources", "icons", "Fabrickator.svg")


def translate(text: str) -> str:
    return App.Qt.translate("Fabrickator", text)


def asking() -> bool:
    """Whether activating the workbench offers the install (the ASK preference)."""
    return App.ParamGet(PARAMETERS).GetBool(ASK, True)


def set_asking(ask: bool) -> None:
    App.ParamGet(PARAMETERS).SetBool(ASK, bool(ask))


def running_installer() -> Installer | None:
    """The install under way in this FreeCAD, or None."""
    for child in Gui.getMainWindow().findChildren(QtCore.QObject, INSTALLER):
        if getattr(child, "running", False):
            return child
    return None


def on_activation(on_installed) -> Installer | None:
    """What activating the workbench does about the packages; the install it started, or None.

    Nothing to install: :func:`.deps.check` (which reports a clash of
    ``core`` packages).  Otherwise :func:`offer` (``on_installed`` is called
    once the packages are in use), unless an install is already running.
    """
    if running_installer() is not None:
        return None
    if deps.needs_install() is None:
        deps.check("the Fabrickator workbench")
        return None
    return offer(on_installed)


def offer(on_installed=None) -> Installer | None:
    """Ask whether to install the packages now; the started :class:`Installer`, or None.

    Asks only when :func:`.deps.needs_install` gives a reason and the ASK
    preference is on; otherwise, or when the user declines, writes one
    Report-view line naming the menu command and the terminal command.
    The dialog (object name OFFER_DIALOG) names what is installed where and
    with which interpreter, and says when FreeCAD will have to restart
    (:func:`.deps.numpy_clash`: FreeCAD already loaded its own numpy, as
    FreeCAD 1.0 does at start-up with its start workbench PartDesign); its
    *Do not ask again* box turns ASK off.
    """
    reason = deps.needs_install()
    if reason is None:
        return None
    later = (f"Fabrickator: its Python packages are not installed ({reason}); install them with "
             f"Fabrickator > Install Python packages..., or run in a terminal: {deps.fix_command()}")
    if not asking():
        deps.report(later, warning=True)
        return None
    python, clash = deps.base_interpreter(), deps.numpy_clash()
    box = QtGui.QMessageBox(Gui.getMainWindow())
    box.setObjectName(OFFER_DIALOG)
    box.setIcon(QtGui.QMessageBox.Question)
    box.setWindowTitle(translate("Fabrickator: install Python packages"))
    box.setText(translate("Fabrickator needs Python packages that FreeCAD does not bring "
                          "(numpy 2, cadquery, scipy, trimesh and others). Install them now?"))
    box.setInformativeText(
        translate("They go into a folder of their own, {venv}, built with FreeCAD's Python ({python}) "
                  "and pip from the package index (about 1.6 GB on disk; a few minutes on a fast "
                  "connection). Nothing of FreeCAD's own is changed; its Python then finds these packages "
                  "first (FreeCAD's Plot and FEM use this numpy too). Reason: {reason}.").format(
            venv=deps.venv_dir(), python=python or translate("not found"), reason=reason)
        + ("" if clash is None else " " + translate(
            "This FreeCAD has already loaded its own numpy ({clash}), so restart FreeCAD after the "
            "install to use them.").format(clash=clash)))
    install = box.addButton(translate("Install"), QtGui.QMessageBox.AcceptRole)
    box.addButton(translate("Not now"), QtGui.QMessageBox.RejectRole)
    box.setDefaultButton(install)
    # parented to the box, so that Qt, not Python, owns the check box the box shows
    never = QtGui.QCheckBox(translate("Do not ask again (install later from the Fabrickator menu)"), box)
    box.setCheckBox(never)
    box.exec_()
    if never.isChecked():
        set_asking(False)
    accepted = box.clickedButton() is install
    box.deleteLater()
    if not accepted:
        deps.report(later, warning=True)
        return None
    return start(on_installed, python)


def start(on_installed=None, python: str | None = None) -> Installer | None:
    """Start building the venv (:class:`Installer`); None when no interpreter is found
    (then a message box says what to install and the command to run)."""
    python = python or deps.base_interpreter()
    if python is None:
        text = deps.no_interpreter_message()
        deps.report(text)
        _message(FAILED_DIALOG, QtGui.QMessageBox.Critical, text)
        return None
    installer = Installer(python, on_installed, Gui.getMainWindow())
    installer.start()
    return installer


#: Where a message gives the command to run by hand (:func:`.deps.failure_message`).
BY_HAND = "run in a terminal: "


def _message(name: str, icon, text: str) -> None:
    """A message box (object name ``name``) with ``text``; a command to run by hand at
    its end is shown on its own, in a fixed font, selectable."""
    box = QtGui.QMessageBox(Gui.getMainWindow())
    box.setObjectName(name)
    box.setIcon(icon)
    box.setWindowTitle(translate("Fabrickator"))
    said, _, command = text.rpartition(BY_HAND) if BY_HAND in text else (text, "", "")
    if command:
        box.setTextFormat(QtCore.Qt.RichText)
        box.setText(f"<p>{html.escape(said + BY_HAND.rstrip())}</p>"
                    f"<pre style='white-space: pre-wrap'>{html.escape(command)}</pre>")
    else:
        box.setText(text)
    box.setTextInteractionFlags(QtCore.Qt.TextSelectableByMouse)
    box.exec_()
    box.deleteLater()


class Installer(QtCore.QObject):
    """Builds the venv in the background: :func:`.deps.install_commands` in a QProcess.

    A non-modal progress dialog (PROGRESS_DIALOG) shows pip's latest line
    and the fraction :class:`.deps.PipProgress` reads from it (a busy bar
    while pip unpacks); its Cancel kills pip, leaving FreeCAD as it was (the
    offer comes back; the next install starts the venv afresh).  When it
    ends, ``result`` is a :class:`.deps.InstallResult`, the Report view has
    its message, a message box (DONE_DIALOG or FAILED_DIALOG) says it, and
    ``finished(ok, message)`` is emitted.  On success with the packages in
    use, ``on_installed()`` is called first.
    """

    finished = QtCore.Signal(bool, str)

    def __init__(self, python: str, on_installed=None, parent=None):
        super().__init__(parent)
        self.setObjectName(INSTALLER)
        self.commands = deps.install_commands(python)
        self.meter = deps.PipProgress()
        self.on_installed = on_installed
        self.loaded_before = deps.loaded_packages()
        self.running = False
        self.cancelled = False
        self.result: deps.InstallResult | None = None
        self.step = 0
        self.lines: list[str] = []
        self._partial = ""
        self.dialog = QtGui.QProgressDialog(parent)
        self.dialog.setObjectName(PROGRESS_DIALOG)
        self.dialog.setWindowTitle(translate("Fabrickator: installing Python packages"))
        self.dialog.setWindowModality(QtCore.Qt.NonModal)
        self.dialog.setAutoClose(False)
        self.dialog.setAutoReset(False)
        self.dialog.setMinimumDuration(0)
        self.dialog.setRange(0, 100)
        self.dialog.setMinimumWidth(560)
        self.dialog.canceled.connect(self.cancel)
        self.process = QtCore.QProcess(self)
        self.process.setProcessChannelMode(QtCore.QProcess.MergedChannels)
        env = QtCore.QProcessEnvironment()
        for key, value in deps.install_env().items():
            env.insert(key, value)
        self.process.setProcessEnvironment(env)
        self.process.readyReadStandardOutput.connect(self._read)
        self.process.finished.connect(self._step_done)
        self.process.errorOccurred.connect(self._error)

    def start(self) -> None:
        """Show the progress dialog and run the first command."""
        self.running = True
        self._show(0.0, self.meter.text)
        self.dialog.show()
        self._run(0)

    def cancel(self) -> None:
        """Stop the install (pip is killed); FreeCAD stays as it was."""
        if self.running:
            self.cancelled = True
            self.process.kill()

    def _run(self, step: int) -> None:
        self.step, self.lines, self._partial = step, [], ""
        argv = self.commands[step]
        App.Console.PrintLog(f"Fabrickator: running {' '.join(argv)}\n")
        self.process.start(argv[0], argv[1:])

    def _show(self, fraction, text: str) -> None:
        if fraction is None:
            self.dialog.setRange(0, 0)
        else:
            self.dialog.setRange(0, 100)
            self.dialog.setValue(int(round(100 * fraction)))
        self.dialog.setLabelText(text[:110])

    def _read(self) -> None:
        text = self._partial + bytes(self.process.readAllStandardOutput()).decode("utf-8", "replace")
        *lines, self._partial = text.replace("\r", "\n").split("\n")
        for line in lines:
            self.lines.append(line)
            App.Console.PrintLog(f"pip: {line}\n")
            fraction = self.meter.feed(line)
            if line.strip():
                self._show(fraction, self.meter.text)

    def _error(self, error) -> None:
        if error == QtCore.QProcess.FailedToStart and self.running:
            self.lines.append(f"ERROR: cannot run {self.commands[self.step][0]}: {self.process.errorString()}")
            self._finish(False, deps.failure_message(self.lines, None, self.step))

    def _step_done(self, code: int, status) -> None:
        if not self.running:
            return
        if self._partial:
            self.lines.append(self._partial)
        if self.cancelled:
            self._finish(False, translate("Fabrickator: the install of its Python packages was cancelled; "
                                          "the workbench offers it again when you activate it"))
        elif status != QtCore.QProcess.NormalExit or code != 0:
            self._finish(False, deps.failure_message(self.lines, code, self.step))
        elif self.step + 1 < len(self.commands):
            self._show(self.meter.started_pip(), self.meter.text)
            self._run(self.step + 1)
        else:
            deps.write_stamp()
            trouble = deps.activate(self.loaded_before)
            if trouble:
                self._finish(True, f"Fabrickator's Python packages are installed; {trouble}.")
            else:
                self._finish(True, "Fabrickator's Python packages are installed and in use: "
                                   "the workbench is ready.")

    def _finish(self, ok: bool, message: str) -> None:
        self.running = False
        self.dialog.close()
        self.result = deps.InstallResult(ok, message)
        if ok:
            App.Console.PrintMessage(message + "\n")
        else:
            deps.report(message, warning=self.cancelled)
        if ok and self.on_installed is not None and "restart FreeCAD" not in message:
            self.on_installed()
        if not self.cancelled:
            _message(DONE_DIALOG if ok else FAILED_DIALOG,
                     QtGui.QMessageBox.Information if ok else QtGui.QMessageBox.Critical, message)
        self.finished.emit(ok, message)


class InstallPackages:
    """The command *Install Python packages...*: enabled while the packages are missing
    and no install runs; builds the venv without asking first."""

    def __init__(self, on_installed=None):
        self.on_installed = on_installed

    def GetResources(self):
        return {"MenuText": translate("Install Python packages..."),
                "ToolTip": translate("Install the Python packages Fabrickator needs (numpy 2, cadquery, "
                                     "...) into its own virtual environment, with FreeCAD's Python and pip"),
                "Pixmap": ICON}

    def IsActive(self):
        return running_installer() is None and deps.needs_install() is not None

    def Activated(self):
        start(self.on_installed)


def register(on_installed=None) -> str:
    """Add :class:`InstallPackages` to FreeCADGui (``on_installed`` as there); its name."""
    Gui.addCommand(COMMAND, InstallPackages(on_installed))
    return COMMAND
