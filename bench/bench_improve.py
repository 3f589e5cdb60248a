"""``make bench``: the layout before and after the improvement stage, against the lower bound.

Per model (the demo and every model in ../shared/models that loads): the
greedy layout (``--effort fast``) and the improved one (``normal``, and
``best`` with ``--best``, which also starts from the relaxed layout,
:func:`core.layout.greedy.relaxed_layout`, as the pipeline's does): bricks, the ratio to the exact-cover lower bound
(integer program, ``--time-limit`` seconds, "yes" when proven) and to the
bound of layouts in one piece per region without leaf bricks
(:func:`core.layout.connected_bound.leaf_free_bound` with ``connected``, its lazy cuts: what a layout
the targets accept needs at least; the larger of the two) and to the bound of the layout's
own kind (:func:`core.layout.search.one_piece_bound`: one piece per region with no weak point,
or with at most as many as it has where they all hold a leaf brick on a one-cell-thin
feature; none for other layouts; each bound has ``--time-limit`` seconds, and where it
is proven its cover is such a layout with the fewest bricks), components
against regions, weak points (and how many of them hold a leaf brick on a
one-cell-thin feature), seconds of the layout and
of the improvement; then whether the issue's targets are met: ratio <= 1.15 to the
largest of these bounds that holds for the layout, components = regions, no weak points
but those holding a leaf brick on a one-cell-thin feature (counted apart).  Then the timing
targets: ``normal`` under 10 s for 2,000 cells and under 60 s for 20,000
(legofied spheres).  Tables go to stdout and ``bench/out/improve.md``.
Set FABRICKATOR_MODELS to measure another models folder.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import trimesh

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

import bench  # noqa: E402
from core import catalog, pipeline, voxelize  # noqa: E402
from core.errors import InputError  # noqa: E402
from core.layout import greedy as layout  # noqa: E402
from core.layout import search as improve  # noqa: E402
from core.layout.bounds import brick_lower_bound  # noqa: E402
from core.layout.connected_bound import leaf_free_bound  # noqa: E402
from core.layout.quality import quality, thin_weak_points  # noqa: E402
from core.stability import analyse  # noqa: E402

#: The issue's targets.
RATIO_TARGET = 1.15
SECONDS_TARGET = {2_000: 10.0, 20_000: 60.0}


def measure(lay, start_s: float, bound, parts, time_limit: float, kinds: dict) -> dict:
    """Bricks, ratio, components, weak points (thin ones apart) of one layout, and the
    bound of its kind (:func:`core.layout.search.one_piece_bound`; ``kinds`` keeps those found
    for the model's other layouts, by whether they are joined and their weak points)."""
    st = analyse(lay)
    forced = len(thin_weak_points(lay))
    n, weak = len(lay.bricks), len(st.weak_points)
    joined = st.components == st.regions
    if (joined, weak, forced) not in kinds:
        kinds[joined, weak, forced] = improve.one_piece_bound(lay, parts, joined, weak, forced,
                                                              time_limit)
    kind = kinds[joined, weak, forced]
    return {"bricks": n, "ratio": n / bound if bound else None,
            "components": st.components, "regions": st.regions,
            "weak": weak, "thin": forced, "s": start_s,
            "kind": kind.get("bound"),
            "kind_proven": _kind_proven(kind)}


def _kind_proven(kind: dict) -> str:
    """Whether the bound of a layout's kind is proven: "yes", "none exists" (the program
    finds no layout of the kind), "n/a" (the layout is of no kind bounded), or why not."""
    if kind.get("bound"):
        return "yes" if kind["proven"] else kind["status"]
    return "none exists" if "finds no layout" in kind.get("why", "") else "n/a"


def bench_model(path: Path, time_limit: float, efforts: list[str]) -> dict:
    """One model: the greedy layout, each effort's improvement, the lower bound."""
    row = {"model": path.name}
    try:
        fab = pipeline.run(path, units=bench.UNITS.get(path.name, "mm"), effort="fast",
                           slice_parts=False, picture=False)
    except InputError as err:
        row["error"] = str(err)
        return row
    lb = brick_lower_bound(fab.grid, fab.parts, time_limit_s=time_limit)
    bound = lb["bound"]
    row.update(cells=fab.grid.count, bound=bound, proven="yes" if lb["optimal"] else lb["status"],
               lb_s=lb["seconds"])
    leafless = leaf_free_bound(fab.grid, fab.parts, time_limit_s=time_limit,
                                       connected=True)
    row.update(leaf_free=_stronger(leafless, bound), leaf_free_proven=_proven(leafless))
    kinds: dict = {}
    row["fast"] = measure(fab.layout, fab.timings_s["layout"], bound, fab.parts, time_limit,
                          kinds)
    for effort in efforts:
        start = time.perf_counter()
        relaxed = (layout.relaxed_layout(fab.grid, None, fab.parts, fab.seed)
                   if improve.EFFORT_LEVELS[effort].relaxed_start else None)
        better = improve.improve(fab.layout, fab.parts, effort, fab.seed,
                                 others=() if relaxed is None else (relaxed,))
        row[effort] = measure(better, fab.timings_s["layout"] + time.perf_counter() - start,
                              bound, fab.parts, time_limit, kinds)
    return row


def _stronger(found: dict, weaker: int | None) -> int | None:
    """A bound of :func:`core.layout.connected_bound.leaf_free_bound`, or the ``weaker`` one where it is less;
    None where the program proved that no such layout exists."""
    if found["status"] == "infeasible":
        return None
    return max(found["bound"] or 0, weaker or 0) or None


def _proven(found: dict) -> str:
    """Whether a bound is proven: "yes", "none exists" (no such layout), or why not."""
    if found["status"] == "infeasible":
        return "none exists"
    return "yes" if found["optimal"] else found["status"]


def model_rows(rows: list[dict], efforts: list[str]) -> list[dict]:
    """Flat table rows: one per model and effort."""
    out = []
    for r in rows:
        if "error" in r:
            continue
        for effort in ["fast"] + efforts:
            m = r[effort]
            accepted = m["components"] == m["regions"] and m["weak"] == m["thin"]
            # the largest bound that holds for this layout
            best = max(r["bound"] or 0, (r["leaf_free"] or 0) if accepted else 0,
                       m["kind"] or 0)
            met = [bool(best) and m["bricks"] <= RATIO_TARGET * best,
                   m["components"] == m["regions"], m["weak"] == m["thin"]]
            out.append({"model": r["model"], "cells": r["cells"], "effort": effort,
                        "bricks": m["bricks"], "lower bound": r["bound"], "proven": r["proven"],
                        "ratio": m["ratio"], "bound, one piece, no leaves": r["leaf_free"],
                        "proven too": r["leaf_free_proven"],
                        "ratio to it": m["bricks"] / r["leaf_free"] if r["leaf_free"] else None,
                        "bound of its kind": m["kind"], "proven (3)": m["kind_proven"],
                        "ratio to it (3)": m["bricks"] / m["kind"] if m["kind"] else None,
                        "components/regions": f"{m['components']}/{m['regions']}",
                        "weak": m["weak"], "weak thin": m["thin"], "seconds": m["s"],
                        "best ratio": m["bricks"] / best if best else None,
                        "ratio<=1.15": "yes" if met[0] else "NO",
                        "connected": "yes" if met[1] else "NO",
                        "no weak": "yes" if met[2] else "NO"})
    return out


def scaling(efforts: list[str]) -> list[dict]:
    """Greedy and improved layout seconds of legofied spheres of about 2,000 and 20,000 cells."""
    rows = []
    for cells, radius in ((2_000, 46.0), (20_000, 100.0)):
        grid = voxelize.legofy(trimesh.creation.icosphere(subdivisions=5, radius=radius))
        start = time.perf_counter()
        lay = layout.lay_out(grid, catalog.CATALOG, seed=0)
        greedy_s = time.perf_counter() - start
        for effort in efforts:
            start = time.perf_counter()
            better = improve.improve(lay, catalog.CATALOG, effort, 0)
            seconds = greedy_s + time.perf_counter() - start
            target = SECONDS_TARGET[cells] if effort == "normal" else 60.0
            k0, k1 = quality(lay), quality(better)
            rows.append({"case": f"sphere r={radius:g} mm", "cells": grid.count, "effort": effort,
                         "greedy key": str(k0), "improved key": str(k1),
                         "greedy s": greedy_s, "total s": seconds, "target s": target,
                         "met": "yes" if seconds < target else "NO"})
    return rows


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--time-limit", type=float, default=10.0,
                        help="seconds per model for the lower-bound integer program")
    parser.add_argument("--best", action="store_true", help="also measure --effort best")
    parser.add_argument("--model", action="append",
                        help="measure only this model (file name; may be repeated)")
    parser.add_argument("--out", default=str(ROOT / "bench" / "out"))
    args = parser.parse_args()
    if os.environ.get("FABRICKATOR_MODELS"):
        bench.MODELS = Path(os.environ["FABRICKATOR_MODELS"])
    efforts = ["normal"] + (["best"] if args.best else [])
    warm = trimesh.creation.box((20, 20, 10))
    improve.improve(layout.lay_out(voxelize.legofy(warm), catalog.CATALOG), catalog.CATALOG)
    rows = []
    for path in bench.model_paths():
        if args.model and path.name not in args.model:
            continue
        rows.append(bench_model(path, args.time_limit, efforts))
        print(f"  measured {path.name}", file=sys.stderr)
    table = model_rows(rows, efforts)
    columns = ["model", "cells", "effort", "bricks", "lower bound", "proven", "ratio",
               "bound, one piece, no leaves", "proven too", "ratio to it",
               "bound of its kind",
               "proven (3)", "ratio to it (3)", "components/regions", "weak", "weak thin",
               "seconds", "best ratio", "ratio<=1.15", "connected", "no weak"]
    scale = scaling(efforts)
    text = ["## Layout quality: greedy (fast) and improved, against the exact lower bound", "",
            bench.table(table, columns), ""]
    refused = [r for r in rows if "error" in r]
    if refused:
        text += ["Refused: " + "; ".join(f"{r['model']} ({r['error']})" for r in refused), ""]
    text += ["## Improvement time", "",
             bench.table(scale, ["case", "cells", "effort", "greedy key", "improved key",
                                 "greedy s", "total s", "target s", "met"]), ""]
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "improve.md").write_text("\n".join(text))
    (out / "improve.json").write_text(json.dumps({"models": rows, "scaling": scale}, indent=2))
    print("\n".join(text))
    return 0


if __name__ == "__main__":
    sys.exit(main())
