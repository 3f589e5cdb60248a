"""Export of printed parts: ``parts/<id>.stl`` and ``.step`` per part, 3MF plates.

The STL is the part's watertight mesh.  The STEP is the part's B-rep for
B-rep input; for mesh input (whose exact result is a mesh) it is a faceted
B-rep of that mesh, one planar face per triangle, written directly as
STEP text (:func:`write_faceted_step`).  Both stay in model coordinates,
where the part belongs in the assembly.

The plate ``parts/plate-1.3mf`` holds every part in its print pose
(:func:`print_pose`: the pose PrusaSlicer prints fastest with the supports
it needs, never studs down, never the engraved ID facing down), each on
the bed (min z = 0), packed in rows within the printer's bed
(:func:`plates`) without overlap, with the settings to print it (supports
on when a part needs them) as its PrusaSlicer project config: opening it
in PrusaSlicer gives the print and the time the report states.  Parts
that do not all fit one bed go on further plates, ``plate-2.3mf``,
``plate-3.3mf``, ...
"""

from __future__ import annotations

import dataclasses
import io
import math
import os
import time
from pathlib import Path

import numpy as np
import trimesh

from core.parts.printed_part import PrintedPart
from core.printing import print_time
from core.printing.plate import ARRANGE_GAP_MM, bed_rectangle, plate_3mf
from core.printing.poses import Pose, posed

#: Gap (mm) between parts on a plate, and between the parts and the bed's edge:
#: the slicer's least gap (supports spread beyond their part; PrusaSlicer 2.9
#: refuses supported parts 6 mm apart).
SPACING_MM = ARRANGE_GAP_MM

#: Extra cost (fraction of the pose's print time) of printing a part with
#: studs or sockets in any pose but upright: its clamping features then print
#: with their layers along the stud axis, less round and less precise.
SIDEWAYS_PENALTY = 0.15

#: Studs count as pointing down when their axis has a z component below this.
STUDS_DOWN_Z = -1e-6

#: An engraved face counts as facing down (onto the bed or onto supports,
#: where the letters fill or smear) when its normal has a z component below this.
ENGRAVING_DOWN_Z = -0.5


def print_pose(mesh: trimesh.Trimesh, studs: bool = True, clamping: bool = True,
               engraving_normal=None, profile: str | os.PathLike | None = None,
               slicer: str | None = "auto", workdir: str | os.PathLike | None = None) -> Pose:
    """The print orientation of a part (its mesh in model mm, studs along +z).

    The pose that prints fastest with the supports it needs
    (:func:`core.printing.print_time.fastest_pose`: upright, upside down, the four
    sideways poses and the most probable resting poses, the best by
    estimate sliced with PrusaSlicer, each with supports exactly when it
    needs them; by the estimate alone without a slicer, ``slicer`` as
    there), under these rules: when the part has studs (``studs``) no
    pose points them down (z below STUDS_DOWN_Z): printed facing down they
    need support and lose their precision; when ``engraving_normal`` (the
    engraved face's outward normal, model frame) is given, no pose turns
    it down (z below ENGRAVING_DOWN_Z), onto the bed or the supports.
    When the part has studs or sockets (``clamping``), any pose but
    upright costs SIDEWAYS_PENALTY more: printed upright, the clamping
    sides lie in the layers and come out round.  ``profile`` (default:
    the presets of the slicer's vendor bundle) is sliced with; slices go under ``workdir`` (a
    temporary folder when None).
    """
    keep_up = ([((0.0, 0.0, 1.0), STUDS_DOWN_Z)] if studs else []) + \
        ([(tuple(engraving_normal), ENGRAVING_DOWN_Z)] if engraving_normal is not None else [])
    return print_time.fastest_pose(mesh, workdir, profile, slicer,
                                   keep_up=keep_up, prefer_upright=SIDEWAYS_PENALTY if clamping else 0.0)


def lay_flat(part: PrintedPart | trimesh.Trimesh, profile: str | os.PathLike | None = None,
             slicer: str | None = "auto",
             workdir: str | os.PathLike | None = None) -> tuple[trimesh.Trimesh, Pose]:
    """A copy of the part's mesh in its :func:`print_pose`, min corner at the origin, and the pose.

    For a PrintedPart the studs rule applies when it has studs, the
    clamping penalty when it has studs or sockets (they clamp the bricks
    above and below) and the engraving rule when its id is engraved; a
    bare mesh is treated as a part with studs and no engraving.  The copy is marked posed
    (:func:`core.printing.poses.posed`), so :func:`core.printing.print_time.print_time`
    slices it as it stands, with the supports its pose needs.  The poses are sliced
    under ``workdir`` (a temporary folder when None).
    """
    if isinstance(part, PrintedPart):
        mesh, studs = part.mesh, bool(part.complete_studs)
        clamping = bool(part.complete_studs or part.complete_sockets)
        normal = part.engraving["normal"] if part.engraved and isinstance(part.engraving, dict) else None
    else:
        mesh, studs, clamping, normal = part, True, True, None
    pose = print_pose(mesh, studs, clamping, normal, profile=profile, slicer=slicer, workdir=workdir)
    return posed(mesh, pose), pose


def plates(parts: list, bed=None, profile: str | os.PathLike | None = None,
           slicer: str | None = "auto",
           workdir: str | os.PathLike | None = None) -> list[list[tuple[int, trimesh.Trimesh, Pose]]]:
    """The parts laid flat (:func:`lay_flat`, ``profile``, ``slicer`` and ``workdir`` as
    there; two parts' pose searches at a time) and packed on as few beds as this simple
    rule gives.

    ``bed`` is the printable (x, y) in mm from the origin (default: the profile's bed,
    :func:`core.printing.plate.bed_rectangle`, where it lies).  Shelf packing: each part is
    turned about z so its longer side runs along the bed's longer side
    when that fits, the parts are taken tallest footprint (y) first and
    set left to right in rows, SPACING_MM apart and from the bed's edges; a
    part that does not fit the row starts a new row above, a row that does
    not fit the bed starts a new plate.  A part larger than the bed gets a
    plate of its own (the slicer will refuse it).  Returns per plate the
    (index into ``parts``, mesh in bed coordinates, pose) of its parts;
    every mesh has min z = 0, is marked posed, and the footprints do not
    overlap.
    """
    rectangle = (np.array([[0.0, 0.0], bed], dtype=float) if bed is not None else
                 bed_rectangle(print_time.load_profile(profile, slicer)))
    size, origin = rectangle[1] - rectangle[0], rectangle[0]
    laid = []
    flat = print_time.in_parallel(lambda part: lay_flat(part, profile, slicer, workdir), parts, 2)
    for index, (mesh, pose) in enumerate(flat):
        extent = mesh.extents[:2]
        if (extent[0] < extent[1]) == (size[0] > size[1]) and np.all(extent[::-1] <= size - 2 * SPACING_MM):
            turn = trimesh.transformations.rotation_matrix(math.pi / 2, [0, 0, 1])
            mesh.apply_transform(turn)
            shift = np.eye(4)
            shift[:3, 3] = -mesh.bounds[0]
            mesh.apply_transform(shift)
            pose.matrix = shift @ turn @ pose.matrix
        laid.append((index, mesh, pose))
    laid.sort(key=lambda item: (-item[1].extents[1], item[0]))
    out: list[list] = []
    x = y = row = 0.0
    for index, mesh, pose in laid:
        w, d = mesh.extents[:2]
        if not out or x + w > size[0] - SPACING_MM + 1e-9:
            x, y = SPACING_MM, y + row + (SPACING_MM if out else 0.0)
            row = 0.0
        if not out or y + d > size[1] - SPACING_MM + 1e-9:
            out.append([])
            x, y, row = SPACING_MM, SPACING_MM, 0.0
        move = np.eye(4)
        move[:2, 3] = origin + (x, y)
        mesh.apply_transform(move)
        pose.matrix = move @ pose.matrix
        out[-1].append((index, mesh, pose))
        x += w + SPACING_MM
        row = max(row, d)
    return out


def plate(parts: list) -> list[trimesh.Trimesh]:
    """Every part's mesh in its print pose on its plate (:func:`plates`), in ``parts`` order."""
    placed = {index: mesh for items in plates(parts) for index, mesh, _ in items}
    return [placed[i] for i in range(len(parts))]


def write_step(shape, path: str | os.PathLike) -> None:
    """Write an OCP shape as a STEP (AP214) file in mm; RuntimeError when OCC's
    writer fails (the shape cannot be written there)."""
    from OCP.IFSelect import IFSelect_RetDone
    from OCP.Interface import Interface_Static
    from OCP.STEPControl import STEPControl_AsIs, STEPControl_Writer

    Interface_Static.SetCVal_s("write.step.unit", "MM")
    writer = STEPControl_Writer()
    writer.Transfer(shape, STEPControl_AsIs)
    if writer.Write(str(path)) != IFSelect_RetDone:
        raise RuntimeError(f"OpenCascade could not write the STEP file {path}")


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
    Raises ValueError for a mesh without triangles.
    """
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    faces = np.asarray(mesh.faces, dtype=np.int64)
    if len(faces) == 0:
        raise ValueError(f"cannot write {path}: the part has no triangles")
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


def export_parts(parts: list[PrintedPart], folder: str | os.PathLike, bed=None,
                 profile: str | os.PathLike | None = None, slicer: str | None = "auto",
                 beds: list | None = None) -> tuple[list[str], list[PrintedPart]]:
    """Write ``<id>.stl``, ``<id>.step`` per part and the 3MF plate(s) into ``folder``.

    Returns the names written and the parts as written: copies whose
    ``stl`` and ``step`` are the paths relative to the folder's parent
    (``parts/P1.stl``) and whose ``pose`` is the print pose
    (:meth:`Pose.to_json` plus the plate file it is on); ``parts`` are not
    changed.  The plates come from :func:`plates` (``bed``, ``profile`` and
    ``slicer`` as there), or are ``beds`` when given (what :func:`plates`
    returned for these ``parts``, so that the poses are not searched again):
    ``plate-1.3mf``, then ``plate-2.3mf`` ... when the parts need more beds.  Each plate carries the settings it is to be
    printed with as PrusaSlicer's project config
    (:func:`core.printing.plate.plate_3mf`): the
    profile's, with :data:`core.printing.print_time.SUPPORT_SETTINGS` when a part on
    it is posed with supports, so PrusaSlicer opening it prints what
    :func:`core.printing.print_time.print_time` timed.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    files: dict[str, dict] = {}
    for p in parts:
        stl, step = folder / f"{p.id}.stl", folder / f"{p.id}.step"
        p.mesh.export(stl)
        if p.solid is not None:
            write_step(p.solid, step)
        else:
            write_faceted_step(p.mesh, step, name=p.id)
        files[p.id] = {"stl": f"{folder.name}/{stl.name}", "step": f"{folder.name}/{step.name}"}
        written += [stl.name, step.name]
    if beds is None:
        beds = plates(parts, bed, profile, slicer) if parts else []
    for number, items in enumerate(beds, start=1):
        name = f"plate-{number}.3mf"
        for index, _, pose in items:
            files[parts[index].id]["pose"] = {**pose.to_json(), "plate": f"{folder.name}/{name}"}
        config = print_time.plate_config(profile, supports=any(pose.supports for _, _, pose in items),
                                         slicer=slicer)
        (folder / name).write_bytes(plate_3mf([mesh for _, mesh, _ in items], config,
                                                         names=[parts[index].id for index, _, _ in items]))
        written.append(name)
    return written, [dataclasses.replace(p, **files[p.id]) for p in parts]
