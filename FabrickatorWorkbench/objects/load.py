"""The Load object: a mass resting on the bricks of a Fabrication (issue 14).

A ``Part::FeaturePython`` whose Shape is a box: ``Length``, ``Width`` and
``Height`` (mm) from its ``Placement`` (in the Source's coordinates, model
mm), and a ``Mass`` in grams.  What the phone in a headset, a lens or a
battery weighs.  Its Fabrication lists it in ``Loads`` and hands every Load
to the core as ``Request.loads`` ("X0,Y0,Z0,X1,Y1,Z1:GRAMS", the box being
the Shape's axis-aligned bounding box, so a turned Load counts as the box
around it); the core's force check puts the mass on the bricks the box
touches (:func:`core.forces.analyse`).  A Load that touches no brick fails
the recompute with one line saying so.
"""

from __future__ import annotations

import FreeCAD as App
import Part

from FabrickatorWorkbench.objects.properties import HIDDEN, Prop, FeatureProxy

QT = App.Qt.QT_TRANSLATE_NOOP

ROLE = "Load"

PROPERTIES = (
    Prop("App::PropertyString", "FabrickatorRole", "Base",
         QT("App::Property", "Fabrickator object role"), ROLE, HIDDEN),
    Prop("App::PropertyLength", "Length", "Load",
         QT("App::Property", "Size of the load's box along x, mm (from its Placement)"), 8.0),
    Prop("App::PropertyLength", "Width", "Load",
         QT("App::Property", "Size of the load's box along y, mm (from its Placement)"), 8.0),
    Prop("App::PropertyLength", "Height", "Load",
         QT("App::Property", "Size of the load's box along z, mm (from its Placement)"), 3.2),
    Prop("App::PropertyFloat", "Mass", "Load",
         QT("App::Property", "Mass resting on the bricks the box touches, in grams "
                             "(a phone about 170 g)"), 100.0),
)


class Load(FeatureProxy):
    """Proxy of a Load; its Shape is its box."""

    PROPERTIES = PROPERTIES

    def execute(self, obj):
        self.ensure_properties(obj)
        obj.Shape = load_shape(obj)


def load_shape(obj):
    """The box of Load ``obj`` at its Placement (a null shape when a side is 0)."""
    sides = [float(obj.Length.Value), float(obj.Width.Value), float(obj.Height.Value)]
    if min(sides) <= 0:
        return Part.Shape()
    box = Part.makeBox(*sides)
    box.Placement = obj.Placement
    return box


def box(obj) -> tuple[float, ...]:
    """The load's box (x0, y0, z0, x1, y1, z1) in the Source's mm: the bounding box of its
    sides at its Placement (what its Shape shows, also before it is recomputed)."""
    shape = load_shape(obj)
    if shape.isNull():
        return (0.0,) * 6
    b = shape.BoundBox
    return (b.XMin, b.YMin, b.ZMin, b.XMax, b.YMax, b.ZMax)


def request_text(obj, scale: float = 1.0) -> str:
    """``"X0,Y0,Z0,X1,Y1,Z1:GRAMS"`` of Load ``obj`` in the core's model mm (the Source's
    mm times ``scale``): one ``Request.loads`` entry."""
    values = ",".join(f"{v * scale:.6f}" for v in box(obj))
    return f"{values}:{float(obj.Mass):.6g}"


def is_load(obj) -> bool:
    """True for a Load object."""
    return obj is not None and getattr(obj, "FabrickatorRole", None) == ROLE
