"""Print poses and the supports they need.

:func:`support_need` measures the surface of a part that needs support as it stands (downward
faces steeper than the profile's threshold, :func:`support_threshold`, above the bed, but not
the ceilings it bridges) and :func:`support_seconds` their print time.
:func:`candidate_poses` gives the poses a part may print in (upright, upside down, the four
sides and its most probable resting poses, each up direction once); :func:`weigh` turns a part
into one and costs it by the estimate plus its supports, and :func:`posed` marks a mesh as in
its print pose (:data:`POSE_KEY`), so that it is sliced as it stands.  :class:`Pose` is one
such pose with its figures.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import trimesh

from core.printing.estimate import ESTIMATE_LAYER_MM, PrintEstimate, estimate_seconds
from core.printing.plate import as_meshes


#: Key of ``Trimesh.metadata`` marking a mesh already in its print pose:
#: ``{"name": <pose name>, "supports": <bool>}`` (set by :func:`posed`).
#: :func:`~core.printing.print_time.print_time` slices such a mesh as it stands and with the
#: supports the mark says; any other mesh it poses first.
POSE_KEY = "fabrickator_print_pose"

#: Most probable stable resting poses (trimesh.poses.compute_stable_poses)
#: tried besides the axis poses.
STABLE_POSES = 4

#: A downward face needs support when it slopes less than this many degrees
#: from horizontal: PrusaSlicer's support_material_threshold when a
#: profile gives none (the default profile says 50).
OVERHANG_DEG = 50.0

#: Faces lower than this (mm) above the bed rest on it.
BED_EPS_MM = 0.05

#: A horizontal downward face region anchored on walls going down and no
#: wider than this (mm, the short side of its box) is bridged, not supported
#: (a brick's cavity ceiling: 13.3 mm under a 2-wide brick).
BRIDGE_MM = 15.0

#: A part needs supports when more than this much surface (mm^2) does
#: (:func:`support_need`): a stray facet or a chamfer's edge does not.
SUPPORT_MIN_MM2 = 5.0

#: Print time of supports: seconds per mm^2 of supported surface and per
#: layer up to the highest supported face, fitted (non-negative least
#: squares on relative error) to prusa-slicer 2.5 with automatic supports
#: minus without, on T shapes and shelves with 200..600 mm^2 supported at
#: 10..40 mm: relative error within 8 %.
SUPPORT_S_PER_MM2 = 0.355
SUPPORT_S_PER_LAYER = 6.43

#: Seconds charged per mm^2 of supported surface for taking the support
#: off and the rough surface it leaves (a judgement, not a measurement);
#: only the estimate's ranking of poses counts it.
SUPPORT_REMOVAL_S_PER_MM2 = 1.0

#: Least area (mm^2) of flat face a pose must rest on the bed with (a 1x1
#: plate's rim is 30 mm^2); a part balancing on an edge or a point gets
#: no first layer (PrusaSlicer refuses it without supports or a raft).
MIN_BED_CONTACT_MM2 = 20.0


@dataclass
class Pose:
    """A print orientation of one part.

    ``matrix`` (4x4) maps model mm to the bed: rotation, then the shift
    that puts the part's min corner at the origin.  ``name`` is
    ``"upright"``, ``"upside down"``, ``"on side +x"`` (the model's +x face
    down) ..., or ``"resting pose <n>"``.  ``print_s`` is the calibrated
    time estimate without supports, ``support_mm2`` / ``support_mm3`` the
    supported area and support volume it needs (:func:`support_need`),
    ``supports`` whether it is printed with supports (:func:`needs_supports`,
    or the slicer asked for them), ``slicer_s`` PrusaSlicer's time with
    those supports (None when not sliced), ``cost`` what
    :func:`~core.printing.print_time.fastest_pose` minimised, ``studs_up`` the z component of the
    model's +z axis in this pose (1 upright, 0 sideways), ``bed_mm2`` the
    flat area it rests on (:func:`bed_contact`), ``chosen_by`` how it was
    chosen, ``sliced`` the winning slice (its G-code kept only when the
    search was given a work folder).
    """

    name: str
    matrix: np.ndarray
    print_s: float
    support_mm3: float
    support_mm2: float
    cost: float
    studs_up: float
    bed_mm2: float
    supports: bool = False
    slicer_s: float | None = None
    chosen_by: str = ""
    sliced: PrintEstimate | None = None

    def to_json(self) -> dict:
        return {"name": self.name, "matrix": np.round(self.matrix, 9).tolist(),
                "estimate_s": round(self.print_s, 1), "support_mm3": round(self.support_mm3, 1),
                "support_mm2": round(self.support_mm2, 1), "bed_contact_mm2": round(self.bed_mm2, 1),
                "studs_up": round(self.studs_up, 6), "supports": self.supports,
                "slicer_s": None if self.slicer_s is None else round(self.slicer_s, 1),
                "chosen_by": self.chosen_by}


def _rotation(axis, degrees: float) -> np.ndarray:
    return trimesh.transformations.rotation_matrix(math.radians(degrees), axis)


#: Upright, upside down and the four sideways poses: (name, 4x4 rotation).
#: "on side +x" puts the model's +x side on the bed.
AXIS_POSES = (
    ("upright", np.eye(4)),
    ("upside down", _rotation([1, 0, 0], 180)),
    ("on side +x", _rotation([0, 1, 0], 90)),
    ("on side -x", _rotation([0, 1, 0], -90)),
    ("on side +y", _rotation([1, 0, 0], -90)),
    ("on side -y", _rotation([1, 0, 0], 90)),
)


def support_threshold(config: dict[str, str]) -> float:
    """The overhang angle (degrees from horizontal) under which the profile supports
    a face: its ``support_material_threshold``, OVERHANG_DEG when that is 0 (auto) or absent."""
    try:
        degrees = float(config.get("support_material_threshold", "0"))
    except ValueError:
        degrees = 0.0
    return degrees if degrees > 0 else OVERHANG_DEG


def support_need(mesh: trimesh.Trimesh, overhang_deg: float = OVERHANG_DEG) -> tuple[float, float, float]:
    """Supported area (mm^2), support height (mm) and support volume (mm^3) of
    ``mesh`` as it stands on z = min z.

    A downward face needs support when it slopes less than ``overhang_deg``
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
    down = (normals[:, 2] < -math.cos(math.radians(overhang_deg))) & (z > BED_EPS_MM)
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


def needs_supports(mesh: trimesh.Trimesh, overhang_deg: float = OVERHANG_DEG) -> bool:
    """Whether ``mesh``, standing as it is, needs supports: more than SUPPORT_MIN_MM2
    of it does (:func:`support_need`)."""
    return support_need(mesh, overhang_deg)[0] > SUPPORT_MIN_MM2


def support_seconds(area_mm2: float, height_mm: float) -> float:
    """Print time (s) of supports under ``area_mm2`` of surface reaching ``height_mm``."""
    if area_mm2 <= 0:
        return 0.0
    return SUPPORT_S_PER_MM2 * area_mm2 + SUPPORT_S_PER_LAYER * height_mm / ESTIMATE_LAYER_MM


def plate_supports(meshes, overhang_deg: float = OVERHANG_DEG) -> bool:
    """Whether a plate of ``meshes`` is printed with supports: any mesh marked
    posed (:data:`POSE_KEY`) says so, or any other needs them (:func:`needs_supports`)."""
    return any(bool(m.metadata[POSE_KEY]["supports"]) if POSE_KEY in m.metadata
               else needs_supports(m, overhang_deg) for m in as_meshes(meshes))


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


def candidate_poses(mesh: trimesh.Trimesh) -> list[tuple[str, np.ndarray]]:
    """The poses :func:`~core.printing.print_time.fastest_pose` weighs, as (name, 4x4 rotation):
    AXIS_POSES, then the STABLE_POSES most probable resting poses of ``mesh``
    (``trimesh.poses.compute_stable_poses``, turned so the footprint is axis-aligned), each up
    direction once (the first pose with it)."""
    candidates = list(AXIS_POSES)
    stable, _ = trimesh.poses.compute_stable_poses(mesh)
    for n, matrix in enumerate(stable[:STABLE_POSES]):
        rotation = np.eye(4)
        rotation[:3, :3] = matrix[:3, :3]
        candidates.append((f"resting pose {n + 1}", _square_to_axes(mesh, rotation)))
    out, seen = [], []
    for name, rotation in candidates:
        up = rotation[2, :3]
        if not any(np.allclose(up, other, atol=1e-6) for other in seen):
            seen.append(up)
            out.append((name, rotation))
    return out


def posed(mesh: trimesh.Trimesh, pose: Pose) -> trimesh.Trimesh:
    """A copy of ``mesh`` in ``pose`` (min corner at the origin), marked with
    :data:`POSE_KEY` (the pose's name and supports) so :func:`~core.printing.print_time.print_time`
    slices it as it stands."""
    out = mesh.copy()
    out.apply_transform(pose.matrix)
    out.metadata[POSE_KEY] = {"name": pose.name, "supports": bool(pose.supports)}
    return out


def weigh(mesh: trimesh.Trimesh, name: str, rotation: np.ndarray, overhang_deg: float,
           prefer_upright: float) -> tuple[Pose, trimesh.Trimesh]:
    """One candidate pose with its estimate cost, and the mesh in it."""
    mesh = mesh.copy()
    mesh.apply_transform(rotation)
    shift = np.eye(4)
    shift[:3, 3] = -mesh.bounds[0]
    mesh.apply_transform(shift)
    seconds = estimate_seconds([mesh])
    area, height, volume = support_need(mesh, overhang_deg)
    supports = area > SUPPORT_MIN_MM2
    cost = seconds + (support_seconds(area, height) + SUPPORT_REMOVAL_S_PER_MM2 * area if supports else 0.0)
    if name != "upright":
        cost *= 1 + prefer_upright
    return Pose(name, shift @ rotation, seconds, volume, area, cost, float(rotation[2, 2]),
                bed_contact(mesh), supports), mesh
