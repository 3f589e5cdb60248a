"""The import graph of ``core`` and of the workbench, read with ``ast`` (no FreeCAD needed).

Every ``import`` counts as an edge, at module level or inside a function: an
import inside a function still ties the two modules together, it only hides
the loop from Python.  The checks:

* no cycle inside ``core`` and none inside ``FabrickatorWorkbench`` (each
  cycle found is named);
* ``core`` never imports FreeCAD or its GUI (FreeCAD, FreeCADGui, Part, Mesh,
  PySide, pivy);
* the workbench in layers: ``objects/`` and ``viewproviders/`` never import
  ``make`` or ``commands``, ``make`` and what it uses never import the commands
  or the task panels;
* what ``freecadcmd`` loads (everything but ``commands/``, ``taskpanels/``, the
  first-run install dialog and the preferences page) imports no GUI module at
  module level;
* importing a workbench module loads none of the venv's heavy packages
  (cadquery, OCP, trimesh, scipy, ... :data:`FabrickatorWorkbench.deps.REQUIRED`
  but numpy), directly or through ``core``: those are imported where they are
  used, after ``deps.check``;
* every other import of the workbench sits at module top.
"""

from __future__ import annotations

import ast
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("core", "FabrickatorWorkbench")
WORKBENCH = "FabrickatorWorkbench"
#: FreeCAD's own modules: never imported by core.
FREECAD_MODULES = {"FreeCAD", "FreeCADGui", "Part", "Mesh", "PySide", "PySide2", "pivy"}
#: FreeCAD's GUI modules: lazy wherever freecadcmd may import the module.
GUI_MODULES = {"FreeCADGui", "PySide", "PySide2", "pivy"}
#: Workbench modules only the GUI loads: they may import the GUI at module top.
GUI_ONLY = ("FabrickatorWorkbench.commands", "FabrickatorWorkbench.taskpanels",
            "FabrickatorWorkbench.install")
#: Imports inside functions that must stay there, with the reason.
LAZY_ON_PURPOSE = {
    # Init.py imports the package (for deps) before deps.bootstrap() puts the venv's numpy
    # first: the scripting API loads on first use
    ("FabrickatorWorkbench", "FabrickatorWorkbench.make"),
    # deps must work outside FreeCAD too (it reports on stderr there)
    ("FabrickatorWorkbench.deps", "FreeCAD"),
    # run as a file by `make gui`, the example schedules the function of its imported module
    ("FabrickatorWorkbench.example", "FabrickatorWorkbench.example"),
}


@dataclass(frozen=True)
class Import:
    """One import statement's target: ``source`` imports ``target`` (a dotted name)."""

    source: str
    target: str
    line: int
    in_function: bool


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def modules() -> dict[str, Path]:
    """Every module of core and of the workbench by dotted name."""
    return {module_name(p): p for package in PACKAGES for p in sorted((ROOT / package).rglob("*.py"))}


def imports(name: str, path: Path, known: dict) -> list[Import]:
    """The imports of one module, relative ones resolved; ``from X import y`` targets the
    module X.y when there is one, else X."""
    tree = ast.parse(path.read_text(), filename=str(path))
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    out = []

    def visit(node, in_function: bool) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.Import):
                out.extend(Import(name, a.name, child.lineno, in_function) for a in child.names)
            elif isinstance(child, ast.ImportFrom) and child.module != "__future__":
                base = child.module or ""
                if child.level:
                    parts = package.split(".")[:len(package.split(".")) - child.level + 1]
                    base = ".".join(parts + ([base] if base else []))
                for a in child.names:
                    full = f"{base}.{a.name}"
                    out.append(Import(name, full if full in known else base, child.lineno,
                                      in_function))
            visit(child, in_function or isinstance(child, (ast.FunctionDef,
                                                           ast.AsyncFunctionDef, ast.Lambda)))

    visit(tree, False)
    return out


def own(target: str, known: dict) -> str | None:
    """The module of ours that importing ``target`` names, or None for another package."""
    while target and target not in known:
        target = target.rpartition(".")[0]
    return target or None


@pytest.fixture(scope="module")
def graph():
    known = modules()
    every = [i for name, path in known.items() for i in imports(name, path, known)]
    edges: dict[str, set[str]] = {name: set() for name in known}
    for i in every:
        target = own(i.target, known)
        if target is not None and target != i.source:
            edges[i.source].add(target)
    return known, every, edges


def cycles(edges: dict[str, set[str]], members: set[str]) -> list[tuple[list[str], list[str]]]:
    """The import cycles among ``members``: per strongly connected set of two or more
    modules (Tarjan), its modules and one shortest closed path through the smallest."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[tuple[list[str], list[str]]] = []

    def strong(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(edges[v] & members):
            if w not in index:
                strong(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            part = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                part.append(w)
                if w == v:
                    break
            if len(part) > 1:
                found.append((sorted(part), _closed_path(edges, set(part))))

    limit = sys.getrecursionlimit()
    sys.setrecursionlimit(max(limit, 10 * len(members) + 100))
    try:
        for v in sorted(members):
            if v not in index:
                strong(v)
    finally:
        sys.setrecursionlimit(limit)
    return found


def _closed_path(edges, part: set[str]) -> list[str]:
    """A shortest cycle through the smallest module of ``part``, as [a, b, ..., a]."""
    start = min(part)
    paths = {start: [start]}
    queue = [start]
    for v in queue:
        for w in sorted(edges[v] & part):
            if w == start:
                return paths[v] + [start]
            if w not in paths:
                paths[w] = paths[v] + [w]
                queue.append(w)
    raise AssertionError(f"no cycle through {start}")


def _in(name: str, *prefixes: str) -> bool:
    return any(name == p or name.startswith(p + ".") for p in prefixes)


def _heavy() -> set[str]:
    """The venv's heavy packages: deps.REQUIRED (read from deps.py) but numpy."""
    tree = ast.parse((ROOT / WORKBENCH / "deps.py").read_text())
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(getattr(t, "id", "") == "REQUIRED"
                                                for t in node.targets):
            return set(ast.literal_eval(node.value)) - {"numpy"}
    raise AssertionError("deps.py has no REQUIRED")


@pytest.mark.parametrize("package", PACKAGES)
def test_no_import_cycle(graph, package):
    known, _, edges = graph
    found = cycles(edges, {m for m in known if _in(m, package)})
    assert not found, f"import cycles in {package}: " + "; ".join(
        f"{len(part)} modules import each other ({', '.join(part)}), e.g. {' -> '.join(path)}"
        for part, path in found)


def test_core_never_imports_freecad(graph):
    _, every, _ = graph
    bad = [f"{i.source}:{i.line} imports {i.target}" for i in every
           if _in(i.source, "core") and i.target.split(".")[0] in FREECAD_MODULES]
    assert not bad, bad


def test_objects_and_viewproviders_never_import_make_or_the_commands(graph):
    known, every, _ = graph
    below = ("FabrickatorWorkbench.objects", "FabrickatorWorkbench.viewproviders")
    above = ("FabrickatorWorkbench.make", "FabrickatorWorkbench.commands",
             "FabrickatorWorkbench.taskpanels")
    bad = [f"{i.source}:{i.line} imports {i.target}" for i in every
           if _in(i.source, *below) and _in(own(i.target, known) or "", *above)]
    assert not bad, bad


def test_make_and_what_it_uses_never_reach_the_commands_or_panels(graph):
    known, _, edges = graph
    reached, todo = set(), ["FabrickatorWorkbench.make"]
    while todo:
        for w in edges[todo.pop()] - reached:
            reached.add(w)
            todo.append(w)
    bad = sorted(m for m in reached if _in(m, *GUI_ONLY))
    assert not bad, f"make reaches {bad}"


def _module_level_closure(graph, start: str) -> set[str]:
    """Everything importing ``start`` executes: its module-level imports, ours followed
    (package __init__ modules included), others as top-level package names."""
    known, every, _ = graph
    top_level = {}
    for i in every:
        if not i.in_function:
            top_level.setdefault(i.source, []).append(i.target)
    seen, outside, todo = {start}, set(), [start]
    while todo:
        for target in top_level.get(todo.pop(), []):
            ours = own(target, known)
            if ours is None:
                outside.add(target.split(".")[0])
                continue
            chain = ours.split(".")
            for n in range(1, len(chain) + 1):
                name = ".".join(chain[:n])
                if name in known and name not in seen:
                    seen.add(name)
                    todo.append(name)
    return outside


def test_freecadcmd_modules_import_no_gui_at_module_level(graph):
    known, _, _ = graph
    app_side = [m for m in known if _in(m, WORKBENCH) and not _in(m, *GUI_ONLY)]
    bad = {m: sorted(_module_level_closure(graph, m) & GUI_MODULES) for m in app_side}
    bad = {m: gui for m, gui in bad.items() if gui}
    assert not bad, f"importing these in freecadcmd loads the GUI: {bad}"


def test_importing_the_workbench_loads_no_heavy_package(graph):
    known, _, _ = graph
    heavy = _heavy()
    bad = {m: sorted(_module_level_closure(graph, m) & heavy) for m in known if _in(m, WORKBENCH)}
    bad = {m: found for m, found in bad.items() if found}
    assert not bad, f"importing these loads heavy packages at once: {bad}"


def test_workbench_imports_sit_at_module_top(graph):
    """An import inside a function must be one that cannot go to the top: a GUI module in
    code freecadcmd loads, a heavy package or a core module that loads one, or one of
    :data:`LAZY_ON_PURPOSE`."""
    known, every, _ = graph
    heavy = _heavy()
    bad = []
    for i in every:
        if not (i.in_function and _in(i.source, WORKBENCH)):
            continue
        root = i.target.split(".")[0]
        ours = own(i.target, known)
        if (i.source, ours or i.target) in LAZY_ON_PURPOSE:
            continue
        if root in GUI_MODULES and not _in(i.source, *GUI_ONLY):
            continue
        if root in heavy:
            continue
        if ours is not None and _in(ours, "core") and _module_level_closure(graph, ours) & heavy:
            continue
        bad.append(f"{i.source}:{i.line} imports {i.target}")
    assert not bad, "imports that belong at module top: " + "; ".join(bad)
