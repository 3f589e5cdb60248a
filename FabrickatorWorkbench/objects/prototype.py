"""Brick prototypes: one solid per catalog part and colour, shared by links.

Every LEGO brick in the tree is an ``App::Link`` to the prototype of its
part and colour, so 3,000 bricks share a few dozen shapes.  A prototype is
a plain ``Part::Feature`` (FreeCAD 0.20 does not draw links to
``Part::FeaturePython`` objects) holding the real brick solid (studs,
hollow underside, tubes; :func:`core.parts.brick_solids.brick_solid`) with its
min corner at the origin and its footprint (short side first) along x, y,
and the properties PartNumber and Color.  The prototypes sit in one group
that the tree view does not show (:func:`hide_group`): a user sees bricks,
not the shapes they share.  Because the colour is an App
property, a document made without the GUI shows its colours when opened in
FreeCAD (:func:`apply_colour`, called by the Fabrication on restore).
"""

from __future__ import annotations

import FreeCAD as App

from FabrickatorWorkbench.objects.properties import HIDDEN, READ_ONLY, Prop, ensure

QT = App.Qt.QT_TRANSLATE_NOOP

ROLE = "Prototype"
#: Role of the document group that holds the prototypes.
GROUP_ROLE = "Prototypes"

#: Colour of bricks new in the last recompute: a saturated magenta, far (CIE76
#: delta E > 150) from FreeCAD's selection green and preselection yellow and
#: (> 70) from every brick colour of :mod:`core.colours` and the printed orange,
#: so a changed brick is neither taken for a selected one nor for a LEGO colour.
#: Their prototypes also glow.
HIGHLIGHT_COLOUR = (1.0, 0.0, 0.85)

#: Colour of the brick edges the 3D view draws (Flat Lines), dark on every palette colour.
EDGE_COLOUR = (0.1, 0.1, 0.12)

#: App::Link properties a brick's user never needs (arrays, copy on change, scaling,
#: claiming children): hidden from the property view so that the brick's own
#: properties are what it shows.  LinkedObject and Placement stay.
LINK_PROPERTIES_HIDDEN = ("ElementCount", "LinkClaimChild", "LinkCopyOnChange", "LinkExecute",
                          "LinkTransform", "PlacementList", "Scale", "ScaleList", "ShowElement")

PROPERTIES = (
    Prop("App::PropertyString", "FabrickatorRole", "Base",
         QT("App::Property", "Fabrickator object role"), ROLE, HIDDEN),
    Prop("App::PropertyString", "PartNumber", " Brick",
         QT("App::Property", "LEGO design number"), "", READ_ONLY),
    Prop("App::PropertyColor", "Color", " Brick",
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
    """Show the prototype (and so every link to it) in its ``Color`` with its edges drawn
    (Flat Lines in :data:`EDGE_COLOUR`, so bricks of one colour stay apart), and keep its
    group out of the tree view (GUI only; :func:`hide_group`).  The prototypes of
    highlighted (new) bricks also glow."""
    view = getattr(obj, "ViewObject", None)
    if view is not None:
        colour = tuple(obj.Color[:3])
        if tuple(view.ShapeColor[:3]) != colour:
            view.ShapeColor = colour
        if rgb_key(colour) == rgb_key(HIGHLIGHT_COLOUR):
            material = view.ShapeMaterial
            material.EmissiveColor = tuple(0.45 * c for c in HIGHLIGHT_COLOUR)
            view.ShapeMaterial = material
        if "Flat Lines" in view.listDisplayModes() and view.DisplayMode != "Flat Lines":
            view.DisplayMode = "Flat Lines"
        if rgb_key(view.LineColor) != rgb_key(EDGE_COLOUR):
            view.LineColor = EDGE_COLOUR
        if view.Visibility:
            view.Visibility = False
        for group in obj.InList:
            if getattr(group, "FabrickatorRole", None) == GROUP_ROLE:
                hide_group(group)


def hide_group(group) -> None:
    """Keep the prototypes' group out of the tree view (its ViewObject's ``ShowInTree``,
    FreeCAD 0.20 and 1.x; no-op without the GUI).  It stays in the document: bricks
    link to its prototypes, and the Fabrication finds it by its role."""
    view = getattr(group, "ViewObject", None)
    if view is not None and getattr(view, "ShowInTree", False):
        view.ShowInTree = False


def hide_link_properties(obj) -> None:
    """Hide :data:`LINK_PROPERTIES_HIDDEN` of the App::Link ``obj`` in the property view
    (its editor mode only; the properties keep working).  Call it after setting the
    link's LinkedObject: App::Link shows ShowElement and ElementCount again then."""
    for name in LINK_PROPERTIES_HIDDEN:
        if name in obj.PropertiesList and "Hidden" not in obj.getEditorMode(name):
            obj.setEditorMode(name, 2)


def rgb_key(colour) -> tuple:
    """A colour as an RGB tuple rounded to 1/255 (a stable dictionary key: one prototype
    per part and key)."""
    return tuple(round(float(c) * 255) / 255 for c in tuple(colour)[:3])
