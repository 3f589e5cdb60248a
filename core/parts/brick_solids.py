"""Exact parametric LEGO brick solids whose faces carry tags.

These are real LEGO bricks (studs, hollow underside, tubes, pins) as the workbench shows
them and as the paper's merge works on them: merging neighbouring bricks removes the faces
where they touch, found by tag, and sews the rest into one solid (:func:`merged_solid`;
"Merging and splitting").  Printed parts are not made from these solids: they keep the
model whole and get studs and sockets only where they meet LEGO (:mod:`core.parts.printed`,
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
from dataclasses import dataclass, field
from pathlib import Path

import cadquery as cq
import numpy as np
import trimesh
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components
from OCP.Bnd import Bnd_Box
from OCP.BRep import BRep_Builder, BRep_Tool
from OCP.BRepAlgoAPI import BRepAlgoAPI_Cut, BRepAlgoAPI_Fuse, BRepAlgoAPI_Splitter
from OCP.BRepBndLib import BRepBndLib
from OCP.BRepBuilderAPI import (BRepBuilderAPI_MakeFace, BRepBuilderAPI_MakePolygon,
                                BRepBuilderAPI_MakeSolid, BRepBuilderAPI_Sewing)
from OCP.BRepCheck import BRepCheck_Analyzer
from OCP.BRepGProp import BRepGProp
from OCP.BRepLib import BRepLib
from OCP.BRepMesh import BRepMesh_IncrementalMesh
from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox, BRepPrimAPI_MakeCylinder
from OCP.gp import gp_Ax2, gp_Dir, gp_Pnt
from OCP.GProp import GProp_GProps
from OCP.ShapeUpgrade import ShapeUpgrade_UnifySameDomain
from OCP.Standard import Standard_Failure
from OCP.StlAPI import StlAPI_Writer
from OCP.TopAbs import TopAbs_FACE, TopAbs_SHELL, TopAbs_SOLID
from OCP.TopExp import TopExp, TopExp_Explorer
from OCP.TopLoc import TopLoc_Location
from OCP.TopoDS import TopoDS, TopoDS_Face, TopoDS_Shape, TopoDS_Shell
from OCP.TopTools import TopTools_IndexedMapOfShape, TopTools_ListOfShape

from core.io import output_dir

#: The four outer side tags, by axis and direction.
SIDE_TAGS = ("side-x", "side+x", "side-y", "side+y")

#: Largest distance (mm) between the bounding boxes of two joint faces that
#: still count as exactly coincident.
JOINT_TOL_MM = 1e-6

#: Sewing tolerance (mm): edges closer than this are joined.
SEW_TOL_MM = 1e-5


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
    brick's cell box in mm.  ``joints`` maps each joint rectangle given to
    :func:`brick_solid` to the index of the one face that is exactly that
    rectangle (these faces also carry their side/top/bottom tag).
    """

    shape: cq.Solid
    tags: dict[str, list[int]]
    size: tuple[int, int, int]
    origin: tuple[float, float, float]
    joints: dict[str, list[int]] = field(default_factory=dict)

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
                origin=(0.0, 0.0, 0.0), flush=(), no_studs=(), solid_under=(),
                joints=None) -> BrickSolid:
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

    ``flush`` names side tags (``"side+x"`` ...) whose face lies on the cell
    boundary without play: give it the sides a printed brick shares with a
    neighbour it is merged with, so that the two facing side faces are
    coplanar and coincide (see :func:`facing_sides`); the wall on such a
    side is ``play`` thicker, the cavity stays where it was.

    The next three arguments serve merging (:func:`merged_solid`), where a
    brick of a printed part stands on or carries another brick of the part:

    * ``no_studs``: footprint cells (a, b) that get no stud (a brick of the
      part stands there, so the top face is plain over them);
    * ``solid_under``: footprint cells (a, b) whose underside is solid down
      to the bottom face (the brick stands on a brick of the part there):
      the cavity is left out over them, a tube or pin over such cells only
      is left out, one partly over them is cut off at their boundary;
    * ``joints``: ``{name: (lo, hi)}`` axis-aligned rectangles (min and max
      corner in mm, zero extent along one axis) lying on an outer plane
      face of the brick (a side, the top or the bottom).  The brick's faces
      are split along each rectangle's edges (an OpenCascade Splitter, with
      history), so that the rectangle is one face of its own, listed in
      ``BrickSolid.joints[name]``; it keeps its side/top/bottom tag.

    Returns one valid closed solid with every face tagged exactly once
    (tags from the history of the Booleans that build it).  Raises
    ValueError for non-positive sizes, an unknown ``flush`` tag, an origin
    that is not three finite numbers, cells outside the footprint, a joint
    rectangle that is not one face of the brick, or an impossible geometry.
    Nothing is cached.
    """
    sizes = (size_x, size_y, layers)
    if not all(isinstance(n, int) and not isinstance(n, bool) and n >= 1 for n in sizes):
        raise ValueError(f"brick size {sizes} must be three positive whole numbers")
    flush = frozenset(flush)
    if not flush <= set(SIDE_TAGS):
        raise ValueError(f"unknown side tag(s) {sorted(flush - set(SIDE_TAGS))} in flush "
                         f"(use {', '.join(SIDE_TAGS)})")
    try:
        ox, oy, oz = (float(v) for v in origin)
    except (TypeError, ValueError):
        raise ValueError(f"brick origin {origin!r} must be three numbers") from None
    if not all(math.isfinite(v) for v in (ox, oy, oz)):
        raise ValueError(f"brick origin {origin!r} must be finite")
    g = geometry
    g.check(layers)
    no_studs, solid_under = _footprint_cells(no_studs, size_x, size_y, "no_studs"), \
        _footprint_cells(solid_under, size_x, size_y, "solid_under")

    p, w = g.pitch, g.printed_wall
    x0 = ox + (0.0 if "side-x" in flush else g.play)
    x1 = ox + size_x * p - (0.0 if "side+x" in flush else g.play)
    y0 = oy + (0.0 if "side-y" in flush else g.play)
    y1 = oy + size_y * p - (0.0 if "side+y" in flush else g.play)
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
    # Solid columns over the cells standing on the part: tools that clip the
    # cavity, tubes, pins and tube holes at those cells' boundaries.
    columns = [BRepPrimAPI_MakeBox(gp_Pnt(ox + a * p, oy + b * p, z0 - 2 * below),
                                   gp_Pnt(ox + (a + 1) * p, oy + (b + 1) * p, z1)).Shape()
               for a, b in sorted(solid_under)]
    body = box.Shape()
    if len(solid_under) < size_x * size_y:
        cavity = _clipped(BRepPrimAPI_MakeBox(gp_Pnt(ox + g.play + w, oy + g.play + w, z0 - below),
                                              gp_Pnt(ox + size_x * p - g.play - w,
                                                     oy + size_y * p - g.play - w, ceiling)).Shape(),
                          columns)
        tagged += [(f, "cavity") for f in face_list(cavity)]
        body = _boolean(BRepAlgoAPI_Cut(), body, [cavity], tagged)

    solids = []
    for a in range(size_x):
        for b in range(size_y):
            if (a, b) not in no_studs:
                stud = _cylinder(ox + (a + 0.5) * p, oy + (b + 0.5) * p, z1 - sink,
                                 g.printed_stud_diameter / 2, g.stud_height + sink)
                solids.append((stud, f"stud:{a},{b}"))
    holes = []
    if size_x >= 2 and size_y >= 2:
        for a in range(size_x - 1):
            for b in range(size_y - 1):
                over = {(a, b), (a + 1, b), (a, b + 1), (a + 1, b + 1)}
                if over <= solid_under:
                    continue
                cx, cy, tag = ox + (a + 1) * p, oy + (b + 1) * p, f"tube:{a},{b}"
                cut = columns if over & solid_under else []
                solids.append((_clipped(_cylinder(cx, cy, z0, g.printed_tube_outer / 2,
                                                  ceiling + sink - z0), cut), tag))
                holes.append((_clipped(_cylinder(cx, cy, z0 - below, g.printed_tube_inner / 2,
                                                 ceiling - z0 + below), cut), tag))
    elif max(size_x, size_y) >= 2:
        along_x = size_x > 1
        for a in range(max(size_x, size_y) - 1):
            over = {(a, 0), (a + 1, 0)} if along_x else {(0, a), (0, a + 1)}
            if over <= solid_under:
                continue
            cx = ox + ((a + 1) if along_x else 0.5) * p
            cy = oy + (0.5 if along_x else (a + 1)) * p
            solids.append((_clipped(_cylinder(cx, cy, z0, g.printed_pin_diameter / 2,
                                              ceiling + sink - z0),
                                    columns if over & solid_under else []), f"pin:{a}"))
    for shape, tag in solids:
        tagged += [(f, tag) for f in face_list(shape)]
    if solids:
        body = _boolean(BRepAlgoAPI_Fuse(), body, [s for s, _ in solids], tagged)
    if holes:
        for shape, tag in holes:
            tagged += [(f, tag) for f in face_list(shape)]
        body = _boolean(BRepAlgoAPI_Cut(), body, [s for s, _ in holes], tagged)
    rects = _joint_rects(joints)
    if rects:
        body = _boolean(BRepAlgoAPI_Splitter(), body, [_rect_face(lo, hi) for lo, hi in rects.values()],
                        tagged)

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
    return BrickSolid(shape=cq.Solid(solid), tags=tags, size=sizes, origin=(ox, oy, oz),
                      joints=_joint_faces(solid, rects))


def facing_sides(a_cell, a_size, b_cell, b_size) -> tuple[str, str] | None:
    """The side tags of brick A and brick B that face each other, or None.

    Cells and sizes are in grid cells, (i, j, k) and (x, y, z) as in
    :class:`core.model.Brick` (two-element x, y footprints work too).  The
    cell boxes touch side by side when they meet in a plane normal to x or
    y and their extents overlap with positive length along every other
    axis.  Returns e.g. ``("side+x", "side-x")`` when B lies on A's +x
    side, None when the boxes are apart, overlap, or meet only along an
    edge, a corner, or top to bottom.  The contact may cover only part of
    each face; the shared rectangle is the overlap of the two footprints.
    """
    a_lo, a_hi, b_lo, b_hi = _cell_boxes(a_cell, a_size, b_cell, b_size)
    touch = None
    for axis in range(len(a_lo)):
        if a_hi[axis] == b_lo[axis] or b_hi[axis] == a_lo[axis]:
            if touch is not None:
                return None
            touch = axis
        elif not (a_lo[axis] < b_hi[axis] and b_lo[axis] < a_hi[axis]):
            return None
    if touch is None or touch > 1:
        return None
    name = "xy"[touch]
    if a_hi[touch] == b_lo[touch]:
        return f"side+{name}", f"side-{name}"
    return f"side-{name}", f"side+{name}"


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


def _cell_boxes(a_cell, a_size, b_cell, b_size):
    """Integer min/max corners of two cell boxes; ValueError when malformed."""
    try:
        parts = [tuple(int(v) for v in t) for t in (a_cell, a_size, b_cell, b_size)]
    except (TypeError, ValueError):
        raise ValueError("facing_sides needs cells and sizes as whole-number tuples") from None
    if len({len(t) for t in parts}) != 1 or len(parts[0]) not in (2, 3):
        raise ValueError("facing_sides needs cells and sizes of the same length, 2 or 3")
    if any(s <= 0 for s in parts[1] + parts[3]):
        raise ValueError("facing_sides needs positive brick sizes")
    (ac, asz, bc, bsz) = parts
    return (ac, tuple(c + s for c, s in zip(ac, asz)), bc, tuple(c + s for c, s in zip(bc, bsz)))


def _footprint_cells(cells, size_x: int, size_y: int, what: str) -> frozenset[tuple[int, int]]:
    """``cells`` as a set of (a, b) footprint cells; ValueError when one lies outside."""
    try:
        out = frozenset((int(a), int(b)) for a, b in cells)
    except (TypeError, ValueError):
        raise ValueError(f"{what} must be footprint cells (a, b)") from None
    if any(not (0 <= a < size_x and 0 <= b < size_y) for a, b in out):
        raise ValueError(f"{what} has cells outside the {size_x}x{size_y} footprint")
    return out


def _clipped(shape: TopoDS_Shape, columns: list) -> TopoDS_Shape:
    """``shape`` minus the ``columns`` (itself when there are none)."""
    if not columns:
        return shape
    return _boolean(BRepAlgoAPI_Cut(), shape, columns, [])


def _joint_rects(joints) -> dict[str, tuple[tuple[float, ...], tuple[float, ...]]]:
    """``joints`` checked: name -> (lo, hi) with zero extent along exactly one axis."""
    out = {}
    for name, corners in dict(joints or {}).items():
        try:
            lo, hi = (tuple(float(v) for v in c) for c in corners)
        except (TypeError, ValueError):
            raise ValueError(f"joint {name}: {corners!r} are not two corners") from None
        flat = [i for i in range(3) if abs(hi[i] - lo[i]) <= 1e-9] if len(lo) == len(hi) == 3 else []
        if len(flat) != 1 or any(hi[i] - lo[i] <= 1e-9 for i in range(3) if i != flat[0]):
            raise ValueError(f"joint {name}: {lo}..{hi} is not a rectangle normal to an axis")
        out[str(name)] = (lo, hi)
    return out


def _rect_face(lo, hi) -> TopoDS_Face:
    """The planar rectangle face spanned by corners ``lo``, ``hi`` (one axis flat)."""
    flat = min(range(3), key=lambda i: abs(hi[i] - lo[i]))
    u, v = (i for i in range(3) if i != flat)
    corners = []
    for a, b in ((lo[u], lo[v]), (hi[u], lo[v]), (hi[u], hi[v]), (lo[u], hi[v])):
        point = [0.0, 0.0, 0.0]
        point[flat], point[u], point[v] = lo[flat], a, b
        corners.append(gp_Pnt(*point))
    wire = BRepBuilderAPI_MakePolygon(*corners, True).Wire()
    return BRepBuilderAPI_MakeFace(wire, True).Face()


def _face_box(face) -> np.ndarray:
    """Tight bounding box (2, 3) of a face."""
    box = Bnd_Box()
    BRepBndLib.AddOptimal_s(face, box, False, False)
    return np.array(box.Get()).reshape(2, 3)


def _joint_faces(solid: TopoDS_Shape, rects: dict) -> dict[str, list[int]]:
    """Per joint rectangle, the index of the one face of ``solid`` that is exactly it.

    :class:`_JointNotAFace` when a rectangle is not exactly one face (it does
    not lie on a plain outer face of the brick)."""
    if not rects:
        return {}
    faces = face_list(solid)
    boxes = np.array([_face_box(f) for f in faces])
    out = {}
    for name, (lo, hi) in rects.items():
        want = np.array([lo, hi])
        hit = np.flatnonzero(np.all(np.abs(boxes - want) < JOINT_TOL_MM, axis=(1, 2)))
        area = float(np.prod([h - l for l, h in zip(lo, hi) if h - l > 1e-9]))
        hit = [int(i) for i in hit if abs(_area(faces[i]) - area) <= 1e-6 * max(area, 1.0)]
        if len(hit) != 1:
            raise _JointNotAFace(f"joint {name} is not one plain outer face of the brick "
                                 f"({len(hit)} found)")
        out[name] = hit
    return out


def _area(face) -> float:
    props = GProp_GProps()
    BRepGProp.SurfaceProperties_s(face, props)
    return float(props.Mass())


@dataclass
class MergedSolid:
    """Several bricks merged into one solid (:func:`merged_solid`).

    ``shape`` is one valid closed ``TopoDS_Solid``; ``tagged`` lists (face,
    tag) for its faces, the tag ``"<name>:<brick tag>"`` (a face that
    OpenCascade unified from faces of several bricks appears once per tag).
    ``method`` says how it was built: ``"single brick"``, ``"face removal"``
    or ``"fuse (face removal failed: <reason>)"``; ``removed_faces`` counts
    the coincident joint faces dropped (0 for a fuse).
    """

    shape: TopoDS_Shape
    tagged: list[tuple[TopoDS_Face, str]]
    method: str
    removed_faces: int = 0


@dataclass
class BrickContacts:
    """How one brick of a merged part meets the others (see :func:`part_contacts`)."""

    flush: tuple[str, ...]
    no_studs: frozenset[tuple[int, int]]
    solid_under: frozenset[tuple[int, int]]
    joints: dict[str, tuple[tuple[float, float, float], tuple[float, float, float]]]


def part_contacts(cells, sizes, geometry: BrickGeometry = BrickGeometry(),
                  grid_origin=(0.0, 0.0, 0.0)) -> list[BrickContacts]:
    """For each brick (grid ``cells`` (i, j, k) and ``sizes`` (x, y, z)), how it meets the others.

    * ``flush``: the side tags facing a neighbour (:func:`facing_sides`),
      built without play so that the two sides coincide;
    * ``no_studs``: footprint cells covered by a brick standing on it;
    * ``solid_under``: footprint cells standing on a brick of the group;
    * ``joints``: per touching pair, the rectangle (mm) where their faces
      meet: the overlap of the two facing sides (or of the lower brick's top
      and the upper brick's bottom), named ``"<a>|<b>"`` by the pair's
      indices.  Both bricks get the same rectangle, so that after
      :func:`brick_solid` splits their faces along it, they share one
      exactly coincident face each.
    """
    boxes = [_cell_boxes(c, s, c, s)[:2] for c, s in zip(cells, sizes)]
    cell_mm = np.array([geometry.pitch, geometry.pitch, geometry.plate_height])
    origin = np.asarray(grid_origin, dtype=float)
    n = len(boxes)
    flush = [set() for _ in range(n)]
    no_studs = [set() for _ in range(n)]
    solid_under = [set() for _ in range(n)]
    pairs = []
    for a in range(n):
        for b in range(a + 1, n):
            sides = facing_sides(cells[a], sizes[a], cells[b], sizes[b])
            if sides:
                flush[a].add(sides[0])
                flush[b].add(sides[1])
                pairs.append((a, b, sides[0]))
                continue
            (alo, ahi), (blo, bhi) = boxes[a], boxes[b]
            lo, hi = np.maximum(alo[:2], blo[:2]), np.minimum(ahi[:2], bhi[:2])
            if np.any(lo >= hi):
                continue
            below, above = (a, b) if ahi[2] == blo[2] else (b, a) if bhi[2] == alo[2] else (None, None)
            if below is None:
                continue
            shared = np.mgrid[lo[0]:hi[0], lo[1]:hi[1]].reshape(2, -1).T
            no_studs[below].update(map(tuple, (shared - boxes[below][0][:2]).tolist()))
            solid_under[above].update(map(tuple, (shared - boxes[above][0][:2]).tolist()))
            pairs.append((below, above, "top"))
    extents = []
    for (lo, hi), f in zip(boxes, flush):
        x0, x1 = origin + np.array(lo) * cell_mm, origin + np.array(hi) * cell_mm
        for axis, name in ((0, "x"), (1, "y")):
            x0[axis] += 0.0 if f"side-{name}" in f else geometry.play
            x1[axis] -= 0.0 if f"side+{name}" in f else geometry.play
        extents.append((x0, x1))
    joints = [{} for _ in range(n)]
    for a, b, side in pairs:
        (alo, ahi), (blo, bhi) = extents[a], extents[b]
        lo, hi = np.maximum(alo, blo), np.minimum(ahi, bhi)
        axis = 2 if side == "top" else "xy".index(side[-1])
        at = ahi[axis] if side == "top" or side[-2] == "+" else alo[axis]
        lo[axis] = hi[axis] = at
        rect = (tuple(float(v) for v in lo), tuple(float(v) for v in hi))
        joints[a][f"{a}|{b}"] = joints[b][f"{a}|{b}"] = rect
    return [BrickContacts(tuple(sorted(f)), frozenset(ns), frozenset(su), j)
            for f, ns, su, j in zip(flush, no_studs, solid_under, joints)]


def merged_solid(cells, sizes, geometry: BrickGeometry = BrickGeometry(),
                 grid_origin=(0.0, 0.0, 0.0), names=None, method: str = "auto") -> MergedSolid:
    """The bricks at grid ``cells`` with ``sizes`` merged into one solid, without a Boolean union.

    The paper's merge ("Merging and splitting"): every brick is built by
    :func:`brick_solid` with the contacts of :func:`part_contacts` (flush
    sides, no studs where a brick of the group stands on it, a solid
    underside where it stands on one, and its faces split along every
    joint rectangle), so that wherever two bricks touch, each has exactly
    one face there and the two coincide.  Those joint faces are dropped, the
    faces left (each brick's shell, open where its joints were) are sewn
    into one closed shell (``BRepBuilderAPI_Sewing``) and made a solid, and
    ``ShapeUpgrade_UnifySameDomain`` merges the coplanar pieces of the outer
    faces.  So the result has no internal face and its volume is that of
    the union of the bricks built this way.  Splitting is the same call on
    fewer bricks: the joint faces of the split come back as outer faces.

    ``method``: ``"auto"`` (face removal; a Boolean fuse of the same brick
    solids when face removal does not give one valid closed solid),
    ``"remove"`` (face removal only: RuntimeError when it fails) or
    ``"fuse"``.  ``names`` label the bricks in the tags (default their
    index).  Raises ValueError for an unknown method, malformed cells or
    sizes and for bricks that overlap or do not form one face-to-face
    connected group.
    """
    if method not in ("auto", "remove", "fuse"):
        raise ValueError(f"merge method {method!r} must be auto, remove or fuse")
    try:
        cells, sizes = [tuple(int(v) for v in c) for c in cells], [tuple(int(v) for v in s) for s in sizes]
    except (TypeError, ValueError):
        raise ValueError("merged_solid needs cells and sizes as whole-number triples") from None
    names = [str(v) for v in (names if names is not None else range(len(cells)))]
    if not cells or len(cells) != len(sizes) or len(names) != len(cells):
        raise ValueError("merged_solid needs as many cells, sizes and names as bricks, at least one")
    _check_group(cells, sizes)
    contacts = part_contacts(cells, sizes, geometry, grid_origin)
    origins = [tuple(np.asarray(grid_origin, float) + np.array(cell) * [geometry.pitch, geometry.pitch,
                                                                        geometry.plate_height])
               for cell in cells]

    def build(joints: bool) -> tuple[list[BrickSolid], list]:
        bricks = [brick_solid(*size, geometry, origin, c.flush, c.no_studs, c.solid_under,
                              c.joints if joints else None)
                  for size, origin, c in zip(sizes, origins, contacts)]
        return bricks, [(face, f"{name}:{tag}") for name, b in zip(names, bricks)
                        for face, tag in zip(face_list(b.shape), b.tag_of())]

    if len(cells) == 1:
        bricks, tagged = build(False)
        return MergedSolid(bricks[0].shape.wrapped, tagged, "single brick")
    reason = None
    if method != "fuse":
        try:
            bricks, tagged = build(True)
            shape, carried, removed = _sew(bricks, tagged)
            return MergedSolid(shape, carried, "face removal", removed)
        except (_MergeFailed, _JointNotAFace) as exc:
            if method == "remove":
                raise RuntimeError(f"face removal failed: {exc}") from None
            reason = str(exc)
    bricks, tagged = build(False)
    shapes = [b.shape.wrapped for b in bricks]
    fused = _only_solid(_boolean(BRepAlgoAPI_Fuse(), shapes[0], shapes[1:], tagged))
    shape, carried = _unified(fused, tagged)
    return MergedSolid(_only_solid(shape), carried,
                       "fuse" if reason is None else f"fuse (face removal failed: {reason})")


class _MergeFailed(Exception):
    """Face removal and sewing did not give one valid closed solid; the message says why."""


class _JointNotAFace(ValueError):
    """A joint rectangle is not exactly one face of the brick built with it."""


def _check_group(cells, sizes) -> None:
    """ValueError unless the bricks neither overlap nor fall apart into several groups."""
    n = len(cells)
    boxes = [_cell_boxes(c, s, c, s)[:2] for c, s in zip(cells, sizes)]
    if any(len(c) != 3 for c in cells) or any(min(s) < 1 for s in sizes):
        raise ValueError("brick cells and sizes must be (i, j, k) and positive (x, y, z)")
    lo, hi = np.array([b[0] for b in boxes]), np.array([b[1] for b in boxes])
    gap = np.minimum(hi[:, None], hi[None]) - np.maximum(lo[:, None], lo[None])  # (n, n, 3)
    overlap = np.all(gap > 0, axis=2) & ~np.eye(n, dtype=bool)
    if overlap.any():
        a, b = np.argwhere(overlap)[0]
        raise ValueError(f"bricks {a} and {b} overlap")
    touch = (np.count_nonzero(gap == 0, axis=2) == 1) & np.all(gap >= 0, axis=2)
    if connected_components(csr_matrix(touch), directed=False)[0] != 1:
        raise ValueError("the bricks to merge do not touch face to face as one group")


def _sew(bricks: list[BrickSolid], tagged: list) -> tuple[TopoDS_Shape, list, int]:
    """Drop the coincident joint faces of ``bricks``, sew the rest into one solid, unify.

    Returns the solid, ``tagged`` carried onto its faces, and the number of
    faces dropped; raises _MergeFailed when a joint is not two exactly
    coincident faces or the sewn result is not one valid closed solid."""
    drop = TopTools_IndexedMapOfShape()
    seen: dict[str, np.ndarray] = {}
    for b in bricks:
        faces = face_list(b.shape)
        for name, (i,) in b.joints.items():
            box = _face_box(faces[i])
            if name not in seen:
                seen[name] = box
            elif not np.all(np.abs(seen.pop(name) - box) < JOINT_TOL_MM):
                raise _MergeFailed(f"the faces of joint {name} do not coincide")
            drop.Add(faces[i])
    if seen:
        raise _MergeFailed(f"joint(s) {sorted(seen)[:3]} have a face on one side only")
    builder = BRep_Builder()
    sewing = BRepBuilderAPI_Sewing(SEW_TOL_MM, True, True, True, False)
    for b in bricks:
        shell = TopoDS_Shell()
        builder.MakeShell(shell)
        for face in face_list(b.shape):
            if not drop.Contains(face):
                builder.Add(shell, face)
        sewing.Add(shell)
    try:
        sewing.Perform()
        if sewing.NbFreeEdges() or sewing.NbMultipleEdges():
            raise _MergeFailed(f"sewing left {sewing.NbFreeEdges()} free and "
                               f"{sewing.NbMultipleEdges()} multiple edges")
        shells = sub_shapes(sewing.SewedShape(), TopAbs_SHELL)
        if len(shells) != 1 or not BRep_Tool.IsClosed_s(shells[0]):
            raise _MergeFailed(f"sewing gave {len(shells)} shell(s), not one closed shell")
        solid = BRepBuilderAPI_MakeSolid(TopoDS.Shell_s(shells[0])).Solid()
        if not BRepLib.OrientClosedSolid_s(solid):
            raise _MergeFailed("the sewn shell does not bound a solid")
        carried = [(_sewn(sewing, face), tag) for face, tag in tagged if not drop.Contains(face)]
        shape, carried = _unified(solid, carried)
    except Standard_Failure as exc:
        raise _MergeFailed(f"OpenCascade: {exc}") from None
    solids = sub_shapes(shape, TopAbs_SOLID)
    if len(solids) != 1 or not BRepCheck_Analyzer(solids[0]).IsValid():
        raise _MergeFailed("the sewn solid is not valid")
    return TopoDS.Solid_s(solids[0]), carried, drop.Extent()


def _sewn(sewing: BRepBuilderAPI_Sewing, face: TopoDS_Face) -> TopoDS_Face:
    """The face of the sewn shape that ``face`` (of a sewn shell) became."""
    if sewing.IsModifiedSubShape(face):
        return TopoDS.Face_s(sewing.ModifiedSubShape(face))
    if sewing.IsModified(face):
        return TopoDS.Face_s(sewing.Modified(face))
    return face


def _unified(shape: TopoDS_Shape, tagged: list) -> tuple[TopoDS_Shape, list]:
    """``shape`` with coplanar / co-cylindrical neighbouring faces merged, ``tagged`` carried."""
    unify = ShapeUpgrade_UnifySameDomain(shape, True, True, False)
    unify.Build()
    history = unify.History()
    carried = []
    for face, tag in tagged:
        if history.IsRemoved(face):
            continue
        new = list(history.Modified(face))
        carried += [(TopoDS.Face_s(m), tag) for m in new] if new else [(face, tag)]
    return unify.Shape(), carried


def sub_shapes(shape: TopoDS_Shape, kind) -> list:
    """The sub-shapes of ``shape`` of the OCC type ``kind`` (TopAbs_SOLID, ...), in explorer order."""
    out = []
    explorer = TopExp_Explorer(shape, kind)
    while explorer.More():
        out.append(explorer.Current())
        explorer.Next()
    return out
