"""The HighResRegion object: part of a Fabrication that must be printed exactly.

A ``Part::FeaturePython`` in one of three modes:

* ``Bricks``: boxes in model mm (``Boxes``, six numbers each), made by the
  brush (one box per brushed brick) or by a script (``box=``);
* ``Solid``: a region solid (``RegionSolid``, any object with a solid or a
  mesh), e.g. a cylinder placed around a screw seat;
* ``Faces``: faces of the Source (``Faces``); every cell the faces' inner
  skin (:data:`core.face_region.SKIN_MM` thick, made by
  :func:`core.face_region.skins`) passes through is marked.

Its Shape shows the region; the Fabrication hands boxes to the core as
boxes and the other modes as a region solid file.

A region shows in the 3D view only while a brush panel is open on its
Fabrication, or always when its ``ShowAlways`` is true (:func:`show`): it
is hidden when made, when its document opens and when the brush panel
closes, so that it neither floats over the assembly nor tints the printed
parts.  Showing or hiding it by hand (Space) works as for any object until
the next of these.
"""

from __future__ import annotations

import FreeCAD as App
import Part

from core import face_region
from FabrickatorWorkbench import bridge, log
from FabrickatorWorkbench.objects.properties import HIDDEN, Prop, FeatureProxy

QT = App.Qt.QT_TRANSLATE_NOOP

ROLE = "HighResRegion"

#: Modes of a region.
MODES = ["Bricks", "Solid", "Faces"]

PROPERTIES = (
    Prop("App::PropertyString", "FabrickatorRole", "Base",
         QT("App::Property", "Fabrickator object role"), ROLE, HIDDEN),
    Prop("App::PropertyEnumeration", "Mode", "Region",
         QT("App::Property", "Bricks (boxes), Solid (a region solid) or Faces (of the Source)"), MODES),
    Prop("App::PropertyFloatList", "Boxes", "Region",
         QT("App::Property", "Bricks mode: boxes X0,Y0,Z0,X1,Y1,Z1 in model mm, one after another")),
    Prop("App::PropertyLink", "RegionSolid", "Region",
         QT("App::Property", "Solid mode: the object whose solid (or mesh) is the region")),
    Prop("App::PropertyLinkSubList", "Faces", "Region",
         QT("App::Property", "Faces mode: faces of the Source that must be exact")),
    Prop("App::PropertyBool", "ShowAlways", "Region",
         QT("App::Property", "Show the region in the 3D view also when no brush panel is open "
                             "(a brush panel shows it anyway)"), False),
)


class HighResRegion(FeatureProxy):
    """Proxy of a high-res region; its Shape shows what it marks."""

    PROPERTIES = PROPERTIES

    def __init__(self, obj):
        super().__init__(obj)
        show(obj)

    def onDocumentRestored(self, obj):
        super().onDocumentRestored(obj)
        show(obj)

    def onChanged(self, obj, prop):
        if prop == "ShowAlways" and "Restore" not in obj.State:
            show(obj)

    def execute(self, obj):
        self.ensure_properties(obj)
        obj.Shape = region_shape(obj)


def show(obj, brushing: bool = False) -> None:
    """Show region ``obj`` when ``brushing`` (a brush panel is open on its Fabrication) or
    when its ``ShowAlways`` is true, hide it otherwise."""
    visible = brushing or bool(getattr(obj, "ShowAlways", False))
    if bool(obj.Visibility) != visible:
        obj.Visibility = visible


def boxes(obj) -> list[tuple[float, ...]]:
    """The region's boxes as (x0, y0, z0, x1, y1, z1) tuples (Bricks mode)."""
    values = list(obj.Boxes)
    return [tuple(values[n:n + 6]) for n in range(0, len(values) - len(values) % 6, 6)]


def region_shape(obj):
    """The shape that shows the region: its boxes, its solid, or the faces' skin."""
    if obj.Mode == "Bricks":
        solids = [Part.makeBox(x1 - x0, y1 - y0, z1 - z0, App.Vector(x0, y0, z0))
                  for x0, y0, z0, x1, y1, z1 in boxes(obj) if x1 > x0 and y1 > y0 and z1 > z0]
        return Part.makeCompound(solids) if solids else Part.Shape()
    if obj.Mode == "Solid":
        source = obj.RegionSolid
        shape = getattr(source, "Shape", None)
        if shape is not None and not shape.isNull() and shape.Solids:
            return shape.copy()
        return Part.Shape()
    return Part.makeCompound(face_skins(obj)) if obj.Faces else Part.Shape()


def face_skins(obj) -> list:
    """One thin solid per picked face (in the document's coordinates): the skin
    :data:`core.face_region.SKIN_MM` into the material, made by
    :func:`core.face_region.skins`.

    A face whose offset fails (a degenerate surface) is marked by its bounding box
    grown by the skin, and a warning says so.
    """
    faces, names = [], []
    for owner, subs in obj.Faces:
        for name in subs:
            face = owner.getSubObject(name)
            if face is not None and not face.isNull():
                faces.append(face)
                names.append(f"{owner.Label}.{name}")
    if not faces:
        return []
    skins = face_region.skins(bridge.shapes_to_brep(faces))
    for n in skins.fallbacks:
        log.warning(f"{obj.Label}: face {names[n]} has no clean offset; "
                    f"marking its bounding box instead")
    return [bridge.occ_to_part(solid) for solid in skins.solids]
