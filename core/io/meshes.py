"""Load any supported model file as one repaired triangle mesh in millimetres.

:func:`load_model` reads STL, OBJ, PLY and 3MF with trimesh, STEP and OCC
BREP (``.brep``, as FreeCAD's ``Shape.exportBrep`` writes it) with
OpenCascade (OCP) and FreeCAD documents (``.FCStd``) without FreeCAD, from the
BREP files inside the zip.  It applies ``units`` and ``scale``, refuses bad
input with an :class:`~core.errors.InputError`, repairs what can be repaired
and says what it did in :attr:`LoadedModel.repaired`.

Repairs, in this order: merge duplicate vertices; drop degenerate and
duplicate faces; drop face-connected pieces that cannot enclose volume;
make the winding consistent; fill small (3- and 4-edge) holes; turn
inside-out closed pieces outward.
"""

from __future__ import annotations

import contextlib
import io
import math
import os
import re
import stat
import sys
import zipfile
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import trimesh
from scipy import sparse
from scipy.sparse.csgraph import connected_components

from core.errors import InputError, shown_path
from core.io import output_dir
from core.model import CELL_MM, UNITS, UP_AXES

#: Length of one file unit in mm, for ``load_model(units=...)``.

#: File suffix (lower case) -> format name.
FORMATS = {".stl": "stl", ".obj": "obj", ".ply": "ply", ".3mf": "3mf",
           ".step": "step", ".stp": "step", ".brep": "brep", ".fcstd": "fcstd"}

#: Angular deflection (rad) of the B-rep tessellation.
ANGULAR_DEFLECTION = 0.3

#: A part larger than this (mm) is probably in a smaller unit than assumed.
LARGEST_PLAUSIBLE_MM = 2000.0

#: Coordinates beyond this (mm) are refused: no part is that large, and
#: vertex merging works on integers at 1e-8 mm.
ABSURD_MM = 1.0e9

#: Coarsest step (mm) a model's coordinates may have in a 32-bit float; a model reaching
#: further from the origin (131 m and more) is moved to it (:func:`load_model`).
PRECISE_MM = 0.01

#: A piece of surface whose corners spread less than this across (mm, standard deviation)
#: and less than a millionth of the model's size is flat: it encloses no volume and is
#: dropped (:func:`repair`).
FLAT_MM = 1e-3

#: FreeCAD link properties through which one object consumes another's shape
#: (a Body its features and Tip, a Boolean its inputs, a pattern its originals).
_CONSUMING = frozenset({"Group", "Tip", "BaseFeature", "Base", "Tool", "Shapes",
                        "Links", "Objects", "Source", "Originals"})

_FORMAT_NAMES = {"stl": "STL", "obj": "OBJ", "ply": "PLY", "3mf": "3MF",
                 "step": "STEP", "brep": "BREP", "fcstd": "FreeCAD document"}


@dataclass
class LoadedModel:
    """A model as the later stages see it.

    ``mesh`` is the repaired triangle mesh in mm (after units and scale);
    ``triangles`` the triangle count before repair (for B-rep formats: of
    the tessellation); ``watertight`` says that after repair every edge is
    shared by exactly two consistently wound faces; ``repaired`` has one
    line per repair done; ``warnings`` one line per doubt about the input;
    ``brep`` is the OCP ``TopoDS_Shape`` of the solid(s) in mm for STEP, BREP and
    FCStd input, ``None`` for meshes.  ``offset_mm`` is the translation the loader
    applied to bring a model that lies too far from the origin for 0.01 mm in 32-bit
    floats back to it (:func:`load_model`; zeros when it did not move it).
    """

    mesh: trimesh.Trimesh
    path: str
    format: str
    triangles: int
    watertight: bool
    repaired: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    brep: object | None = None
    offset_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)


def load_model(path: str | os.PathLike, units: str = "mm", scale: float = 1.0,
               tolerance_mm: float = 0.05, recentre: bool = True, up: str = "z") -> LoadedModel:
    """Load the model at ``path`` and repair it.

    Coordinates are multiplied by ``UNITS[units] * scale`` and turned about the
    origin by ``UP_AXES[up]``, so that the file's axis ``up`` points along +z.  B-rep input
    (STEP, BREP, FCStd) is tessellated at linear deflection ``tolerance_mm`` (in
    mm, after scaling).  Raises :class:`InputError` with a one-line message
    for a missing, empty, unreadable or unsupported file, bad units or
    scale, non-finite coordinates, a file without triangles or solids, or a
    mesh of which nothing encloses volume.  Never raises another exception
    for a bad file; a ``tolerance_mm`` that is not a positive number (the
    caller's) is a ValueError.

    A surface that is not closed after repair (open, non-manifold or
    one-sided) is said in one line of ``warnings`` (:func:`surface_warning`).
    With ``recentre``, a model whose coordinates reach where a 32-bit float
    (STL, the printed parts' files) is coarser than :data:`PRECISE_MM` is
    moved to the origin (x and y centred, lowest point at z = 0): ``repaired``
    says so and ``offset_mm`` holds the move (region files are loaded without
    it and moved with their model).
    """
    factor = _unit_factor(units, scale)
    if up not in UP_AXES:
        raise InputError(f"unknown up axis {up!r}: use one of {', '.join(UP_AXES)}")
    turn = np.array(UP_AXES[up], dtype=float)
    if not (isinstance(tolerance_mm, (int, float)) and math.isfinite(tolerance_mm)
            and tolerance_mm > 0):
        raise ValueError(f"tolerance_mm must be a positive number of mm, not {tolerance_mm!r}")
    file = _check_file(path)
    fmt = FORMATS[file.suffix.lower()]
    warnings: list[str] = []
    read: list[str] = []
    brep = None
    if fmt in ("step", "brep", "fcstd"):
        readers = {"step": _read_step, "brep": _read_brep}
        shape = readers[fmt](file) if fmt in readers else _read_fcstd(file, warnings)
        brep = _scaled_turned_shape(shape, factor, file.name, turn)
        vertices, faces = _tessellate(brep, tolerance_mm, file.name)
    else:
        vertices, faces = _read_mesh(file, fmt, read)
        with np.errstate(over="ignore", invalid="ignore"):    # non-finite: _check_arrays says so
            vertices = (vertices * factor) @ turn.T
    _check_arrays(vertices, faces, file.name)
    triangles = len(faces)
    mesh, repaired = repair(vertices, faces, file.name, report_merges=fmt in ("obj", "ply", "3mf"))
    repaired = read + repaired
    warnings.extend(size_warnings(mesh.extents, units))
    watertight = bool(mesh.is_watertight and mesh.is_winding_consistent)
    if not watertight:
        warnings.extend(surface_warning(mesh))
    offset = np.zeros(3)
    reach = float(np.abs(mesh.bounds).max())
    if recentre and np.spacing(np.float32(reach)) > PRECISE_MM:
        lo, hi = mesh.bounds
        offset = 0.0 - np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]])
        mesh = mesh.copy()
        mesh.apply_translation(offset)
        brep = None if brep is None else _translated_shape(brep, offset, file.name)
        repaired.append(f"moved by {', '.join(f'{v:.6g}' for v in offset)} mm to the origin: its "
                        f"coordinates reach {reach:.6g} mm, where a 32-bit float (STL, the printed "
                        f"parts' files) holds only {float(np.spacing(np.float32(reach))):g} mm steps")
    return LoadedModel(mesh=mesh, path=str(path), format=fmt, triangles=triangles,
                       watertight=watertight, repaired=repaired, warnings=warnings, brep=brep,
                       offset_mm=tuple(float(v) for v in offset))


def _unit_factor(units: str, scale: float) -> float:
    """mm per file unit for ``units`` and ``scale``; InputError if either is bad."""
    if units not in UNITS:
        raise InputError(f"unknown units {units!r}: use one of {', '.join(UNITS)}")
    try:
        value = float(scale)
    except (TypeError, ValueError):
        raise InputError(f"scale must be a number, not {scale!r}") from None
    if not math.isfinite(value) or value <= 0:
        raise InputError(f"scale must be a finite number above 0, not {scale!r}")
    return UNITS[units] * value


#: The units a 3MF model may name (its ``<model unit=...>``; trimesh's own default, when
#: none is named, is "millimeters").
THREEMF_UNITS = ("micron", "millimeter", "centimeter", "inch", "foot", "meter")


def regular_file(file: Path, what: str, read_as: str) -> os.stat_result:
    """The status of ``file`` when it is a regular file; InputError (one line) when it is
    missing, on a path the user may not search, a folder (not ``what``), or a named pipe,
    socket or device (only files are read as ``read_as``): such a file is refused before
    it is opened, since reading a pipe waits for a writer for ever."""
    try:
        st = os.stat(file)
    except FileNotFoundError:
        raise InputError(f"{shown_path(file)}: no such file") from None
    except PermissionError:
        raise InputError(f"{shown_path(file)}: permission denied: a folder on its path may not be "
                         f"searched by you") from None
    except OSError as exc:
        raise InputError(f"{shown_path(file)}: cannot be read ({exc.strerror or exc})") from None
    if stat.S_ISDIR(st.st_mode):
        raise InputError(f"{shown_path(file)}: is a directory, not a {what}")
    if not stat.S_ISREG(st.st_mode):
        raise InputError(f"{shown_path(file)}: is {_special_kind(st.st_mode)}, not a regular file: "
                         f"only files are read as {read_as}")
    return st


def _check_file(path: str | os.PathLike) -> Path:
    """The path as a Path if it names a non-empty, readable regular file of a known format.

    Only regular files are read: a named pipe, a socket or a device is refused
    before it is opened (reading a pipe would wait for a writer for ever), and
    the file is opened without blocking to find out whether it can be read.
    """
    file = Path(path)
    st = regular_file(file, "model file", "models and regions")
    if file.suffix.lower() not in FORMATS:
        known = ", ".join(sorted({s.lstrip(".").upper() for s in FORMATS}))
        raise InputError(f"{shown_path(file.name)}: unknown file type {file.suffix or '(none)'!r}: "
                         f"use one of {known}")
    try:
        fd = os.open(file, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
        try:
            opened = os.fstat(fd)
        finally:
            os.close(fd)
    except PermissionError:
        raise InputError(f"{shown_path(file)}: permission denied: you may not read this file "
                         f"(mode {stat.filemode(st.st_mode)}, owner uid {st.st_uid})") from None
    except OSError as exc:
        raise InputError(f"{shown_path(file)}: cannot be read ({exc.strerror or exc})") from None
    if not stat.S_ISREG(opened.st_mode):
        raise InputError(f"{shown_path(file)}: is {_special_kind(opened.st_mode)}, not a regular file")
    if opened.st_size == 0:
        raise InputError(f"{shown_path(file.name)}: the file is empty (0 bytes)")
    return file


def _special_kind(mode: int) -> str:
    """What a file of ``mode`` that is neither a folder nor a regular file is, in words."""
    return ("a named pipe (FIFO)" if stat.S_ISFIFO(mode) else "a socket" if stat.S_ISSOCK(mode)
            else "a character device" if stat.S_ISCHR(mode) else "a block device"
            if stat.S_ISBLK(mode) else "a special file")


def _first_line(exc: BaseException) -> str:
    """A short one-line description of an exception from a reader library."""
    text = str(exc).strip().splitlines()
    return (text[0][:160] if text else type(exc).__name__)


#: An OBJ face corner with vertex index 0 (OBJ counts from 1): a face line with a 0 token.
_OBJ_ZERO = re.compile(rb"(?m)^[ \t]*f[ \t][^\r\n]*?(?<![\w.+-])0(?=[/ \t\r\n]|$)")
_OBJ_FACE = re.compile(rb"(?m)^([ \t]*f[ \t])([^\r\n#]*)")
_OBJ_NUMBER = re.compile(rb"-?\d+")


def _obj_source(file: Path, repaired: list[str]):
    """What trimesh reads of the OBJ ``file``: the file itself, or, when its faces count
    vertices from 0 (the format counts from 1; some exporters get it wrong), its text with
    every face index raised by one (said in ``repaired``).  InputError for a file that
    mixes index 0 with relative (negative) indices or refers past its vertices."""
    data = file.read_bytes()
    if not _OBJ_ZERO.search(data):
        return str(file)
    numbers = np.array([int(n) for line in _OBJ_FACE.findall(data)
                        for n in _OBJ_NUMBER.findall(line[1])], dtype=np.int64)
    vertices = len(re.findall(rb"(?m)^[ \t]*v[ \t]", data))
    if numbers.min() < 0 or numbers.max() >= max(vertices, 1):
        raise InputError(f"{file.name}: malformed OBJ: a face refers to vertex 0, which does not "
                         f"exist (OBJ counts vertices from 1), and the indices are not 0-based "
                         f"either")
    fixed = _OBJ_FACE.sub(lambda m: m[1] + _OBJ_NUMBER.sub(lambda n: b"%d" % (int(n[0]) + 1), m[2]),
                          data)
    repaired.append("read the faces as counting vertices from 0: the file refers to vertex 0, "
                    "which OBJ does not have (it counts from 1)")
    return io.BytesIO(fixed)


def _read_mesh(file: Path, fmt: str, repaired: list[str] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and faces of every mesh in a trimesh-readable file, transforms applied
    (an OBJ with 0-based faces read as such, :func:`_obj_source`, said in ``repaired``)."""
    kwargs = {"skip_materials": True} if fmt == "obj" else {}
    source = _obj_source(file, [] if repaired is None else repaired) if fmt == "obj" else str(file)
    try:
        loaded = trimesh.load(source, file_type=fmt, process=False, **kwargs)
        geometries = loaded.dump() if isinstance(loaded, trimesh.Scene) else [loaded]
    except ImportError:
        raise InputError(f"{file.name}: not a valid {_FORMAT_NAMES[fmt]} file "
                         f"(binary content that is not {_FORMAT_NAMES[fmt]} data)") from None
    except Exception as exc:
        raise InputError(f"{file.name}: cannot be read as {_FORMAT_NAMES[fmt]}: "
                         f"{_first_line(exc)}") from None
    unit = (getattr(loaded, "metadata", None) or {}).get("units") if fmt == "3mf" else None
    if unit is not None and str(unit) not in THREEMF_UNITS and str(unit) != "millimeters":
        raise InputError(f"{file.name}: the 3MF model's unit {str(unit)[:40]!r} is not a 3MF "
                         f"unit (the format allows {', '.join(THREEMF_UNITS)})")
    meshes = [g for g in geometries
              if isinstance(g, trimesh.Trimesh) and len(g.faces) and len(g.vertices)]
    if not meshes:
        raise InputError(f"{file.name}: no triangles found in the file")
    vertices = [np.asarray(m.vertices, dtype=np.float64) for m in meshes]
    offsets = np.cumsum([0] + [len(v) for v in vertices[:-1]])
    faces = [np.asarray(m.faces, dtype=np.int64) + o for m, o in zip(meshes, offsets)]
    return np.concatenate(vertices), np.concatenate(faces)


def _check_arrays(vertices: np.ndarray, faces: np.ndarray, name: str) -> None:
    """InputError unless the faces are triangles on valid, finite vertices."""
    if faces.ndim != 2 or faces.shape[1] != 3 or len(faces) == 0:
        raise InputError(f"{name}: no triangles found in the file")
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise InputError(f"{name}: faces refer to vertices that do not exist")
    used = vertices[np.bincount(faces.ravel(), minlength=len(vertices)) > 0]
    finite = np.isfinite(used).all(axis=1)
    if not finite.all():
        bad = int(np.count_nonzero(~finite))
        raise InputError(f"{name}: {bad:,} {'vertex has' if bad == 1 else 'vertices have'} "
                         f"NaN or infinite coordinates")
    reach = float(np.abs(used).max())
    if reach > ABSURD_MM:
        raise InputError(f"{name}: coordinates reach {reach:.3g} mm: check --units and --scale")


# --- B-rep input (OCP) -------------------------------------------------------

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


def _read_step(file: Path):
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
        raise InputError(f"{file.name}: cannot be read as STEP: {_first_line(exc)}") from None
    if shape is None or shape.IsNull():
        raise InputError(f"{file.name}: the STEP file contains no shape")
    return _solids(shape, file.name, "the STEP file")


def _read_brep(file: Path):
    """The solid(s) of an OCC BREP text file as an OCP shape in mm."""
    from OCP.BRep import BRep_Builder
    from OCP.BRepTools import BRepTools
    from OCP.TopoDS import TopoDS_Shape

    shape = TopoDS_Shape()
    try:
        read = BRepTools.Read_s(shape, str(file), BRep_Builder())
    except Exception as exc:
        raise InputError(f"{file.name}: cannot be read as BREP: {_first_line(exc)}") from None
    if not read or shape.IsNull():
        raise InputError(f"{file.name}: not a valid BREP file (the BREP reader gave up)")
    return _solids(shape, file.name, "the BREP file")


def _scaled_turned_shape(shape, factor: float, name: str, turn: np.ndarray | None = None):
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
                         f"{_first_line(exc)}") from None


def _translated_shape(shape, offset, name: str):
    """``shape`` moved by the vector ``offset`` (mm)."""
    from OCP.BRepBuilderAPI import BRepBuilderAPI_Transform
    from OCP.gp import gp_Trsf, gp_Vec

    trsf = gp_Trsf()
    trsf.SetTranslation(gp_Vec(*(float(v) for v in offset)))
    try:
        return BRepBuilderAPI_Transform(shape, trsf, True).Shape()
    except Exception as exc:
        raise InputError(f"{name}: the solid cannot be moved to the origin: "
                         f"{_first_line(exc)}") from None


def _tessellate(shape, tolerance_mm: float, name: str) -> tuple[np.ndarray, np.ndarray]:
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


# --- FreeCAD documents without FreeCAD ----------------------------------------

@dataclass
class _FcObject:
    """What :func:`_read_fcstd` needs to know of one FreeCAD document object."""

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
        raise InputError(f"{name}: {member} is not valid XML: {_first_line(exc)}") from None


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


def _read_fcstd(file: Path, warnings: list[str]):
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
                         f"{_first_line(exc)}") from None

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


# --- units -------------------------------------------------------------------

def size_warnings(extents: np.ndarray, units: str = "mm") -> list[str]:
    """Warnings if a part ``extents`` mm across looks like it was read in the wrong unit.

    Smaller than one cell (8 mm): names the larger units that would give a
    plausible size, most likely first.  Larger than 2 m: suggests ``--scale``.
    """
    size = float(np.max(extents))
    unit_mm = UNITS.get(units, 1.0)
    names = {"mm": "millimetres", "cm": "centimetres", "m": "metres", "in": "inches"}
    if size < CELL_MM[0]:
        fits = sorted((mm, u) for u, mm in UNITS.items()
                      if mm > unit_mm and CELL_MM[0] <= size / unit_mm * mm <= LARGEST_PLAUSIBLE_MM)
        if fits:
            (_, best), others = fits[-1], fits[-2::-1]
            hint = f"if the file is in {names[best]}, use --units {best}"
            if others:
                hint += " (or " + ", ".join(f"{names[u]}: --units {u}" for _, u in others) + ")"
        else:
            hint = "check --units and --scale"
        return [f"the part is only {size:.3g} mm across, smaller than one {CELL_MM[0]:g} mm "
                f"stud: {hint}"]
    if size > LARGEST_PLAUSIBLE_MM:
        hint = "" if units == "mm" else f", or leave out --units {units}"
        return [f"the part is {size:,.0f} mm across, over {LARGEST_PLAUSIBLE_MM / 1000:g} m: "
                f"if the file is in tenths of mm or µm, use --scale (e.g. --scale 0.1){hint}"]
    return []


def surface_warning(mesh: trimesh.Trimesh) -> list[str]:
    """One line on a repaired surface that is not closed, or none: how many edges border
    one triangle only (open), how many are shared by more than two (non-manifold), whether
    it cannot be oriented (one-sided, like a Möbius strip), and what legofy does with it."""
    _, counts = np.unique(mesh.edges_sorted, axis=0, return_counts=True)
    open_edges = int(np.count_nonzero(counts == 1))
    shared = int(np.count_nonzero(counts > 2))
    what = []
    if open_edges:
        what.append(f"{_n(open_edges, 'edge')} border{'s' if open_edges == 1 else ''} one triangle only "
                    f"(holes larger than the repair fills)")
    if shared:
        what.append(f"{_n(shared, 'edge')} {'is' if shared == 1 else 'are'} shared by more than two "
                    f"triangles (non-manifold)")
    if not mesh.is_winding_consistent:
        what.append("it cannot be oriented (one-sided, like a Möbius strip)")
    if not what:
        return []
    return [f"the surface is not closed: {'; '.join(what)}; it encloses no volume of its own, so "
            f"its holes were capped to decide which cells are inside: check the cells filled"]


# --- repair ------------------------------------------------------------------

def repair(vertices: np.ndarray, faces: np.ndarray, name: str = "the model",
           report_merges: bool = True) -> tuple[trimesh.Trimesh, list[str]]:
    """A repaired mesh from finite ``vertices`` and triangle ``faces``, and what was done.

    Merges duplicate vertices (reported if ``report_merges``: an STL stores
    every corner separately, so merging is no repair there); drops
    collapsed, zero-area and duplicate faces (a zero-area face whose three
    edges each join exactly one other face is kept: it closes a T-junction
    seam and dropping it would open the surface); drops face-connected
    pieces with fewer than 4 faces or all in one plane; makes the winding
    of each piece consistent; fills 3- and 4-edge holes; turns closed
    pieces that are inside out (negative volume, not inside another piece)
    outward, with any pieces nested inside them.  Raises InputError if no
    piece is left.
    """
    done: list[str] = []
    mesh = trimesh.Trimesh(vertices=vertices, faces=faces, process=False, validate=False)
    loaded_faces = len(mesh.faces)

    referenced = int(np.count_nonzero(np.bincount(mesh.faces.ravel(), minlength=len(mesh.vertices))))
    mesh.merge_vertices(merge_tex=True, merge_norm=True)
    merged = referenced - len(mesh.vertices)
    if merged and report_merges:
        done.append(f"merged {_n(merged, 'duplicate vertex', 'duplicate vertices')}")

    keep, collapsed, flat, duplicate = _face_filter(mesh)
    if not keep.all():
        mesh.update_faces(keep)
        if collapsed + flat:
            done.append(f"removed {_n(collapsed + flat, 'degenerate face')}")
        if duplicate:
            done.append(f"removed {_n(duplicate, 'duplicate face')}")
    if len(mesh.faces) == 0:
        raise InputError(f"{name}: no volume: all {loaded_faces:,} triangles are degenerate "
                         f"(zero area)")

    labels = _piece_labels(mesh)
    solid = _pieces_with_volume(mesh, labels)
    if not solid.all():
        pieces = len(solid)
        dropped_faces = int(np.count_nonzero(~solid[labels]))
        if not solid.any():
            n = len(mesh.faces)
            what = ("one piece that encloses" if pieces == 1
                    else f"{pieces:,} separate pieces that enclose")
            raise InputError(f"{name}: no volume: the {n:,} triangles form {what} nothing")
        mesh.update_faces(solid[labels])
        labels = np.unique(labels[solid[labels]], return_inverse=True)[1]
        dead = pieces - int(np.count_nonzero(solid))
        done.append(f"dropped {_n(dead, 'loose piece')} without volume "
                    f"({_n(dropped_faces, 'triangle')})")
    mesh.remove_unreferenced_vertices()

    flipped = np.zeros(len(mesh.faces), dtype=bool)
    if not mesh.is_winding_consistent:
        flipped = _consistent_winding(mesh)
        if flipped.any():
            f = mesh.faces.copy()
            f[flipped] = f[flipped][:, ::-1]
            mesh.faces = f

    if not mesh.is_watertight:
        before = len(mesh.faces)
        open_edges = _boundary_edge_count(mesh)
        trimesh.repair.fill_holes(mesh)
        added = len(mesh.faces) - before
        if added:
            closed_edges = open_edges - _boundary_edge_count(mesh)
            quads = max((3 * added - closed_edges) // 2, 0)
            holes = added - quads
            done.append(f"filled {_n(holes, 'small hole')} ({_n(added, 'triangle')})")
            flipped = np.concatenate([flipped, np.zeros(added, dtype=bool)])
            labels = _piece_labels(mesh)

    inverted = _inside_out(mesh, labels)
    if inverted.any():
        f = mesh.faces.copy()
        f[inverted] = f[inverted][:, ::-1]
        mesh.faces = f
        flipped ^= inverted
    if flipped.any():
        done.append(f"fixed face orientation "
                    f"({_n(int(np.count_nonzero(flipped)), 'face')} flipped)")
    return mesh, done


def _n(count: int, singular: str, plural: str | None = None) -> str:
    """``count`` and the noun, e.g. "1 face", "1,204 faces"."""
    return f"{count:,} {singular if count == 1 else plural or singular + 's'}"


def _face_filter(mesh: trimesh.Trimesh) -> tuple[np.ndarray, int, int, int]:
    """Mask of faces to keep, and the counts of collapsed, zero-area and duplicate faces."""
    f = mesh.faces
    collapsed = (f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 0] == f[:, 2])
    zero = ~mesh.nondegenerate_faces() & ~collapsed
    if zero.any():
        whole = f[~collapsed]
        edges = np.sort(whole[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
        _, inverse, counts = np.unique(trimesh.grouping.hashable_rows(edges),
                                       return_inverse=True, return_counts=True)
        seam = np.zeros(len(f), dtype=bool)
        seam[~collapsed] = (counts[inverse] == 2).reshape(-1, 3).all(axis=1)
        zero &= ~seam
    unique = mesh.unique_faces()
    keep = ~collapsed & ~zero & unique
    duplicate = int(np.count_nonzero(~unique & ~collapsed & ~zero))
    return keep, int(np.count_nonzero(collapsed)), int(np.count_nonzero(zero)), duplicate


def _piece_labels(mesh: trimesh.Trimesh) -> np.ndarray:
    """Per face, the index of its piece: faces joined through edges shared by two faces."""
    return trimesh.graph.connected_component_labels(mesh.face_adjacency,
                                                    node_count=len(mesh.faces))


def _pieces_with_volume(mesh: trimesh.Trimesh, labels: np.ndarray) -> np.ndarray:
    """Per piece, whether it may enclose volume: 4 faces or more, not all in one plane.

    Flatness is judged from the smallest principal extent of the piece's
    corners (vectorised covariance per piece): flat is at most FLAT_MM *and*
    at most a millionth of the model's size (so a long thin bar is no
    flatter than a short one, and a tiny part read in the wrong unit is not
    flat either).
    """
    pieces = int(labels.max()) + 1
    count = np.bincount(labels, minlength=pieces)
    corners = mesh.triangles.reshape(-1, 3)
    corners = corners - corners.mean(axis=0)
    if pieces == 1:
        cov = np.cov(corners.T, bias=True)[None]
    else:
        lab = np.repeat(labels, 3)
        n = 3.0 * count
        mean = np.stack([np.bincount(lab, corners[:, i], pieces) for i in range(3)], axis=1) / n[:, None]
        cov = np.empty((pieces, 3, 3))
        for i in range(3):
            for j in range(i, 3):
                cov[:, i, j] = cov[:, j, i] = (np.bincount(lab, corners[:, i] * corners[:, j], pieces)
                                               / n - mean[:, i] * mean[:, j])
    thinnest = np.sqrt(np.clip(np.linalg.eigvalsh(cov)[:, 0], 0.0, None))
    scale = float(np.linalg.norm(np.ptp(corners, axis=0)))
    return (count >= 4) & (thinnest > min(FLAT_MM, 1e-6 * scale))


def _consistent_winding(mesh: trimesh.Trimesh) -> np.ndarray:
    """Mask of faces to flip so that neighbours across each shared edge agree.

    Vectorised: a face and its flipped copy are two nodes of a "double
    cover" graph; agreeing neighbours join same-orientation nodes,
    disagreeing ones opposite nodes.  Connected components of that graph
    give each piece's two consistent orientations; the one that flips
    fewer faces wins.  Pieces that cannot be oriented (Möbius-like) are
    left alone.  (trimesh.repair.fix_winding does the same face by face in
    Python, far slower.)
    """
    f = mesh.faces
    nf = len(f)
    pairs = mesh.face_adjacency
    edge = mesh.face_adjacency_edges

    def forward(face_index: np.ndarray) -> np.ndarray:
        rows = f[face_index]
        at = np.argmax(rows == edge[:, :1], axis=1)
        return rows[np.arange(len(rows)), (at + 1) % 3] == edge[:, 1]

    agree = forward(pairs[:, 0]) != forward(pairs[:, 1])
    a, b = pairs[:, 0], pairs[:, 1]
    b_same = np.where(agree, b, b + nf)
    b_other = np.where(agree, b + nf, b)
    rows = np.concatenate([a, a + nf])
    cols = np.concatenate([b_same, b_other])
    graph = sparse.coo_matrix((np.ones(len(rows), dtype=np.int8), (rows, cols)),
                              shape=(2 * nf, 2 * nf))
    _, lab = connected_components(graph, directed=False)
    keep_lab, flip_lab = lab[:nf], lab[nf:]
    count = np.bincount(keep_lab, minlength=lab.max() + 1)
    fewer = (count[keep_lab] < count[flip_lab]) | (
        (count[keep_lab] == count[flip_lab]) & (keep_lab > flip_lab))
    return (keep_lab != flip_lab) & fewer


def _boundary_edge_count(mesh: trimesh.Trimesh) -> int:
    """Number of edges used by exactly one face."""
    return len(trimesh.grouping.group_rows(mesh.edges_sorted, require_count=1))


def _inside_out(mesh: trimesh.Trimesh, labels: np.ndarray) -> np.ndarray:
    """Mask of faces to flip so that closed pieces face outward.

    A closed piece with negative signed volume is inside out, unless it lies
    inside another closed piece (then it may be a cavity).  A nest of pieces
    is turned as a whole, following its outermost piece, so that cavities
    stay cavities.  Nesting is decided by the generalised winding number of
    one vertex of a piece with respect to each closed piece whose bounding
    box contains it; it is only computed when some closed piece has
    negative volume, for the pieces that could be in such a nest.
    """
    pieces = int(labels.max()) + 1
    tri = mesh.triangles
    if mesh.is_watertight:
        closed = np.ones(pieces, dtype=bool)
    else:
        edges_face = mesh.edges_face
        paired = np.zeros(len(edges_face), dtype=bool)
        paired[np.asarray(trimesh.grouping.group_rows(mesh.edges_sorted, require_count=2),
                          dtype=np.int64).ravel()] = True
        open_face = np.zeros(len(tri), dtype=bool)
        open_face[edges_face[~paired]] = True
        closed = np.bincount(labels, open_face, pieces) == 0
    rel = tri - tri[:, 0].mean(axis=0)
    volume = np.bincount(labels, np.einsum("ij,ij->i", rel[:, 0],
                                           np.cross(rel[:, 1], rel[:, 2])) / 6.0, pieces)
    negative = np.flatnonzero(closed & (volume < 0))
    if not len(negative):
        return np.zeros(len(tri), dtype=bool)

    corners = tri.reshape(-1, 3)
    lab3 = np.repeat(labels, 3)
    lo = np.full((pieces, 3), np.inf)
    hi = np.full((pieces, 3), -np.inf)
    np.minimum.at(lo, lab3, corners)
    np.maximum.at(hi, lab3, corners)

    def boxes_around(q: int) -> np.ndarray:
        inside = closed & (lo <= lo[q]).all(axis=1) & (hi >= hi[q]).all(axis=1)
        inside[q] = False
        return np.flatnonzero(inside)

    in_negative = np.zeros(pieces, dtype=bool)
    for n in negative:
        in_negative |= (lo >= lo[n]).all(axis=1) & (hi <= hi[n]).all(axis=1)
    order = np.argsort(labels, kind="stable")
    bounds = np.searchsorted(labels[order], np.arange(pieces + 1))
    root = np.arange(pieces)
    for q in np.flatnonzero(in_negative):
        hosts = boxes_around(q)
        if not len(hosts):
            continue
        faces = np.concatenate([order[bounds[h]:bounds[h + 1]] for h in hosts])
        point = tri[order[bounds[q]], 0]
        winding = np.bincount(labels[faces], _solid_angles(point, tri[faces]), pieces)
        holders = hosts[np.abs(winding[hosts]) > 2.0 * np.pi]
        if len(holders):
            root[q] = holders[np.argmax(np.abs(volume[holders]))]
    return (closed & (volume[root] < 0))[labels]


def _solid_angles(point: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Signed solid angle of each triangle seen from ``point`` (Van Oosterom and Strackee).

    Their sum over a closed surface is 4 pi times its winding number
    around the point.
    """
    v = tri - point
    length = np.linalg.norm(v, axis=2)
    a, b, c = v[:, 0], v[:, 1], v[:, 2]
    det = np.einsum("ti,ti->t", a, np.cross(b, c))
    den = (length[:, 0] * length[:, 1] * length[:, 2]
           + np.einsum("ti,ti->t", a, b) * length[:, 2]
           + np.einsum("ti,ti->t", b, c) * length[:, 0]
           + np.einsum("ti,ti->t", c, a) * length[:, 1])
    return 2.0 * np.arctan2(det, den)
