"""``make bench``: every benchmark script, one after the other, collected into docs/benchmarks.md.

Runs each script of :data:`SCRIPTS` in a process of its own, with its output on
the terminal as it comes, and keeps what it prints on stdout: its markdown tables.  When all have ended, writes
``docs/benchmarks.md`` (or ``--out``): a header saying that ``make bench``
generated it, the date, the commit and the machine (CPU, cores, memory;
Python, FreeCAD, PrusaSlicer), then a section per script in this order,
headed by the first line of its module docstring and holding what it
printed (its headings below the section's; FreeCAD's start-up banner left out).  A
script that fails, or cannot be started, has a line saying so and why in its
section (one that skips its models prints so itself), and the scripts after it
still run.  The document is written to a temporary file beside it and renamed,
so a run that is interrupted leaves the previous document whole.  Exits 1 when
a script that is not :attr:`Script.tolerated` failed or could not be started
(``check.py``: a row over its target is its result, not a failure), 0 otherwise.
"""

from __future__ import annotations

import argparse
import ast
import collections
import datetime
import os
import platform
import re
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import NamedTuple, TextIO

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))
OUT = ROOT / "docs" / "benchmarks.md"
#: Seconds a version question (``freecadcmd``, ``prusa-slicer``) may take.
ASK_TIMEOUT_S = 60
#: Lines of a script's stderr kept to say why it failed.
STDERR_TAIL = 20


class Script(NamedTuple):
    """One benchmark run: ``path`` (from the checkout's root) with ``args``.

    ``freecad`` runs it with FreeCAD's ``freecadcmd`` instead of this Python.
    ``tolerated``, when not empty, says what a non-zero exit of the script means:
    such an exit never fails the whole run, and after tables it is their result,
    not a failure.  Empty, a non-zero exit is a failure.
    """

    path: str
    args: tuple[str, ...] = ()
    freecad: bool = False
    tolerated: str = ""


#: The benchmarks of ``make bench``, in the order they run and appear.
SCRIPTS = (
    Script("bench/check.py", ("--all",),
           tolerated="a row is over its target, or its bricks or verdicts moved from bench/reference.json"),
    Script("bench/bench.py"),
    Script("bench/bench_improve.py", ("--best", "--time-limit", "60")),
    Script("bench/bench_printed.py"),
    Script("bench/bench_printers.py",
           tolerated="a plate re-sliced by hand differs from the report's time by more than 2 %, "
                     "or a run failed (under its table)"),
    Script("bench/bench_forces.py"),
    Script("bench/bench_grid_fit.py"),
    Script("bench/bench_suggest.py", tolerated="a row is over its target"),
    Script("bench/bench_instructions.py"),
    Script("bench/bench_iterate.py"),
    Script("bench/bench_big.py"),
    Script("bench/bench_startup.py"),
    Script("bench/bench_freecad.py", freecad=True),
)


class Outcome(NamedTuple):
    """What one script's run gave: its stdout, how it ended (``kind``: ``ok``,
    ``tolerated``, ``failed`` or ``not run``) and, unless it is ``ok`` with output,
    one line why (:func:`run`)."""

    script: Script
    stdout: str
    kind: str
    why: str = ""

    @property
    def counts(self) -> bool:
        """Whether this outcome makes the whole run fail."""
        return self.kind in ("failed", "not run") and not self.script.tolerated


def title(path: Path) -> str:
    """The first line of the module docstring of ``path``, as markdown (reST roles and
    double backquotes become code spans), without its final full stop and without
    saying `make bench` (every section is from it); the file's name when it has no
    docstring."""
    try:
        doc = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8")))
    except (OSError, SyntaxError, ValueError):
        doc = None
    if not doc:
        return path.name
    line = re.sub(r":\w+:`~?([^`]+)`", r"`\1`", doc.strip().splitlines()[0]).replace("``", "`")
    line = re.sub(r"^`make bench`: |:? \(?`make bench`\)?(?=\.?$)", "", line).rstrip(".")
    return line[:1].upper() + line[1:]


def command(script: Script, root: Path, freecadcmd: str) -> list[str]:
    """The command line that runs ``script`` from ``root``: with this Python unbuffered
    (``-u``: its stdout comes through the pipe as it prints, as on a terminal), or with
    ``freecadcmd``."""
    program = [freecadcmd] if script.freecad else [sys.executable, "-u"]
    return program + [str(root / script.path), *script.args]


def _echo(source: TextIO, sink: TextIO, keep) -> None:
    """Copy ``source`` to ``sink`` line by line as it comes, giving each line to ``keep``."""
    for line in source:
        sink.write(line)
        sink.flush()
        keep(line)


def run(script: Script, root: Path, freecadcmd: str) -> Outcome:
    """Run ``script`` with its output on this process's stdout and stderr as it comes.

    A script that ends with a non-zero status has failed, its ``why`` that status (or
    signal) and its last line on stderr, unless it is :attr:`Script.tolerated` and
    printed something; one whose program cannot be started is ``not run``.  One that
    ends with status 0 but prints nothing has its last line on stderr as ``why``
    (``freecadcmd`` ends so when the script raised).
    """
    argv = command(script, root, freecadcmd)
    try:
        proc = subprocess.Popen(argv, cwd=root, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True, encoding="utf-8", errors="replace")
    except OSError as exc:
        return Outcome(script, "", "not run", f"`{argv[0]}` cannot be started: {exc.strerror or exc}")
    out: list[str] = []
    tail: collections.deque[str] = collections.deque(maxlen=STDERR_TAIL)
    errors = threading.Thread(target=_echo, args=(proc.stderr, sys.stderr, tail.append), daemon=True)
    with proc:
        try:
            errors.start()
            _echo(proc.stdout, sys.stdout, out.append)
            status = proc.wait()
        except BaseException:
            proc.kill()
            raise
        finally:
            errors.join(timeout=5)
    stdout = "".join(out)
    last = next((line.strip() for line in reversed(tail) if line.strip()), "")
    if status == 0:
        return Outcome(script, stdout, "ok", "" if stdout.strip() else last)
    ended = (f"killed by {signal.Signals(-status).name}" if -status in signal.valid_signals()
             else f"ended with status {status}")
    if script.tolerated and stdout.strip():
        return Outcome(script, stdout, "tolerated", f"{ended}: {script.tolerated}")
    return Outcome(script, stdout, "failed", ended + (f": {last}" if last else ""))


def without_banner(text: str) -> str:
    """``text`` without FreeCAD's start-up banner (its lines up to the first empty one),
    when it starts with one."""
    lines = text.splitlines(keepends=True)
    if not lines or not re.match(r"FreeCAD \S+, Libs:", lines[0]):
        return text
    end = next((i for i, line in enumerate(lines) if not line.strip()), len(lines) - 1)
    return "".join(lines[end + 1:])


def below(text: str, level: int) -> str:
    """``text`` (markdown) with its headings moved so the highest of them is at ``level``,
    the others kept beneath it as they were."""
    heading = re.compile(r"^(#{1,6}) ", re.M)
    levels = [len(found[1]) for found in heading.finditer(text)]
    if not levels:
        return text
    shift = level - min(levels)
    return heading.sub(lambda found: "#" * min(6, len(found[1]) + shift) + " ", text)


def section(outcome: Outcome, root: Path) -> str:
    """The document's section of one script: its title, its command, what it printed on
    stdout (its headings from level 3 down, :func:`below`) and, unless it ended with
    status 0, a line saying how it ended and why."""
    script = outcome.script
    printed = without_banner(outcome.stdout) if script.freecad else outcome.stdout
    printed = below(printed.strip("\n"), 3)
    parts = [f"## {title(root / script.path)}", "", f"`{' '.join([script.path, *script.args])}`", ""]
    if printed:
        parts += [printed, ""]
    if outcome.kind == "tolerated":
        parts += [f"It {outcome.why}.", ""]
    elif outcome.kind != "ok":
        parts += [f"**{outcome.kind.capitalize()}**: {outcome.why}", ""]
    elif not printed:
        parts += ["It printed nothing" + (f"; its last line on stderr: {outcome.why}" if outcome.why else "."), ""]
    return "\n".join(parts)


def _ask(argv: list[str], pattern: str) -> str | None:
    """The first group of ``pattern`` in what ``argv`` prints, or None when it cannot be
    run, takes too long or prints no match."""
    try:
        proc = subprocess.run(argv, capture_output=True, text=True, errors="replace", timeout=ASK_TIMEOUT_S,
                              stdin=subprocess.DEVNULL)
    except (OSError, subprocess.SubprocessError):
        return None
    found = re.search(pattern, proc.stdout + proc.stderr, re.M)
    return found[1] if found else None


def git_commit(root: Path) -> str:
    """The commit checked out in ``root`` (short), with "+ uncommitted changes" when
    tracked files differ from it; "unknown" outside a git checkout."""
    try:
        head = subprocess.run(["git", "rev-parse", "--short=12", "HEAD"], cwd=root, capture_output=True,
                              text=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=root,
                               capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return head + (" + uncommitted changes" if dirty else "")


def cpu_model() -> str:
    """The CPU's model name (Linux's /proc/cpuinfo), else what :mod:`platform` knows."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as info:
            for line in info:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine() or "unknown CPU"


def memory_gib() -> float | None:
    """The machine's physical memory in GiB, or None where the OS does not say."""
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2 ** 30
    except (AttributeError, ValueError, OSError):
        return None


def slicer_version() -> str:
    """The version of the PrusaSlicer the benchmarks slice with
    (:func:`core.printing.print_time.slicer_path`), or why there is none."""
    try:
        from core.printing.print_time import slicer_path
    except ImportError as exc:
        return f"unknown (core.printing.print_time: {exc})"
    slicer = slicer_path()
    if slicer is None:
        return "not found"
    return _ask([slicer, "--help"], r"PrusaSlicer-(\S+)") or f"{Path(slicer).name} (version unknown)"


def freecad_version(freecadcmd: str) -> str:
    """The version of FreeCAD that ``freecadcmd`` runs, or "not found"."""
    if shutil.which(freecadcmd) is None:
        return "not found"
    code = "import FreeCAD,sys; sys.stdout.write('FREECAD_VERSION=' + '.'.join(FreeCAD.Version()[:3]) + '\\n')"
    return _ask([freecadcmd, "-c", code], r"^FREECAD_VERSION=(\S+)") or "version unknown"


def header(root: Path, freecadcmd: str, started: datetime.datetime, seconds: float) -> str:
    """The document's header: generated by ``make bench``, when, which commit, which machine."""
    memory = memory_gib()
    machine = f"{cpu_model()}, {os.cpu_count()} cores" + (f", {memory:.1f} GiB memory" if memory else "")
    return "\n".join([
        "# Benchmarks",
        "",
        "Generated by `make bench` (bench/run_all.py): do not edit by hand, the next run rewrites it.",
        "",
        f"- date: {started.strftime('%Y-%m-%d %H:%M %Z')} (the run took "
        + (f"{seconds / 60:.0f} min)" if seconds >= 60 else f"{seconds:.0f} s)"),
        f"- commit: {git_commit(root)}",
        f"- machine: {machine}",
        f"- Python {platform.python_version()}, FreeCAD {freecad_version(freecadcmd)}, "
        f"PrusaSlicer {slicer_version()}",
        "",
    ])


def write_atomically(path: Path, text: str) -> None:
    """Make ``path`` hold ``text`` (UTF-8) whole or, when writing fails, leave it as it was
    and no temporary file behind."""
    path.parent.mkdir(parents=True, exist_ok=True)
    temporary = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        with open(temporary, "w", encoding="utf-8") as file:
            file.write(text)
            file.flush()
            os.fsync(file.fileno())
        os.replace(temporary, path)
    except BaseException:
        temporary.unlink(missing_ok=True)
        raise


def run_all(scripts=SCRIPTS, out: Path = OUT, root: Path = ROOT, freecadcmd: str = "freecadcmd") -> int:
    """Run ``scripts`` from ``root`` in order, then write their document to ``out``.

    Returns 1 when a script failed, or could not be started, that is not
    :attr:`Script.tolerated`; 0 otherwise.  ``out`` is only replaced once every script has ended.
    """
    started = datetime.datetime.now().astimezone()
    start = time.monotonic()
    outcomes = []
    for script in scripts:
        print(f"== {' '.join([script.path, *script.args])}", flush=True)
        outcomes.append(run(script, root, freecadcmd))
        if outcomes[-1].kind != "ok":
            print(f"== {script.path}: {outcomes[-1].kind}: {outcomes[-1].why}", file=sys.stderr, flush=True)
    text = header(root, freecadcmd, started, time.monotonic() - start)
    text += "".join("\n" + section(outcome, root) for outcome in outcomes)
    write_atomically(out, text)
    failed = [o.script.path for o in outcomes if o.counts]
    print(f"== wrote {out}" + (f"; failed: {', '.join(failed)}" if failed else ""), flush=True)
    return 1 if failed else 0


def main(argv: list[str] | None = None) -> int:
    """The command line: ``--out`` and ``--freecadcmd``; the exit status of :func:`run_all`."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=OUT, help=f"the document to write (default {OUT})")
    parser.add_argument("--freecadcmd", default="freecadcmd", help="FreeCAD's command line, for bench_freecad.py")
    args = parser.parse_args(argv)
    return run_all(out=args.out, freecadcmd=args.freecadcmd)


if __name__ == "__main__":
    sys.exit(main())
