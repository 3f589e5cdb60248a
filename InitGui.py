# Fabrickator: the workbench class.  FreeCAD runs this file with exec(), so
# nothing can import from it, and the methods import what they use themselves
# (names imported at the top of an exec'd file are not their globals).
# Commands are imported inside Initialize(); the GUI tests are registered at
# start-up, and so is the preferences page once Fabrickator's Python packages
# are installed (it imports numpy: before the first-run install that would
# load FreeCAD's own numpy 1.x and keep the installed packages out until a
# restart).
import os

import FreeCAD
import FreeCADGui

import FabrickatorWorkbench as _fabrickator_package
from FabrickatorWorkbench import deps as _fabrickator_deps


class FabrickatorWorkbench(FreeCADGui.Workbench):
    """Build a part from LEGO bricks and print only what must be exact."""

    MenuText = "Fabrickator"
    ToolTip = "Build most of a part from LEGO bricks, 3D print only what must be exact"

    def __init__(self):
        import os

        import FabrickatorWorkbench as package

        self.__class__.Icon = os.path.join(os.path.dirname(package.__file__),
                                           "resources", "icons", "Fabrickator.svg")
        self.preferences_added = False

    def Initialize(self):
        """Register the commands and put them on the toolbar and in the menu.

        While Fabrickator's Python packages are missing (an Addon Manager
        install before its first run) only *Install Python packages...* is
        there; the others follow once they are installed (:meth:`add_commands`).
        """
        from FabrickatorWorkbench import deps, install

        install.register(self.add_commands)
        if not deps.missing():
            self.add_commands()
        else:
            self.appendToolbar("Fabrickator", [install.COMMAND])
            self.appendMenu("&Fabrickator", [install.COMMAND])

    def add_commands(self):
        """Register the workbench's commands and the preferences page and show them (once);
        called by Initialize and after the first-run install."""
        import FreeCADGui

        from FabrickatorWorkbench import commands, install

        self.add_preferences()
        if "Fabrickator_Legofy" in self.getToolbarItems().get("Fabrickator", []):
            return
        names = commands.register()
        self.removeToolbar("Fabrickator")
        self.removeMenu("&Fabrickator")
        self.appendToolbar("Fabrickator", names)
        self.appendMenu("&Fabrickator", names + [install.COMMAND])
        if FreeCADGui.activeWorkbench().name() == "FabrickatorWorkbench":
            self.reloadActive()

    def add_preferences(self):
        """Add the preferences page to FreeCAD's preferences dialog (once)."""
        import os

        import FreeCADGui

        import FabrickatorWorkbench as package
        from FabrickatorWorkbench.preferences import PreferencePage

        if self.preferences_added:
            return
        # the preferences dialog shows the group's icon "preferences-fabrickator" from an icon path
        FreeCADGui.addIconPath(os.path.join(os.path.dirname(package.__file__), "resources", "icons"))
        FreeCADGui.addPreferencePage(PreferencePage, "Fabrickator")
        self.preferences_added = True

    def Activated(self):
        """Offer to install the Python packages when they are missing (:mod:`.install`)."""
        from FabrickatorWorkbench import install

        install.on_activation(self.add_commands)

    def GetClassName(self):
        return "Gui::PythonWorkbench"


_fabrickator_workbench = FabrickatorWorkbench()
FreeCADGui.addWorkbench(_fabrickator_workbench)
if not _fabrickator_deps.missing():
    _fabrickator_workbench.add_preferences()
_fabrickator_gui_tests = os.path.join(os.path.dirname(os.path.dirname(_fabrickator_package.__file__)),
                                      "tests", "gui")
if os.path.isdir(_fabrickator_gui_tests):
    import sys

    if _fabrickator_gui_tests not in sys.path:
        sys.path.append(_fabrickator_gui_tests)
    FreeCAD.__unit_test__ += ["TestFabrickatorGui"]
FreeCAD.Console.PrintLog("Fabrickator workbench registered\n")
