"""The main job: a model file in, a LEGO layout and its report out.

:func:`run` chains the stages and returns plain data; :func:`fabricate`
also writes the output folder of the headless contract (DESIGN.md):
``report.json``, ``layout.json`` and ``layout.png``.  The folder is
written to a temporary sibling and renamed into place only when complete,
so a failed run never leaves a folder that looks finished.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from core import catalog, layout as layout_stage, mesh_io, stability as stability_stage, voxelize
from core.errors import InputError
from core.model import CELL_MM, Grid, Layout

Progress = Callable[[float, str], None]

#: Files that mark a folder as an output of ours (and so safe to replace).
OUTPUT_MARKERS = ("report.json", "layout.json")


@dataclass
class Fabrication:
    """Everything one run produced, stage by stage."""

    model: mesh_io.LoadedModel
    parts: tuple[catalog.Part, ...]
    grid: Grid
    layout: Layout
    stability: stability_stage.Stability
    seed: int
    timings_s: dict[str, float] = field(default_factory=dict)


def _noop(fraction: float, message: str) -> None:
    """Progress sink that ignores everything."""


def run(path: str | os.PathLike, units: str = "mm", scale: float = 1.0, seed: int = 0,
        parts: str | None = None, progress: Progress | None = None) -> Fabrication:
    """Load, repair, legofy and lay out the model at ``path``.

    ``parts`` restricts the brick set (see :func:`core.catalog.select`).
    Raises :class:`~core.errors.InputError` for bad input; otherwise returns
    a :class:`Fabrication` whose layout covers every filled cell once.
    """
    progress = progress or _noop
    chosen = catalog.select(parts)
    timings: dict[str, float] = {}

    def timed(name: str, fraction: float, fn, *args, **kwargs):
        progress(fraction, name)
        start = time.perf_counter()
        value = fn(*args, **kwargs)
        timings[name] = round(time.perf_counter() - start, 4)
        return value

    model = timed("load", 0.0, mesh_io.load_model, path, units=units, scale=scale)
    grid = timed("legofy", 0.2, voxelize.legofy, model.mesh, closed=model.watertight)
    if grid.count == 0:
        raise InputError(f"{Path(path).name}: the part fills no cell of the "
                         f"{CELL_MM[0]:g} x {CELL_MM[1]:g} x {CELL_MM[2]:g} mm grid")
    layout = timed("layout", 0.4, layout_stage.lay_out, grid, chosen, seed=seed)
    stab = timed("stability", 0.9, stability_stage.analyse, layout)
    return Fabrication(model, chosen, grid, layout, stab, seed, timings)


def report(fab: Fabrication) -> dict:
    """The ``report.json`` document for a fabrication (DESIGN.md contract)."""
    by_part: dict[str, int] = {}
    for b in fab.layout.bricks:
        by_part[b.part] = by_part.get(b.part, 0) + 1
    lego = sum(1 for b in fab.layout.bricks if b.kind == "lego")
    m, st = fab.model, fab.stability
    bounds = m.mesh.bounds
    return {
        "model": {
            "path": str(m.path),
            "format": m.format,
            "triangles": int(m.triangles),
            "watertight": bool(m.watertight),
            "repaired": list(m.repaired),
            "warnings": list(m.warnings),
            "bbox_mm": [round(float(v), 4) for v in (bounds[1] - bounds[0])],
            "bounds_mm": [[round(float(v), 4) for v in row] for row in bounds],
        },
        "grid": {
            "origin_mm": [round(float(v), 6) for v in fab.grid.origin],
            "shape": list(fab.grid.shape),
            "cell_mm": [float(c) for c in fab.grid.cell],
            "alignment": "z from the part's lowest point; x and y centred on the part's bounding box",
        },
        "plates": fab.grid.count,
        "bricks": {
            "total": len(fab.layout.bricks),
            "lego": lego,
            "by_part": dict(sorted(by_part.items())),
            "per_cell": round(len(fab.layout.bricks) / max(fab.grid.count, 1), 4),
        },
        "brick_set": [p.number for p in fab.parts],
        "seed": fab.seed,
        "stability": {
            "regions": st.regions,
            "components": st.components,
            "weak_points": len(st.weak_points),
            "weak_point_bricks": list(st.weak_points),
            "unconnectable": list(st.unconnectable),
            "incomplete_studs": 0,
        },
        "printed_parts": [],
        "timings_s": dict(fab.timings_s),
    }


def _prepare_out(out: Path) -> None:
    """Refuse an ``out`` that exists and is not an (empty or earlier) output folder."""
    if out.exists() and not out.is_dir():
        raise InputError(f"--out {out} exists and is not a folder")
    if out.is_dir() and any(out.iterdir()) and not any((out / f).exists() for f in OUTPUT_MARKERS):
        raise InputError(f"--out {out} is a folder with other files in it; "
                         "choose an empty or new folder")


def write_outputs(fab: Fabrication, out: str | os.PathLike, picture: bool = True,
                  progress: Progress | None = None) -> dict:
    """Write ``report.json``, ``layout.json`` (and ``layout.png``) into ``out``.

    Everything is written into a temporary sibling folder first and moved
    into place at the end, replacing an earlier output; returns the report.
    """
    progress = progress or _noop
    out = Path(out)
    _prepare_out(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    tmp.chmod(0o755)
    try:
        start = time.perf_counter()
        (tmp / "layout.json").write_text(json.dumps(fab.layout.to_json()))
        if picture:
            progress(0.95, "picture")
            from core import render
            render.render_layout(fab.layout, tmp / "layout.png",
                                 title=f"{Path(fab.model.path).name}: "
                                       f"{len(fab.layout.bricks)} bricks")
        fab.timings_s["write"] = round(time.perf_counter() - start, 4)
        doc = report(fab)
        doc["outputs"] = sorted(p.name for p in tmp.iterdir()) + ["report.json"]
        (tmp / "report.json").write_text(json.dumps(doc, indent=2))
        if out.exists():
            shutil.rmtree(out)
        os.replace(tmp, out)
        progress(1.0, "done")
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
    return doc


def fabricate(path: str | os.PathLike, out: str | os.PathLike, units: str = "mm",
              scale: float = 1.0, seed: int = 0, parts: str | None = None,
              picture: bool = True, progress: Progress | None = None) -> dict:
    """Run the pipeline on ``path`` and write its outputs into ``out``; returns the report."""
    _prepare_out(Path(out))
    fab = run(path, units=units, scale=scale, seed=seed, parts=parts, progress=progress)
    return write_outputs(fab, out, picture=picture, progress=progress)
