"""``make bench``: start-up time of a mesh fabricate, before and after the lazy imports.

Times, in fresh Python processes (median of :data:`RUNS` after one warm-up
run that writes the byte code and numba's caches):

* ``python -m core fabricate box.stl --out DIR --no-picture --quiet``, a
  40 x 24 x 19.2 mm box without printed parts, so nearly all of it is
  start-up;
* ``python -c "import core.cli"``;

and counts the modules a fabricate has imported when it ends, and whether
OpenCascade (OCP) or cadquery are among them.  The row "after" is this
checkout; the row "before" is :data:`BEFORE` (the commit before OCP and
cadquery became lazy imports, or ``--before SHA``), checked out with
``git worktree add`` into a temporary folder and run with the same Python,
then removed.  Prints a markdown table and writes it to
``bench/out/startup.md``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import trimesh

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "bench" / "out"
#: The last commit whose mesh fabricate imported OCP and cadquery at start-up.
BEFORE = "c8935db"
#: Timed runs per command (after one warm-up run).
RUNS = 3

#: Runs the CLI and prints what it imported, as JSON on its last line.
MODULES = """
import json, sys
from core import cli
status = cli.main(sys.argv[1:])
names = {name.split(".")[0] for name in sys.modules}
print(json.dumps({"status": status, "modules": len(sys.modules),
                  "heavy": sorted(names & {"OCP", "cadquery"})}))
"""


def wall_time(command: list[str], cwd: Path) -> float:
    """Seconds ``command`` takes in ``cwd``; it must succeed."""
    start = time.perf_counter()
    proc = subprocess.run(command, cwd=cwd, capture_output=True, text=True, timeout=600)
    seconds = time.perf_counter() - start
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(command)} failed in {cwd}:\n{proc.stderr}")
    return seconds


def median_time(command: list[str], cwd: Path) -> float:
    """Median wall time of :data:`RUNS` runs after one warm-up run."""
    wall_time(command, cwd)
    return statistics.median(wall_time(command, cwd) for _ in range(RUNS))


def measure(label: str, commit: str, checkout: Path, model: Path, work: Path) -> dict:
    """One row: the timings and the import facts of the code in ``checkout``."""
    out = work / f"out-{label}"
    args = ["fabricate", str(model), "--out", str(out), "--no-picture", "--quiet"]
    fabricate = median_time([sys.executable, "-m", "core", *args], checkout)
    import_cli = median_time([sys.executable, "-c", "import core.cli"], checkout)
    proc = subprocess.run([sys.executable, "-c", MODULES, *args], cwd=checkout,
                          capture_output=True, text=True, timeout=600)
    facts = json.loads(proc.stdout.strip().splitlines()[-1])
    return {"version": label, "commit": commit, "fabricate s": round(fabricate, 2),
            "import core.cli s": round(import_cli, 2), "modules": facts["modules"],
            "OCP/cadquery": ", ".join(facts["heavy"]) or "no"}


def git(*args: str) -> str:
    return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True,
                          check=True).stdout.strip()


def table(rows: list[dict]) -> str:
    columns = list(rows[0])
    lines = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    lines += ["| " + " | ".join(str(r[c]) for c in columns) + " |" for r in rows]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--before", default=BEFORE, metavar="SHA",
                        help=f"the commit to compare with (default {BEFORE})")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="fabrickator-bench-startup-") as tmp:
        work = Path(tmp)
        model = work / "box.stl"
        box = trimesh.creation.box((40.0, 24.0, 19.2))
        box.apply_translation(-box.bounds[0])
        box.export(model)
        rows = []
        notes = []
        try:
            before = git("rev-parse", "--short", f"{args.before}^{{commit}}")
        except subprocess.CalledProcessError:
            before = None
            notes.append(f"before: commit {args.before} is not in this clone; not measured")
        if before is not None:
            checkout = work / "before"
            git("worktree", "add", "--detach", str(checkout), before)
            try:
                rows.append(measure("before", before, checkout, model, work))
            finally:
                git("worktree", "remove", "--force", str(checkout))
        dirty = " + changes" if git("status", "--porcelain", "--untracked-files=no") else ""
        rows.append(measure("after", git("rev-parse", "--short", "HEAD") + dirty, ROOT, model, work))
    text = (f"## Start-up of a mesh fabricate (box.stl, no printed parts; median of {RUNS}, "
            f"wall seconds)\n\n" + table(rows) + "\n"
            + "".join(f"\n{n}\n" for n in notes))
    print(text)
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "startup.md").write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
