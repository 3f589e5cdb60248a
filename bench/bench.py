"""``make bench``: the core pipeline measured on every model that loads.

Prints markdown tables (and writes them with the raw numbers to
``bench/out/``): per model the triangles, cells, bricks, bricks per cell,
components vs regions, weak points, seconds per stage, the exact lower bound
on the brick count (integer program, time-limited) and the ratio to it; then
the synthetic scaling rows (a 1M-triangle sphere, a 100k-cell block).
Timings are warm: one small model runs first so numba's compiled code is
loaded before anything is timed.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import trimesh

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from core import catalog, pipeline, stability, voxelize  # noqa: E402
from core.errors import InputError  # noqa: E402
from core.layout import greedy as layout  # noqa: E402
from core.layout.bounds import brick_lower_bound  # noqa: E402
from core.model import CELL_MM, Grid  # noqa: E402

MODELS = ROOT.parent / "shared" / "models"
DEMO = ROOT / "examples" / "build" / "hmd.step"
#: Files whose units are not millimetres (CATALOG.md).
UNITS = {"stanford_bunny_open.obj": "m"}
FORMATS = {".stl", ".obj", ".ply", ".3mf", ".step", ".stp", ".fcstd"}


def model_paths() -> list[Path]:
    """The demo model (if built) and every loadable-format file in ../shared/models."""
    paths = [DEMO] if DEMO.exists() else []
    if MODELS.is_dir():
        paths += sorted(p for p in MODELS.iterdir() if p.suffix.lower() in FORMATS)
    return paths


def table(rows: list[dict], columns: list[str]) -> str:
    """A markdown table of ``rows`` with the given columns."""
    def cell(v):
        if isinstance(v, float):
            return f"{v:.3f}" if abs(v) < 100 else f"{v:.0f}"
        return "" if v is None else str(v)

    lines = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    lines += ["| " + " | ".join(cell(r.get(c)) for c in columns) + " |" for r in rows]
    return "\n".join(lines)


def bench_model(path: Path, time_limit: float) -> dict:
    """One row: the pipeline on ``path`` with stage timings and the lower bound."""
    row = {"model": path.name}
    start = time.perf_counter()
    try:
        fab = pipeline.run(path, units=UNITS.get(path.name, "mm"))
    except InputError as err:
        row["error"] = str(err)
        return row
    total = time.perf_counter() - start
    bricks = len(fab.layout.bricks)
    st = fab.stability
    row.update({
        "triangles": fab.model.triangles,
        "cells": fab.grid.count,
        "bricks": bricks,
        "bricks/cell": bricks / fab.grid.count,
        "components/regions": f"{st.components}/{st.regions}",
        "weak": len(st.weak_points),
        "weak (leaf only)": len(st.leaf_supports),
        **{f"{k} s": v for k, v in fab.timings_s.items()},
        "total s": total,
    })
    lb = brick_lower_bound(fab.grid, fab.parts, time_limit_s=time_limit)
    row["lower bound"] = lb["bound"]
    row["lb optimal"] = "yes" if lb["optimal"] else lb["status"]
    row["ratio"] = bricks / lb["bound"] if lb["bound"] else None
    return row


def bench_scaling() -> list[dict]:
    """Synthetic rows: legofy of a 1M-triangle sphere, layout of a 100k-cell block."""
    rows = []
    sphere = trimesh.creation.icosphere(subdivisions=8, radius=100.0)
    voxelize.legofy(sphere)
    start = time.perf_counter()
    grid = voxelize.legofy(sphere)
    rows.append({"case": "legofy icosphere r=100 mm", "triangles": len(sphere.faces),
                 "cells": grid.count, "seconds": time.perf_counter() - start})
    for name, shape in (("layout solid block 50x50x40", (50, 50, 40)),
                        ("layout sphere grid", None)):
        g = Grid(np.zeros(3), np.array(CELL_MM), np.ones(shape, bool)) if shape else grid
        start = time.perf_counter()
        lay = layout.lay_out(g, catalog.CATALOG, seed=0)
        seconds = time.perf_counter() - start
        st = stability.analyse(lay)
        rows.append({"case": name, "cells": g.count, "bricks": len(lay.bricks),
                     "components/regions": f"{st.components}/{st.regions}",
                     "weak": len(st.weak_points), "weak (leaf only)": len(st.leaf_supports),
                     "seconds": seconds})
    return rows


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--time-limit", type=float, default=10.0,
                        help="seconds per model for the lower-bound integer program")
    parser.add_argument("--out", default=str(ROOT / "bench" / "out"))
    args = parser.parse_args()
    paths = model_paths()
    if not MODELS.is_dir():
        print(f"note: {MODELS} is absent: only the bundled demo model is measured")
    warm = trimesh.creation.box((20, 20, 10))
    layout.lay_out(voxelize.legofy(warm), catalog.CATALOG)
    rows = []
    for path in paths:
        rows.append(bench_model(path, args.time_limit))
        print(f"  measured {path.name}", file=sys.stderr)
    order = ["load s", "grid_fit s", "legofy s", "high_res s", "layout s", "stability s"]
    stage_cols = sorted({k for r in rows for k in r if k.endswith(" s") and k != "total s"},
                        key=lambda k: (order.index(k) if k in order else len(order), k))
    columns = (["model", "triangles", "cells", "bricks", "bricks/cell", "components/regions",
                "weak", "weak (leaf only)"] + stage_cols + ["total s", "lower bound", "lb optimal", "ratio"])
    ok = [r for r in rows if "error" not in r]
    refused = [r for r in rows if "error" in r]
    scaling = bench_scaling()
    text = ["## Models (fabricate without printed parts)", "", table(ok, columns), ""]
    if refused:
        text += ["## Refused inputs", "", table(refused, ["model", "error"]), ""]
    text += ["## Scaling", "",
             table(scaling, ["case", "triangles", "cells", "bricks", "components/regions",
                             "weak", "weak (leaf only)", "seconds"]), ""]
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "core.md").write_text("\n".join(text))
    (out / "core.json").write_text(json.dumps({"models": rows, "scaling": scaling}, indent=2))
    print("\n".join(text))
    return 0


if __name__ == "__main__":
    sys.exit(main())
