"""High-res regions from faces: the skin of material under faces picked on a part.

A user who picks faces of the part means "these surfaces must be exact".
The region they mark is each face's *skin*: the solid between the face and
the face offset :data:`SKIN_MM` into the material (against the face's
normal, which on a solid points out of it), made by OpenCascade's offset
with thickening.  Every cell the skin passes through is then marked like
any region solid (:mod:`core.high_res`).  A face whose offset fails (a
degenerate or self-overlapping surface) is marked by its bounding box grown
by the skin instead, and the result names it.

The faces come as an OCP shape or its BREP text (one face, or a compound of
faces); OCP is imported on first use, so importing this module is cheap.
"""

from __future__ import annotations

import io
from dataclasses import dataclass, field

#: Thickness (mm) of the skin under a picked face.
SKIN_MM = 0.4
#: Tolerance (mm) of the offset.
OFFSET_TOLERANCE_MM = 0.01


@dataclass(frozen=True)
class FaceSkins:
    """The skins of some faces: ``solids`` (OCP ``TopoDS_Shape``, one per face, in
    the faces' order) and ``fallbacks``, the indices of the faces whose offset
    failed and whose grown bounding box stands in for the skin."""

    solids: list = field(default_factory=list)
    fallbacks: list[int] = field(default_factory=list)

    def compound(self):
        """All the skins as one OCP compound."""
        from OCP.BRep import BRep_Builder
        from OCP.TopoDS import TopoDS_Compound

        builder, out = BRep_Builder(), TopoDS_Compound()
        builder.MakeCompound(out)
        for solid in self.solids:
            builder.Add(out, solid)
        return out

    def volume_mm3(self) -> float:
        """The skins' total volume, mm³."""
        return float(sum(_volume(s) for s in self.solids))


def read_brep(text: str):
    """The OCP shape of BREP text (as FreeCAD's ``exportBrepToString`` writes it)."""
    from OCP.BRep import BRep_Builder
    from OCP.BRepTools import BRepTools
    from OCP.TopoDS import TopoDS_Shape

    shape = TopoDS_Shape()
    BRepTools.Read_s(shape, io.BytesIO(text.encode("ascii")), BRep_Builder())
    if shape.IsNull():
        raise ValueError("the BREP text holds no shape")
    return shape


def faces_of(shape) -> list:
    """The faces of an OCP shape, in the order OpenCascade explores them."""
    from OCP.TopAbs import TopAbs_FACE
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    out = []
    explorer = TopExp_Explorer(shape, TopAbs_FACE)
    while explorer.More():
        out.append(TopoDS.Face_s(explorer.Current()))
        explorer.Next()
    return out


def skin(face, thickness: float = SKIN_MM, tolerance: float = OFFSET_TOLERANCE_MM):
    """The solid between ``face`` (OCP face) and its offset ``thickness`` mm against its
    normal; raises ValueError when OpenCascade cannot make it (no solid, no volume)."""
    from OCP.BRepOffset import BRepOffset_MakeOffset, BRepOffset_Skin
    from OCP.GeomAbs import GeomAbs_Arc
    from OCP.Standard import Standard_Failure
    from OCP.TopAbs import TopAbs_SOLID
    from OCP.TopExp import TopExp_Explorer

    maker = BRepOffset_MakeOffset()
    try:
        maker.Initialize(face, -float(thickness), float(tolerance), BRepOffset_Skin, False, False,
                         GeomAbs_Arc, True)
        maker.MakeOffsetShape()
    except Standard_Failure as exc:
        raise ValueError(f"the offset failed: {exc}") from None
    if not maker.IsDone():
        raise ValueError(f"the offset failed (error {maker.Error()})")
    out = maker.Shape()
    if out.IsNull() or not TopExp_Explorer(out, TopAbs_SOLID).More() or _volume(out) <= 0.0:
        raise ValueError("the offset made no solid")
    return out


def grown_box(face, margin: float):
    """The bounding box of ``face`` grown by ``margin`` mm on every side, as an OCP solid."""
    from OCP.Bnd import Bnd_Box
    from OCP.BRepBndLib import BRepBndLib
    from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox
    from OCP.gp import gp_Pnt

    box = Bnd_Box()
    BRepBndLib.Add_s(face, box, False)
    x0, y0, z0, x1, y1, z1 = box.Get()
    return BRepPrimAPI_MakeBox(gp_Pnt(x0 - margin, y0 - margin, z0 - margin),
                               gp_Pnt(x1 + margin, y1 + margin, z1 + margin)).Shape()


def skins(faces, thickness: float = SKIN_MM,
          tolerance: float = OFFSET_TOLERANCE_MM) -> FaceSkins:
    """The skin (:func:`skin`) of every face of ``faces`` (an OCP shape, or BREP text),
    each face on its own; a face whose offset fails is marked by its bounding box grown
    by ``thickness`` (:func:`grown_box`) and listed in ``fallbacks``.

    Raises ValueError when ``faces`` holds no face.
    """
    shape = read_brep(faces) if isinstance(faces, str) else faces
    found = faces_of(shape)
    if not found:
        raise ValueError("no face to make a region of")
    solids, fallbacks = [], []
    for n, face in enumerate(found):
        try:
            solids.append(skin(face, thickness, tolerance))
        except ValueError:
            solids.append(grown_box(face, thickness))
            fallbacks.append(n)
    return FaceSkins(solids, fallbacks)


def _volume(shape) -> float:
    from OCP.BRepGProp import BRepGProp
    from OCP.GProp import GProp_GProps

    props = GProp_GProps()
    BRepGProp.VolumeProperties_s(shape, props)
    return abs(props.Mass())
