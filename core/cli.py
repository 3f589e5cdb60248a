"""Command line of the headless core: ``python -m core fabricate MODEL --out DIR``.

The options are the settings of :class:`core.request.Request` (their flags,
help and defaults come from it); the command builds a Request, runs the
driver (:func:`core.pipeline.fabricate`) and prints the result.  Bad input
ends with one line on stderr naming the problem and exit status 2; any
other failure is a bug: one line saying so and naming the log file with the
traceback (:func:`core.errors.log_bug`), exit status 1.  Progress goes to
stderr, a short summary to stdout.
"""

from __future__ import annotations

import argparse
import sys
import time

from core import __version__, request
from core.errors import InputError, bug_message, log_bug


#: Area (mm²) thinner than a nozzle prints from which the summary warns; smaller spots
#: (a sharp corner of the engraved letters, say) stay in report.json's thin_features.
THIN_WARNING_MM2 = 1.0


class _Parser(argparse.ArgumentParser):
    """argparse that reports a usage mistake as one line and exit status 2."""

    def error(self, message: str):
        sys.stderr.write(f"{self.prog}: error: {message} (see --help)\n")
        sys.exit(2)


def _progress_printer(stream):
    """A progress callback that prints each stage once with its elapsed time."""
    start = time.perf_counter()

    def progress(fraction: float, message: str) -> None:
        stream.write(f"[{time.perf_counter() - start:6.2f} s] {int(fraction * 100):3d}%  {message}\n")
        stream.flush()

    return progress


def _parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="python -m core",
                     description="Fabrickator: build a part from LEGO bricks.")
    parser.add_argument("--version", action="version", version=f"fabrickator {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    fab = sub.add_parser("fabricate", help="legofy and lay out a model",
                         description="Legofy MODEL (STL, OBJ, PLY, 3MF, STEP or FCStd) into "
                                     "1x1 plate cells of 8 x 8 x 3.2 mm and lay them out as "
                                     "standard LEGO plates and bricks.")
    fab.add_argument("model", metavar="MODEL")
    fab.add_argument("--out", required=True, metavar="DIR",
               help="output folder (report.json, layout.json, layout.png, instructions.html, assembly.mpd, bom.csv, bricklink.xml, parts/)")
    _model_options(fab)
    request.add_options(fab, ("seconds_per_brick", "seconds_per_part", "previous", "connectors",
                              "fit_grid", "picture", "palette"))
    fab.add_argument("--quiet", action="store_true", help="no progress on stderr")
    wat = sub.add_parser("watch", help="fabricate every new version of a model saved into a folder",
                         description="Watch FOLDER for STL/OBJ/PLY/3MF/STEP files that appear or "
                                     "change (e.g. exported by Blender with "
                                     "tools/blender/fabrickator_blender.py) and fabricate each as "
                                     "the next iteration of the previous one, into "
                                     "OUT/<name>-<n>. Ctrl-C ends it.")
    wat.add_argument("folder", metavar="FOLDER")
    wat.add_argument("--out", required=True, metavar="ROOT", help="folder for the outputs")
    request.add_options(wat, ("previous", "seconds_per_brick", "seconds_per_part", "connectors",
                              "fit_grid", "picture", "palette"))
    wat.add_argument("--existing", action="store_true",
               help="also fabricate the files already in FOLDER")
    wat.add_argument("--timeout", type=float, default=None, metavar="S",
               help="stop after S seconds (default: run until Ctrl-C)")
    _model_options(wat)
    wat.add_argument("--quiet", action="store_true", help="no progress on stderr")
    _calibration_parser(sub)
    return parser


def _calibration_parser(sub) -> None:
    """The ``calibration-strip`` command's options; its values default around Fit's."""
    from core import calibration

    low, high = calibration.default_range()
    cal = sub.add_parser("calibration-strip",
                         help="write a strip of test studs and sockets to find --stud-fit and "
                              "--socket-fit for your printer",
                         description="Write a printable strip (calibration_strip.stl and .3mf, "
                                     "README.txt on how to read it) with one column per value: "
                                     "a printed stud of 4.8 + value mm diameter on top, a square "
                                     "socket 4.8 + value mm wide underneath, the value embossed "
                                     "beside it. Press real LEGO onto the studs and into the "
                                     "sockets; the first value that clamps firmly is your "
                                     "--stud-fit or --socket-fit.")
    cal.add_argument("--out", required=True, metavar="DIR", help="output folder")
    cal.add_argument("--from", dest="start", type=float, default=low, metavar="MM",
                     help=f"first (loosest stud, tightest socket) value (default {low:+g})")
    cal.add_argument("--to", dest="stop", type=float, default=high, metavar="MM",
                     help=f"last value (default {high:+g})")
    cal.add_argument("--step", type=float, default=calibration.STEP_MM, metavar="MM",
                     help=f"step between two columns (default {calibration.STEP_MM:g})")


def _model_options(p: argparse.ArgumentParser) -> None:
    """The options that say how to read a model and what to print (fabricate and watch)."""
    request.add_options(p, ("units", "scale", "seed", "parts", "effort", "lower_bound", "high_res",
                            "high_res_solids", "stud_fit", "socket_fit"), units=request.UNITS)


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit status (0 ok, 2 bad input, 1 a bug)."""
    args = _parser().parse_args(argv)
    command = {"watch": _watch, "calibration-strip": _calibration_strip}.get(args.command, _fabricate)
    try:
        return command(args)
    except InputError as err:
        sys.stderr.write(f"error: {err}\n")
        return 2
    except Exception as exc:  # noqa: BLE001 - any other failure is a bug, reported as one
        sys.stderr.write(bug_message(exc, log_bug(exc, f"python -m core {args.command}")) + "\n")
        return 1


def _fabricate(args) -> int:
    """The ``fabricate`` command: one Request, the driver, the summary."""
    from core import pipeline

    progress = None if args.quiet else _progress_printer(sys.stderr)
    doc = pipeline.fabricate(request.from_options(args, args.model), args.out, progress=progress)
    _summary(doc, args.out)
    return 0


def _watch(args) -> int:
    """The ``watch`` command: each new file fabricated with the same settings as
    ``fabricate``, as an iteration on the last output of a version of the same model
    (:class:`core.watch.Versions`, the one version rule the workbench uses too)."""
    from pathlib import Path

    from core import pipeline, watch

    progress = None if args.quiet else _progress_printer(sys.stderr)
    root, runs = Path(args.out), 0
    job = request.from_options(args, "watched")
    versions = watch.Versions(first=job.previous)
    files = watch.watch(args.folder, include_existing=args.existing, timeout_s=args.timeout)
    sys.stderr.write(f"watching {args.folder} (Ctrl-C to stop)\n")
    try:
        for path in files:
            runs += 1
            out = root / f"{path.stem}-{runs}"
            previous = versions.previous(path)
            try:
                doc = pipeline.fabricate(job.replace(model=str(path), previous=previous and str(previous)),
                                         out, progress=progress)
            except InputError as err:
                sys.stderr.write(f"error: {path.name}: {err}\n")
                continue
            _summary(doc, out)
            versions.record(path, out)
    except KeyboardInterrupt:
        sys.stderr.write(f"stopped after {runs} version(s)\n")
    return 0


def _calibration_strip(args) -> int:
    """The ``calibration-strip`` command: one line per file written, or one error line
    and exit status 2."""
    from core import calibration

    values = calibration.column_values(args.start, args.stop, args.step)
    _, written = calibration.write_strip(args.out, values)
    for path in written:
        print(path)
    return 0


def _summary(doc: dict, out) -> None:
    """The short summary of one fabricate run on stdout."""
    for warning in doc["model"]["warnings"]:
        sys.stderr.write(f"warning: {warning}\n")
    for note in doc.get("notes", ()):
        sys.stderr.write(f"note: {note}\n")
    st, br = doc["stability"], doc["bricks"]
    print(f"{doc['plates']} cells -> {br['total']} bricks "
          f"({', '.join(f'{n}x {p}' for p, n in br['by_part'].items())}); "
          f"{st['components']} component(s) for {st['regions']} region(s), "
          f"{st['weak_points']} weak point(s); written to {out}")
    fit = doc["grid"].get("fit")
    if fit and any(fit["shift_mm"]):
        vol = fit["marked_model_mm3"]
        print(f"grid shifted {fit['shift_mm'][0]:g}, {fit['shift_mm'][1]:g} mm in x, y: the high-res "
              f"cells hold {vol['fitted']:.0f} mm³ of the part instead of {vol['centred']:.0f}")
    if doc["printed_parts"]:
        pt = doc["print_time_s"] or {}
        print(f"{len(doc['printed_parts'])} printed part(s), {st['incomplete_studs']} incomplete "
              f"stud(s); print {pt.get('full_model')} s whole vs {pt.get('printed_parts')} s parts, "
              f"{doc['assembly_s']} s assembly (LEGO built while it prints): "
              f"{doc['fabrication_s']} s, speed-up {doc['speedup']}")
    for part in doc["printed_parts"]:
        if not part["engaged"]["clamps"]:
            sys.stderr.write(f"warning: printed part {part['id']} does not clamp: {part['engaged']['why']}\n")
        thin = part.get("thin_features") or {}
        if thin.get("area_mm2", 0.0) >= THIN_WARNING_MM2:
            spot = thin["spots"][0]
            sys.stderr.write(f"warning: printed part {part['id']} has {thin['area_mm2']:.1f} mm² thinner than "
                             f"{thin['limit_mm']:g} mm (a nozzle cannot print it), thinnest {thin['thinnest_mm']:g} mm "
                             f"near {', '.join(f'{v:g}' for v in spot['centre_mm'])}\n")
    ch = doc.get("changes")
    if ch:
        t = ch["transform"]
        if not t.get("confident", True):
            sys.stderr.write(f"warning: {t.get('message')}\n")
        print(f"changes: {ch['cells_added']} cell(s) added, {ch['cells_removed']} removed; "
              f"{ch['bricks_kept']} brick(s) kept, {len(ch['take_off'])} to take off, "
              f"{len(ch['add'])} to add; reprint {', '.join(ch['parts_reprinted']) or 'nothing'} "
              f"(see changes.html)")
