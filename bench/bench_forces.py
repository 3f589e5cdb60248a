"""``make bench``: the force check (issue 14) on every model, and its scaling.

Per model (no printed parts, on a table, as the CLI runs it): bricks, the
force verdict and worst utilisation of the laid-out object before and after
the layout uses the forces (:mod:`core.layout.reinforce`), failing and unsupported
bricks, whether every build step stands (unstable and moved steps, props, steps checked
by the brick graph only), seconds
of the force stage and of the build-order check, on a table and on a baseplate.  Then the synthetic rows:
the force check of a ~3,000-brick layout (and of bigger ones, by their
hanging parts, beside the whole program where it can be solved) and all build
prefixes of a ~500-brick build.  Prints markdown tables and writes them to ``bench/out/``.
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

from bench import MODELS, UNITS, model_paths, table  # noqa: E402  (bench/bench.py)
from core import catalog, forces, hollow, pipeline, voxelize  # noqa: E402
from core.errors import InputError  # noqa: E402
from core.forces import limits  # noqa: E402
from core.instructions import build_order  # noqa: E402
from core.layout import greedy as layout  # noqa: E402
from core.model import CELL_MM, Grid  # noqa: E402


def _verdict(f: forces.Forces) -> str:
    worst = "inf" if not np.isfinite(f.max_utilisation) else f"{f.max_utilisation:.3f}"
    return f"{'stands' if f.stable else 'FAILS'} {worst}"


#: Models whose file is not z-up, benched again turned upright (``--up``) after their row as
#: given: the Stanford bunny's scan is y-up (as given it lies on its side).
UPRIGHT = {"stanford_bunny_open.obj": "y"}


def _finished(finished: dict | None) -> str | None:
    """The finished build with the props it keeps (:func:`core.instructions.build_order.finished_with_props`)."""
    if finished is None:
        return None
    if not finished["checked"]:
        return "graph only"
    worst = "inf" if finished["max_utilisation"] is None else f"{finished['max_utilisation']:.3f}"
    return f"{'stands' if finished['stands'] else 'FAILS'} {worst}"


def bench_model(path: Path, ground: str, up: str = "z") -> dict:
    """One row: the pipeline on ``path`` turned by ``up`` (no slicing), its force and build verdicts."""
    row = {"model": path.name + ("" if up == "z" else f" --up {up}"), "ground": ground}
    try:
        fab = pipeline.run(path, units=UNITS.get(path.name, "mm"), slice_parts=False, ground=ground,
                           picture=False, up=up)
    except InputError as err:
        row["error"] = str(err)
        return row
    except Exception as exc:  # noqa: BLE001 - a bug: the row says so, the bench goes on
        row["error"] = f"BUG {type(exc).__name__}: {exc}"
        return row
    f = fab.forces
    rf = fab.reinforced
    row.update({
        "bricks": len(fab.layout.bricks),
        "before forces (layout)": None if rf is None else
        f"{'stands' if rf.before['stable'] else 'FAILS'} {rf.before['max_utilisation']}",
        "after forces (layout)": None if rf is None else
        f"{'stands' if rf.after['stable'] else 'FAILS'} {rf.after['max_utilisation']}",
        "reinforce s": fab.timings_s.get("reinforce"),
        "verdict": _verdict(f),
        "failing": len(f.failing_bricks),
        "unsupported": len(f.unsupported),
        "every step stands": "yes" if not fab.order.unstable else f"no: {len(fab.order.unstable)}",
        "steps moved": fab.order.moved,
        "props": len(fab.order.props),
        "props left in": sum(p["removed_after"] is None for p in fab.order.props),
        "finished with them": _finished(fab.order.finished),
        "steps by the graph only": int(np.isnan(fab.order.utilisation).sum()),
        "steps": len(fab.order.steps),
        "forces s": round(fab.forces.seconds, 2),
        "build check s": fab.timings_s.get("build_stability"),
    })
    return row


#: The scaling cases: a hollow box standing on the table under a slab of six plate layers
#: that overhangs it all round (so that the clutch is needed): (name, grid, wall, rim, whether
#: to check every build prefix).  The 1,474-brick one's prefixes take about 15 minutes
#: (session 8: 932 s, 292 programs), so the bench checks them on the 454-brick one.
SCALING_CASES = (("hollow box 48x48x60 cells under a 64x64 slab", (64, 64, 66), 3, 8, False),
                 ("hollow box 30x30x40 cells under a 42x42 slab", (42, 42, 46), 2, 6, True),
                 ("hollow box 24x24x30 cells under a 34x34 slab", (34, 34, 36), 2, 5, True))
#: Hollowed cubes (the hollow stage's 2-stud shell and pillars; the roof hangs between
#: them): (name, side in studs).  The 45 cm one is the ~3,000-brick case.  Their build
#: steps are checked too: past MAX_BODIES without programs (the roof's by the graph only).
HOLLOW_CUBES = (("hollow cube 45 cm (56x56x140 cells)", 56),
                ("hollow cube 1 m (125x125x312 cells)", 125))


def _method(f: forces.Forces) -> str:
    return "unchecked" if f.unchecked else (
        f"{f.sub_structures} hanging part(s)" if f.sub_structures else "whole program")


def _scaling_grids():
    """(name, grid, whether to check every build prefix) of the scaling rows."""
    for name, outer, wall, rim, prefixes in SCALING_CASES:
        # walls standing on the table, a slab of six plate layers on top reaching out all round
        filled = np.zeros(outer, dtype=bool)
        filled[rim:-rim, rim:-rim, :-6] = True
        filled[rim + wall:-rim - wall, rim + wall:-rim - wall, :-6] = False
        filled[:, :, -6:] = True
        yield name, Grid(np.zeros(3), np.array(CELL_MM), filled), prefixes
    for name, side in HOLLOW_CUBES:
        solid = Grid(np.zeros(3), np.array(CELL_MM), np.ones((side, side, int(side * 2.5)), bool))
        yield name, hollow.hollow(solid, hollow.SHELL_STUDS)[0], True


def bench_scaling() -> list[dict]:
    """The force check of the :data:`SCALING_CASES` (1,474, 454 and 269 bricks) and the
    :data:`HOLLOW_CUBES` (3,091 and 22,657) and, where asked, every build prefix, on a
    table; up to :data:`core.forces.limits.MAX_BODIES` bodies also by the whole program alone."""
    rows = []
    for name, grid, prefixes in _scaling_grids():
        lay = layout.lay_out(grid, catalog.CATALOG, seed=0)
        start = time.perf_counter()
        f = forces.analyse(lay, ground="table")
        analyse_s = time.perf_counter() - start
        start = time.perf_counter()
        quick = forces.analyse(lay, ground="table", detail=False)
        verdict_s = time.perf_counter() - start
        order = build_order.plan(lay)
        row = {"case": name, "cells": grid.count, "bricks": len(lay.bricks),
               "verdict": _verdict(f), "method": _method(f), "verdict only s": verdict_s,
               "verdict + per-brick s": analyse_s, "steps": len(order.steps),
               "quick agrees": quick.stable == f.stable}
        if f.sub_structures and len(lay.bricks) <= limits.MAX_BODIES:
            exact_at, limits.EXACT_BODIES = limits.EXACT_BODIES, limits.MAX_BODIES
            start = time.perf_counter()
            whole = forces.analyse(lay, ground="table", detail=False)
            row.update({"whole program": _verdict(whole),
                        "whole program s": time.perf_counter() - start})
            limits.EXACT_BODIES = exact_at
        if prefixes:
            checker = forces.BuildChecker(lay, ground="table")
            start = time.perf_counter()
            checked = build_order.standing(lay, order, checker.stands)
            row.update({"prefix programs": checker.solves,
                        "all prefixes s": time.perf_counter() - start,
                        "every step stands": "yes" if not checked.unstable else "no",
                        "steps by the graph only": int(np.isnan(checked.utilisation).sum())})
        rows.append(row)
    return rows


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(ROOT / "bench" / "out"))
    parser.add_argument("--ground", default=None, choices=forces.GROUNDS,
                        help="one ground only (default: both, table and baseplate)")
    parser.add_argument("--scaling-only", action="store_true",
                        help="only the synthetic scaling rows, not the models")
    args = parser.parse_args()
    if not MODELS.is_dir():
        print(f"note: {MODELS} is absent: only the bundled demo model is measured")
    warm = trimesh.creation.box((20, 20, 10))
    forces.analyse(layout.lay_out(voxelize.legofy(warm), catalog.CATALOG))
    rows = []
    for path in [] if args.scaling_only else model_paths():
        for ground in [args.ground] if args.ground else list(forces.GROUNDS):
            for up in ("z",) + ((UPRIGHT[path.name],) if path.name in UPRIGHT else ()):
                rows.append(bench_model(path, ground, up))
                print(f"  measured {rows[-1]['model']}: {rows[-1]}", file=sys.stderr)
    ok = [r for r in rows if "error" not in r]
    refused = [r for r in rows if "error" in r]
    cols = ["model", "ground", "bricks", "before forces (layout)", "after forces (layout)", "verdict",
            "failing", "unsupported", "every step stands", "steps moved", "props", "props left in",
            "finished with them", "steps by the graph only", "steps", "reinforce s",
            "forces s", "build check s"]
    scaling = bench_scaling()
    text = ["## Forces per model (verdict: stands/FAILS and the worst utilisation)", "",
            table(ok, cols), ""]
    if refused:
        text += ["## Refused or failed", "", table(refused, ["model", "error"]), ""]
    text += ["## Force check scaling", "",
            table(scaling, ["case", "cells", "bricks", "verdict", "method", "verdict only s",
                            "verdict + per-brick s", "whole program", "whole program s", "steps",
                            "prefix programs", "all prefixes s", "every step stands",
                            "steps by the graph only",
                            "quick agrees"]), ""]
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "forces.md").write_text("\n".join(text))
    (out / "forces.json").write_text(json.dumps({"models": rows, "scaling": scaling}, indent=2,
                                                default=str))
    print("\n".join(text))
    return 0


if __name__ == "__main__":
    sys.exit(main())
