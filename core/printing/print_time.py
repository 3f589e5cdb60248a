"""How long parts take to print, and the pose that prints them fastest.

:func:`print_time` puts all given meshes on one plate, slices them with the
``prusa-slicer`` command line and the MK3S, 0.20 mm QUALITY, Prusament PLA
presets resolved from the vendor bundle installed with that slicer
(:mod:`core.printing.slicer_profile`: PrusaSlicer 2.5's and 2.9's bundles alike; the
committed fallback profile where none is found), and reads the slicer's
own estimate from the G-code.  The parts are placed apart on the bed here
(:func:`arrange`) and sliced with ``--dont-arrange``, which every version
honours alike (PrusaSlicer 2.9 does not arrange a project's objects and
crashes on ones that overlap).  Supports are switched on (:data:`SUPPORT_SETTINGS`:
PrusaSlicer's automatic supports, none under bridges) exactly when a part
on the plate needs them (:func:`needs_supports`); a plate the slicer still
refuses for want of support is sliced again with supports, then with
supports on a raft.

A mesh that is not in a print pose yet (the whole model: ``core.printing.export``
marks the parts it lays flat with :data:`POSE_KEY`) is first turned into
the pose that prints fastest (:func:`fastest_pose`): the candidate poses
are ranked by the calibrated estimate plus their supports, the best
POSES_SLICED are sliced, each with the supports it needs, SLICER_PROCESSES
at a time, and PrusaSlicer's time decides.

Where no slicer is installed, it is disabled (``FABRICKATOR_SLICER=none``)
or it fails (parts too large for the bed, timeout), :func:`estimate_seconds`
stands in: a linear model in volume, surface area and layers fitted against
real PrusaSlicer runs, plus :func:`support_seconds` for the parts that need
supports.  The returned :class:`PrintEstimate` says which method gave the
number, the pose and whether supports were used, and why the slicer was
not used.
"""

from __future__ import annotations

import io
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
import threading
import zipfile
from concurrent.futures import Future, ThreadPoolExecutor
from contextlib import nullcontext
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import trimesh
from scipy.optimize import nnls

from core.errors import InputError
from core.io import output_dir
from core.printing import slice_cache, slicer_profile

#: The flat PrusaSlicer config used where the slicer's vendor bundle is not found
#: (:mod:`core.printing.slicer_profile`); a ``profile`` of None means the bundle's presets.
FALLBACK_PROFILE = slicer_profile.FALLBACK_PROFILE

#: Environment variable naming the slicer binary, or ``none`` to disable it.
SLICER_ENV = "FABRICKATOR_SLICER"

#: Seconds one slicer run may take before it is killed.
SLICER_TIMEOUT_S = 300.0

#: Slicer processes :func:`fastest_pose` runs at once (the machine's cores).
SLICER_PROCESSES = 2

ESTIMATE_METHOD = "estimate (volume/surface/layers model)"

#: Layer height (mm) the estimate counts layers with: the default profile's.
ESTIMATE_LAYER_MM = 0.2

#: Coefficients of :func:`estimate_seconds`, multiplying the plate's
#: (volume mm^3, surface area mm^2, layers, part-layers, 1).  Fitted with
#: :func:`fit_estimate` (least squares on relative error, coefficients >= 0)
#: against prusa-slicer 2.5.0 with FALLBACK_PROFILE (its bundle) on the calibration plates
#: of tests/core/test_print_time.py (boxes, cylinders, a tube, a cup, a
#: sphere, LEGO-like studded parts, multi-part plates and six models of
#: /work/shared/models), 21 plates from 20 min to 5 h, sliced without
#: supports.  Relative error of the fit: rms 10.6 %, max 21 %; leave-one-out
#: rms 14 %, max 31 %.
ESTIMATE_COEFFS = (0.04172, 0.2796, 5.67, 0.5232, 53.98)

#: Settings laid over the profile for a plate that needs supports:
#: PrusaSlicer's automatic supports (generated only under overhangs steeper
#: than the profile's support_material_threshold) and none under bridges,
#: as :func:`support_need` counts them (a brick's socket stays clear).
SUPPORT_SETTINGS = {"support_material": "1", "support_material_auto": "1", "dont_support_bridges": "1"}

#: SUPPORT_SETTINGS on a 2-layer raft, for a part the bed barely touches.
RAFT_SETTINGS = {**SUPPORT_SETTINGS, "raft_layers": "2"}

#: Slicer settings tried in turn, (label, settings laid over the profile):
#: as the profile says (no supports), then with automatic supports, then
#: with supports on a 2-layer raft.  A plate that needs supports starts
#: with the second; the next one is tried only when PrusaSlicer refuses a
#: plate or warns for want of support (:data:`_NEEDS_SUPPORT`).
RETRY_SETTINGS = (
    ("", {}),
    ("with supports", SUPPORT_SETTINGS),
    ("with supports and a 2-layer raft", RAFT_SETTINGS),
)

#: Key of ``Trimesh.metadata`` marking a mesh already in its print pose:
#: ``{"name": <pose name>, "supports": <bool>}`` (set by :func:`posed`).
#: :func:`print_time` slices such a mesh as it stands and with the
#: supports the mark says; any other mesh it poses first.
POSE_KEY = "fabrickator_print_pose"

#: Least gap (mm) between parts on a plate (:func:`arrange`).  Supports
#: spread a few mm beyond their part: PrusaSlicer 2.9 finds "gcode path
#: conflicts" between two supported lens mounts 6 mm apart (and then crashes
#: on the command line), none at 8 mm.
ARRANGE_GAP_MM = 10.0

#: Where PrusaSlicer reads a 3MF's project settings from.
SLIC3R_CONFIG = "Metadata/Slic3r_PE.config"

#: Most probable stable resting poses (trimesh.poses.compute_stable_poses)
#: tried besides the axis poses.
STABLE_POSES = 4

#: Candidate poses sliced by :func:`fastest_pose`: the best by estimate.
POSES_SLICED = 3

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

#: PrusaSlicer's messages that supports or a raft can cure: a part touching
#: the bed only at a point or thin edge, a piece hovering above the rest.
_NEEDS_SUPPORT = re.compile(r"no extrusions in the first layer|empty layer between", re.I)

_TIME_LINE = re.compile(r"^; estimated printing time \(normal mode\) = (.+)$", re.M)
_DURATION = re.compile(r"^\s*(?:(\d+)d)?\s*(?:(\d+)h)?\s*(?:(\d+)m)?\s*(?:(\d+)s)?\s*$")
_VERSION = re.compile(r"^; generated by PrusaSlicer (\d+(?:\.\d+)*)", re.M)


@dataclass
class PrintEstimate:
    """Print time of one plate.

    ``method`` names the slicer, version and profile and the settings that
    were added (``"prusa-slicer 2.5.0 (MK3S, 0.20mm QUALITY, PLA; with
    supports)"``), then the pose print_time chose, if it chose one
    (``"; posed on side +y, the fastest of 3 sliced poses"``); or it starts
    with ``"estimate"`` and then says why no slicer was used.
    ``gcode_path`` is the sliced G-code, or None for an estimate.
    ``supports`` says whether the time includes supports, ``pose`` names
    the pose :func:`print_time` turned the mesh into (several meshes'
    joined by ", "), None when every mesh came in its print pose.
    ``cached`` says the slicer's answer came from :mod:`core.printing.slice_cache`
    (the same plate sliced before; no G-code then).  ``enlarged_bed`` says it
    was sliced on a bed enlarged to fit (:func:`core.printing.printers.reference_time`).
    """

    seconds: float
    method: str
    gcode_path: str | None
    supports: bool = False
    pose: str | None = None
    cached: bool = False
    enlarged_bed: bool = False


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
    :func:`fastest_pose` minimised, ``studs_up`` the z component of the
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


class _SlicerFailed(Exception):
    """The slicer could not give a time; the message is the one-line reason."""


def slicer_path() -> str | None:
    """The PrusaSlicer binary to use, or None when there is none.

    ``$FABRICKATOR_SLICER`` wins when set: ``none`` (any case) or an empty
    value disables slicing, anything else is a binary name or path, returned
    resolved if it is executable and None otherwise.  Unset, the first of
    ``prusa-slicer`` and ``prusa-slicer-console`` on PATH.
    """
    chosen = os.environ.get(SLICER_ENV)
    if chosen is not None:
        if chosen.strip().lower() in ("", "none"):
            return None
        return shutil.which(chosen.strip())
    for name in ("prusa-slicer", "prusa-slicer-console"):
        found = shutil.which(name)
        if found:
            return found
    return None


def parse_duration(text: str) -> float:
    """Seconds in a PrusaSlicer duration such as ``"1d 2h 3m 4s"``.

    Every unit is optional (``"45s"``, ``"2h 0m 5s"``, ``"1d 0h 1m 0s"``);
    raises ValueError for anything else, including an empty string.
    """
    match = _DURATION.match(text)
    if not match or not any(match.groups()):
        raise ValueError(f"not a PrusaSlicer duration: {text!r}")
    days, hours, minutes, seconds = (int(g) if g else 0 for g in match.groups())
    return float(((days * 24 + hours) * 60 + minutes) * 60 + seconds)


def gcode_seconds(gcode: str | os.PathLike) -> float:
    """The normal-mode print time PrusaSlicer wrote into ``gcode``, in seconds.

    Raises ValueError when the file has no such line.
    """
    text = Path(gcode).read_text(encoding="utf-8", errors="replace")
    match = _TIME_LINE.search(text)
    if not match:
        raise ValueError(f"{gcode}: no '; estimated printing time (normal mode)' line")
    return parse_duration(match[1])


def load_profile(profile: str | os.PathLike | None = None, slicer: str | None = "auto") -> dict[str, str]:
    """The settings to slice with: the ``key = value`` pairs of a flat PrusaSlicer ini, values verbatim.

    ``profile`` None is the default: the presets resolved from the vendor
    bundle installed with the slicer ``slicer`` names (as in
    :func:`resolve_slicer`; :func:`core.printing.slicer_profile.bundle_profile`), or
    FALLBACK_PROFILE when there is no slicer, no bundle beside it, or the
    bundle lacks the presets.  Raises InputError when a given file cannot
    be read.  A dict (a chosen printer's config, :mod:`core.printing.printers`) is the settings
    themselves.
    """
    if isinstance(profile, dict):
        return dict(profile)
    if profile is None:
        binary, _ = resolve_slicer(slicer)
        bundle = slicer_profile.find_bundle(binary)
        if bundle is not None:
            try:
                return slicer_profile.bundle_profile(bundle)
            except (OSError, UnicodeError, slicer_profile.BundleError):
                pass
        profile = FALLBACK_PROFILE
    try:
        text = Path(profile).read_text(encoding="utf-8")
    except OSError as exc:
        raise InputError(f"slicer profile {profile}: {exc.strerror or exc}") from None
    pairs = (line.split("=", 1) for line in text.splitlines()
             if "=" in line and not line.lstrip().startswith(("#", ";")))
    return {key.strip(): value.strip() for key, value in pairs}


def build_volume(config: dict[str, str]) -> np.ndarray:
    """Printable size (x, y, z) in mm: the size of :func:`bed_rectangle` and ``max_print_height``.

    Raises InputError when the profile lacks either key or they are malformed.
    """
    bed = bed_rectangle(config)
    try:
        return np.append(bed[1] - bed[0], float(config["max_print_height"]))
    except (KeyError, ValueError) as exc:
        raise InputError(f"slicer profile: no valid bed_shape / max_print_height ({exc})") from None


def profile_label(config: dict[str, str]) -> str:
    """Short name of a profile: ``"MK3S, 0.20mm QUALITY, PLA"``."""
    print_name = config.get("print_settings_id", "").strip('"').split("@")[0].strip()
    return ", ".join(part for part in (config.get("printer_model", ""), print_name,
                                       config.get("filament_type", "").strip('"')) if part)


def as_meshes(meshes) -> list[trimesh.Trimesh]:
    """Meshes from a list of ``trimesh.Trimesh`` and/or mesh file paths.

    Raises InputError naming the file that is missing, unreadable or holds
    no triangles, ValueError for a given mesh without triangles (the
    caller's).
    """
    loaded = []
    for index, item in enumerate(meshes):
        if isinstance(item, trimesh.Trimesh):
            mesh, name = item, f"#{index}"
        else:
            name = str(item)
            try:
                mesh = trimesh.load(str(item), force="mesh")
            except Exception as exc:  # trimesh raises many types for bad files
                raise InputError(f"cannot read mesh {item}: {exc}") from None
            if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
                raise InputError(f"cannot read mesh {item}: no triangles")
        if len(mesh.faces) == 0:
            raise ValueError(f"mesh {name} has no triangles")
        loaded.append(mesh)
    return loaded


def estimate_features(meshes) -> np.ndarray:
    """The estimate's inputs for one plate: (volume, area, layers, part-layers, 1).

    Volume (mm^3, absolute value, so inverted meshes count) and surface
    area (mm^2) are summed over the parts; layers is the tallest part's
    height / ESTIMATE_LAYER_MM (layer changes); part-layers the sum of that
    over all parts (per-layer travel and retraction between parts).
    """
    parts = as_meshes(meshes)
    return plate_features([abs(float(m.volume)) for m in parts], [float(m.area) for m in parts],
                          [float(m.extents[2]) for m in parts])


def plate_features(volumes, areas, heights) -> np.ndarray:
    """The estimate's inputs (as :func:`estimate_features`) of one plate whose parts have
    these volumes (mm^3), surface areas (mm^2) and heights on the bed (mm), one each."""
    layers = np.asarray(heights, dtype=float) / ESTIMATE_LAYER_MM
    return np.array([float(np.sum(volumes)), float(np.sum(areas)), layers.max(), layers.sum(), 1.0])


def estimate_seconds(meshes, coeffs=ESTIMATE_COEFFS) -> float:
    """Estimated print time in seconds of all ``meshes`` on one plate, no slicer needed.

    ``coeffs`` . :func:`estimate_features`; the default coefficients are
    calibrated for FALLBACK_PROFILE (see ESTIMATE_COEFFS).  An empty plate
    takes 0 s.
    """
    if len(meshes) == 0:
        return 0.0
    return float(estimate_features(meshes) @ np.asarray(coeffs, dtype=float))


def fit_estimate(plates: list, seconds) -> tuple[np.ndarray, np.ndarray]:
    """Coefficients for :func:`estimate_seconds` fitted to measured times.

    ``plates`` is a list of mesh lists, ``seconds`` the slicer's time for
    each.  Minimises the squared relative error with coefficients >= 0
    (scipy ``nnls``); returns the coefficients and each plate's relative
    error (estimate / measured - 1).
    """
    measured = np.asarray(seconds, dtype=float)
    features = np.array([estimate_features(plate) for plate in plates])
    coeffs, _ = nnls(features / measured[:, None], np.ones_like(measured))
    return coeffs, features @ coeffs / measured - 1.0


def resolve_slicer(slicer: str | None = "auto") -> tuple[str | None, str]:
    """The slicer binary ``slicer`` asks for, or None and why there is none.

    ``"auto"``: :func:`slicer_path`; None or ``"none"``: no slicer; anything
    else: that binary, found on PATH or as a path.  The reason (for a
    method string) is set either way and only meaningful with None.
    """
    if slicer == "auto":
        reason = (f"{SLICER_ENV}={os.environ[SLICER_ENV]}" if SLICER_ENV in os.environ
                  else "prusa-slicer not found on PATH")
        return slicer_path(), reason
    if slicer is None or slicer.strip().lower() == "none":
        return None, "slicer disabled"
    return shutil.which(slicer), f"slicer {slicer} not found"


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


def plate_config(profile: str | os.PathLike | None = None, supports: bool = False,
                 slicer: str | None = "auto") -> dict[str, str]:
    """The settings a plate is sliced with: the profile's (:func:`load_profile`, for
    ``slicer``), SUPPORT_SETTINGS over them when ``supports``.  Raises InputError
    when the profile cannot be read."""
    return {**load_profile(profile, slicer), **(SUPPORT_SETTINGS if supports else {})}


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
    """The poses :func:`fastest_pose` weighs, as (name, 4x4 rotation): AXIS_POSES,
    then the STABLE_POSES most probable resting poses of ``mesh``
    (``trimesh.poses.compute_stable_poses``, turned so the footprint is
    axis-aligned), each up direction once (the first pose with it)."""
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
    :data:`POSE_KEY` (the pose's name and supports) so :func:`print_time`
    slices it as it stands."""
    out = mesh.copy()
    out.apply_transform(pose.matrix)
    out.metadata[POSE_KEY] = {"name": pose.name, "supports": bool(pose.supports)}
    return out


def _weigh(mesh: trimesh.Trimesh, name: str, rotation: np.ndarray, overhang_deg: float,
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


def _slice_or_reason(mesh: trimesh.Trimesh, workdir, profile, slicer: str, supports: bool) -> PrintEstimate | str:
    """:func:`slice_plate` of ``mesh`` alone, or the reason it failed."""
    try:
        return slice_plate([mesh], workdir, profile, slicer, supports=supports)
    except _SlicerFailed as exc:
        return str(exc)


def fastest_pose(mesh: trimesh.Trimesh, workdir: str | os.PathLike | None = None,
                 profile: str | os.PathLike | None = None, slicer: str | None = "auto",
                 keep_up=(), prefer_upright: float = 0.0, sliced: int = POSES_SLICED) -> Pose:
    """The pose ``mesh`` (model mm) prints fastest in, with the supports it needs.

    Candidates are :func:`candidate_poses`; ``keep_up`` lists (direction,
    least z) pairs: a pose that turns a model-frame direction (a 3-vector,
    e.g. the studs' axis or an engraved face's normal) to a z component
    below its least z is not allowed (ValueError when none is).  Poses
    alike (the same height, footprint, supported area, bed contact and
    estimate, as a cube's six) count once, the first.  Among the
    allowed poses, those resting on at least MIN_BED_CONTACT_MM2 of flat
    face are kept (all when none does), of those the ones that fit the
    profile's build volume (all when none does).  Each is costed by the
    estimate: :func:`estimate_seconds` plus, when it needs supports
    (:func:`needs_supports` at the profile's threshold),
    :func:`support_seconds` and SUPPORT_REMOVAL_S_PER_MM2 per supported
    mm^2.  Any pose but upright costs ``prefer_upright`` (a fraction) more,
    in this and in the slicer's ranking.

    With a slicer (``slicer`` as in :func:`resolve_slicer`), the ``sliced``
    cheapest by estimate are sliced on their own (:func:`slice_plate`,
    supports on exactly for those that need them), SLICER_PROCESSES at a
    time, in folders under ``workdir`` (a temporary folder when None), and
    the pose with the least slicer time (times the upright preference)
    wins; ``slicer_s`` and ``sliced`` hold its slice.  Without a slicer,
    or when every slice fails, the cheapest estimate wins and
    ``chosen_by`` says why.  Ties go to the pose the estimate ranks first,
    and among poses the estimate ties, to the earlier candidate (upright
    first).  ``profile`` is as in :func:`load_profile` (None: the slicer's
    bundle).  Raises InputError for an unreadable profile.
    """
    binary, reason = resolve_slicer(slicer)
    config = load_profile(profile, binary)
    overhang = support_threshold(config)
    rules = [(np.asarray(d, float) / np.linalg.norm(d), float(z)) for d, z in keep_up]
    allowed = [(name, rotation) for name, rotation in candidate_poses(mesh)
               if all(float(rotation[2, :3] @ d) >= z for d, z in rules)]
    if not allowed:
        raise ValueError("no candidate pose keeps every required direction up")
    weighed, seen = [], set()
    for name, rotation in allowed:
        pose, placed = _weigh(mesh, name, rotation, overhang, prefer_upright)
        alike = (round(float(placed.extents[2]), 1), *np.round(np.sort(placed.extents[:2]), 1),
                 round(pose.support_mm2), round(pose.bed_mm2), round(pose.cost))
        if alike not in seen:
            seen.add(alike)
            weighed.append((pose, placed))
    resting = [w for w in weighed if w[0].bed_mm2 >= MIN_BED_CONTACT_MM2] or weighed
    volume = build_volume(config)
    fitting = [w for w in resting if np.all(w[1].extents <= volume + 1e-6)] or resting
    ranked = sorted(fitting, key=lambda w: w[0].cost)
    if binary is None:
        return replace(ranked[0][0], chosen_by=f"by the estimate ({reason})")
    kept = ranked[:sliced]
    with nullcontext(workdir) if workdir is not None else output_dir.scratch("pose") as work:
        results = in_parallel(lambda w: _slice_or_reason(w[1], work, profile, binary, w[0].supports),
                              kept, SLICER_PROCESSES)
    timed = []
    for (pose, _), result in zip(kept, results):
        if isinstance(result, PrintEstimate):
            upright = 1.0 if pose.name == "upright" else 1.0 + prefer_upright
            timed.append(replace(pose, slicer_s=result.seconds, cost=result.seconds * upright,
                                 supports=result.supports,
                                 sliced=result if workdir is not None else replace(result, gcode_path=None)))
    if not timed:
        return replace(ranked[0][0], chosen_by=f"by the estimate ({results[0]})")
    best = min(timed, key=lambda p: p.cost)
    return replace(best, chosen_by=f"the fastest of {len(timed)} sliced poses")


def slice_plate(meshes, workdir: str | os.PathLike, profile: str | os.PathLike | None = None,
                slicer: str | None = None, supports: bool | None = None) -> PrintEstimate:
    """Slice all ``meshes`` on one plate with PrusaSlicer; the time from its G-code.

    Writes the plate as a 3MF carrying its settings (:func:`plate_3mf`,
    the file ``core.printing.export`` writes for the user) and the G-code into a new
    folder under ``workdir``, and slices it as a user would
    (``prusa-slicer --dont-arrange --export-gcode plate-1.3mf``), the parts
    where :func:`arrange` puts them (as given when they lie apart on the
    bed, as ``core.printing.export``'s plates do), each in its orientation.  The
    settings are the profile's (:func:`plate_config`; ``profile`` None: the
    slicer's own bundle), with SUPPORT_SETTINGS when
    ``supports`` is True, or, for None, when :func:`plate_supports` says a
    part needs them.  When PrusaSlicer
    refuses the plate for want of support ("no extrusions in the first
    layer": a part touches the bed only at a point or a thin edge) or
    warns of empty layers (a piece hovers), the plate is sliced again with
    the next of :data:`RETRY_SETTINGS` (automatic supports, then supports
    and a raft).  ``method`` ends with the settings used (``"...; with
    supports"``), ``supports`` says whether they include supports.  Raises
    _SlicerFailed with a one-line reason when a part exceeds the build
    volume, the parts do not fit the bed together, the slicer fails (also
    with every retry setting) or exceeds SLICER_TIMEOUT_S.  A plate sliced before (the
    same meshes on the bed, settings and binary: :mod:`core.printing.slice_cache`) is not sliced
    again: its stored answer comes back, ``cached`` and without G-code.
    """
    slicer = slicer or slicer_path()
    if not slicer:
        raise _SlicerFailed("no slicer")
    config = load_profile(profile, slicer)
    volume = build_volume(config)
    parts = as_meshes(meshes)
    for index, mesh in enumerate(parts):
        if np.any(mesh.extents > volume + 1e-6):
            size = " x ".join(f"{v:.0f}" for v in mesh.extents)
            bed = " x ".join(f"{v:.0f}" for v in volume)
            raise _SlicerFailed(f"part {index} ({size} mm) exceeds the build volume {bed} mm")
    try:
        parts = arrange(parts, config)
    except ValueError as exc:
        raise _SlicerFailed(str(exc)) from None
    if supports is None:
        supports = plate_supports(parts, support_threshold(config))
    attempts = RETRY_SETTINGS[1:] if supports else RETRY_SETTINGS
    slice_key = slice_cache.key(parts, config_text(config), attempts, slicer)
    known = slice_cache.get(slice_key)
    if known is not None:
        return PrintEstimate(float(known["seconds"]), str(known["method"]), None,
                             supports=bool(known["supports"]), cached=True)
    Path(workdir).mkdir(exist_ok=True)      # not its parents: a run's removed folder stays so
    folder = Path(tempfile.mkdtemp(prefix="slice-", dir=workdir)).resolve()
    for attempt, (label, settings) in enumerate(attempts):
        last = attempt == len(attempts) - 1
        suffix = f"-{attempt}" if attempt else ""
        gcode, plate = folder / f"plate{suffix}.gcode", folder / f"plate{suffix}.3mf"
        plate.write_bytes(plate_3mf(parts, {**config, **settings}))
        command = [slicer, "--loglevel", "1", "--dont-arrange", "--export-gcode", "--output", str(gcode),
                   str(plate)]
        try:
            run = subprocess.run(dying_with_us(yielding(command)), cwd=folder, capture_output=True, text=True,
                                 timeout=SLICER_TIMEOUT_S, stdin=subprocess.DEVNULL)
        except subprocess.TimeoutExpired:
            raise _SlicerFailed(f"{Path(slicer).name} timed out after {SLICER_TIMEOUT_S:.0f} s") from None
        except OSError as exc:
            raise _SlicerFailed(f"cannot run {slicer}: {exc.strerror or exc}") from None
        refused = run.returncode != 0 or not gcode.exists()
        needs_support = bool(_NEEDS_SUPPORT.search(run.stderr + run.stdout))
        if needs_support and not last:
            continue
        if refused:
            tried = f" (even {label})" if label else ""
            raise _SlicerFailed(f"{Path(slicer).name} failed{tried}: {_last_message(run)}")
        break
    try:
        seconds = gcode_seconds(gcode)
    except ValueError as exc:
        raise _SlicerFailed(str(exc)) from None
    with open(gcode, encoding="utf-8", errors="replace") as head:
        version = _VERSION.search(head.read(4096))
    name = f"prusa-slicer {version[1]}" if version else Path(slicer).name
    needed = "".join(f"; {text}" for text in (label, "slicer still warns of empty layers" if needs_support else "")
                     if text)
    result = PrintEstimate(seconds, f"{name} ({profile_label(config)}{needed})", str(gcode),
                           supports=settings.get("support_material") == "1")
    slice_cache.put(slice_key, {"seconds": result.seconds, "method": result.method,
                                "supports": result.supports})
    return result


def dying_with_us(command: list[str]) -> list[str]:
    """``command`` so that the process it starts is killed when the thread that starts it
    ends, whatever ends it (a kill of the run included): on Linux, run through
    util-linux ``setpriv --pdeathsig KILL`` when that is installed; elsewhere as it is
    (a Ctrl-C at the terminal reaches the slicer too, it shares our process group)."""
    if not sys.platform.startswith("linux"):
        return command
    setpriv = shutil.which("setpriv")
    return [setpriv, "--pdeathsig", "KILL", "--", *command] if setpriv else command


#: Niceness of the slicer's processes: slicing runs beside the layout stages, which
#: decide how soon a run ends, so it takes the cores they leave idle.
SLICER_NICENESS = 10


def yielding(command: list[str]) -> list[str]:
    """``command`` run at :data:`SLICER_NICENESS` (through ``nice`` where it is installed)."""
    nice = shutil.which("nice")
    return [nice, "-n", str(SLICER_NICENESS), *command] if nice else command


def in_parallel(fn, items, workers: int) -> list:
    """``[fn(item) for item in items]``, ``workers`` at a time in threads.  When the caller
    is interrupted (Ctrl-C, a failure) it does not wait for the running calls: the pool is
    shut down at once, the calls not started are cancelled (a slicer already running dies
    with the run, :func:`dying_with_us`)."""
    pool = ThreadPoolExecutor(max_workers=workers)
    try:
        results = list(pool.map(fn, items))
    except BaseException:
        pool.shutdown(wait=False, cancel_futures=True)
        raise
    pool.shutdown(wait=True)
    return results


def in_background(fn, *args) -> Future:
    """A Future of ``fn(*args)`` computed in a daemon thread: the caller goes on meanwhile
    and takes the answer (or the exception) with ``result()``.  A run that ends without
    asking does not wait for it (a slicer it started dies with the process,
    :func:`dying_with_us`)."""
    future: Future = Future()

    def work() -> None:
        if future.set_running_or_notify_cancel():
            try:
                future.set_result(fn(*args))
            except BaseException as exc:      # handed to whoever asks for the result
                future.set_exception(exc)

    threading.Thread(target=work, name="fabrickator-slicing", daemon=True).start()
    return future


def bed_rectangle(config: dict[str, str]) -> np.ndarray:
    """The bed's min and max corner (2x2, mm) from the profile's ``bed_shape``: its
    bounding box when it has four corners (a rectangle), else (a delta's round bed) the
    square centred on its corners' mean that stays within their least distance from it.

    Raises InputError when the profile has no valid bed_shape.
    """
    try:
        corners = np.array([[float(v) for v in point.split("x")]
                            for point in config["bed_shape"].split(",")])
        if corners.ndim != 2 or corners.shape[1] != 2 or len(corners) < 3:
            raise ValueError(f"bed_shape {config['bed_shape']!r}")
    except (KeyError, ValueError) as exc:
        raise InputError(f"slicer profile: no valid bed_shape ({exc})") from None
    if len(corners) <= 4:
        return np.array([corners.min(axis=0), corners.max(axis=0)])
    centre = corners.mean(axis=0)
    half = float(np.min(np.linalg.norm(corners - centre, axis=1))) / math.sqrt(2)
    return np.array([centre - half, centre + half])


def _apart(meshes: list[trimesh.Trimesh], bed: np.ndarray) -> bool:
    """Whether every footprint lies on ``bed`` and they are ARRANGE_GAP_MM or more apart."""
    boxes = [m.bounds[:, :2] for m in meshes]
    if any(np.any(b[0] < bed[0] - 1e-6) or np.any(b[1] > bed[1] + 1e-6) for b in boxes):
        return False
    gap = ARRANGE_GAP_MM - 1e-6
    return not any(np.all(a[0] < b[1] + gap) and np.all(b[0] < a[1] + gap)
                   for n, a in enumerate(boxes) for b in boxes[n + 1:])


def arrange(meshes, config: dict[str, str]) -> list[trimesh.Trimesh]:
    """The plate's meshes where they are sliced: each standing on the bed (min z = 0),
    their footprints on the profile's bed and apart.

    Meshes whose footprints already lie on the bed, ARRANGE_GAP_MM or
    more apart, keep their x and y (a plate ``core.printing.export`` laid out).
    Otherwise they are set in rows, deepest footprint (y) first, left to
    right ARRANGE_GAP_MM apart, each mesh in its orientation, and the rows
    are centred on the bed, as PrusaSlicer's own arrange would centre
    them.  Returns copies (metadata kept); raises ValueError saying the
    parts could not fit the bed when the rows do not.
    """
    parts = [m.copy() for m in as_meshes(meshes)]
    for m in parts:
        m.apply_translation((0.0, 0.0, -m.bounds[0][2]))
    bed = bed_rectangle(config)
    if _apart(parts, bed):
        return parts
    room = bed[1] - bed[0]
    spots, x, y, row = {}, 0.0, 0.0, 0.0
    for index in sorted(range(len(parts)), key=lambda i: (-parts[i].extents[1], i)):
        w, d = parts[index].extents[:2]
        if x > 0 and x + w > room[0] + 1e-6:
            x, y, row = 0.0, y + row + ARRANGE_GAP_MM, 0.0
        spots[index] = (x, y)
        x, row = x + w + ARRANGE_GAP_MM, max(row, d)
    used = np.array([max(spots[i][0] + parts[i].extents[0] for i in spots), y + row])
    if np.any(used > room + 1e-6):
        size = " x ".join(f"{v:.0f}" for v in room)
        raise ValueError(f"the {len(parts)} parts could not fit the {size} mm bed together")
    corner = bed[0] + (room - used) / 2
    for index, (px, py) in spots.items():
        part = parts[index]
        part.apply_translation((corner[0] + px - part.bounds[0][0], corner[1] + py - part.bounds[0][1], 0.0))
    return parts


def plate_3mf(meshes, config: dict[str, str], names=None) -> bytes:
    """A 3MF of ``meshes`` as they stand (named ``names``, default ``part_000`` ...)
    with ``config`` as its PrusaSlicer project settings (SLIC3R_CONFIG), which
    PrusaSlicer applies when it opens or slices the file."""
    scene = trimesh.Scene()
    for index, mesh in enumerate(as_meshes(meshes)):
        name = names[index] if names is not None else f"part_{index:03d}"
        scene.add_geometry(mesh, node_name=name, geom_name=name)
    buffer = io.BytesIO(trimesh.exchange.threemf.export_3MF(scene))
    with zipfile.ZipFile(buffer, "a", compression=zipfile.ZIP_DEFLATED) as archive:
        archive.writestr(SLIC3R_CONFIG, "; generated by Fabrickator\n" + config_text(config, "; "))
    return buffer.getvalue()


def config_text(config: dict[str, str], prefix: str = "") -> str:
    """``config`` as PrusaSlicer config lines, ``<prefix>key = value`` sorted by key
    (``prefix="; "`` gives the form a 3MF's Metadata/Slic3r_PE.config holds)."""
    return "".join(f"{prefix}{key} = {config[key]}\n" for key in sorted(config))


def _last_message(run: subprocess.CompletedProcess) -> str:
    """The slicer's last meaningful output line (its error: a plain line or the text of
    an ``[error]`` log line), or its exit status; with the status when it crashed."""
    messages = []
    for line in (line.strip() for line in (run.stderr + "\n" + run.stdout).splitlines()):
        if "[error]" in line:
            messages.append(line.split("[error]", 1)[1].strip())
        elif line and not line.startswith("[") and not line[:1].isdigit():
            messages.append(line.removeprefix("what():").strip())
    status = f"exit status {run.returncode}"
    if not messages:
        return status
    return f"{messages[-1]} ({status})" if run.returncode < 0 else messages[-1]


def print_time(meshes, workdir: str | os.PathLike, profile: str | os.PathLike | None = None,
               slicer: str | None = "auto", pose_search: bool = True) -> PrintEstimate:
    """Print time of all ``meshes`` (Trimesh objects or mesh files) on ONE plate.

    With ``pose_search``, every mesh not marked as posed (:data:`POSE_KEY`,
    set by ``core.printing.export`` for the parts it lays flat) is first turned into
    its fastest pose (:func:`fastest_pose`, no pose forbidden); the others,
    and all without ``pose_search``, are sliced as given (the slicer places
    them on the bed).  With a slicer (``slicer="auto"``:
    :func:`slicer_path`; a path: that binary; None or ``"none"``: no
    slicer) the seconds are PrusaSlicer's normal-mode estimate, with
    supports exactly when a part needs them (:func:`plate_supports`) and a
    raft where the slicer asks for one (:func:`slice_plate`; ``method``
    names the settings and the pose); a single mesh posed here is not
    sliced again, its winning slice is the answer.  Without one, or when
    slicing fails, the result is :func:`estimate_seconds` plus
    :func:`support_seconds` for each part that needs supports, and
    ``method`` says ``"estimate (...; <reason>)"``.  Never raises for parts
    that do not fit; raises InputError only for mesh files that cannot be
    read or an unreadable profile (ValueError for a given mesh without
    triangles).  An empty list takes 0 s.
    """
    parts = as_meshes(meshes)
    if not parts:
        return PrintEstimate(0.0, "nothing to print", None)
    binary, reason = resolve_slicer(slicer)
    config = load_profile(profile, binary)
    poses = [fastest_pose(m, workdir, profile, binary or slicer) if pose_search and POSE_KEY not in m.metadata else None
             for m in parts]
    parts = [m if p is None else posed(m, p) for m, p in zip(parts, poses)]
    chosen = [p for p in poses if p is not None]
    pose = ", ".join(p.name for p in chosen) or None
    posing = "".join(f"; posed {p.name}, {p.chosen_by}" if p.slicer_s is not None
                     else f"; posed {p.name} by the estimate" for p in chosen)
    if len(parts) == 1 and chosen and chosen[0].sliced is not None:
        result = chosen[0].sliced
        return replace(result, method=result.method + posing, pose=pose)
    if binary:
        try:
            result = slice_plate(parts, workdir, profile, binary)
            return replace(result, method=result.method + posing, pose=pose)
        except _SlicerFailed as exc:
            reason = str(exc)
    overhang = support_threshold(config)
    supported = [m for m in parts if plate_supports([m], overhang)]
    seconds = estimate_seconds(parts) + sum(support_seconds(*support_need(m, overhang)[:2]) for m in supported)
    label = ESTIMATE_METHOD.rstrip(")") + (", with supports" if supported else "")
    return PrintEstimate(seconds, f"{label}; {reason}){posing}", None, bool(supported), pose)

