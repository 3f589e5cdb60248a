"""Make Fabrickator's Python packages importable inside FreeCAD, install them, or say why not.

The core needs numpy 2, cadquery, scipy, matplotlib ... (``requirements.txt``)
in the module folder's ``.venv``, built from FreeCAD's own interpreter,
while Debian's FreeCAD brings numpy 1.x.  :func:`bootstrap`, called by
``Init.py`` before any module imports numpy, puts the venv's
``site-packages`` first on ``sys.path``, so that FreeCAD, its Plot and FEM
modules and Fabrickator all use one consistent set (numpy 2 and the
matplotlib and scipy built for it).  It imports nothing but the standard
library and never raises: a problem becomes one line in the Report view
that names the fix.

A user who installed the add-on with FreeCAD's Addon Manager (a clone of
the repository in FreeCAD's user ``Mod`` folder) has no venv yet: the
workbench offers to build it on activation (:mod:`.install`, the GUI),
which runs :func:`install_commands` -- ``python -m venv`` with the real
interpreter behind FreeCAD (:func:`base_interpreter`; inside FreeCAD
``sys.executable`` is the FreeCAD binary), then that venv's pip on
``requirements.txt``.  :func:`install` does the same from a script or
``freecadcmd``; :class:`PipProgress` reads pip's output lines as progress
and :func:`failure_message` turns a failure into one message with the
command to run by hand.  :func:`activate` then puts the new packages to
use in the running FreeCAD, or says that FreeCAD must restart.
Developers run ``make setup`` (the same venv, from the Makefile).

Inside FreeCAD every Mod folder is on ``sys.path``, so ``core`` is a global
name; :func:`load_core` makes sure it is this repository's ``core`` and says
so clearly when another add-on's ``core`` got there first.
"""

from __future__ import annotations

import importlib
import importlib.util
import os
import re
import shlex
import shutil
import subprocess
import sys
from dataclasses import dataclass

from . import llvm

#: The module folder (the repository root): parent of this package.
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

#: Environment variable naming another virtual environment to use (tests, packagers).
VENV_ENV = "FABRICKATOR_VENV"

#: The pinned packages the venv is built with.
REQUIREMENTS = os.path.join(ROOT, "requirements.txt")

#: File the install (and ``make setup``) writes into the venv once it is complete.
STAMP = ".installed"

#: Packages the workbench needs at run time, by import name.
REQUIRED = ("numpy", "scipy", "trimesh", "networkx", "cadquery", "OCP", "manifold3d",
            "matplotlib", "numba", "highspy")

#: Environment variables not passed to the install's processes: FreeCAD's own
#: module path would make pip count FreeCAD's packages as installed in the venv.
UNSET_FOR_INSTALL = ("PYTHONPATH", "PYTHONSTARTUP", "PYTHONNOUSERSITE", "PIP_USER", "PIP_TARGET",
                     "PIP_PREFIX")


def venv_dir() -> str:
    """The virtual environment Fabrickator uses: ``$FABRICKATOR_VENV`` or ROOT/.venv."""
    return os.environ.get(VENV_ENV) or os.path.join(ROOT, ".venv")


def venv_python(venv: str | None = None) -> str:
    """The interpreter of the venv (``bin/python``, on Windows ``Scripts/python.exe``)."""
    venv = venv or venv_dir()
    if os.name == "nt":
        return os.path.join(venv, "Scripts", "python.exe")
    return os.path.join(venv, "bin", "python")


def site_packages() -> str:
    """The venv's site-packages folder for this interpreter's Python version."""
    if os.name == "nt":
        return os.path.join(venv_dir(), "Lib", "site-packages")
    version = f"python{sys.version_info[0]}.{sys.version_info[1]}"
    return os.path.join(venv_dir(), "lib", version, "site-packages")


def _interpreter_candidates() -> list[str]:
    """Where the Python behind this process may be, most likely first: this process
    itself when it is a plain ``python``, then ``bin/`` of its prefixes, the folder of
    the FreeCAD binary, then PATH."""
    major, minor = sys.version_info[:2]
    names = ([f"python{major}.{minor}.exe", "python.exe", "python3.exe"] if os.name == "nt"
             else [f"python{major}.{minor}", f"python{major}", "python"])
    paths = [sys.executable] if os.path.basename(sys.executable).lower().startswith("python") else []
    folders = [os.path.join(sys.base_prefix, "bin"), os.path.join(sys.exec_prefix, "bin"),
               sys.base_prefix, sys.exec_prefix,
               os.path.dirname(os.path.realpath(sys.executable)), os.path.dirname(sys.executable)]
    paths += [os.path.join(folder, name) for folder in folders for name in names]
    paths += [shutil.which(name) or "" for name in names]
    unique = []
    for path in paths:
        if path and path not in unique and os.path.isfile(path) and os.access(path, os.X_OK):
            unique.append(path)
    return unique


def base_interpreter() -> str | None:
    """The Python interpreter to build the venv with: the one FreeCAD itself runs, or None.

    Inside FreeCAD ``sys.executable`` is the FreeCAD binary, so the
    interpreter is looked for where it lies (Debian: ``/usr/bin/python3.11``
    under ``sys.base_prefix``; FreeCAD's AppImage and Windows builds: beside
    the FreeCAD binary; then PATH) and each candidate is asked its version:
    the first that reports exactly this ``sys.version`` wins, else the first
    of the same major.minor (same ABI, so the venv's compiled packages load
    here).
    """
    same_minor = None
    wanted = f"{sys.version_info[0]}.{sys.version_info[1]}"
    for path in _interpreter_candidates():
        try:
            run = subprocess.run([path, "-c", "import sys; print(sys.version.splitlines()[0])"],
                                 capture_output=True, text=True, timeout=30, env=install_env(),
                                 stdin=subprocess.DEVNULL)
        except (OSError, subprocess.SubprocessError):
            continue
        version = run.stdout.strip()
        if run.returncode != 0:
            continue
        if version == sys.version.splitlines()[0]:
            return path
        if same_minor is None and version.split(" ")[0].rsplit(".", 1)[0] == wanted:
            same_minor = path
    return same_minor


def install_env(environ=None) -> dict[str, str]:
    """The environment the install's processes run in: ``environ`` (default this
    process's) without UNSET_FOR_INSTALL."""
    env = dict(os.environ if environ is None else environ)
    for name in UNSET_FOR_INSTALL:
        env.pop(name, None)
    return env


def install_commands(python: str, venv: str | None = None) -> list[list[str]]:
    """The commands that build the venv: ``python -m venv --clear VENV`` (a half-built
    one is started afresh), then the venv's pip installing REQUIREMENTS."""
    venv = venv or venv_dir()
    return [[python, "-m", "venv", "--clear", venv],
            [venv_python(venv), "-m", "pip", "install", "--disable-pip-version-check",
             "--progress-bar", "off", "-r", REQUIREMENTS]]


def _quote(argv: list[str]) -> str:
    if os.name == "nt":
        return subprocess.list2cmdline(argv)
    return " ".join(shlex.quote(a) for a in argv)


def fix_command(python: str | None = None) -> str:
    """The shell command that builds the venv Fabrickator needs, for a terminal.

    With the real interpreter (``python``, default :func:`base_interpreter`;
    ``python3`` when none is found), in this platform's shell quoting.
    """
    python = python or base_interpreter() or ("python" if os.name == "nt" else "python3")
    return " && ".join(_quote(argv) for argv in install_commands(python))


def numpy_importers(limit: int = 3) -> list[str]:
    """Names of up to ``limit`` loaded modules (not numpy's own) that hold numpy, sorted:
    who loaded it, as far as can be told in a running process."""
    numpy = sys.modules.get("numpy")
    if numpy is None:
        return []
    holders = []
    for name, module in list(sys.modules.items()):
        if name.split(".")[0] == "numpy" or module is None:
            continue
        try:
            found = any(value is numpy for value in vars(module).values())
        except TypeError:
            continue
        if found:
            holders.append(name)
    return sorted(holders)[:limit]


def numpy_clash() -> str | None:
    """A phrase naming the numpy loaded in this process from outside the venv (its version,
    folder and the modules that hold it), or None when none is or it is the venv's."""
    numpy = sys.modules.get("numpy")
    if numpy is None:
        return None
    where = os.path.abspath(getattr(numpy, "__file__", "") or "")
    if where.startswith(os.path.abspath(site_packages()) + os.sep):
        return None
    holders = numpy_importers()
    by = f", used by {', '.join(holders)}" if holders else ""
    return (f"numpy {getattr(numpy, '__version__', '?')} from {os.path.dirname(os.path.dirname(where))} "
            f"was loaded in this FreeCAD before Fabrickator could put its own first{by}")


def problem() -> str | None:
    """Why the venv cannot be put first on ``sys.path`` in this process (a phrase), or None.

    The venv must exist for this Python version, and numpy, if already
    imported, must be the venv's: another numpy (FreeCAD's own 1.x, which
    FreeCAD's PartDesign workbench loads when it is activated, as FreeCAD
    1.0's start workbench is) cannot be replaced in a running process
    (:func:`numpy_clash`).  That phrase says to restart FreeCAD: at the next
    start ``Init.py`` puts the venv first before any workbench is loaded.
    """
    packages = site_packages()
    if not os.path.isdir(packages):
        return f"{packages} is missing"
    clash = numpy_clash()
    if clash:
        return (f"{clash}: restart FreeCAD (if this comes back after a restart, a module that starts "
                f"before Fabrickator loads numpy)")
    return None


def bootstrap() -> str | None:
    """Put the venv's site-packages first on ``sys.path``; the problem line, or None when fine.

    Idempotent.  Also points the ``mpl_toolkits`` namespace (which Debian's
    matplotlib pre-imports from a .pth file) at the venv's copy first, so
    3-D plotting matches the venv's matplotlib.  When the venv cannot be
    used and the required packages are not importable otherwise either,
    writes the problem to the Report view / console as a warning.
    """
    trouble = problem()
    if trouble is None:
        packages = site_packages()
        if packages not in sys.path:
            sys.path.insert(0, packages)
        toolkits = sys.modules.get("mpl_toolkits")
        local = os.path.join(packages, "mpl_toolkits")
        path = getattr(toolkits, "__path__", None)
        if path is not None and os.path.isdir(local) and local not in list(path):
            if isinstance(path, list):
                path.insert(0, local)
            else:
                toolkits.__path__ = [local] + list(path)
    elif missing():
        report(f"Fabrickator: its Python packages are not installed ({trouble}). The Fabrickator "
               f"workbench offers to install them; from Python: "
               f"from FabrickatorWorkbench import deps; deps.install(); in a terminal: {fix_command()}",
               warning=True)
    return trouble


def load_core():
    """This repository's ``core`` package, imported as ``core``; raises ImportError if impossible.

    When ``core`` is not imported yet, it is loaded from ROOT/core even if
    another folder on ``sys.path`` has a ``core`` first (that other package
    is then shadowed in this FreeCAD session, and a warning says so).  When
    another ``core`` is already imported, raises ImportError naming both.
    """
    ours = os.path.join(ROOT, "core", "__init__.py")
    loaded = sys.modules.get("core")
    if loaded is not None:
        if os.path.abspath(getattr(loaded, "__file__", "") or "") == ours:
            return loaded
        raise ImportError(f"Fabrickator: another add-on's 'core' package "
                          f"({getattr(loaded, '__file__', '?')}) is already loaded, so "
                          f"Fabrickator's {os.path.dirname(ours)} cannot be; "
                          f"disable that add-on or restart FreeCAD")
    found = importlib.util.find_spec("core")
    if found is not None and found.origin and os.path.abspath(found.origin) != ours:
        report(f"Fabrickator: another 'core' package ({found.origin}) comes first on sys.path; "
                f"loading Fabrickator's {os.path.dirname(ours)} instead, so that add-on's "
                f"'core' is shadowed in this session\n", warning=True)
    spec = importlib.util.spec_from_file_location("core", ours,
                                                  submodule_search_locations=[os.path.dirname(ours)])
    module = importlib.util.module_from_spec(spec)
    sys.modules["core"] = module
    try:
        spec.loader.exec_module(module)
    except BaseException:
        del sys.modules["core"]
        raise
    return module


def missing(names=None) -> list[str]:
    """The packages ``names`` (default REQUIRED) that cannot be found (without importing them)."""
    return [n for n in (REQUIRED if names is None else names) if importlib.util.find_spec(n) is None]


def installed_not_in_use() -> bool:
    """True when the venv is built (its STAMP is there) but not on ``sys.path`` in this
    process: installed in this session after numpy was loaded, so FreeCAD must restart."""
    packages = site_packages()
    return (os.path.isdir(packages) and os.path.exists(os.path.join(venv_dir(), STAMP))
            and packages not in sys.path)


def check(command: str) -> bool:
    """True when ``command`` can run; else writes one Report-view line naming the fix.

    Checks that the required packages can be imported (from the venv, or
    installed otherwise) and that ``core`` is this repository's.  When the
    venv is installed but cannot be used before a restart, the line says to
    restart FreeCAD (not to install again).
    """
    trouble = bootstrap()
    gone = missing()
    if gone and installed_not_in_use():
        trouble = (f"Fabrickator: {command} needs the Python packages installed in {venv_dir()}, which "
                   f"this FreeCAD cannot use yet ({trouble or 'not on sys.path'})")
    elif gone:
        trouble = (f"Fabrickator: {command} needs the Python package(s) {', '.join(gone)}, "
                   f"which cannot be imported ({trouble or 'not installed'}); install them from "
                   f"the Fabrickator menu (Install Python packages...) or run: {fix_command()}")
    else:
        trouble = None
        try:
            load_core()
        except ImportError as exc:
            trouble = str(exc)
    if trouble:
        report(f"{trouble} ({command} did nothing)")
        return False
    return True


def report(line: str, warning: bool = False) -> None:
    """Write one line to FreeCAD's Report view (or stderr outside FreeCAD)."""
    text = line.rstrip("\n") + "\n"
    try:
        import FreeCAD
    except ImportError:
        sys.stderr.write(text)
        return
    (FreeCAD.Console.PrintWarning if warning else FreeCAD.Console.PrintError)(text)


def needs_install() -> str | None:
    """Why the venv must be (re)built before the workbench can run, or None.

    A reason when required packages cannot be found (no venv, a half-built
    one without STAMP, or a venv for another Python version), or when
    ``requirements.txt`` is newer than the venv's STAMP (the add-on was
    updated).  None also when the packages are importable without a venv
    (installed by a packager), and when the venv is built but this FreeCAD
    cannot use it before a restart (:func:`installed_not_in_use`).
    """
    stamp = os.path.join(venv_dir(), STAMP)
    if os.path.isdir(site_packages()) and os.path.exists(stamp) and \
            os.path.getmtime(REQUIREMENTS) > os.path.getmtime(stamp):
        return f"{REQUIREMENTS} changed since {venv_dir()} was built"
    gone = missing()
    if gone and not installed_not_in_use():
        where = site_packages()
        state = "is missing" if not os.path.isdir(where) else "lacks them"
        return f"{', '.join(gone)} cannot be imported: {where} {state}"
    return None


class PipProgress:
    """Progress of an install, read from the output lines of :func:`install_commands`.

    :meth:`feed` takes one line and returns the fraction done (0..1) or
    None while pip installs the downloaded packages (it says nothing until
    it is done, so no fraction can be told: show a busy indicator), and
    keeps the line as ``text`` when it is worth showing.  Building the venv
    counts as VENV_SHARE of the work, pip's "Collecting" lines (one per
    pinned requirement) as the rest up to INSTALL_FROM.
    """

    VENV_SHARE = 0.05
    INSTALL_FROM = 0.6

    def __init__(self, requirements: str = REQUIREMENTS):
        with open(requirements, encoding="utf-8") as lines:
            self.total = max(1, sum(1 for line in lines if line.strip() and not line.lstrip().startswith("#")))
        self.collected = 0
        self.installing = False
        self.fraction = 0.0
        self.text = "Building the virtual environment"

    def started_pip(self) -> float:
        """The step that builds the venv is done; pip starts."""
        self.fraction = self.VENV_SHARE
        self.text = "Starting pip"
        return self.fraction

    def feed(self, line: str) -> float | None:
        line = line.strip()
        if not line:
            return None if self.installing else self.fraction
        if line.startswith("Collecting "):
            self.collected += 1
            share = min(1.0, self.collected / self.total)
            self.fraction = self.VENV_SHARE + (self.INSTALL_FROM - self.VENV_SHARE) * share
            self.text = line
        elif line.startswith(("Downloading ", "Using cached ", "Processing ", "Requirement already")):
            self.text = line
        elif line.startswith("Installing collected packages"):
            self.installing = True
            self.text = f"Installing {self.collected} packages (this takes a while)"
        elif line.startswith("Successfully installed"):
            self.installing = False
            self.fraction = 1.0
            self.text = "Installed"
        return None if self.installing else self.fraction


#: pip's words for a package index it could not reach or that has no such release.
_NETWORK = re.compile(r"NewConnectionError|Failed to establish a new connection|Name or service not known|"
                      r"Temporary failure in name resolution|No matching distribution found|"
                      r"Could not find a version that satisfies|ConnectTimeout|ReadTimeout|"
                      r"ConnectionError|ProxyError|SSLError|Network is unreachable|"
                      r"connection broken", re.I)


def failure_message(lines: list[str], status: int | None, step: int) -> str:
    """One message for an install that failed: what went wrong and the command to run by hand.

    ``lines`` is the failing command's output, ``status`` its exit status
    (None: it could not start), ``step`` 0 for building the venv, 1 for pip.
    A package index that cannot be reached (no network, a proxy, an index
    without the pinned releases) is said so, with pip's own error line.
    """
    errors = [line.strip() for line in lines if line.strip().startswith("ERROR:")]
    said = (errors[-1] if errors else next((line.strip() for line in reversed(lines) if line.strip()), ""))
    said = said.removeprefix("ERROR:").strip()
    by_hand = f"When that is fixed, activate the Fabrickator workbench again, or run in a terminal: {fix_command()}"
    if step == 0:
        if any("ensurepip" in line for line in lines):
            return ("Fabrickator could not build its virtual environment: this Python has no "
                    "ensurepip (on Debian and Ubuntu install the package python3-venv, e.g. "
                    f"sudo apt install python3-venv). {by_hand}")
        return (f"Fabrickator could not build its virtual environment in {venv_dir()}: "
                f"{said or f'exit status {status}'}. {by_hand}")
    if any(_NETWORK.search(line) for line in lines):
        return ("Fabrickator could not download its Python packages: no network, or the package "
                f"index cannot be reached (pip: {said}). {by_hand}")
    return f"Fabrickator could not install its Python packages (pip: {said or f'exit status {status}'}). {by_hand}"


def no_interpreter_message() -> str:
    """What to do when :func:`base_interpreter` finds no interpreter."""
    return (f"Fabrickator found no Python {sys.version_info[0]}.{sys.version_info[1]} interpreter to build "
            f"its packages with (FreeCAD runs {sys.executable}). Install one, then run in a terminal: "
            f"{fix_command('python3')}")


@dataclass
class InstallResult:
    """How an install ended: ``ok``, and ``message`` (the failure's, or what to do next)."""

    ok: bool
    message: str


def write_stamp() -> None:
    """Mark the venv complete (STAMP, as ``make setup`` does)."""
    with open(os.path.join(venv_dir(), STAMP), "w", encoding="utf-8") as stamp:
        stamp.write(f"built from {REQUIREMENTS} for Python {sys.version.split()[0]}\n")


def install(progress=None, python: str | None = None) -> InstallResult:
    """Build the venv from REQUIREMENTS with FreeCAD's own interpreter, from a script or freecadcmd.

    Runs :func:`install_commands` one after the other (``python``: the
    interpreter, default :func:`base_interpreter`), calling
    ``progress(fraction or None, line)`` for every output line
    (:class:`PipProgress`).  On success writes the STAMP and calls
    :func:`activate`; the result says whether the packages work now or
    FreeCAD must restart.  On failure the result's message is
    :func:`failure_message`'s.  Never raises for a failed install.
    """
    python = python or base_interpreter()
    if python is None:
        return InstallResult(False, no_interpreter_message())
    meter, before = PipProgress(), loaded_packages()
    for step, argv in enumerate(install_commands(python)):
        if step == 1 and progress is not None:
            progress(meter.started_pip(), meter.text)
        lines: list[str] = []
        try:
            with subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                  env=install_env(), stdin=subprocess.DEVNULL, bufsize=1) as run:
                for line in run.stdout:
                    lines.append(line.rstrip("\n"))
                    fraction = meter.feed(line)
                    if progress is not None:
                        progress(fraction, line.rstrip("\n"))
            status = run.returncode
        except OSError as exc:
            lines.append(f"ERROR: cannot run {argv[0]}: {exc.strerror or exc}")
            status = None
        if status != 0:
            return InstallResult(False, failure_message(lines, status, step))
    write_stamp()
    trouble = activate(before)
    if trouble:
        return InstallResult(True, f"Fabrickator's Python packages are installed; {trouble}")
    return InstallResult(True, "Fabrickator's Python packages are installed and in use")


def loaded_packages() -> list[str]:
    """The required packages already imported in this process (REQUIRED names)."""
    return [name for name in REQUIRED if name in sys.modules]


def activate(loaded_before=()) -> str | None:
    """Put a newly built venv to use in this process; None when it is in use, else what to do.

    Runs :func:`bootstrap` (after clearing the import system's caches, so
    the new folders are seen), :func:`.llvm.isolate` (as ``Init.py`` does
    at start-up: without it the first numba kernel compiled in FreeCAD 1.0's
    GUI crashes it) and :func:`load_core`.  When numpy was
    imported from elsewhere before (its old version stays loaded: FreeCAD
    1.0's start workbench PartDesign loads FreeCAD's own), or
    ``loaded_before`` names packages imported before the venv was rebuilt,
    returns "restart FreeCAD to use them" with the reason (:func:`numpy_clash`).
    """
    importlib.invalidate_caches()
    trouble = numpy_clash() or problem()
    if trouble is None and loaded_before:
        trouble = f"{', '.join(loaded_before)} were already loaded"
    if trouble is None:
        bootstrap()
        # what Init.py does at start-up once the venv is there (before any kernel is compiled)
        llvm.isolate()
    gone = missing()
    if trouble or gone:
        return f"restart FreeCAD to use them ({trouble or ', '.join(gone) + ' still cannot be imported'})"
    try:
        load_core()
    except ImportError as exc:
        return f"restart FreeCAD to use them ({exc})"
    return None
