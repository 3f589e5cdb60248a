"""Exact parametric LEGO brick solids whose faces carry tags.

These are real LEGO bricks (studs, hollow underside, tubes, pins) as the workbench shows
them.  Printed parts are not made from these solids: they keep the model whole and get
studs and sockets only where they meet LEGO (:mod:`core.parts.printed`,
:mod:`core.parts.interfaces`).  The solid is built with OpenCascade (through cadquery's OCP) and
every face is tagged from the construction history of the Boolean operations, never by
guessing from positions afterwards.

Nothing here sees the user's input (the callers build bricks from a layout and the
catalog): wrong arguments raise ValueError or TypeError, an OpenCascade step that fails
RuntimeError (:class:`BooleanFailed`, :class:`TessellationFailed`).

**Face indices.**  ``BrickSolid.tags`` maps a tag to indices into :func:`face_list` of the
solid: the order of ``TopExp.MapShapes_s(shape, TopAbs_FACE, map)`` (index ``i`` is
``map.FindKey(i + 1)``), which is also that of ``TopExp_Explorer`` and of cadquery's
``Shape.Faces()``.  It depends only on the shape's topology, so it survives copying, moving
and a BREP round trip (``BRepTools.Write_s`` / ``Read_s``, the way shapes travel into
FreeCAD), but not an operation that rebuilds it (a Boolean, a fillet, a re-import as STEP).

**Clearance.**  ``BrickGeometry.clearance`` (a diameter, default 0: real LEGO) shrinks the
stud, the tube's outside and the pin by it, widens the tube's inside by it and thins the
cavity's walls by half of it; the outer size stays ``n * pitch - 2 * play``.  Printed parts
do not use it: their fit is :class:`core.parts.interfaces.Fit`.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass
from pathlib import Path

import cadquery as cq
import trimesh
from OCP.BRep import BRep_Tool
from OCP.BRepAlgoAPI import BRepAlgoAPI_Cut, BRepAlgoAPI_Fuse
from OCP.BRepMesh import BRepMesh_IncrementalMesh
from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox, BRepPrimAPI_MakeCylinder
from OCP.gp import gp_Ax2, gp_Dir, gp_Pnt
from OCP.StlAPI import StlAPI_Writer
from OCP.TopAbs import TopAbs_FACE, TopAbs_SOLID
from OCP.TopExp import TopExp, TopExp_Explorer
from OCP.TopLoc import TopLoc_Location
from OCP.TopoDS import TopoDS, TopoDS_Face, TopoDS_Shape
from OCP.TopTools import TopTools_IndexedMapOfShape, TopTools_ListOfShape

from core.io import output_dir

#: The four outer side tags, by axis and direction.
SIDE_TAGS = ("side-x", "side+x", "side-y", "side+y")


@dataclass(frozen=True)
class BrickGeometry:
    """All dimensions in mm; defaults are LEGO's, clearance is the FDM setting.

    ``clearance`` is a diameter: see the module docstring for exactly which
    features it changes (studs shrink by it, tube outsides and pins shrink
    by it, tube insides grow by it, the cavity walls thin by half of it).
    """

    pitch: float = 8.0
    plate_height: float = 3.2
    play: float = 0.1
    stud_diameter: float = 4.8
    stud_height: float = 1.7
    wall: float = 1.2
    top: float = 1.0
    tube_outer: float = 6.51
    tube_inner: float = 4.8
    pin_diameter: float = 3.2
    clearance: float = 0.0

    @property
    def printed_stud_diameter(self) -> float:
        """Diameter of a printed stud: ``stud_diameter - clearance``."""
        return self.stud_diameter - self.clearance

    @property
    def printed_tube_outer(self) -> float:
        """Outer diameter of a printed tube: ``tube_outer - clearance``."""
        return self.tube_outer - self.clearance

    @property
    def printed_tube_inner(self) -> float:
        """Inner diameter of a printed tube: ``tube_inner + clearance``."""
        return self.tube_inner + self.clearance

    @property
    def printed_pin_diameter(self) -> float:
        """Diameter of a printed pin: ``pin_diameter - clearance``."""
        return self.pin_diameter - self.clearance

    @property
    def printed_wall(self) -> float:
        """Side wall thickness of a printed brick: ``wall - clearance / 2``."""
        return self.wall - self.clearance / 2

    def check(self, layers: int) -> None:
        """Raise ValueError unless a brick of ``layers`` plates can be built."""
        values = {name: getattr(self, name) for name in self.__dataclass_fields__}
        bad = [n for n, v in values.items()
               if isinstance(v, bool) or not isinstance(v, numbers.Real) or not math.isfinite(v)]
        if bad:
            raise ValueError(f"brick geometry: {', '.join(bad)} must be finite numbers")
        needs = (
            ("pitch", self.pitch > 0),
            ("plate_height", self.plate_height > 0),
            ("play", 0 <= self.play < self.pitch / 4),
            ("clearance", self.clearance >= 0),
            ("stud_diameter - clearance", 0 < self.printed_stud_diameter < self.pitch),
            ("stud_height", self.stud_height > 0),
            ("wall - clearance/2", 0 < self.printed_wall
             and 2 * (self.play + self.printed_wall) < self.pitch),
            ("top", 0 < self.top < layers * self.plate_height),
            ("tube_inner + clearance < tube_outer - clearance",
             0 < self.printed_tube_inner < self.printed_tube_outer < self.pitch),
            ("pin_diameter - clearance", 0 < self.printed_pin_diameter < self.pitch),
        )
        wrong = [name for name, ok in needs if not ok]
        if wrong:
            raise ValueError(f"brick geometry: impossible {', '.join(wrong)}")


@dataclass
class BrickSolid:
    """One brick as a valid closed solid, with every face tagged once.

    ``shape`` is a ``cadquery.Solid`` (``shape.wrapped`` is the
    ``TopoDS_Solid``).  ``tags`` maps a tag to indices into
    :func:`face_list` ``(shape)``; every face index occurs under exactly one
    tag.  Tags:

    * ``side-x``, ``side+x``, ``side-y``, ``side+y``: the outer vertical
      side faces;
    * ``top``: the outer top face (holed where the studs stand);
    * ``bottom``: the rim of the walls at the bottom;
    * ``cavity``: the inner faces of the hollow underside (inner walls and
      ceiling);
    * ``stud:<a>,<b>``: all faces of the stud over footprint cell (a, b),
      a along x and b along y, counted from 0;
    * ``tube:<a>,<b>``: all faces of the tube at the node between studs
      a, a+1 along x and b, b+1 along y (centre at ``(a+1, b+1) * pitch``
      from the origin), including the ceiling of its hole;
    * ``pin:<a>``: all faces of the pin between studs a and a+1 along the
      long axis of a 1-wide brick.

    ``size`` is (size_x, size_y, layers), ``origin`` the min corner of the
    brick's cell box in mm.
    """

    shape: cq.Solid
    tags: dict[str, list[int]]
    size: tuple[int, int, int]
    origin: tuple[float, float, float]

    def faces(self, tag: str) -> list[TopoDS_Face]:
        """The faces carrying ``tag`` (empty for an unknown tag)."""
        every = face_list(self.shape)
        return [every[i] for i in self.tags.get(tag, [])]

    def tag_of(self) -> list[str]:
        """The tag of each face, in :func:`face_list` order."""
        out = [""] * sum(len(v) for v in self.tags.values())
        for tag, idx in self.tags.items():
            for i in idx:
                out[i] = tag
        return out


def face_list(shape) -> list[TopoDS_Face]:
    """The distinct faces of ``shape`` (cadquery or OCP) in face-map order.

    Index ``i`` here is the index used by :attr:`BrickSolid.tags`; it equals
    ``map.FindKey(i + 1)`` of ``TopExp.MapShapes_s(shape, TopAbs_FACE, map)``.
    """
    fmap = _face_map(_occ(shape))
    return [TopoDS.Face_s(fmap.FindKey(i)) for i in range(1, fmap.Extent() + 1)]


def brick_solid(size_x: int, size_y: int, layers: int,
                geometry: BrickGeometry = BrickGeometry(),
                origin=(0.0, 0.0, 0.0)) -> BrickSolid:
    """The brick occupying cells [origin, origin + (size_x*8, size_y*8, layers*3.2)).

    The solid is the cell box minus ``geometry.play`` on each vertical side
    (outer size ``n * pitch - 2 * play``; full height, no play vertically),
    with ``size_x * size_y`` studs standing ``stud_height`` above the box
    (as on a real brick), and a hollow underside: side walls, a top
    ``geometry.top`` thick (a plate, layers=1, thus gets the shallow cavity
    of a real plate), one tube per interior node of a part at least 2 wide
    in both directions (3 under a 2x4), and one solid pin per interior node
    of a 1-wide part longer than 1 (3 under a 1x4).  Diameters follow the
    clearance rule in the module docstring.

    Returns one valid closed solid with every face tagged exactly once
    (tags from the history of the Booleans that build it).  Raises
    ValueError for non-positive sizes, an origin that is not three finite
    numbers, or an impossible geometry.
    Nothing is cached.
    """
    sizes = (size_x, size_y, layers)
    if not all(isinstance(n, int) and not isinstance(n, bool) and n >= 1 for n in sizes):
        raise ValueError(f"brick size {sizes} must be three positive whole numbers")
    try:
        ox, oy, oz = (float(v) for v in origin)
    except (TypeError, ValueError):
        raise ValueError(f"brick origin {origin!r} must be three numbers") from None
    if not all(math.isfinite(v) for v in (ox, oy, oz)):
        raise ValueError(f"brick origin {origin!r} must be finite")
    g = geometry
    g.check(layers)

    p, w = g.pitch, g.printed_wall
    x0, x1 = ox + g.play, ox + size_x * p - g.play
    y0, y1 = oy + g.play, oy + size_y * p - g.play
    z0, z1 = oz, oz + layers * g.plate_height
    ceiling = z1 - g.top
    sink = g.top / 2  # studs, tubes and pins reach this far into the top slab
    below = g.top  # the cavity and tube holes start this far below the bottom

    box = BRepPrimAPI_MakeBox(gp_Pnt(x0, y0, z0), gp_Pnt(x1, y1, z1))
    tagged = [
        (box.BackFace(), "side-x"), (box.FrontFace(), "side+x"),
        (box.LeftFace(), "side-y"), (box.RightFace(), "side+y"),
        (box.BottomFace(), "bottom"), (box.TopFace(), "top"),
    ]
    cavity = BRepPrimAPI_MakeBox(gp_Pnt(ox + g.play + w, oy + g.play + w, z0 - below),
                                 gp_Pnt(ox + size_x * p - g.play - w, oy + size_y * p - g.play - w,
                                        ceiling)).Shape()
    tagged += [(f, "cavity") for f in face_list(cavity)]
    body = _boolean(BRepAlgoAPI_Cut(), box.Shape(), [cavity], tagged)

    solids = []
    for a in range(size_x):
        for b in range(size_y):
            stud = _cylinder(ox + (a + 0.5) * p, oy + (b + 0.5) * p, z1 - sink,
                             g.printed_stud_diameter / 2, g.stud_height + sink)
            solids.append((stud, f"stud:{a},{b}"))
    holes = []
    if size_x >= 2 and size_y >= 2:
        for a in range(size_x - 1):
            for b in range(size_y - 1):
                cx, cy, tag = ox + (a + 1) * p, oy + (b + 1) * p, f"tube:{a},{b}"
                solids.append((_cylinder(cx, cy, z0, g.printed_tube_outer / 2, ceiling + sink - z0), tag))
                holes.append((_cylinder(cx, cy, z0 - below, g.printed_tube_inner / 2,
                                        ceiling - z0 + below), tag))
    elif max(size_x, size_y) >= 2:
        along_x = size_x > 1
        for a in range(max(size_x, size_y) - 1):
            cx = ox + ((a + 1) if along_x else 0.5) * p
            cy = oy + (0.5 if along_x else (a + 1)) * p
            solids.append((_cylinder(cx, cy, z0, g.printed_pin_diameter / 2, ceiling + sink - z0),
                           f"pin:{a}"))
    for shape, tag in solids:
        tagged += [(f, tag) for f in face_list(shape)]
    if solids:
        body = _boolean(BRepAlgoAPI_Fuse(), body, [s for s, _ in solids], tagged)
    if holes:
        for shape, tag in holes:
            tagged += [(f, tag) for f in face_list(shape)]
        body = _boolean(BRepAlgoAPI_Cut(), body, [s for s, _ in holes], tagged)

    solid = _only_solid(body)
    fmap = _face_map(solid)
    owner: dict[int, str] = {}
    for face, tag in tagged:
        i = fmap.FindIndex(face)
        if i == 0:
            continue
        if owner.setdefault(i - 1, tag) != tag:
            raise RuntimeError(f"face {i - 1} tagged both {owner[i - 1]} and {tag}")
    if len(owner) != fmap.Extent():
        raise RuntimeError(f"{fmap.Extent() - len(owner)} face(s) of the brick have no tag")
    tags: dict[str, list[int]] = {}
    for i in sorted(owner):
        tags.setdefault(owner[i], []).append(i)
    return BrickSolid(shape=cq.Solid(solid), tags=tags, size=sizes, origin=(ox, oy, oz))


def to_trimesh(shape, tolerance: float = 0.05, angular_tolerance: float = 0.3) -> trimesh.Trimesh:
    """A watertight triangle mesh of a closed OCP/cadquery shape, in mm.

    Meshes with ``BRepMesh_IncrementalMesh`` (linear deflection
    ``tolerance`` mm, angular deflection ``angular_tolerance`` rad; the
    triangulation is stored on the shape, as OpenCascade does), then reads
    every face's triangulation in bulk through OpenCascade's binary STL
    writer into a temporary file and trimesh's vectorised STL reader, which
    merges the shared edge nodes.  The mesh is watertight when the shape is
    a valid closed solid.  Raises TypeError for what is not a shape,
    ValueError for a shape without faces or a non-positive tolerance and
    :class:`TessellationFailed` when OpenCascade cannot mesh a face.
    """
    occ = _occ(shape)
    if not (tolerance > 0 and angular_tolerance > 0):
        raise ValueError(f"tessellation tolerances {tolerance}, {angular_tolerance} must be positive")
    if occ.IsNull() or _face_map(occ).Extent() == 0:
        raise ValueError("the shape to tessellate has no faces")
    mesher = BRepMesh_IncrementalMesh(occ, tolerance, False, angular_tolerance, False)
    mesher.Perform()
    missing = [f for f in face_list(occ) if BRep_Tool.Triangulation_s(f, TopLoc_Location()) is None]
    if missing:
        raise TessellationFailed(f"{len(missing)} face(s) of the shape could not be tessellated")
    with output_dir.scratch("stl") as tmp:
        path = Path(tmp) / "shape.stl"
        writer = StlAPI_Writer()
        writer.ASCIIMode = False
        if not writer.Write(occ, str(path)):
            raise TessellationFailed("OpenCascade's STL writer could not write the tessellated shape")
        mesh = trimesh.load(str(path), file_type="stl", force="mesh")
    mesh.merge_vertices()
    return mesh


def _occ(shape) -> TopoDS_Shape:
    """The OCP shape inside a cadquery shape, or the OCP shape itself."""
    occ = getattr(shape, "wrapped", shape)
    if not isinstance(occ, TopoDS_Shape):
        raise TypeError(f"expected a cadquery or OCP shape, got {type(shape).__name__}")
    return occ


def _face_map(shape: TopoDS_Shape) -> TopTools_IndexedMapOfShape:
    """The indexed map of distinct faces (1-based, TopExp order)."""
    fmap = TopTools_IndexedMapOfShape()
    TopExp.MapShapes_s(shape, TopAbs_FACE, fmap)
    return fmap


def _cylinder(cx: float, cy: float, z: float, radius: float, height: float) -> TopoDS_Shape:
    """A vertical solid cylinder standing on (cx, cy, z)."""
    return BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(cx, cy, z), gp_Dir(0, 0, 1)), radius, height).Shape()


def _listed(shapes) -> TopTools_ListOfShape:
    out = TopTools_ListOfShape()
    for s in shapes:
        out.Append(s)
    return out


class BooleanFailed(RuntimeError):
    """OpenCascade could not compute a Boolean."""


class TessellationFailed(RuntimeError):
    """OpenCascade could not tessellate a shape (:func:`to_trimesh`)."""


def run_boolean(op, argument: TopoDS_Shape, tools: list, tagged: list | None = None,
                parallel: bool = False) -> TopoDS_Shape:
    """Run the OCC Boolean ``op`` (argument op tools) with history; its result shape.

    ``tagged`` (face, tag) pairs, if given, are carried through in place: a
    deleted face drops out, a modified face is replaced by the faces it
    became (same tag), an untouched face stays.  Raises :class:`BooleanFailed`
    when OpenCascade gives up.
    """
    op.SetArguments(_listed([argument]))
    op.SetTools(_listed(tools))
    op.SetRunParallel(parallel)
    op.SetToFillHistory(True)
    op.Build()
    if not op.IsDone():
        raise BooleanFailed("OpenCascade Boolean failed")
    if tagged is not None:
        carried = []
        for face, tag in tagged:
            if op.IsDeleted(face):
                continue
            modified = list(op.Modified(face))
            carried += [(TopoDS.Face_s(m), tag) for m in modified] if modified else [(face, tag)]
        tagged[:] = carried
    return op.Shape()


def _boolean(op, argument: TopoDS_Shape, tools: list, tagged: list) -> TopoDS_Shape:
    """:func:`run_boolean` for building a brick: a failure is a programming error."""
    try:
        return run_boolean(op, argument, tools, tagged)
    except BooleanFailed:
        raise RuntimeError("OpenCascade Boolean failed while building a brick solid") from None


def _only_solid(shape: TopoDS_Shape) -> TopoDS_Shape:
    """The single solid in a Boolean's result."""
    found = []
    explorer = TopExp_Explorer(shape, TopAbs_SOLID)
    while explorer.More():
        found.append(explorer.Current())
        explorer.Next()
    if len(found) != 1:
        raise RuntimeError(f"brick Boolean gave {len(found)} solids, expected 1")
    return TopoDS.Solid_s(found[0])


class _JointNotAFace(ValueError):
    """A joint rectangle is not exactly one face of the brick built with it."""


def sub_shapes(shape: TopoDS_Shape, kind) -> list:
    """The sub-shapes of ``shape`` of the OCC type ``kind`` (TopAbs_SOLID, ...), in explorer order."""
    out = []
    explorer = TopExp_Explorer(shape, kind)
    while explorer.More():
        out.append(explorer.Current())
        explorer.Next()
    return out
