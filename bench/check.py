"""``make bench-check``: the rows of :mod:`bench.targets` against their targets.

Runs each row as a user types it, in a fresh process (``python -m core
fabricate ...``), and prints a markdown table: wall seconds and peak memory
against the row's targets, the bricks and the two stability verdicts (the
finished object, every build step), and for a row over its target the stage
whose seconds grew most against ``bench/reference.json`` (the last committed
measurement).  Quick rows only unless ``--all``; ``--rows`` picks rows by a
word of their names.  ``--write-reference`` stores this run's figures as the
new reference.  The table is also written to ``bench/out/check.md``.  Exits 1
when a row is over its target or its bricks or verdicts moved from the
reference (bricks by more than :data:`BRICKS_TOLERANCE`), 0 otherwise.
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

sys.path.insert(0, str(Path(__file__).resolve().parent))
from targets import ROWS, Row  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
MODELS = ROOT.parent / "shared" / "models"
DEMO = ROOT / "examples" / "build" / "hmd.step"
REFERENCE = Path(__file__).resolve().parent / "reference.json"
OUT = ROOT / "bench" / "out"
#: Relative change in the brick count that counts as a changed result (issue 44: 2 %).
BRICKS_TOLERANCE = 0.02
#: Edge of the boxes made for the rows ``cube20``, ``cube1m``, ``cube2m`` (mm).
CUBES_MM = {"cube20": 20.0, "cube1m": 1000.0, "cube2m": 2000.0}


def model_path(row: Row, work: Path) -> Path | None:
    """The input file of ``row`` (made in ``work`` for the cubes), or None when it needs
    none; raises SystemExit naming what is missing."""
    if row.model is None:
        return None
    if row.model in CUBES_MM:
        path = work / f"{row.model}.stl"
        if not path.exists():
            trimesh.creation.box([CUBES_MM[row.model]] * 3).export(path)
        return path
    path = DEMO if row.model == "demo" else MODELS / row.model
    if not path.exists():
        raise SystemExit(f"{path} is missing (demo: make examples/build/hmd.step; "
                         f"models: ../shared/models)")
    return path


def timed_run(command: list[str], env: dict) -> tuple[float, float, str]:
    """Wall seconds, peak resident memory (GB, the largest of the process tree's
    waited-for processes) and stderr of ``command``; it must succeed."""
    start = time.perf_counter()
    with tempfile.TemporaryFile("w+") as err:
        proc = subprocess.Popen(command, cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=err)
        _, status, usage = os.wait4(proc.pid, 0)
        seconds = time.perf_counter() - start
        proc.returncode = os.waitstatus_to_exitcode(status)
        err.seek(0)
        stderr = err.read()
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(command)} failed ({proc.returncode}):\n{stderr}")
    return seconds, usage.ru_maxrss / 1024 ** 2, stderr


def measure(row: Row, work: Path) -> dict:
    """One row's figures: wall s, peak GB, stage seconds, bricks and verdicts."""
    model = model_path(row, work)
    out = work / "out"
    command = [sys.executable, "-m", "core"]
    command += ["fabricate", str(model), *row.args, "--out", str(out)] if model else list(row.args)
    cache = {"none": "none"}.get(row.cache, str(work / "cache"))
    env = {**os.environ, "FABRICKATOR_CACHE": cache, **row.env}
    if row.cache == "warm":
        timed_run(command, env)
    seconds, gb, _ = timed_run(command, env)
    figures = {"wall_s": round(seconds, 2), "peak_gb": round(gb, 3)}
    if model is not None:
        report = json.loads((out / "report.json").read_text())
        stability = report["stability"]
        figures.update(
            stages_s=report["timings_s"], bricks=report["bricks"]["total"],
            stands=stability["force"]["stable"] if stability["force"]["checked"] else None,
            failing=sorted(map(str, stability["force"]["failing_bricks"])),
            builds=stability["build"]["stands_every_step"] if stability.get("build") else None)
    return figures


def grown_stage(figures: dict, before: dict | None) -> str:
    """The stage whose seconds grew most against ``before``, as ``name a -> b s``."""
    if not before or "stages_s" not in figures or "stages_s" not in before:
        slowest = max(figures.get("stages_s", {}).items(), key=lambda kv: kv[1], default=None)
        return f"{slowest[0]} {slowest[1]:.1f} s (no reference)" if slowest else ""
    grown = max(figures["stages_s"], key=lambda k: figures["stages_s"][k] - before["stages_s"].get(k, 0.0))
    if figures["stages_s"][grown] - before["stages_s"].get(grown, 0.0) < 0.05:
        slowest = max(figures["stages_s"], key=figures["stages_s"].get)
        return f"none grew; slowest {slowest} {figures['stages_s'][slowest]:.1f} s"
    return f"{grown} {before['stages_s'].get(grown, 0.0):.1f} -> {figures['stages_s'][grown]:.1f} s"


def changed(figures: dict, before: dict | None) -> str:
    """What moved in the result against ``before``: bricks beyond the tolerance, a verdict."""
    if not before or "bricks" not in figures:
        return ""
    moved = []
    if abs(figures["bricks"] - before["bricks"]) > BRICKS_TOLERANCE * before["bricks"]:
        moved.append(f"bricks {before['bricks']} -> {figures['bricks']}")
    for key in ("stands", "builds", "failing"):
        if figures.get(key) != before.get(key):
            moved.append(f"{key} {before.get(key)} -> {figures.get(key)}")
    return "; ".join(moved)


def table(rows: list[tuple[Row, dict]], reference: dict) -> tuple[str, bool]:
    """The markdown table of the measured rows, and whether any is over or moved."""
    lines = ["| row | wall s | target s | peak GB | bricks | stands | builds | over | stage that grew | result moved |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    bad = False
    for row, figures in rows:
        before = reference.get(row.name)
        over = figures["wall_s"] > row.target_s or (row.target_gb is not None
                                                     and figures["peak_gb"] > row.target_gb)
        moved = changed(figures, before)
        bad |= over or bool(moved)
        target = f"{row.target_s:g}" + (f" (< {row.target_gb:g} GB)" if row.target_gb else "")
        lines.append(f"| {row.name} | {figures['wall_s']:.2f} | {target} | {figures['peak_gb']:.2f} | "
                     f"{figures.get('bricks', '')} | {figures.get('stands', '')} | {figures.get('builds', '')} | "
                     f"{'**OVER**' if over else 'ok'} | {grown_stage(figures, before) if over else ''} | {moved} |")
    return "\n".join(lines), bad


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--all", action="store_true", help="the long rows too")
    parser.add_argument("--rows", nargs="*", default=None, help="rows whose name has one of these words")
    parser.add_argument("--write-reference", action="store_true", help="store this run as the reference")
    args = parser.parse_args(argv)
    chosen = [r for r in ROWS if (args.all or r.quick or args.rows)
              and (not args.rows or any(w.lower() in r.name.lower() for w in args.rows))]
    reference = json.loads(REFERENCE.read_text()) if REFERENCE.exists() else {}
    measured = []
    for row in chosen:
        if row.model not in (None, "demo", *CUBES_MM) and not (MODELS / row.model).exists():
            print(f"skipped {row.name}: ../shared/models/{row.model} is absent", file=sys.stderr)
            continue
        with tempfile.TemporaryDirectory(prefix="fabrickator-bench-") as work:
            measured.append((row, measure(row, Path(work))))
        print(f"{row.name}: {measured[-1][1]['wall_s']:.2f} s", file=sys.stderr, flush=True)
    text, bad = table(measured, reference)
    print(text)
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "check.md").write_text(text + "\n")
    if args.write_reference:
        REFERENCE.write_text(json.dumps({**reference, **{r.name: f for r, f in measured}}, indent=1) + "\n")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
