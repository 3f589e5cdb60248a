"""The PrintedPart object: one printed part of a Fabrication.

A ``Part::FeaturePython`` whose Shape is the exact printed solid (the
marked LEGO bricks intersected with the Source, ID engraved), with its ID,
bricks, stud and tube completeness and print time.  Its Fabrication writes
it; it has nothing to compute itself.
"""

from __future__ import annotations

import FreeCAD as App

from FabrickatorWorkbench.objects.properties import HIDDEN, READ_ONLY, Prop, FeatureProxy

QT = App.Qt.QT_TRANSLATE_NOOP

ROLE = "PrintedPart"

PROPERTIES = (
    Prop("App::PropertyString", "FabrickatorRole", "Base",
         QT("App::Property", "Fabrickator object role"), ROLE, HIDDEN),
    Prop("App::PropertyString", "PartId", "Printed part",
         QT("App::Property", "ID engraved on the part (P1, P2, ...)"), "", READ_ONLY),
    Prop("App::PropertyIntegerList", "BrickIds", "Printed part",
         QT("App::Property", "Layout bricks the part replaces"), None, READ_ONLY),
    Prop("App::PropertyInteger", "Cells", "Printed part",
         QT("App::Property", "1x1 plate cells the part covers"), 0, READ_ONLY),
    Prop("App::PropertyFloat", "VolumeMm3", "Printed part",
         QT("App::Property", "Volume of the printed solid, mm^3"), 0.0, READ_ONLY),
    Prop("App::PropertyInteger", "CompleteStuds", "Printed part",
         QT("App::Property", "Exposed studs left whole: they clamp"), 0, READ_ONLY),
    Prop("App::PropertyStringList", "IncompleteStuds", "Printed part",
         QT("App::Property", "Exposed studs the intersection cut: they cannot clamp"), None, READ_ONLY),
    Prop("App::PropertyStringList", "IncompleteTubes", "Printed part",
         QT("App::Property", "Tubes, pins and cavities the intersection cut"), None, READ_ONLY),
    Prop("App::PropertyBool", "Engraved", "Printed part",
         QT("App::Property", "Whether the ID is engraved on a side"), False, READ_ONLY),
    Prop("App::PropertyFloat", "PrintTime", "Printed part",
         QT("App::Property", "Print time in seconds"), 0.0, READ_ONLY),
    Prop("App::PropertyString", "PrintTimeMethod", "Printed part",
         QT("App::Property", "Where the print time comes from (slicer or estimate)"), "", READ_ONLY),
    Prop("App::PropertyBool", "Reprint", "Printed part",
         QT("App::Property", "New or changed in the last recompute: print it (again)"), True,
         READ_ONLY),
    Prop("App::PropertyInteger", "Step", "Printed part",
         QT("App::Property", "Assembly step that inserts the part"), 0, READ_ONLY),
)


class PrintedPart(FeatureProxy):
    """Proxy of a PrintedPart; the shape is set by its Fabrication."""

    PROPERTIES = PROPERTIES

    def execute(self, obj):
        """Nothing to compute: the Fabrication writes the shape."""
