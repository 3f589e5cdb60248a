"""Export of printed parts: ``parts/<id>.stl`` and ``.step`` per part, 3MF plates.

The STL is the part's watertight mesh.  The STEP is the part's B-rep for
B-rep input; for mesh input (whose exact result is a mesh) it is a faceted
B-rep of that mesh, one planar face per triangle, written directly as
STEP text (:func:`write_faceted_step`).  Both stay in model coordinates,
where the part belongs in the assembly.

The plate ``parts/plate.3mf`` holds every part in its print pose
(:func:`print_pose`: studs up unless another resting pose saves supports,
never studs down), each on the bed (min z = 0), packed in rows within the
printer's bed (:func:`plates`) without overlap, ready to slice.  Parts
that do not all fit one bed go on further plates, ``plate-2.3mf``,
``plate-3.3mf``, ...
"""

from __future__ import annotations

import io
import math
import os
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh
from OCP.IFSelect import IFSelect_RetDone
from OCP.Interface import Interface_Static
from OCP.STEPControl import STEPControl_AsIs, STEPControl_Writer

from core import print_time
from core.errors import InputError
from core.printed import PrintedPart

#: Gap (mm) between parts on a plate, and between the parts and the bed's edge.
SPACING_MM = 5.0

#: Most probable stable resting poses (trimesh.poses.compute_stable_poses)
#: tried besides upright and the four sideways poses.
STABLE_POSES = 4

#: A downward face needs support when it slopes less than this many degrees
#: from horizontal (PrusaSlicer's support_material_threshold, 50).
OVERHANG_DEG = 50.0

#: Faces lower than this (mm) above the bed rest on it.
BED_EPS_MM = 0.05

#: A horizontal downward face region anchored on walls going down and no
#: wider than this (mm, the short side of its box) is bridged, not supported
#: (a brick's cavity ceiling: 13.3 mm under a 2-wide brick).
BRIDGE_MM = 15.0

#: Print time of supports: seconds per mm^2 of supported surface and per
#: layer up to the highest supported face, fitted (non-negative least
#: squares on relative error) to prusa-slicer 2.5 with automatic supports
#: minus without, on T shapes and shelves with 200..600 mm^2 supported at
#: 10..40 mm: relative error within 8 %.
SUPPORT_S_PER_MM2 = 0.355
SUPPORT_S_PER_LAYER = 6.43

#: Seconds charged per mm^2 of supported surface for taking the support
#: off and the rough surface it leaves (a judgement, not a measurement).
SUPPORT_REMOVAL_S_PER_MM2 = 1.0

#: Extra cost (fraction of the pose's cost) of printing a part with studs
#: or tubes in any pose but upright: its clamping features then print with
#: their layers along the stud axis, less round and less precise.
SIDEWAYS_PENALTY = 0.15

#: Studs count as pointing down when their axis has a z component below this.
STUDS_DOWN_Z = -1e-6

#: Least area (mm^2) of flat face a pose must rest on the bed with (a 1x1
#: plate's rim is 30 mm^2); a part balancing on an edge or a point gets
#: no first layer (PrusaSlicer refuses it without supports or a raft).
MIN_BED_CONTACT_MM2 = 20.0


@dataclass
class Pose:
    """A print orientation of one part.

    ``matrix`` (4x4) maps model mm to the bed: rotation, then the shift
    that puts the part's min corner at the origin.  ``name`` is
    ``"upright"``, ``"on side +x"`` (the model's +x face down; studs
    sideways) ..., or ``"resting pose <n>"``.  ``print_s`` is the
    calibrated time estimate without supports, ``support_mm2`` /
    ``support_mm3`` the supported area and support volume it needs,
    ``cost`` what :func:`print_pose` minimised, ``studs_up`` the z
    component of the stud axis in this pose (1 upright, 0 sideways),
    ``bed_mm2`` the flat area it rests on (:func:`bed_contact`).
    """

    name: str
    matrix: np.ndarray
    print_s: float
    support_mm3: float
    support_mm2: float
    cost: float
    studs_up: float
    bed_mm2: float

    def to_json(self) -> dict:
        return {"name": self.name, "matrix": np.round(self.matrix, 9).tolist(),
                "estimate_s": round(self.print_s, 1), "support_mm3": round(self.support_mm3, 1),
                "support_mm2": round(self.support_mm2, 1), "bed_contact_mm2": round(self.bed_mm2, 1),
                "studs_up": round(self.studs_up, 6)}


def _rotation(axis, degrees: float) -> np.ndarray:
    return trimesh.transformations.rotation_matrix(math.radians(degrees), axis)


#: Upright and the four sideways poses: (name, 4x4 rotation).  "on side +x"
#: puts the model's +x side on the bed.
AXIS_POSES = (
    ("upright", np.eye(4)),
    ("on side +x", _rotation([0, 1, 0], 90)),
    ("on side -x", _rotation([0, 1, 0], -90)),
    ("on side +y", _rotation([1, 0, 0], -90)),
    ("on side -y", _rotation([1, 0, 0], 90)),
)


def support_need(mesh: trimesh.Trimesh) -> tuple[float, float, float]:
    """Supported area (mm^2), support height (mm) and support volume (mm^3) of
    ``mesh`` as it stands on z = min z.

    A downward face needs support when it slopes less than OVERHANG_DEG
    from horizontal and is above the bed, unless it belongs to a bridge: a
    connected region of horizontal downward faces whose every outer edge
    meets a face reaching lower (walls it spans between, as a brick's
    cavity ceiling) and whose box is at most BRIDGE_MM wide.  The height is
    that of the highest supported face; the volume is each supported face's
    area projected on the bed times its height (the column a slicer fills,
    ignoring that it may land on the part itself).
    """
    normals, areas = mesh.face_normals, mesh.area_faces
    z = mesh.triangles_center[:, 2] - mesh.bounds[0][2]
    down = (normals[:, 2] < -math.cos(math.radians(OVERHANG_DEG))) & (z > BED_EPS_MM)
    flat = down & (normals[:, 2] < -1 + 1e-6)
    if flat.any():
        pairs = mesh.face_adjacency
        low = mesh.vertices[mesh.faces][:, :, 2].min(axis=1)
        inside = flat[pairs[:, 0]] & flat[pairs[:, 1]]
        regions = trimesh.graph.connected_components(pairs[inside], nodes=np.flatnonzero(flat))
        edge = flat[pairs[:, 0]] != flat[pairs[:, 1]]
        face, other = np.where(flat[pairs[edge, 0]], pairs[edge, 0], pairs[edge, 1]), \
            np.where(flat[pairs[edge, 0]], pairs[edge, 1], pairs[edge, 0])
        loose = np.zeros(len(mesh.faces), bool)
        loose[face[low[other] >= mesh.triangles_center[face, 2] - BED_EPS_MM]] = True
        corners = mesh.triangles[:, :, :2]
        for region in regions:
            extent = np.ptp(corners[region].reshape(-1, 2), axis=0)
            if not loose[region].any() and extent.min() <= BRIDGE_MM:
                down[region] = False
    if not down.any():
        return 0.0, 0.0, 0.0
    projected = areas[down] * -normals[down, 2]
    return float(areas[down].sum()), float(z[down].max()), float(np.dot(projected, z[down]))


def support_seconds(area_mm2: float, height_mm: float) -> float:
    """Print time (s) of supports under ``area_mm2`` of surface reaching ``height_mm``."""
    if area_mm2 <= 0:
        return 0.0
    return SUPPORT_S_PER_MM2 * area_mm2 + SUPPORT_S_PER_LAYER * height_mm / print_time.ESTIMATE_LAYER_MM


def print_pose(mesh: trimesh.Trimesh, studs: bool = True, clamping: bool = True) -> Pose:
    """The print orientation of a part (its mesh in model mm, studs along +z).

    The rule: candidates are upright (as the brick stands: studs up, its
    underside on the bed), the four sideways poses (a side on the bed,
    studs pointing sideways) and the STABLE_POSES most probable resting
    poses of the part (``trimesh.poses.compute_stable_poses``).  When the
    part has studs (``studs``) every pose that would point them down, onto
    the bed, is dropped: studs printed facing down need support and lose
    their precision.  Each remaining pose costs its estimated print time
    (:func:`core.print_time.estimate_seconds`, which in a pose changes with
    the height) plus its supports (:func:`support_need`): their print time
    (:func:`support_seconds`) and SUPPORT_REMOVAL_S_PER_MM2 per mm^2 of
    supported surface for removing them.  When the part has complete
    studs or tubes (``clamping``), any pose but upright costs
    SIDEWAYS_PENALTY more: printed upright, the clamping sides lie in the
    layers and come out round.  The cheapest pose wins, upright on a tie,
    among the poses resting on at least MIN_BED_CONTACT_MM2 of flat face
    (:func:`bed_contact`; among all when none does).
    """
    candidates = list(AXIS_POSES)
    stable, _ = trimesh.poses.compute_stable_poses(mesh)
    for n, matrix in enumerate(stable[:STABLE_POSES]):
        rotation = np.eye(4)
        rotation[:3, :3] = matrix[:3, :3]
        candidates.append((f"resting pose {n + 1}", _square_to_axes(mesh, rotation)))
    poses, seen = [], []
    for name, rotation in candidates:
        up = rotation[2, :3]
        if any(np.allclose(up, other, atol=1e-6) for other in seen):
            continue
        seen.append(up)
        studs_up = float(rotation[2, 2])
        if studs and studs_up < STUDS_DOWN_Z:
            continue
        posed = mesh.copy()
        posed.apply_transform(rotation)
        shift = np.eye(4)
        shift[:3, 3] = -posed.bounds[0]
        posed.apply_transform(shift)
        seconds = print_time.estimate_seconds([posed])
        area, height, volume = support_need(posed)
        cost = seconds + support_seconds(area, height) + SUPPORT_REMOVAL_S_PER_MM2 * area
        if clamping and name != "upright":
            cost *= 1 + SIDEWAYS_PENALTY
        poses.append(Pose(name, shift @ rotation, seconds, volume, area, cost, studs_up, bed_contact(posed)))
    resting = [p for p in poses if p.bed_mm2 >= MIN_BED_CONTACT_MM2] or poses
    return min(resting, key=lambda p: p.cost)


def bed_contact(mesh: trimesh.Trimesh) -> float:
    """Area (mm^2) of the downward flat faces of ``mesh`` lying on its lowest plane, the bed."""
    low = mesh.triangles_center[:, 2] - mesh.bounds[0][2] < BED_EPS_MM
    return float(mesh.area_faces[low & (mesh.face_normals[:, 2] < -1 + 1e-6)].sum())


def _square_to_axes(mesh: trimesh.Trimesh, rotation: np.ndarray) -> np.ndarray:
    """``rotation`` followed by the turn about z that makes the part's footprint
    box (minimum-area rectangle of its convex hull seen from above) axis-aligned."""
    points = trimesh.transform_points(mesh.convex_hull.vertices, rotation)[:, :2]
    turn_2d, _ = trimesh.bounds.oriented_bounds_2D(points)
    turn = np.eye(4)
    turn[:2, :2] = turn_2d[:2, :2]
    return turn @ rotation


def lay_flat(part: PrintedPart | trimesh.Trimesh) -> tuple[trimesh.Trimesh, Pose]:
    """A copy of the part's mesh in its :func:`print_pose`, min corner at the origin, and the pose.

    For a PrintedPart the studs rule applies when it has any studs and the
    clamping penalty when any stud or tube is complete; a bare mesh is
    treated as a part with complete studs.
    """
    if isinstance(part, PrintedPart):
        mesh, studs = part.mesh, bool(part.studs)
        clamping = bool(part.complete_studs or part.complete_tubes)
    else:
        mesh, studs, clamping = part, True, True
    pose = print_pose(mesh, studs, clamping)
    out = mesh.copy()
    out.apply_transform(pose.matrix)
    return out, pose


def plates(parts: list, bed=None) -> list[list[tuple[int, trimesh.Trimesh, Pose]]]:
    """The parts laid flat (:func:`lay_flat`) and packed on as few beds as this simple rule gives.

    ``bed`` is the printable (x, y) in mm (default: the slicer profile's,
    :func:`core.print_time.build_volume`).  Shelf packing: each part is
    turned about z so its longer side runs along the bed's longer side
    when that fits, the parts are taken tallest footprint (y) first and
    set left to right in rows, SPACING_MM apart and from the bed's edges; a
    part that does not fit the row starts a new row above, a row that does
    not fit the bed starts a new plate.  A part larger than the bed gets a
    plate of its own (the slicer will refuse it).  Returns per plate the
    (index into ``parts``, mesh in bed coordinates, pose) of its parts;
    every mesh has min z = 0 and the footprints do not overlap.
    """
    size = np.asarray(bed if bed is not None else
                      print_time.build_volume(print_time.load_profile())[:2], dtype=float)
    laid = []
    for index, part in enumerate(parts):
        mesh, pose = lay_flat(part)
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
        move[:2, 3] = [x, y]
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


def export_parts(parts: list[PrintedPart], folder: str | os.PathLike, bed=None) -> list[str]:
    """Write ``<id>.stl``, ``<id>.step`` per part and the 3MF plate(s) into ``folder``.

    Sets ``stl`` and ``step`` of each part to the paths relative to the
    folder's parent (``parts/P1.stl``) and ``pose`` to its print pose
    (:meth:`Pose.to_json` plus the plate file it is on); returns the names
    written.  The plates come from :func:`plates` (``bed`` as there):
    ``plate.3mf``, then ``plate-2.3mf`` ... when the parts need more beds.
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
    for number, items in enumerate(plates(parts, bed) if parts else [], start=1):
        name = "plate.3mf" if number == 1 else f"plate-{number}.3mf"
        scene = trimesh.Scene()
        for index, mesh, pose in items:
            part = parts[index]
            scene.add_geometry(mesh, node_name=part.id, geom_name=part.id)
            part.pose = {**pose.to_json(), "plate": f"{folder.name}/{name}"}
        (folder / name).write_bytes(trimesh.exchange.threemf.export_3MF(scene))
        written.append(name)
    return written
