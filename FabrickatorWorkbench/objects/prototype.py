"""Brick prototypes: one solid per catalog part and colour, shared by links.

Every LEGO brick in the tree is an ``App::Link`` to the prototype of its
part and colour, so 3,000 bricks share a few dozen shapes.  A prototype is
a plain ``Part::Feature`` (FreeCAD 0.20 does not draw links to
``Part::FeaturePython`` objects) holding the real brick solid (studs,
hollow underside, tubes; :func:`core.brick_solids.brick_solid`) with its
min corner at the origin and its footprint (short side first) along x, y,
and the properties PartNumber and Color.  Because the colour is an App
property, a document made without the GUI shows its colours when opened in
FreeCAD (:func:`apply_colour`, called by the Fabrication on restore).
"""

from __future__ import annotations

import FreeCAD as App

from FabrickatorWorkbench.objects.properties import HIDDEN, READ_ONLY, Prop, ensure

QT = App.Qt.QT_TRANSLATE_NOOP

ROLE = "Prototype"

#: Colour of bricks new in the last recompute (a bright green no LEGO brick of
#: the layout has, :data:`core.render.PALETTE`): their prototypes glow.
HIGHLIGHT_COLOUR = (0.1, 1.0, 0.45)

PROPERTIES = (
    Prop("App::PropertyString", "FabrickatorRole", "Base",
         QT("App::Property", "Fabrickator object role"), ROLE, HIDDEN),
    Prop("App::PropertyString", "PartNumber", "Brick",
         QT("App::Property", "LEGO design number"), "", READ_ONLY),
    Prop("App::PropertyColor", "Color", "Brick",
         QT("App::Property", "Colour of the bricks linking here"), None, READ_ONLY),
)


def make_prototype(doc, part: str, colour: tuple, shape):
    """A new hidden prototype of ``part`` in ``colour`` with the brick solid ``shape``."""
    obj = doc.addObject("Part::Feature", f"Proto_{part}")
    ensure(obj, PROPERTIES)
    obj.PartNumber = part
    obj.Color = colour
    obj.Shape = shape
    obj.Label = f"{part} prototype"
    obj.Visibility = False
    return obj


def apply_colour(obj) -> None:
    """Show the prototype (and so every link to it) in its ``Color`` (GUI only); the
    prototypes of highlighted (new) bricks also glow, so they stand out from LEGO greens."""
    view = getattr(obj, "ViewObject", None)
    if view is not None:
        colour = tuple(obj.Color[:3])
        if tuple(view.ShapeColor[:3]) != colour:
            view.ShapeColor = colour
        if rgb_key(colour) == rgb_key(HIGHLIGHT_COLOUR):
            material = view.ShapeMaterial
            material.EmissiveColor = tuple(0.45 * c for c in HIGHLIGHT_COLOUR)
            view.ShapeMaterial = material
        if view.Visibility:
            view.Visibility = False


def rgb_key(colour) -> tuple:
    """A colour as an RGB tuple rounded to 1/255 (a stable dictionary key: one prototype
    per part and key)."""
    return tuple(round(float(c) * 255) / 255 for c in tuple(colour)[:3])
