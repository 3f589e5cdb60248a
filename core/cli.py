"""Command line of the headless core: ``python -m core fabricate MODEL --out DIR``.

The options are the settings of :class:`core.request.Request` (their flags,
help and defaults come from it); the command builds a Request, runs the
driver (:func:`core.pipeline.fabricate`) and prints the result.  Bad input
ends with one line on stderr naming the problem and exit status 2; any
other failure is a bug: one line saying so and naming the log file with the
traceback (:func:`core.errors.log_bug`), exit status 1; memory that runs out is one
line ``not enough memory: ...`` and exit status 2 (:func:`core.errors.memory_shortage`;
``python -m core`` checks the address-space limit before it loads anything,
:func:`core.errors.address_space_shortage`).  Ctrl-C (and a
SIGTERM or SIGHUP) stops a run in one line, exit status 128 + the signal
(130 for Ctrl-C); an unfinished output is removed, a finished one stays.  Progress goes to
stderr, a short summary to stdout.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import signal
import sys
import threading
import time
import warnings

from core import __version__, request
from core.errors import InputError, bug_line, check_path, memory_shortage
from core.parts.interfaces import Fit


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
    _stability_parser(sub)
    fit = sub.add_parser("save-fit", help="save the stud and socket fit the calibration strip "
                                          "found for a printer and filament",
                         description="Save --stud-fit and --socket-fit for the printer (and "
                                     "filament) named, in the user's fits file; fabricate and "
                                     "watch use them whenever that printer is chosen and the fit "
                                     "is not given.")
    request.add_options(fit, ("printer", "print_preset", "filament", "slicer_config"))
    fit.add_argument("--stud-fit", dest="stud_fit", type=float, required=True, metavar="MM",
                     help="the stud fit the strip found")
    fit.add_argument("--socket-fit", dest="socket_fit", type=float, required=True, metavar="MM",
                     help="the socket fit the strip found")
    sub.add_parser("printers", help="list the printers --printer can name",
                   description="List the printer presets of PrusaSlicer's installed vendor "
                               "bundles, by vendor, with each build volume (x, y, z mm).")
    _suggest_parser(sub)
    return parser


def _suggest_parser(sub) -> None:
    """The ``suggest`` command: the regions a model's features ask to be printed."""
    sug = sub.add_parser("suggest", help="list the regions that must be printed: holes, pins, "
                                         "thin walls",
                         description="Find the features of MODEL that the 8 x 8 x 3.2 mm grid "
                                     "cannot hold (holes and pins under 20 mm from a STEP or "
                                     "FCStd's round faces; round holes and walls thinner than a "
                                     "cell in a mesh) and print one line per suggested region: "
                                     "why, where, and its box as a --high-res option. "
                                     "fabricate --suggest marks the same regions.")
    sug.add_argument("model", metavar="MODEL")
    sug.add_argument("--out", metavar="FILE", default=None,
                     help="also write the regions as JSON (boxes in the frame of --high-res)")
    request.add_options(sug, ("units", "scale", "up", "suggest_tolerance", "suggest_speedup"),
                        units=request.UNITS)


def _stability_parser(sub) -> None:
    """The ``stability`` command: the force check of any layout.json."""
    sta = sub.add_parser("stability", help="check whether a layout stands, with what it carries",
                         description="The force check of LAYOUT (a layout.json of fabricate, or any "
                                     "file in its format): every brick's joints against the clutch "
                                     "of real LEGO studs and its own strength. Prints the verdict, "
                                     "the worst utilisation and the failing bricks; exits 0 whether "
                                     "it stands or not. A brick's load_g rests on it; printed parts "
                                     "weigh what parts/<id>.stl beside the layout prints as.")
    sta.add_argument("layout", metavar="LAYOUT")
    sta.add_argument("--out", metavar="REPORT", default=None,
                     help="write the verdict as JSON (the stability.force block of report.json)")
    request.add_options(sta, ("ground", "loads", "clutch_n"))
    sta.add_argument("--seconds", metavar="S", type=float, default=None,
                     help="let the force check take up to S seconds: a build of more than 2,500 "
                          "bricks that its hanging parts and height bands do not settle is then "
                          "solved as one program (minutes for 4,000 bricks)")


def _calibration_parser(sub) -> None:
    """The ``calibration-strip`` command's options; its values default around Fit's."""
    from core.parts import calibration

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


class _Stored(argparse._StoreAction):
    """argparse's plain option that also notes in ``given`` that it was given."""

    def __call__(self, parser, namespace, values, option_string=None):
        super().__call__(parser, namespace, values, option_string)
        namespace.given = set(getattr(namespace, "given", ())) | {self.dest}


def _model_options(p: argparse.ArgumentParser) -> None:
    """The options that say how to read a model and what to print (fabricate and watch);
    ``given`` names the plain ones given (the stud and socket fit, :func:`_fit_of_printer`)."""
    p.register("action", None, _Stored)
    p.set_defaults(given=set())
    request.add_options(p, ("units", "scale", "up", "seed", "parts", "effort", "lower_bound", "high_res",
                            "high_res_solids", "stud_fit", "socket_fit", "ground", "loads",
                            "clutch_n", "hollow", "inventory", "inventory_only", "colour",
                            "printer", "print_preset", "filament", "slicer_config", "slicer",
                            "suggest", "suggest_tolerance", "suggest_speedup"),
                        units=request.UNITS)


#: Signals that stop a run like Ctrl-C does (SIGINT raises KeyboardInterrupt by itself).
STOP_SIGNALS = tuple(getattr(signal, name) for name in ("SIGTERM", "SIGHUP") if hasattr(signal, name))


class Stopped(KeyboardInterrupt):
    """A stop signal (SIGTERM, SIGHUP) turned into an interruption, so that the run unwinds
    (temporary folders removed, the output left as it was) as on Ctrl-C."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


def _stop(signum, frame):
    raise Stopped(signum)


@contextlib.contextmanager
def _stop_signals():
    """SIGTERM and SIGHUP raise :class:`Stopped` in the main thread for the ``with`` block."""
    if not STOP_SIGNALS or threading.current_thread() is not threading.main_thread():
        yield
        return
    before = {s: signal.signal(s, _stop) for s in STOP_SIGNALS}
    try:
        yield
    finally:
        for s, handler in before.items():
            signal.signal(s, handler)


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit status (0 ok, 2 bad input or not enough
    memory, 1 a bug, 128 + the signal when stopped: 130 for Ctrl-C).  A standard stream
    that is closed (``2>&-``) or cannot be written changes no status: only its lines are
    lost (standard output aside, :func:`_command`)."""
    _open_standard_streams()
    for stream in (sys.stdout, sys.stderr):       # a file name that is not UTF-8 prints escaped
        with contextlib.suppress(AttributeError, ValueError):
            stream.reconfigure(errors="backslashreplace")
    given = sys.stderr
    err = sys.stderr = _Guarded(given, pipe_raises=False)
    try:
        return _command(argv)
    finally:
        if sys.stderr is err:
            sys.stderr = given


def _open_standard_streams() -> None:
    """Give each standard stream the caller closed (``<&-``, ``>&-``, ``2>&-``) the null
    device: its file descriptor, so that no file the run opens becomes descriptor 0, 1 or 2
    (a slicer's messages would land in it), and the ``sys`` stream Python left None.  What
    would have been shown is lost; the exit status still tells.  Left None (and dropped by
    :class:`_Guarded`) when even the null device cannot be opened."""
    for fd, name in ((0, "stdin"), (1, "stdout"), (2, "stderr")):
        with contextlib.suppress(OSError):
            try:
                os.fstat(fd)
            except OSError:
                null = os.open(os.devnull, os.O_RDWR)
                if null != fd:
                    os.dup2(null, fd)
                    os.close(null)
            if getattr(sys, name) is None:
                setattr(sys, name, open(fd, "r" if fd == 0 else "w", closefd=False))


def _command(argv: list[str] | None) -> int:
    """Parse ``argv`` and run its command: the exit status of :func:`main`.  Standard output
    that cannot be written (a full disk, a file opened read-only) ends the run in one line
    and status 2 once the files are written; a reader that quit (``| head``) ends it
    quietly with status 0."""
    args = _parser().parse_args(argv)
    command = {"watch": _watch, "calibration-strip": _calibration_strip,
               "stability": _stability, "printers": _printers, "save-fit": _save_fit,
               "suggest": _suggest}.get(args.command, _fabricate)
    given = sys.stdout
    out = sys.stdout = _Guarded(given, pipe_raises=True)
    try:
        with _stop_signals(), warnings.catch_warnings():
            # numbers at the edge of a float (a huge box, a load) are checked where they are
            # used; Python's own warnings are no line for the user
            warnings.simplefilter("ignore", RuntimeWarning)
            status = command(args)
        sys.stdout.flush()                          # a closed pipe shows here, not at exit
        if out.failed is not None:
            err = out.failed
            sys.stderr.write(f"error: standard output could not be written "
                             f"({getattr(err, 'strerror', None) or err}); what the run wrote "
                             f"into files is complete\n")
            return 2
        return status
    except BrokenPipeError:                         # stdout piped into a reader that quit
        with contextlib.suppress(OSError, ValueError):
            os.dup2(os.open(os.devnull, os.O_WRONLY), given.fileno())
        return 0
    except InputError as err:
        sys.stderr.write(f"error: {err}\n")
        return 2
    except KeyboardInterrupt as stop:
        with contextlib.suppress(ValueError):
            signal.signal(signal.SIGINT, signal.SIG_IGN)
        signum = getattr(stop, "signum", signal.SIGINT)
        what = "Ctrl-C" if signum == signal.SIGINT else signal.Signals(signum).name
        sys.stderr.write(f"stopped by {what}: nothing half-written was left behind\n")
        return 128 + int(signum)
    except Exception as exc:  # noqa: BLE001 - any other failure is a bug, reported as one
        shortage = memory_shortage(exc)
        if shortage is not None:
            sys.stderr.write(shortage + "\n")
            return 2
        sys.stderr.write(bug_line(exc, f"python -m core {args.command}") + "\n")
        return 1
    finally:
        if sys.stdout is out:
            sys.stdout = given


class _Guarded:
    """A standard stream during a command: a failure to write it (a full disk, a file opened
    read-only, a closed file, none at all) is kept in :attr:`failed` and the stream's file
    pointed at the null device, so that the run finishes and its status stays what the
    run decides; with ``pipe_raises`` (standard output) a reader that quit
    (BrokenPipeError) still raises."""

    def __init__(self, stream, pipe_raises: bool):
        self._stream, self._pipe_raises, self.failed = stream, pipe_raises, None

    def write(self, text: str) -> int:
        return self._guarded("write", text, default=len(text))

    def flush(self) -> None:
        self._guarded("flush")

    def _guarded(self, name: str, *args, default=None):
        if self.failed is not None:
            return default
        try:
            return getattr(self._stream, name)(*args)
        except (OSError, ValueError, AttributeError) as err:
            if self._pipe_raises and isinstance(err, BrokenPipeError):
                raise
            self.failed = err
            with contextlib.suppress(OSError, ValueError, AttributeError):
                os.dup2(os.open(os.devnull, os.O_WRONLY), self._stream.fileno())
            return default

    def __getattr__(self, name):
        return getattr(self._stream, name)


#: The path options of fabricate and watch: flag (as messages name it), argparse dest.
PATH_OPTIONS = (("MODEL", "model"), ("FOLDER", "folder"), ("--out", "out"),
                ("--previous", "previous"), ("--high-res-solid", "high_res_solids"),
                ("--inventory", "inventory"))


def _check_paths(args, out_name_checked: bool = False) -> None:
    """One line for a path option whose name the system refuses outright (too long, a loop
    of symbolic links): :func:`core.errors.check_path` of each of :data:`PATH_OPTIONS` given
    (with ``out_name_checked``, of --out's folder only: the output folder checks its name)."""
    for flag, dest in PATH_OPTIONS:
        value = getattr(args, dest, None)
        for path in value if isinstance(value, list) else [value]:
            if path and dest == "out" and out_name_checked:
                check_path(os.path.dirname(os.path.abspath(path)), flag)
            elif path:
                check_path(path, flag)


def _stability(args) -> int:
    """The ``stability`` command: read a layout, run the force stage, print and write the verdict."""
    import json
    from pathlib import Path

    from core import forces
    from core.io.layout_file import layout_from_document

    path = Path(args.layout)
    text = _read_small_file(path, "layout.json")
    try:
        data = json.loads(text)
    except RecursionError:
        raise InputError(f"{path}: not a layout.json (its values are nested too deeply)") from None
    except ValueError as exc:
        raise InputError(f"{path}: not a layout.json ({type(exc).__name__}: {exc})") from None
    try:
        layout = layout_from_document(data, path.parent / "parts")
    except InputError as err:
        raise InputError(f"{path}: {err}") from None
    del data, text
    out = _report_target(args.out, path) if args.out else None
    printed = _printed_meshes(path.parent / "parts", layout)
    unread = sorted({b.printed_part for b in layout.bricks if b.printed_part}
                    - {p.id for p in printed if len(getattr(p.mesh, "faces", ())) > 0})
    if unread:
        raise InputError(f"{path}: printed part {unread[0]}: parts/{unread[0]}.stl beside the "
                         f"layout cannot be read as a mesh (or has no triangles)")
    result = forces.analyse(layout, ground=args.ground, loads=args.loads, printed=printed,
                            clutch_n=args.clutch_n, seconds=args.seconds)
    doc = result.to_json()
    if out is not None:
        _write_report(out, json.dumps(doc, indent=2))
    if result.unchecked:
        print(f"force check skipped: {result.unchecked}")
        return 0
    worst = forces.worst_words(doc, 3)
    print(f"{'stands' if result.stable else 'does not stand'} on a {result.ground}: "
          f"worst utilisation {worst}, {len(layout.bricks)} bricks, {result.mass_g:.1f} g"
          + (f", resting leaning {result.tilt_deg:.1f}° on its lower points"
             if result.tilt_deg >= 1 else ""))
    for topple in result.topples:
        print(f"  {topple['why']}")
    for failure in result.failures[:20]:
        print(f"  brick {failure['brick']}: {failure['why']}")
    if len(result.failures) > 20:
        print(f"  ... and {len(result.failures) - 20} more failing bricks")
    return 0


#: Largest layout.json (and earlier stability report) the ``stability`` command reads: a
#: layout of a metre-sized part is a few tens of MB; anything larger is not a layout.
_MAX_LAYOUT_BYTES = 100 * 1024 * 1024

#: Keys by which an earlier ``stability --out`` report is known (forces.Forces.to_json).
_REPORT_KEYS = frozenset({"stable", "ground", "checked", "max_utilisation", "failures",
                          "utilisation", "mass_g"})


def _read_small_file(path, what: str) -> str:
    """The UTF-8 text of the regular file ``path``; InputError for a missing file, a folder,
    a named pipe, socket or device (refused before it is opened, as
    :func:`core.io.meshes._check_file` does: reading a pipe waits for ever, a device may never
    end), an unreadable file or one larger than :data:`_MAX_LAYOUT_BYTES`."""
    import stat
    from pathlib import Path

    from core.io.meshes import _special_kind, regular_file

    regular_file(Path(path), what, f"a {what}")
    limit = f"larger than {_MAX_LAYOUT_BYTES // 2**20} MB, the most read as a {what}"
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
        with os.fdopen(fd, "rb") as stream:
            opened = os.fstat(stream.fileno())
            if not stat.S_ISREG(opened.st_mode):
                raise InputError(f"{path}: is {_special_kind(opened.st_mode)}, not a regular file")
            if opened.st_size > _MAX_LAYOUT_BYTES:
                raise InputError(f"{path}: is {opened.st_size / 2**20:.0f} MB, {limit}")
            data = stream.read(_MAX_LAYOUT_BYTES + 1)
    except OSError as exc:
        raise InputError(f"{path}: cannot read it ({exc.strerror or exc})") from None
    if len(data) > _MAX_LAYOUT_BYTES:
        raise InputError(f"{path}: is {limit}")
    try:
        return data.decode("utf-8")
    except UnicodeError as exc:
        raise InputError(f"{path}: cannot read it (not UTF-8 text: {exc.reason} at byte "
                         f"{exc.start})") from None


def _is_stability_report(path) -> bool:
    """Whether the file ``path`` is a report an earlier ``stability --out`` wrote."""
    import json

    try:
        doc = json.loads(_read_small_file(path, "report"))
    except (InputError, ValueError, RecursionError):
        return False
    return isinstance(doc, dict) and _REPORT_KEYS <= doc.keys()


def _report_target(out_arg, layout_path):
    """The file ``--out`` names, checked before any work: InputError when it is the layout
    itself, a folder, a device or other special file, a broken symbolic link, lies in no
    folder, or is an existing file other than an earlier stability report (which may be
    replaced).  A symbolic link to an earlier report stands for its target."""
    import stat
    from pathlib import Path

    from core.io.meshes import _special_kind

    out = Path(out_arg)
    try:
        st = os.stat(out)
    except FileNotFoundError:
        if os.path.lexists(out):
            raise InputError(f"--out {out}: is a broken symbolic link; remove it or choose "
                             f"another name") from None
        if not out.parent.is_dir():
            raise InputError(f"--out {out}: no such folder {out.parent}") from None
        return out
    except OSError as exc:
        raise InputError(f"--out {out}: cannot write it ({exc.strerror or exc})") from None
    source = os.stat(layout_path)
    if (st.st_dev, st.st_ino) == (source.st_dev, source.st_ino):
        raise InputError(f"--out {out}: is the layout being checked; the report would replace "
                         f"it: choose another file")
    if stat.S_ISDIR(st.st_mode):
        raise InputError(f"--out {out}: is a directory; name the report file")
    if not stat.S_ISREG(st.st_mode):
        raise InputError(f"--out {out}: is {_special_kind(st.st_mode)}, not a regular file: "
                         f"the report is only written to a file")
    if not _is_stability_report(out):
        raise InputError(f"--out {out}: exists and is not a stability report written by this "
                         f"command; not overwriting it: remove it or choose another name")
    return Path(os.path.realpath(out))


def _write_report(out, text: str) -> None:
    """Write ``text`` to ``out`` atomically: a new temporary file in the same folder, then
    renamed over ``out``; on any failure the temporary file is removed (InputError for an
    OSError: a full disk, a read-only folder)."""
    import tempfile

    try:
        fd, tmp = tempfile.mkstemp(dir=os.fspath(out.parent), prefix=f".{out.name}.",
                                   suffix=".tmp")
    except OSError as exc:
        raise InputError(f"--out {out}: cannot write it ({exc.strerror or exc})") from None
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as stream:
            stream.write(text)
            stream.flush()
            os.fsync(stream.fileno())
        umask = os.umask(0o022)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, out)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        if isinstance(exc, OSError):
            raise InputError(f"--out {out}: cannot write it ({exc.strerror or exc})") from None
        raise


def _printed_meshes(folder, layout) -> list:
    """The printed parts of ``layout`` whose STL lies in ``folder`` (id and mesh: what the force
    stage weighs); none when the folder or a file is missing or unreadable."""
    from types import SimpleNamespace

    import trimesh

    names = sorted({b.printed_part for b in layout.bricks if b.printed_part})
    out = []
    for name in names:
        stl = folder / f"{name}.stl"
        if stl.is_file():
            try:
                out.append(SimpleNamespace(id=name, mesh=trimesh.load(stl, force="mesh")))
            except (OSError, ValueError):
                continue
    return out


def _fabricate(args) -> int:
    """The ``fabricate`` command: one Request, the driver, the summary."""
    from core import pipeline

    _check_paths(args, out_name_checked=True)
    _fit_of_printer(args)
    progress = None if args.quiet else _progress_printer(sys.stderr)
    doc = pipeline.fabricate(request.from_options(args, args.model), args.out, progress=progress)
    _summary(doc, args.out)
    return 0


def _watch(args) -> int:
    """The ``watch`` command: each new file fabricated with the same settings as
    ``fabricate``, as an iteration on the last output of a version of the same model
    (:class:`core.watch.Versions`, the one version rule the workbench uses too)."""
    from core import pipeline, result, watch
    from core.io import output_dir

    _check_paths(args)
    progress = None if args.quiet else _progress_printer(sys.stderr)
    _fit_of_printer(args)
    job = request.from_options(args, "watched")
    timeout = request.timeout_seconds(args.timeout)
    if job.previous is not None:
        result.snapshot_state(job.previous)         # a bad --previous now, not at the first file

    def skipped(path, why):
        sys.stderr.write(f"skipped: {_naming(path, why)}\n")

    files = watch.watch(args.folder, include_existing=args.existing, timeout_s=timeout,
                        on_skip=skipped)
    root, runs, built = output_dir.check_root(args.out, watched=args.folder), 0, 0
    versions = watch.Versions(first=job.previous)
    try:
        sys.stderr.write(f"watching {args.folder} (Ctrl-C to stop)\n")
        for path in files:
            runs += 1
            out = root / f"{path.stem}-{runs}"
            previous = versions.previous(path)
            try:
                doc = pipeline.fabricate(job.replace(model=str(path), previous=previous and str(previous)),
                                         out, progress=progress)
            except InputError as err:
                sys.stderr.write(f"error: {_naming(path, str(err))}\n")
                continue
            built += 1
            _summary(doc, out)
            versions.record(path, out)
    except KeyboardInterrupt:
        sys.stderr.write(f"stopped after {built} version(s) built\n")
    return 0


def _naming(path, line: str) -> str:
    """``line`` (a message about the watched file ``path``) as it names the file: itself
    when it starts with the file's name or path, as ``fabricate``'s messages do, else
    after the file's name."""
    named = line.startswith((path.name + ":", os.fspath(path) + ":"))
    return line if named else f"{path.name}: {line}"


def _fit_of_printer(args) -> None:
    """Set the stud and socket fit ``args`` do not give (``args.given``) to the fit saved for
    the chosen printer and filament (:func:`core.parts.calibration.saved_fit`) when there is one,
    and ``args.fit_source`` to where they came from."""
    from core.parts import calibration
    from core.printing import printers

    names = ("stud_fit", "socket_fit")
    given = [n for n in names if n in args.given]
    chosen = printers.chosen(args)              # a bad printer or config: one line, now
    path = calibration.fits_file()
    saved = (None if chosen is None or len(given) == len(names)
             else calibration.saved_fit(chosen.printer, chosen.filament, path))
    source = (f"saved for {chosen.printer} / {chosen.filament} in {path}" if saved is not None
              else "default")
    for name in names:
        if saved is not None and name not in given:
            setattr(args, name, getattr(saved, name))
    args.fit_source = ("given" if len(given) == len(names) else source if not given
                       else f"{', '.join(given)} given, the rest {source}")


def _save_fit(args) -> int:
    """The ``save-fit`` command: the fit saved for the printer and filament, in one line."""
    from core.parts import calibration
    from core.printing import printers

    chosen = printers.chosen(args)
    if chosen is None:
        raise InputError("save-fit needs the printer: give --printer NAME or --slicer-config FILE.ini")
    fit = Fit(stud_fit=args.stud_fit, socket_fit=args.socket_fit).check()
    path = calibration.save_fit(chosen.printer, chosen.filament, fit)
    print(f"saved stud fit {fit.stud_fit:+g} mm, socket fit {fit.socket_fit:+g} mm for "
          f"{chosen.printer} / {chosen.filament} in {path}")
    return 0


def _printers(args) -> int:
    """The ``printers`` command: the printer names by vendor with their build volume."""
    from core.printing import printers

    lines = printers.listing_lines(printers.bundle_folder())
    if not lines:
        raise InputError("no PrusaSlicer vendor bundles found: install PrusaSlicer, or give "
                         "fabricate --slicer-config FILE.ini")
    print("\n".join(lines))
    return 0


def _suggest(args) -> int:
    """The ``suggest`` command: one line per suggested region on stdout, warnings on
    stderr, and with --out the regions as JSON."""
    import json
    from pathlib import Path

    from core import suggest
    from core.io import meshes as mesh_io

    _check_paths(args)
    job = request.from_options(args, args.model)
    out = None if not args.out else _regions_target(Path(args.out))
    model = mesh_io.load_model(job.model, units=job.units, scale=job.scale, up=job.up)
    for warning in model.warnings:
        sys.stderr.write(f"warning: {warning}\n")
    found = suggest.suggest(model, job.suggest_tolerance, min_speedup=job.suggest_speedup)
    for region in found.regions:
        print(region.line(model.offset_mm))
    print(f"{len(found.regions)} region(s) suggested from the {found.source}, marking cells "
          f"that hold {found.share:.0%} of the part ({found.cells_share:.0%} of its cells)")
    for warning in found.warnings:
        sys.stderr.write(f"warning: {warning}\n")
    if out is not None:
        _write_report(out, json.dumps(found.to_json(model.offset_mm), indent=1,
                                       ensure_ascii=False) + "\n")
    return 0


def _regions_target(out):
    """The file ``suggest --out`` names, checked before any work: InputError unless it is a
    new file in an existing folder or an earlier regions file of this command."""
    import json

    if out.is_dir() or not out.parent.is_dir():
        raise InputError(f"--out {out}: name a file in an existing folder")
    if os.path.lexists(out):
        try:
            ours = set(json.loads(_read_small_file(out, "--out"))) >= {"source", "regions", "dropped"}
        except (InputError, ValueError, TypeError):
            ours = False
        if not ours:
            raise InputError(f"--out {out}: exists and is not a regions file written by this "
                             f"command; not overwriting it: remove it or choose another name")
    return out


def _calibration_strip(args) -> int:
    """The ``calibration-strip`` command: one line per file written, or one error line
    and exit status 2."""
    from core.parts import calibration

    values = calibration.column_values(args.start, args.stop, args.step)
    _, written = calibration.write_strip(args.out, values)
    for path in written:
        print(path)
    return 0


def _summary(doc: dict, out) -> None:
    """The short summary of one fabricate run: lines on stdout, warnings and notes on stderr."""
    from core import report

    lines, notes = report.summary(doc, out)
    for note in notes:
        sys.stderr.write(note + "\n")
    for line in lines:
        print(line)
