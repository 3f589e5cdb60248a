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

import io
import math
import os
import re
import stat
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import trimesh

from core.errors import InputError, shown_path
from core.io.brep import (first_line, read_brep, read_fcstd, read_step, scaled_turned_shape, tessellate,
                           translated_shape)
from core.io.repair import count_words, repair
from core.model import CELL_MM, UNITS, UP_AXES

#: File suffix (lower case) -> format name.
FORMATS = {".stl": "stl", ".obj": "obj", ".ply": "ply", ".3mf": "3mf",
           ".step": "step", ".stp": "step", ".brep": "brep", ".fcstd": "fcstd"}


#: A part larger than this (mm) is probably in a smaller unit than assumed.
LARGEST_PLAUSIBLE_MM = 2000.0

#: Coordinates beyond this (mm) are refused: no part is that large, and
#: vertex merging works on integers at 1e-8 mm.
ABSURD_MM = 1.0e9

#: Coarsest step (mm) a model's coordinates may have in a 32-bit float; a model reaching
#: further from the origin (131 m and more) is moved to it (:func:`load_model`).
PRECISE_MM = 0.01


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
        readers = {"step": read_step, "brep": read_brep}
        shape = readers[fmt](file) if fmt in readers else read_fcstd(file, warnings)
        brep = scaled_turned_shape(shape, factor, file.name, turn)
        vertices, faces = tessellate(brep, tolerance_mm, file.name)
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
        brep = None if brep is None else translated_shape(brep, offset, file.name)
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
                         f"{first_line(exc)}") from None
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
        what.append(f"{count_words(open_edges, 'edge')} border{'s' if open_edges == 1 else ''} one triangle only "
                    f"(holes larger than the repair fills)")
    if shared:
        what.append(f"{count_words(shared, 'edge')} {'is' if shared == 1 else 'are'} shared by more than two "
                    f"triangles (non-manifold)")
    if not mesh.is_winding_consistent:
        what.append("it cannot be oriented (one-sided, like a Möbius strip)")
    if not what:
        return []
    return [f"the surface is not closed: {'; '.join(what)}; it encloses no volume of its own, so "
            f"its holes were capped to decide which cells are inside: check the cells filled"]


