"""Make Fabrickator's Python packages importable inside FreeCAD, or say why not.

The core needs numpy 2, cadquery, scipy, matplotlib ... from the module
folder's ``.venv`` (built from FreeCAD's own interpreter by ``make
setup``), while Debian's FreeCAD brings numpy 1.x.  :func:`bootstrap`,
called by ``Init.py`` before any module imports numpy, puts the venv's
``site-packages`` first on ``sys.path``, so that FreeCAD, its Plot and FEM
modules and Fabrickator all use one consistent set (numpy 2 and the
matplotlib and scipy built for it).  It imports nothing but the standard
library and never raises: a problem becomes one line in the Report view
that names the command fixing it.

Inside FreeCAD every Mod folder is on ``sys.path``, so ``core`` is a global
name; :func:`load_core` makes sure it is this repository's ``core`` and says
so clearly when another add-on's ``core`` got there first.
"""

from __future__ import annotations

import importlib.util
import os
import sys

#: The module folder (the repository root): parent of this package.
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

#: Environment variable naming another virtual environment to use (tests, packagers).
VENV_ENV = "FABRICKATOR_VENV"

#: Packages the workbench needs at run time, by import name.
REQUIRED = ("numpy", "scipy", "trimesh", "networkx", "cadquery", "OCP", "manifold3d",
            "matplotlib", "numba", "highspy")


def venv_dir() -> str:
    """The virtual environment Fabrickator uses: ``$FABRICKATOR_VENV`` or ROOT/.venv."""
    return os.environ.get(VENV_ENV) or os.path.join(ROOT, ".venv")


def site_packages() -> str:
    """The venv's site-packages folder for this interpreter's Python version."""
    version = f"python{sys.version_info[0]}.{sys.version_info[1]}"
    return os.path.join(venv_dir(), "lib", version, "site-packages")


def fix_command() -> str:
    """The shell command that builds the venv Fabrickator needs."""
    if os.path.exists(os.path.join(ROOT, "Makefile")):
        return f"cd {ROOT} && make setup"
    return (f"{sys.executable} -m venv {venv_dir()} && "
            f"{venv_dir()}/bin/pip install -r {ROOT}/requirements.txt")


def problem() -> str | None:
    """Why the venv cannot be put first on ``sys.path`` in this process (a phrase), or None.

    The venv must exist for this Python version, and numpy, if already
    imported, must be the venv's (numpy 1.x imported first by another
    module cannot be replaced in a running process).
    """
    packages = site_packages()
    if not os.path.isdir(packages):
        return f"{packages} is missing"
    numpy = sys.modules.get("numpy")
    if numpy is not None:
        where = os.path.abspath(getattr(numpy, "__file__", "") or "")
        if not where.startswith(os.path.abspath(packages) + os.sep):
            return (f"numpy {getattr(numpy, '__version__', '?')} from {os.path.dirname(where)} was "
                    f"imported before Fabrickator could put its own first: restart FreeCAD and "
                    f"disable the add-on that imports numpy at start-up")
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
        report(f"Fabrickator: cannot use its Python packages ({trouble}); run: {fix_command()}",
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


def missing(names=REQUIRED) -> list[str]:
    """The required packages that cannot be found (without importing them)."""
    return [n for n in names if importlib.util.find_spec(n) is None]


def check(command: str) -> bool:
    """True when ``command`` can run; else writes one Report-view line naming the fix.

    Checks that the required packages can be imported (from the venv, or
    installed otherwise) and that ``core`` is this repository's.
    """
    trouble = bootstrap()
    gone = missing()
    if gone:
        trouble = (f"Fabrickator: {command} needs the Python package(s) {', '.join(gone)}, "
                   f"which cannot be imported ({trouble or 'not installed'}); run: {fix_command()}")
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
