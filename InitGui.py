# Fabrickator: the workbench class.  FreeCAD runs this file with exec(), so
# nothing can import from it; commands are imported inside Initialize().
import os

import FreeCAD
import FreeCADGui


class FabrickatorWorkbench(FreeCADGui.Workbench):
    """Build a part from LEGO bricks and print only what must be exact."""

    MenuText = "Fabrickator"
    ToolTip = "Build most of a part from LEGO bricks, 3D print only what must be exact"

    def __init__(self):
        import FabrickatorWorkbench as package

        self.__class__.Icon = os.path.join(os.path.dirname(package.__file__),
                                           "resources", "icons", "Fabrickator.svg")

    def Initialize(self):
        """Commands come with the workbench issue; the core runs headless today."""

    def GetClassName(self):
        return "Gui::PythonWorkbench"


FreeCADGui.addWorkbench(FabrickatorWorkbench())
FreeCAD.Console.PrintLog("Fabrickator workbench registered\n")
