# Fabrickator: the workbench class.  FreeCAD runs this file with exec(), so
# nothing can import from it, and the methods import what they use themselves
# (names imported at the top of an exec'd file are not their globals).
# Commands are imported inside Initialize(); the preferences page and the GUI
# tests are registered at start-up.
import os

import FreeCAD
import FreeCADGui

import FabrickatorWorkbench as _fabrickator_package


class FabrickatorWorkbench(FreeCADGui.Workbench):
    """Build a part from LEGO bricks and print only what must be exact."""

    MenuText = "Fabrickator"
    ToolTip = "Build most of a part from LEGO bricks, 3D print only what must be exact"

    def __init__(self):
        import os

        import FabrickatorWorkbench as package

        self.__class__.Icon = os.path.join(os.path.dirname(package.__file__),
                                           "resources", "icons", "Fabrickator.svg")

    def Initialize(self):
        """Register the commands and put them on the toolbar and in the menu."""
        from FabrickatorWorkbench import commands

        names = commands.register()
        self.appendToolbar("Fabrickator", names)
        self.appendMenu("&Fabrickator", names)

    def Activated(self):
        from FabrickatorWorkbench import deps

        deps.check("the Fabrickator workbench")

    def GetClassName(self):
        return "Gui::PythonWorkbench"


FreeCADGui.addWorkbench(FabrickatorWorkbench())
from FabrickatorWorkbench.preferences import PreferencePage as _FabrickatorPreferencePage  # noqa: E402

# the preferences dialog shows the group's icon "preferences-fabrickator" from an icon path
FreeCADGui.addIconPath(os.path.join(os.path.dirname(_fabrickator_package.__file__), "resources",
                                    "icons"))
FreeCADGui.addPreferencePage(_FabrickatorPreferencePage, "Fabrickator")
_fabrickator_gui_tests = os.path.join(os.path.dirname(os.path.dirname(_fabrickator_package.__file__)),
                                      "tests", "gui")
if os.path.isdir(_fabrickator_gui_tests):
    import sys

    if _fabrickator_gui_tests not in sys.path:
        sys.path.append(_fabrickator_gui_tests)
    FreeCAD.__unit_test__ += ["TestFabrickatorGui"]
FreeCAD.Console.PrintLog("Fabrickator workbench registered\n")
