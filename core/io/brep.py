"""B-rep model files (STEP, BREP, FreeCAD documents) read as OpenCascade solids and
tessellated, in the units and pose the model is loaded in.
"""

from __future__ import annotations

import contextlib
import io
import os
import sys
import zipfile
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh

from core.errors import InputError
from core.io import output_dir

#: Angular deflection (rad) of the B-rep tessellation.
ANGULAR_DEFLECTION = 0.3
#: FreeCAD link properties through which one object consumes another's shape
#: (a Body its features and Tip, a Boolean its inputs, a pattern its originals).
_CONSUMING = frozenset({"Group", "Tip", "BaseFeature", "Base", "Tool", "Shapes",
                        "Links", "Objects", "Source", "Originals"})


def first_line(exc: BaseException) -> str:
    """A short one-line description of an exception from a reader library."""
    text = str(exc).strip().splitlines()
    return (text[0][:160] if text else type(exc).__name__)


def _solids(shape, name: str, what: str):
    """The solids of ``shape``: the solid itself if one, else a compound of them."""
    from OCP.BRep import BRep_Builder
    from OCP.TopAbs import TopAbs_SOLID
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS_Compound

    found = []
    explorer = TopExp_Explorer(shape, TopAbs_SOLID)
    while explorer.More():
        found.append(explorer.Current())
        explorer.Next()
    if not found:
        raise InputError(f"{name}: {what} contains no solid")
    if len(found) == 1:
        return found[0]
    compound = TopoDS_Compound()
    builder = BRep_Builder()
    builder.MakeCompound(compound)
    for solid in found:
        builder.Add(compound, solid)
    return compound


@contextlib.contextmanager
def _quiet_stdout():
    """Standard output (the file descriptor: OpenCascade's C++ prints there) sent to the null
    device for the ``with`` block: the STEP parser prints its complaints about a broken
    file (``**** ERR StepFile ...``), which the one line of the InputError says instead."""
    try:
        sys.stdout.flush()
        saved = os.dup(1)
    except (OSError, ValueError, AttributeError):
        yield
        return
    try:
        null = os.open(os.devnull, os.O_WRONLY)
        os.dup2(null, 1)
        os.close(null)
        yield
    finally:
        os.dup2(saved, 1)
        os.close(saved)


def read_step(file: Path):
    """The solid(s) of a STEP file as an OCP shape in mm."""
    from OCP.IFSelect import IFSelect_RetDone
    from OCP.STEPControl import STEPControl_Reader

    try:
        reader = STEPControl_Reader()
        with _quiet_stdout():
            status = reader.ReadFile(str(file))
        if status != IFSelect_RetDone:
            raise InputError(f"{file.name}: not a valid STEP file (the STEP reader gave up)")
        reader.TransferRoots()
        shape = reader.OneShape()
    except InputError:
        raise
    except Exception as exc:
        raise InputError(f"{file.name}: cannot be read as STEP: {first_line(exc)}") from None
    if shape is None or shape.IsNull():
        raise InputError(f"{file.name}: the STEP file contains no shape")
    return _solids(shape, file.name, "the STEP file")


def read_brep(file: Path):
    """The solid(s) of an OCC BREP text file as an OCP shape in mm."""
    from OCP.BRep import BRep_Builder
    from OCP.BRepTools import BRepTools
    from OCP.TopoDS import TopoDS_Shape

    shape = TopoDS_Shape()
    try:
        read = BRepTools.Read_s(shape, str(file), BRep_Builder())
    except Exception as exc:
        raise InputError(f"{file.name}: cannot be read as BREP: {first_line(exc)}") from None
    if not read or shape.IsNull():
        raise InputError(f"{file.name}: not a valid BREP file (the BREP reader gave up)")
    return _solids(shape, file.name, "the BREP file")


def scaled_turned_shape(shape, factor: float, name: str, turn: np.ndarray | None = None):
    """``shape`` scaled by ``factor`` and turned by the rotation ``turn`` (3 x 3) about the
    origin (the shape itself if neither changes it)."""
    turn = np.eye(3) if turn is None else np.asarray(turn, dtype=float)
    if factor == 1.0 and np.array_equal(turn, np.eye(3)):
        return shape
    from OCP.BRepBuilderAPI import BRepBuilderAPI_Transform
    from OCP.gp import gp_Trsf

    trsf = gp_Trsf()
    m = factor * turn
    trsf.SetValues(*m[0], 0.0, *m[1], 0.0, *m[2], 0.0)
    try:
        return BRepBuilderAPI_Transform(shape, trsf, True).Shape()
    except Exception as exc:
        raise InputError(f"{name}: the solid cannot be scaled by {factor:g}: "
                         f"{first_line(exc)}") from None


def translated_shape(shape, offset, name: str):
    """``shape`` moved by the vector ``offset`` (mm)."""
    from OCP.BRepBuilderAPI import BRepBuilderAPI_Transform
    from OCP.gp import gp_Trsf, gp_Vec

    trsf = gp_Trsf()
    trsf.SetTranslation(gp_Vec(*(float(v) for v in offset)))
    try:
        return BRepBuilderAPI_Transform(shape, trsf, True).Shape()
    except Exception as exc:
        raise InputError(f"{name}: the solid cannot be moved to the origin: "
                         f"{first_line(exc)}") from None


def tessellate(shape, tolerance_mm: float, name: str) -> tuple[np.ndarray, np.ndarray]:
    """Triangles of ``shape`` meshed at linear deflection ``tolerance_mm``.

    Meshes with ``BRepMesh_IncrementalMesh`` (in parallel) and lets OCP's
    STL writer collect the triangles of all faces, correctly oriented, in
    one pass in C++; the STL is read back with trimesh.
    """
    from OCP.BRepMesh import BRepMesh_IncrementalMesh
    from OCP.BRepTools import BRepTools
    from OCP.StlAPI import StlAPI_Writer

    failed = InputError(f"{name}: the solid could not be tessellated")
    writer = StlAPI_Writer()
    writer.ASCIIMode = False
    with output_dir.scratch("stl") as tmp:
        out = os.path.join(tmp, "tessellation.stl")
        try:
            BRepTools.Clean_s(shape)
            mesher = BRepMesh_IncrementalMesh(shape, tolerance_mm, False, ANGULAR_DEFLECTION, True)
            if not mesher.IsDone() or not writer.Write(shape, out) or os.path.getsize(out) <= 84:
                raise failed
        except InputError:
            raise
        except Exception:
            raise failed from None
        mesh = trimesh.load(out, file_type="stl", process=False)
    return np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces, dtype=np.int64)


@dataclass
class _FcObject:
    """What :func:`read_fcstd` needs to know of one FreeCAD document object."""

    name: str
    type: str
    shape_file: str | None
    visible: bool | None
    links: dict[str, list[str]]
    placement: tuple[float, ...] | None


def _xml(data: bytes, name: str, member: str):
    """Parsed XML root of a document member, with entities and network off."""
    from lxml import etree

    parser = etree.XMLParser(resolve_entities=False, no_network=True, huge_tree=True)
    try:
        return etree.fromstring(data, parser)
    except etree.XMLSyntaxError as exc:
        raise InputError(f"{name}: {member} is not valid XML: {first_line(exc)}") from None


def _bool_value(prop) -> bool | None:
    """Value of an ``App::PropertyBool`` element, None if absent."""
    if prop is None:
        return None
    b = prop.find("Bool")
    return None if b is None else b.get("value", "").lower() == "true"


def _fc_objects(doc, gui) -> dict[str, _FcObject]:
    """The objects of a Document.xml root, with visibility from GuiDocument.xml."""
    gui_visible: dict[str, bool] = {}
    if gui is not None:
        for vp in gui.iter("ViewProvider"):
            for prop in vp.iter("Property"):
                if prop.get("name") == "Visibility" and _bool_value(prop) is not None:
                    gui_visible[vp.get("name")] = _bool_value(prop)
    types = {o.get("name"): o.get("type", "") for o in doc.iter("Object") if o.get("type")}
    objects: dict[str, _FcObject] = {}
    data = doc.find("ObjectData")
    for od in ([] if data is None else data.findall("Object")):
        name = od.get("name")
        props = {p.get("name"): p for p in od.findall("Properties/Property")}
        shape_file = None
        shape = props.get("Shape")
        if shape is not None:
            part = shape.find("Part")
            shape_file = part.get("file") if part is not None else None
        links = {}
        for key in _CONSUMING:
            prop = props.get(key)
            if prop is not None:
                links[key] = [el.get("value") or el.get("obj") for el in prop.iter("Link", "LinkSub")
                              if el.get("value") or el.get("obj")]
        placement = None
        pl = props.get("Placement")
        if pl is not None and pl.find("PropertyPlacement") is not None:
            el = pl.find("PropertyPlacement")
            try:
                placement = tuple(float(el.get(k, "0")) for k in
                                  ("Px", "Py", "Pz", "Q0", "Q1", "Q2", "Q3"))
            except ValueError:
                placement = None
        visible = gui_visible.get(name, _bool_value(props.get("Visibility")))
        objects[name] = _FcObject(name, types.get(name, ""), shape_file or None, visible,
                                  links, placement)
    return objects


def _reachable(objects: dict[str, _FcObject], start: str) -> set[str]:
    """Names of the objects whose shapes ``start`` consumes, transitively."""
    seen: set[str] = set()
    todo = [n for names in objects[start].links.values() for n in names]
    while todo:
        n = todo.pop()
        if n in seen or n not in objects:
            continue
        seen.add(n)
        todo.extend(m for names in objects[n].links.values() for m in names)
    return seen


def _select_fc_objects(objects: dict[str, _FcObject], solid: set[str],
                       warnings: list[str], name: str) -> list[str]:
    """Names of the objects that make up the part, without double counting.

    Takes the shown objects with solids (an object inside a hidden group
    counts as hidden); if none is shown, all objects with solids.  Drops
    every object whose shape another taken object already contains (a
    Body's features including its Tip, a Boolean's inputs).
    """
    parent = {child: o.name for o in objects.values() for child in o.links.get("Group", [])}

    def shown(n: str) -> bool:
        seen = set()
        while n is not None and n not in seen:
            seen.add(n)
            if objects[n].visible is False:
                return False
            n = parent.get(n) if parent.get(n) in objects else None
        return True

    chosen = [n for n in objects if n in solid and shown(n)]
    if not chosen:
        chosen = [n for n in objects if n in solid]
        if chosen:
            warnings.append(f"{name}: no solid is shown in the document; "
                            f"took every object with a solid")
    reach = {n: _reachable(objects, n) for n in chosen}
    return [n for n in chosen
            if not any(n in reach[m] and m not in reach[n] for m in chosen if m != n)]


def _placed(shape, placements: list[tuple[float, ...]]):
    """``shape`` moved by the App::Part placements around it (innermost first)."""
    from OCP.gp import gp_Quaternion, gp_Trsf, gp_Vec
    from OCP.TopLoc import TopLoc_Location

    for px, py, pz, qx, qy, qz, qw in placements:
        if (px, py, pz, qx, qy, qz) == (0.0,) * 6:
            continue
        trsf = gp_Trsf()
        trsf.SetRotation(gp_Quaternion(qx, qy, qz, qw))
        trsf.SetTranslationPart(gp_Vec(px, py, pz))
        shape = shape.Moved(TopLoc_Location(trsf))
    return shape


def read_fcstd(file: Path, warnings: list[str]):
    """The solid(s) a FreeCAD document shows, as one OCP shape in mm, read without FreeCAD."""
    from OCP.BinTools import BinTools
    from OCP.BRep import BRep_Builder
    from OCP.BRepTools import BRepTools
    from OCP.TopoDS import TopoDS_Compound, TopoDS_Shape

    try:
        with zipfile.ZipFile(file) as archive:
            members = set(archive.namelist())
            if "Document.xml" not in members:
                raise InputError(f"{file.name}: not a FreeCAD document (no Document.xml inside)")
            doc = _xml(archive.read("Document.xml"), file.name, "Document.xml")
            gui = (_xml(archive.read("GuiDocument.xml"), file.name, "GuiDocument.xml")
                   if "GuiDocument.xml" in members else None)
            objects = _fc_objects(doc, gui)
            shapes = {}
            for obj in objects.values():
                if obj.shape_file and obj.shape_file in members:
                    shapes[obj.name] = archive.read(obj.shape_file)
    except InputError:
        raise
    except (zipfile.BadZipFile, zipfile.LargeZipFile, OSError, EOFError, ValueError,
            NotImplementedError, zlib.error) as exc:
        raise InputError(f"{file.name}: cannot be read as a FreeCAD document: "
                         f"{first_line(exc)}") from None

    def read_shape(obj: _FcObject):
        shape = TopoDS_Shape()
        try:
            if obj.shape_file.lower().endswith(".bin"):
                BinTools.Read_s(shape, io.BytesIO(shapes[obj.name]))
            else:
                BRepTools.Read_s(shape, io.BytesIO(shapes[obj.name]), BRep_Builder())
        except Exception:
            return None
        return None if shape.IsNull() else shape

    solids = {}
    for n in shapes:
        shape = read_shape(objects[n])
        if shape is not None:
            try:
                solids[n] = _solids(shape, file.name, n)
            except InputError:
                continue
    if not solids:
        raise InputError(f"{file.name}: the FreeCAD document contains no solid")
    chosen = _select_fc_objects(objects, set(solids), warnings, file.name)
    parent = {child: o.name for o in objects.values() for child in o.links.get("Group", [])}
    compound = TopoDS_Compound()
    builder = BRep_Builder()
    builder.MakeCompound(compound)
    for n in chosen:
        containers, p = [], parent.get(n)
        while p in objects and len(containers) < len(objects):
            if objects[p].type == "App::Part" and objects[p].placement is not None:
                containers.append(objects[p].placement)
            p = parent.get(p)
        builder.Add(compound, _placed(solids[n], containers))
    return _solids(compound, file.name, "the FreeCAD document")
