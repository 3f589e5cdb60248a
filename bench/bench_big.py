"""Big objects, hollow and solid: cells, bricks, seconds per stage and peak memory.

Each model is fabricated by the command line (``python -m core fabricate``) in a
subprocess of its own under ``/usr/bin/time``, with the default (automatic)
setting, hollowed (``--hollow``, a 2-stud shell with pillars) and solid
(``--hollow=0``); the 2 m cube only by default and solid, which the size limit
refuses.
``solid bricks`` is what a hollowed run's report gives for the part built solid: its
fast layout, or ``>=`` a lower bound (core.report.hollow_report).
The stages' seconds come from the run's report.json (``timings_s``; ``write``
is everything written after the driver: instructions, LDraw, picture, ...;
``layout`` includes the solid layout made beside a shell, core.hollow.solid_layout_wanted),
the peak resident memory from ``/usr/bin/time``.  Prints a markdown table.

The models: the Stanford bunny scaled x3 (its file is in metres), the
Assembly4 example part (the collection has no Assembly4 support bracket, so its
connecting rod, scaled x6 to 84 cm), a 1 m solid cube, and an HMD-like shell
(the Relativty HMD body scaled x5 to 89 cm).  Models missing from
../shared/models are left out with a line saying so.

Run: ``.venv/bin/python bench/bench_big.py`` (a few minutes on 2 cores); ``--case TEXT``
runs only the cases whose name holds TEXT, ``--setting auto|hollow|solid`` only those
settings (both repeatable): ``--case "cube 1 m" --setting hollow``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import trimesh

ROOT = Path(__file__).resolve().parents[1]
MODELS = ROOT.parent / "shared" / "models"
if not MODELS.is_dir():
    MODELS = Path("/work/shared/models")
STAGES = ("load", "legofy", "hollow", "layout", "improve", "reinforce", "stability", "build_order",
          "write")


def cases(work: Path) -> list[tuple[str, Path, list[str], list[str]]]:
    """(name, model, extra options, hollow settings to run) of every case there is."""
    cube = work / "cube_1m.stl"
    trimesh.creation.box((1000.0, 1000.0, 1000.0)).export(cube)
    cube2 = work / "cube_2m.stl"
    trimesh.creation.box((2000.0, 2000.0, 2000.0)).export(cube2)
    both = ["auto", "--hollow", "--hollow=0"]
    out = []
    for name, file, options in (
            ("bunny x3", "stanford_bunny_open.obj", ["--units", "m", "--scale", "3"]),
            ("Assembly4 connecting rod x6", "asm4_connecting_rod.FCStd", ["--scale", "6"]),
            ("HMD body shell x5", "relativty_hmd_body.stl", ["--scale", "5"])):
        path = MODELS / file
        if path.exists():
            out.append((name, path, options, both))
        else:
            print(f"skipped {name}: {path} is missing", file=sys.stderr)
    out.append(("solid cube 1 m", cube, [], both))
    out.append(("solid cube 2 m", cube2, [], ["auto", "--hollow=0"]))
    return out


def run(model: Path, options: list[str], hollow: str, work: Path) -> dict:
    """One fabricate run: its report's figures, wall seconds and peak RSS."""
    out = work / "out"
    stats = work / "time.txt"
    flags = [] if hollow == "auto" else [hollow]
    cmd = ["/usr/bin/time", "-o", str(stats), "-f", "%e %M", sys.executable, "-m", "core",
           "fabricate", str(model), *options, *flags, "--out", str(out), "--quiet"]
    start = time.perf_counter()
    proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
    wall = time.perf_counter() - start
    last = stats.read_text().strip().splitlines()[-1].split() if stats.exists() else ["0", "0"]
    row = {"wall_s": wall, "rss_gb": int(last[1]) / 1e6}
    if proc.returncode != 0:
        row["error"] = (proc.stderr.strip().splitlines() or ["?"])[-1]
        return row
    doc = json.loads((out / "report.json").read_text())
    h = doc.get("hollow") or {}
    solid = (h.get("bricks") or {})
    row.update(cells=doc["plates"], solid_cells=h.get("cells_solid", doc["plates"]),
               bricks=doc["bricks"]["total"], assembly_h=doc["assembly_s"] / 3600,
               solid_bricks=(f"{solid['solid']:,} (fast)" if "solid" in solid else
                             f">= {solid['solid_at_least']:,}" if "solid_at_least" in solid else "-"),
               hollow_on=h.get("on", False), components=doc["stability"]["components"],
               regions=doc["stability"]["regions"],
               html_s=doc["assembly"]["timings_s"].get("html", 0.0),
               **{f"{s}_s": doc["timings_s"].get(s, 0.0) for s in STAGES})
    row["layout_s"] += doc["timings_s"].get("layout_solid", 0.0)
    force = doc["stability"].get("force") or {}
    if not force.get("checked", False):
        row["force"] = "unchecked"
    elif force.get("topples"):
        row["force"] = "tips over"
    elif force.get("max_utilisation") is None:
        row["force"] = "falls"
    else:
        row["force"] = ("stands" if force["stable"] else "falls") + f" {force['max_utilisation']:.2f}"
    return row


#: The hollow settings by the name ``--setting`` gives them.
SETTINGS = {"auto": "auto", "hollow": "--hollow", "solid": "--hollow=0"}


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description="Big objects, hollow and solid: a markdown "
                                                 "table of cells, bricks, seconds and memory.")
    parser.add_argument("--case", action="append", default=[], metavar="TEXT",
                        help="only the cases whose name holds TEXT (repeatable)")
    parser.add_argument("--setting", action="append", default=[], choices=sorted(SETTINGS),
                        help="only these hollow settings (repeatable)")
    args = parser.parse_args(argv)
    wanted = {SETTINGS[s] for s in args.setting}
    load = os.getloadavg()
    print(f"# Big objects (bench/bench_big.py), {os.cpu_count()} cores, load average "
          f"{load[0]:.1f} at the start\n")
    head = ["model", "hollow", "cells (solid)", "bricks", "solid bricks", "assembly h", "comp/reg", "force",
            *[s.replace("build_order", "order") for s in STAGES], "(html)", "wall s", "peak GB"]
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    with tempfile.TemporaryDirectory(prefix="bench-big-") as tmp:
        work = Path(tmp)
        for name, model, options, settings in cases(work):
            if args.case and not any(text in name for text in args.case):
                continue
            for hollow in settings:
                if wanted and hollow not in wanted:
                    continue
                r = run(model, options, hollow, work)
                label = {"auto": "default", "--hollow": "2 studs", "--hollow=0": "solid"}[hollow]
                if "error" in r:
                    print(f"| {name} | {label} | refused: {r['error']} |" + " |" * (len(head) - 5)
                          + f" {r['wall_s']:.1f} | {r['rss_gb']:.2f} |")
                    continue
                if hollow == "auto":
                    label += " (hollow)" if r["hollow_on"] else " (solid)"
                print(f"| {name} | {label} | {r['cells']:,} ({r['solid_cells']:,}) | "
                      f"{r['bricks']:,} | {r['solid_bricks']} | {r['assembly_h']:.1f} | "
                      f"{r['components']}/{r['regions']} | "
                      f"{r['force']} | "
                      + " | ".join(f"{r[s + '_s']:.1f}" for s in STAGES)
                      + f" | {r['html_s']:.1f} | {r['wall_s']:.1f} | {r['rss_gb']:.2f} |", flush=True)
    load = os.getloadavg()
    print(f"\nload average {load[0]:.1f} at the end (other work on the machine slows every stage)")


if __name__ == "__main__":
    main()
