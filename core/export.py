"""Export of printed parts: ``parts/<id>.stl`` and ``.step`` per part, one 3MF plate.

The STL is the part's watertight mesh.  The STEP is the part's B-rep for
B-rep input; for mesh input (whose exact result is a mesh) it is a faceted
B-rep of that mesh, one planar face per triangle, written directly as
STEP text (:func:`write_faceted_step`).  The plate
``parts/plate.3mf`` holds every part laid flat (upright, its underside on the bed,
see :func:`lay_flat`) and placed in a row with :data:`SPACING_MM`
between neighbours, ready to slice.
"""

from __future__ import annotations

import io
import os
import time
from pathlib import Path

import numpy as np
import trimesh
from OCP.IFSelect import IFSelect_RetDone
from OCP.Interface import Interface_Static
from OCP.STEPControl import STEPControl_AsIs, STEPControl_Writer

from core.errors import InputError
from core.printed import PrintedPart

#: Gap (mm) between parts on the 3MF plate.
SPACING_MM = 5.0


def lay_flat(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """A copy of ``mesh`` standing upright as the brick stands (studs up, the
    underside on the bed, which is how studs print round) with its min corner at 0."""
    out = mesh.copy()
    out.apply_translation(-out.bounds[0])
    return out


def plate(parts: list[PrintedPart]) -> list[trimesh.Trimesh]:
    """The parts' meshes laid flat and placed in a row along x, SPACING_MM apart."""
    out, x = [], 0.0
    for p in parts:
        m = lay_flat(p.mesh)
        m.apply_translation([x, 0.0, 0.0])
        x += float(m.extents[0]) + SPACING_MM
        out.append(m)
    return out


def write_step(shape, path: str | os.PathLike) -> None:
    """Write an OCP shape as a STEP (AP214) file in mm; InputError when OCC refuses."""
    Interface_Static.SetCVal_s("write.step.unit", "MM")
    writer = STEPControl_Writer()
    writer.Transfer(shape, STEPControl_AsIs)
    if writer.Write(str(path)) != IFSelect_RetDone:
        raise InputError(f"could not write the STEP file {path}")


#: Fixed part of a faceted STEP file: header, product and mm units (entities #1..#13).
_STEP_HEAD = """ISO-10303-21;
HEADER;
FILE_DESCRIPTION(('Fabrickator printed part, faceted B-rep'),'2;1');
FILE_NAME('{name}','{stamp}',(''),(''),'Fabrickator','Fabrickator','');
FILE_SCHEMA(('AUTOMOTIVE_DESIGN {{ 1 0 10303 214 1 1 1 1 }}'));
ENDSEC;
DATA;
#1=APPLICATION_PROTOCOL_DEFINITION('international standard','automotive_design',2000,#2);
#2=APPLICATION_CONTEXT('core data for automotive mechanical design processes');
#3=SHAPE_DEFINITION_REPRESENTATION(#4,#14);
#4=PRODUCT_DEFINITION_SHAPE('','',#5);
#5=PRODUCT_DEFINITION('design','',#6,#9);
#6=PRODUCT_DEFINITION_FORMATION('','',#7);
#7=PRODUCT('{name}','{name}','',(#8));
#8=PRODUCT_CONTEXT('',#2,'mechanical');
#9=PRODUCT_DEFINITION_CONTEXT('part definition',#2,'design');
#10=(LENGTH_UNIT()NAMED_UNIT(*)SI_UNIT(.MILLI.,.METRE.));
#11=(NAMED_UNIT(*)PLANE_ANGLE_UNIT()SI_UNIT($,.RADIAN.));
#12=(NAMED_UNIT(*)SI_UNIT($,.STERADIAN.)SOLID_ANGLE_UNIT());
#13=(GEOMETRIC_REPRESENTATION_CONTEXT(3)GLOBAL_UNCERTAINTY_ASSIGNED_CONTEXT((#15))\
GLOBAL_UNIT_ASSIGNED_CONTEXT((#10,#11,#12))REPRESENTATION_CONTEXT('Context #1','3D Context with UNIT and UNCERTAINTY'));
#14=FACETED_BREP_SHAPE_REPRESENTATION('',(#16),#13);
#15=UNCERTAINTY_MEASURE_WITH_UNIT(LENGTH_MEASURE(1.E-06),#10,'distance_accuracy_value','confusion accuracy');
#16=FACETED_BREP('',#17);
"""
_STEP_FIRST_FREE = 18


def write_faceted_step(mesh: trimesh.Trimesh, path: str | os.PathLike, name: str = "part") -> None:
    """Write the closed ``mesh`` as an AP214 STEP faceted B-rep (mm): one planar face per triangle.

    The file is written as text, vectorised with numpy (no OCC shape is
    built, so it takes milliseconds for 100k triangles): a
    ``FACETED_BREP`` whose ``CLOSED_SHELL`` holds one ``FACE_SURFACE`` per
    triangle, bounded by a ``POLY_LOOP`` of its three corners (counter-
    clockwise seen from outside) on the ``PLANE`` of its outward normal.
    OpenCascade reads it back as one closed solid of the mesh's volume.
    """
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    faces = np.asarray(mesh.faces, dtype=np.int64)
    if len(faces) == 0:
        raise InputError(f"cannot write {path}: the part has no triangles")
    normals = np.cross(vertices[faces[:, 1]] - vertices[faces[:, 0]], vertices[faces[:, 2]] - vertices[faces[:, 0]])
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    normals = np.where(length > 1e-300, normals / np.where(length > 1e-300, length, 1.0), [0.0, 0.0, 1.0])
    helper = np.where(np.abs(normals[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    ref = np.cross(normals, helper)
    ref /= np.linalg.norm(ref, axis=1, keepdims=True)
    nv, nf = len(vertices), len(faces)
    point_ids = _STEP_FIRST_FREE + np.arange(nv)
    base = _STEP_FIRST_FREE + nv + 7 * np.arange(nf)
    corners = point_ids[faces]
    points = _rows("#%d=CARTESIAN_POINT('',(%.9f,%.9f,%.9f));", point_ids, vertices)
    blocks = np.column_stack([base, base + 1, base + 3, base + 1, base + 2, base + 2, corners,
                              base + 3, base + 4, base + 4, corners[:, 0], base + 5, base + 6,
                              base + 5, normals, base + 6, ref])
    face_rows = _rows("#%d=FACE_SURFACE('',(#%d),#%d,.T.);\n#%d=FACE_OUTER_BOUND('',#%d,.T.);\n"
                      "#%d=POLY_LOOP('',(#%d,#%d,#%d));\n#%d=PLANE('',#%d);\n"
                      "#%d=AXIS2_PLACEMENT_3D('',#%d,#%d,#%d);\n#%d=DIRECTION('',(%.12f,%.12f,%.12f));\n"
                      "#%d=DIRECTION('',(%.12f,%.12f,%.12f));", blocks[:, :1], blocks[:, 1:])
    shell = _rows("#%d,", base[:, None], np.zeros((nf, 0)))
    name = str(name).replace("'", "")
    stamp = time.strftime("%Y-%m-%dT%H:%M:%S")
    text = "".join([_STEP_HEAD.format(name=name, stamp=stamp), points, face_rows,
                    "#17=CLOSED_SHELL('',(", shell.replace("\n", "").rstrip(","), "));\n",
                    "ENDSEC;\nEND-ISO-10303-21;\n"])
    Path(path).write_text(text, encoding="ascii")


def _rows(fmt: str, ids, values) -> str:
    """``fmt`` applied to each row of ``[ids, values]`` (numpy's savetxt), one per line."""
    table = np.column_stack([np.asarray(ids).reshape(len(ids), -1).astype(np.float64),
                             np.asarray(values, dtype=np.float64).reshape(len(ids), -1)])
    out = io.StringIO()
    np.savetxt(out, table, fmt=fmt, delimiter="", newline="\n")
    return out.getvalue()


def export_parts(parts: list[PrintedPart], folder: str | os.PathLike) -> list[str]:
    """Write ``<id>.stl``, ``<id>.step`` per part and ``plate.3mf`` into ``folder``.

    Sets ``stl`` and ``step`` of each part to the paths relative to the
    folder's parent (``parts/P1.stl``); returns the names written.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for p in parts:
        stl, step = folder / f"{p.id}.stl", folder / f"{p.id}.step"
        p.mesh.export(stl)
        if p.solid is not None:
            write_step(p.solid, step)
        else:
            write_faceted_step(p.mesh, step, name=p.id)
        p.stl, p.step = f"{folder.name}/{stl.name}", f"{folder.name}/{step.name}"
        written += [stl.name, step.name]
    if parts:
        scene = trimesh.Scene()
        for p, m in zip(parts, plate(parts)):
            scene.add_geometry(m, node_name=p.id, geom_name=p.id)
        (folder / "plate.3mf").write_bytes(trimesh.exchange.threemf.export_3MF(scene))
        written.append("plate.3mf")
    return written
