"""The stored result of a run: what a later iteration, the workbench and an export read back.

:func:`snapshot` writes into an output folder (``iteration/``) the model
mesh (``model.ply``) and B-rep (``model.brep``, binary OpenCascade), each
printed part's mesh and B-rep, each high-res region solid, and
``state.json`` (the layout as in ``layout.json``, stability, settings, fit,
regions, printed-part records).  :func:`load_previous` reads it back as a
:class:`Previous`.  The layout's JSON form is :meth:`core.model.Layout.to_json`
/ :meth:`~core.model.Layout.from_json` everywhere.
"""

from __future__ import annotations

import dataclasses
import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh

from core import high_res
from core.errors import InputError, check_path, shown_path
from core.inventory import with_colours
from core.model import Grid, Layout
from core.parts.printed_part import PrintedPart

#: Folder inside an output folder that holds the iteration snapshot.
SNAPSHOT_DIR = "iteration"
#: Version of the snapshot format (2 records the high-res regions and the settings).
SNAPSHOT_VERSION = 2
#: Older snapshot versions that can still be read.
READABLE_VERSIONS = (1, 2)



def snapshot(fab, folder: str | os.PathLike) -> Path:
    """Write what a later iteration needs into ``folder/iteration/``; returns that folder.

    ``fab`` is a :class:`core.pipeline.Fabrication`.  Written: ``model.ply``
    (the repaired model mesh, mm), ``model.brep`` for B-rep input,
    ``parts/<id>.ply`` (and ``.brep``) per printed part, ``regions/<n>.ply``
    per high-res region solid, and ``state.json`` with the layout, its
    stability, the brick set, seed, units and scale, the stud and socket fit,
    the high-res region boxes, every printed part's record (bricks,
    studs, tubes, clamp cells, engraving) and the build order with its checks
    (:meth:`core.instructions.build_order.BuildOrder.to_json`).  Reads ``fab`` only.
    """
    out = Path(folder) / SNAPSHOT_DIR
    (out / "parts").mkdir(parents=True, exist_ok=True)
    (out / "regions").mkdir(exist_ok=True)
    model = fab.model
    model.mesh.export(out / "model.ply", file_type="ply")
    if model.brep is not None:
        _write_brep(model.brep, out / "model.brep")
    records = []
    for p in fab.printed:
        p.mesh.export(out / "parts" / f"{p.id}.ply", file_type="ply")
        if p.solid is not None:
            _write_brep(p.solid, out / "parts" / f"{p.id}.brep")
        records.append(_part_record(p))
    for n, (mesh, _) in enumerate(fab.regions.solids):
        mesh.export(out / "regions" / f"{n}.ply", file_type="ply")
    st = fab.stability
    req = fab.request
    state = {
        "version": SNAPSHOT_VERSION,
        "model": {"path": str(model.path), "format": model.format,
                  "watertight": bool(model.watertight), "brep": model.brep is not None},
        "layout": with_colours(fab.layout.to_json(), getattr(fab, "colouring", None)),
        "stability": {"regions": st.regions, "components": st.components,
                      "weak_points": list(st.weak_points)},
        "brick_set": [p.number for p in fab.parts],
        "seed": fab.seed,
        "settings": {"units": req.units, "scale": float(req.scale), "up": req.up, "seed": int(req.seed)},
        "fit": dataclasses.asdict(req.fit),
        "regions": {"boxes": [np.asarray(b, dtype=float).tolist() for b in fab.regions.boxes],
                    "solids_closed": [bool(c) for _, c in fab.regions.solids]},
        "printed": records,
        "hollow_studs": fab.hollowing.studs if fab.hollowing is not None else 0,
        "order": fab.order.to_json(),
    }
    (out / "state.json").write_text(json.dumps(state))
    return out


def _write_brep(shape, path: Path) -> None:
    from OCP.BinTools import BinTools
    BinTools.Write_s(shape, str(path))


def _read_brep(path: Path):
    from OCP.BinTools import BinTools
    from OCP.TopoDS import TopoDS_Shape
    shape = TopoDS_Shape()
    BinTools.Read_s(shape, str(path))
    return shape


#: PrintedPart fields kept as grid-cell maps; they are stored as [i, j, k, value] rows.
_CELL_MAPS = ("top_ok", "bottom_ok")


def _part_record(p: PrintedPart) -> dict:
    """A printed part as JSON: every field but its geometry (``solid``, ``mesh``)."""
    out = {}
    for f in dataclasses.fields(p):
        value = getattr(p, f.name)
        if f.name in ("solid", "mesh"):
            continue
        if f.name in _CELL_MAPS:
            value = [[*map(int, c), bool(v)] for c, v in value.items()]
        out[f.name] = value
    return out


@dataclass
class Previous:
    """An earlier output folder as the iteration sees it.

    ``grid`` and ``layout`` as that run made them; ``mesh`` / ``brep`` its
    model (mm, its frame); ``parts`` its printed parts by id (cells in its
    grid); ``state`` the raw ``state.json``; ``regions`` its high-res
    regions in its frame (None for a snapshot of version 1, which did not
    record them).
    """

    folder: Path
    grid: Grid
    layout: Layout
    mesh: trimesh.Trimesh
    brep: object | None
    watertight: bool
    parts: dict[str, PrintedPart]
    state: dict
    regions: high_res.Regions | None = None

    @property
    def weak_points(self) -> set[int]:
        return set(self.state["stability"]["weak_points"])

    @property
    def shell_studs(self) -> int:
        """The shell thickness (studs) the previous layout's cells were hollowed with, 0
        for solid (and for snapshots written before hollowing was recorded)."""
        return int(self.state.get("hollow_studs", 0))

    @property
    def extra_components(self) -> int:
        st = self.state["stability"]
        return max(0, int(st["components"]) - int(st["regions"]))


def snapshot_state(folder: str | os.PathLike) -> dict:
    """The ``state.json`` of the snapshot in output folder ``folder``, read without its
    geometry (a cheap check that the folder can be iterated on).

    Raises :class:`InputError` when ``folder`` is missing, is not an output
    folder, was written without a snapshot or by an unreadable version.
    """
    folder = Path(folder)
    state_file = folder / SNAPSHOT_DIR / "state.json"
    check_path(folder, "--previous")            # a name too long, a loop of links: one line
    if not folder.is_dir():
        raise InputError(f"--previous {shown_path(folder)}: no such folder")
    if not state_file.is_file():
        raise InputError(f"--previous {folder}: not an output folder with an iteration snapshot "
                         f"({SNAPSHOT_DIR}/state.json is missing); fabricate that version again")
    try:
        state = json.loads(state_file.read_text())
    except (OSError, ValueError) as err:
        raise InputError(f"--previous {folder}: the iteration snapshot cannot be read "
                         f"({type(err).__name__})") from None
    if not isinstance(state, dict) or state.get("version") not in READABLE_VERSIONS:
        version = state.get("version") if isinstance(state, dict) else None
        raise InputError(f"--previous {folder}: snapshot version {version} "
                         f"is not {SNAPSHOT_VERSION}; fabricate that version again")
    return state


def read_ply(source) -> trimesh.Trimesh:
    """The mesh stored as PLY in ``source`` (a path or a binary file object), exactly as
    written: no merging, no repair."""
    return trimesh.load(source, file_type="ply", process=False, force="mesh")


def load_previous(folder: str | os.PathLike) -> Previous:
    """Read the snapshot of an earlier output folder (``--previous DIR``).

    Raises :class:`InputError` when ``folder`` is missing, is not an output
    folder, or was written without a snapshot (then it must be made again).
    """
    folder = Path(folder)
    state = snapshot_state(folder)
    try:
        layout = Layout.from_json(state["layout"])
        snap = folder / SNAPSHOT_DIR
        mesh = read_ply(snap / "model.ply")
        brep = _read_brep(snap / "model.brep") if state["model"]["brep"] else None
        parts = {}
        for rec in state["printed"]:
            part_mesh = read_ply(snap / "parts" / f"{rec['id']}.ply")
            brep_file = snap / "parts" / f"{rec['id']}.brep"
            parts[rec["id"]] = _part_from_record(rec, part_mesh,
                                                 _read_brep(brep_file) if brep_file.exists() else None)
        regions = _read_regions(state.get("regions"), snap)
    except InputError:
        raise
    except (OSError, ValueError, KeyError, TypeError, IndexError) as err:
        raise InputError(f"--previous {folder}: the iteration snapshot cannot be read "
                         f"({type(err).__name__}: {str(err).splitlines()[0] if str(err) else ''})") from None
    return Previous(folder, layout.grid, layout, mesh, brep,
                    bool(state["model"]["watertight"]), parts, state, regions)


def _read_regions(record: dict | None, snap: Path) -> high_res.Regions | None:
    """The regions of a snapshot's ``state["regions"]`` (None when it has none)."""
    if record is None:
        return None
    boxes = tuple(np.asarray(b, dtype=np.float64).reshape(2, 3) for b in record["boxes"])
    solids = tuple((read_ply(snap / "regions" / f"{n}.ply"), bool(closed))
                   for n, closed in enumerate(record["solids_closed"]))
    return high_res.Regions(boxes, solids)


def _part_from_record(rec: dict, mesh: trimesh.Trimesh, solid) -> PrintedPart:
    """The :class:`~core.parts.printed_part.PrintedPart` of a record and its geometry (fields
    the record lacks keep their defaults; fields it has that the class lacks are dropped)."""
    names = {f.name for f in dataclasses.fields(PrintedPart)} - {"solid", "mesh"}
    values = {k: v for k, v in rec.items() if k in names}
    for key in _CELL_MAPS:
        if key in values:
            values[key] = {tuple(int(v) for v in c[:3]): bool(c[3]) for c in values[key]}
    values["bricks"] = [int(i) for i in values.get("bricks", [])]
    return PrintedPart(solid=solid, mesh=mesh, **values)
