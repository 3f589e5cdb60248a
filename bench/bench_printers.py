"""Printed parts' time per printer, re-sliced by hand from the written plates (issue 46).

For two shared models with a precision region (the phone mount's rail and
screw boss as boxes, the motor bracket's holes found by ``--suggest``), runs
``python -m core fabricate`` once per printer: the Prusa MINI, two non-Prusa
printers of PrusaSlicer's vendor bundles and the default (no ``--printer``:
the MK3S).  Then, as a user would, it slices every written
``parts/plate-*.3mf`` again with ``prusa-slicer --dont-arrange
--export-gcode`` (the flags :func:`core.printing.print_time.slice_plate`
uses), reads the G-code's ``; estimated printing time (normal mode)`` line
(parsed here, not with core's parser) and compares the sum over the plates
with ``report.json``'s ``print_time_s.printed_parts``.

The table gives per model and printer the plates written, the report's
printed-parts seconds, the re-sliced seconds, their difference in % of the
re-sliced time and the whole model's seconds (``print_time_s.full_model``;
"enlarged bed" when it does not fit the printer).  A last column says
whether the printed-parts time differs from the MK3S's for the same model.
The print preset is the one the first plate's config names
(``print_settings_id``), what PrusaSlicer shows when it opens the plate.
PrusaSlicer 2.5 itself does not always give the same time for the same
file: the MINI's motor-bracket plate (five parts with supports) came out
between 11868 and 11919 s in seven slices of one file (0.4 %), so a
difference of that size is the slicer's own spread.
Exits 1 when any row differs by more than :data:`TOLERANCE_PCT`, or a run
fails; skips with a message (exit 0) without ``../shared/models`` or
``prusa-slicer``.
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import subprocess
import sys
import tempfile
import time
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MODELS = ROOT.parent / "shared" / "models"

#: A row fails when the re-sliced time differs from the report's by more than this.
TOLERANCE_PCT = 2.0

#: Seconds one fabricate run, or one re-slice, may take.
TIMEOUT_S = 1800

#: model file -> (its fabricate options marking the precision region, what they mark).
CASES = {
    # As in bench_printed.py: the rail channel's lips and the screw boss.
    "openbot_phone_mount.stl": (("--high-res", "30,14,0,92,20.5,22", "--high-res", "30,0,4,44,14,18"),
                                "rail lips + screw boss (boxes)"),
    # The motor clamp bore and screw holes (CATALOG: 5 round holes d4.5), found by suggest.
    "openbot_motor_bracket.stl": (("--suggest",), "holes by --suggest"),
}

#: The printers, None for the default (the MK3S).
PRINTERS = (
    "Original Prusa MINI & MINI+",
    "Creality Ender-3 (0.4 mm nozzle)",
    "Anycubic i3 Mega",
    None,
)
DEFAULT_NAME = "(default) Original Prusa i3 MK3S & MK3S+"

_TIME = re.compile(r"^; estimated printing time \(normal mode\) = (.+)$", re.M)
_UNIT = {"d": 86400, "h": 3600, "m": 60, "s": 1}


def gcode_seconds(gcode: Path) -> float:
    """The normal-mode estimate of ``gcode`` in seconds ("1d 2h 3m 4s", units optional)."""
    found = _TIME.search(gcode.read_text(encoding="utf-8", errors="replace"))
    if not found:
        raise ValueError(f"{gcode.name}: no 'estimated printing time (normal mode)' line")
    pieces = re.findall(r"(\d+)([dhms])", found[1])
    if not pieces:
        raise ValueError(f"{gcode.name}: cannot read the time {found[1]!r}")
    return float(sum(int(n) * _UNIT[u] for n, u in pieces))


def plate_setting(plate: Path, key: str) -> str | None:
    """The value of ``key`` in the PrusaSlicer project config inside ``plate``."""
    with zipfile.ZipFile(plate) as archive:
        text = archive.read("Metadata/Slic3r_PE.config").decode("utf-8", errors="replace")
    found = re.search(rf"^; {re.escape(key)} = (.*)$", text, re.M)
    return found[1].strip() if found else None


def reslice(plate: Path, slicer: str, work: Path) -> float:
    """Slice ``plate`` as a user would and return the G-code's time."""
    gcode = work / (plate.stem + ".gcode")
    run = subprocess.run([slicer, "--loglevel", "1", "--dont-arrange", "--export-gcode", "--output",
                          str(gcode), str(plate)], capture_output=True, text=True, timeout=TIMEOUT_S,
                         stdin=subprocess.DEVNULL)
    if run.returncode != 0 or not gcode.exists():
        last = (run.stderr or run.stdout).strip().splitlines()[-1:] or ["no output"]
        raise RuntimeError(f"prusa-slicer failed on {plate.name}: {last[0]}")
    return gcode_seconds(gcode)


def fabricate(model: Path, options: tuple[str, ...], printer: str | None, out: Path) -> dict:
    """``python -m core fabricate`` on ``model`` into ``out``; its report."""
    argv = [sys.executable, "-m", "core", "fabricate", str(model), "--out", str(out), "--no-picture", *options]
    if printer:
        argv += ["--printer", printer]
    run = subprocess.run(argv, cwd=ROOT, capture_output=True, text=True, timeout=TIMEOUT_S,
                         stdin=subprocess.DEVNULL)
    if run.returncode != 0:
        last = (run.stderr or run.stdout).strip().splitlines()[-1:] or [f"status {run.returncode}"]
        raise RuntimeError(f"fabricate failed: {last[0]}")
    return json.loads((out / "report.json").read_text(encoding="utf-8"))


def measure(model: Path, options: tuple[str, ...], printer: str | None, work: Path, slicer: str) -> dict:
    """One row: fabricate, then re-slice every written plate."""
    out = work / f"{model.stem}-{re.sub(r'[^A-Za-z0-9]+', '_', printer or 'default')}"
    start = time.perf_counter()
    doc = fabricate(model, options, printer, out)
    pt = doc.get("print_time_s") or {}
    plates = sorted((out / "parts").glob("plate-*.3mf"), key=lambda p: int(re.findall(r"\d+", p.stem)[0]))
    row = {"model": model.name, "printer": printer or DEFAULT_NAME, "plates": len(plates),
           "report_plates": pt.get("print_plates"), "report": pt.get("printed_parts"),
           "full": pt.get("full_model"), "enlarged": pt.get("full_model_on_enlarged_bed"),
           "method": pt.get("method", "")}
    if not plates or row["report"] is None:
        raise RuntimeError("no plate written or no printed-parts time (nothing printed?)")
    row["preset"] = plate_setting(plates[0], "print_settings_id")
    row["plate_s"] = [reslice(p, slicer, out) for p in plates]
    row["resliced"] = sum(row["plate_s"])
    row["diff"] = 100.0 * (row["report"] - row["resliced"]) / row["resliced"]
    row["run_s"] = time.perf_counter() - start
    return row


def main(argv: list[str] | None = None) -> int:
    """Measure every model and printer, print the table; 1 when a row is off or a run failed."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--keep", type=Path, help="write the runs here (default: a temporary folder, removed)")
    args = parser.parse_args(argv)
    slicer = shutil.which("prusa-slicer")
    if not MODELS.is_dir():
        print(f"skipped: {MODELS} not found")
        return 0
    if slicer is None:
        print("skipped: prusa-slicer not found")
        return 0
    rows, failures = [], []
    with tempfile.TemporaryDirectory(prefix="bench-printers-") as tmp:
        work = args.keep or Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        for name, (options, _) in CASES.items():
            model = MODELS / name
            if not model.exists():
                print(f"skipped {name}: not found")
                continue
            for printer in PRINTERS:
                try:
                    rows.append(measure(model, options, printer, work, slicer))
                except (RuntimeError, ValueError, OSError, subprocess.TimeoutExpired) as exc:
                    failures.append(f"{name}, {printer or DEFAULT_NAME}: {exc}")
                    print(f"failed: {failures[-1]}", file=sys.stderr, flush=True)
                    continue
                r = rows[-1]
                print(f"{name} / {r['printer']}: report {r['report']:.0f} s, re-sliced {r['resliced']:.0f} s "
                      f"({r['diff']:+.2f} %), {r['run_s']:.0f} s", file=sys.stderr, flush=True)
    mk3s = {r["model"]: r["report"] for r in rows if r["printer"] == DEFAULT_NAME}
    print("| model | printer | print preset | plates | report printed-parts s | re-sliced s | difference % "
          "| whole-model s | differs from MK3S |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        plates = str(r["plates"]) + ("" if r["report_plates"] == r["plates"] else f" (report: {r['report_plates']})")
        full = "" if r["full"] is None else f"{r['full']:.0f}" + (" (enlarged bed)" if r["enlarged"] else "")
        base = mk3s.get(r["model"])
        differs = "-" if r["printer"] == DEFAULT_NAME or base is None else ("yes" if r["report"] != base else "NO")
        print(f"| {r['model']} | {r['printer']} | {r['preset']} | {plates} | {r['report']:.0f} "
              f"| {r['resliced']:.0f} | {r['diff']:+.2f} | {full} | {differs} |")
    off = [r for r in rows if abs(r["diff"]) > TOLERANCE_PCT or r["report_plates"] != r["plates"]]
    print()
    print(f"{len(rows)} run(s); {len(off)} over {TOLERANCE_PCT:g} % (or plate count unlike the report's); "
          f"models: " + "; ".join(f"{n}: {why}" for n, (_, why) in CASES.items()))
    for failure in failures:
        print(f"\n**Failed**: {failure}")
    return 1 if off or failures else 0


if __name__ == "__main__":
    sys.exit(main())
