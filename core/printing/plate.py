"""The plate a slicer gets: the parts set apart on the printer's bed, as a 3MF with its settings.

:func:`as_meshes` reads the parts (meshes or mesh files); :func:`bed_rectangle` and
:func:`build_volume` read the bed and the printable size from a PrusaSlicer config;
:func:`arrange` stands every part on the bed and sets the footprints :data:`ARRANGE_GAP_MM`
apart, keeping a plate that already lies so (as ``core.printing.export`` lays them out), in
rows centred on the bed otherwise; :func:`plate_3mf` writes the plate with the config as its
project settings (:data:`SLIC3R_CONFIG`), which PrusaSlicer applies when it slices it, and
:func:`config_text` gives a config as PrusaSlicer's lines.
"""

from __future__ import annotations

import io
import math
import zipfile

import numpy as np
import trimesh

from core.errors import InputError


#: Least gap (mm) between parts on a plate (:func:`arrange`).  Supports
#: spread a few mm beyond their part: PrusaSlicer 2.9 finds "gcode path
#: conflicts" between two supported lens mounts 6 mm apart (and then crashes
#: on the command line), none at 8 mm.
ARRANGE_GAP_MM = 10.0

#: Where PrusaSlicer reads a 3MF's project settings from.
SLIC3R_CONFIG = "Metadata/Slic3r_PE.config"


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


def build_volume(config: dict[str, str]) -> np.ndarray:
    """Printable size (x, y, z) in mm: the size of :func:`bed_rectangle` and ``max_print_height``.

    Raises InputError when the profile lacks either key or they are malformed.
    """
    bed = bed_rectangle(config)
    try:
        return np.append(bed[1] - bed[0], float(config["max_print_height"]))
    except (KeyError, ValueError) as exc:
        raise InputError(f"slicer profile: no valid bed_shape / max_print_height ({exc})") from None


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
