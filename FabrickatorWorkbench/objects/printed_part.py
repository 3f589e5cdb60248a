"""The PrintedPart object: one printed part of a Fabrication.

A ``Part::FeaturePython`` whose Shape is the exact printed solid (the
Source inside the marked bricks, with studs and sockets where it meets
LEGO, ID engraved), with its ID, bricks, studs and sockets engaged and
print time.  Its Fabrication writes
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
         QT("App::Property", "Studs on the part under the LEGO bricks above it: they clamp"), 0, READ_ONLY),
    Prop("App::PropertyStringList", "IncompleteStuds", "Printed part",
         QT("App::Property", "Cells (i,j,k) that meet a brick above without a stud"), None, READ_ONLY),
    Prop("App::PropertyInteger", "Sockets", "Printed part",
         QT("App::Property", "Sockets in the part over the LEGO studs below it: they clamp"), 0, READ_ONLY),
    Prop("App::PropertyStringList", "IncompleteSockets", "Printed part",
         QT("App::Property", "Cells (i,j,k) that stand on a brick without a socket"), None, READ_ONLY),
    Prop("App::PropertyString", "Clamping", "Printed part",
         QT("App::Property", "Whether two or more studs and sockets hold the part, and why not"), "",
         READ_ONLY),
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
