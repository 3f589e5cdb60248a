"""Data flows one way: no module of core imports one that comes after it in the pipeline,
and no package of core imports one that imports it back."""

from __future__ import annotations

import ast
from pathlib import Path

import networkx as nx

CORE = Path(__file__).resolve().parents[2] / "core"

#: The modules of core (dotted below ``core``; a package by its own name is its
#: ``__init__``) in pipeline order: shared data and utilities first, then the stages as
#: the driver runs them (regions are read before the grid is fitted to them), then the
#: exports, then the drivers and tools that use them all.  The force model comes before
#: the layout: the exact-cover bounds solve with its HiGHS settings and reinforce asks it.
#: The maker's inventory (read before any geometry) limits the layout and colours the outputs.
#: The print-time estimate and poses (plain geometry, no slicer) come before suggest, which
#: prices its regions with them.
ORDER = [
    "io", "parts", "layout", "printing", "instructions",
    "errors", "io.output_dir", "colours", "model", "parts.interfaces", "request", "catalog", "inventory",
    "connectivity", "parts.brick_solids", "parts.thickness", "io.brep", "io.repair", "io.meshes", "voxelize", "hollow",
    "high_res", "printing.plate", "printing.estimate", "printing.poses", "suggest", "grid_fit",
    "forces.limits", "forces.joints", "forces.solver", "forces.verdict", "forces.bodies",
    "forces.program", "forces.decompose", "forces.analyse", "forces.build_steps", "forces",
    "layout.bounds", "layout.brick_cells", "layout.merge_kernels", "layout.repair",
    "layout.greedy", "layout.quality", "layout.window_program",
    "layout.connected_bound", "layout.neighbourhood", "layout.search", "align", "diff", "parts.connectors",
    "parts.printed_part", "parts.booleans", "parts.engraving", "parts.printed", "stability", "layout.reinforce", "result", "instructions.build_order",
    "printing.slicer_profile", "printing.slice_cache", "printing.print_time", "printing.printers", "printing.export",
    "instructions.render", "instructions.picture", "instructions.ldraw", "instructions.bom", "instructions.drawing_order",
    "instructions.page", "instructions.changes_page", "picking", "face_region",
    "iterate", "report", "pipeline", "live_estimate", "watch", "parts.calibration", "io.layout_file",
    "cli", "__main__", "__init__",
]


def _modules() -> dict[str, Path]:
    """Every module of core by its dotted name below ``core``."""
    out = {}
    for path in CORE.rglob("*.py"):
        parts = path.relative_to(CORE).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" and len(parts) > 1 else parts)
        out[name] = path
    return out


def _imports(path: Path, known) -> set[str]:
    """The core modules ``path`` imports, at module level or inside functions."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module \
                and (node.module == "core" or node.module.startswith("core.")):
            base = node.module.removeprefix("core").removeprefix(".")
            for a in node.names:
                full = f"{base}.{a.name}" if base else a.name
                out.add(full if full in known else base)
        elif isinstance(node, ast.Import):
            out |= {a.name.removeprefix("core.") for a in node.names if a.name.startswith("core.")}
    return out & set(known)


def test_every_core_module_has_its_place():
    assert sorted(_modules()) == sorted(ORDER)


def test_no_module_imports_a_later_one():
    place = {name: n for n, name in enumerate(ORDER)}
    known = _modules()
    later = {name: sorted(m for m in _imports(path, known) if place[m] > place[name])
             for name, path in known.items()}
    assert not {k: v for k, v in later.items() if v}, "imports of modules later in the pipeline"


def test_no_import_circle_between_packages():
    """Each package (and each single-module stage) is one node: a package's modules may use
    each other, but no two packages depend on each other."""
    known = _modules()
    graph = nx.DiGraph()
    for name, path in known.items():
        for m in _imports(path, known):
            if m.split(".")[0] != name.split(".")[0]:
                graph.add_edge(name.split(".")[0], m.split(".")[0])
    assert nx.is_directed_acyclic_graph(graph), nx.find_cycle(graph)


def test_each_package_states_its_contract():
    """A package's ``__init__`` opens with a docstring of what it holds and promises."""
    for init in CORE.glob("*/__init__.py"):
        doc = ast.get_docstring(ast.parse(init.read_text())) or ""
        assert len(doc.split()) >= 20 and "TODO" not in doc, init


def _module_aliases(tree) -> dict[str, str]:
    """Name -> dotted core module, for each ``from core[.pkg] import module [as name]`` and
    ``import core.x as name`` in ``tree`` (a function's own imports included)."""
    out = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module \
                and (node.module == "core" or node.module.startswith("core.")):
            for a in node.names:
                full = f"{node.module}.{a.name}"
                where = CORE.parent / full.replace(".", "/")
                if where.with_suffix(".py").is_file() or (where / "__init__.py").is_file():
                    out[a.asname or a.name] = full
        elif isinstance(node, ast.Import):
            out.update({a.asname: a.name for a in node.names if a.name.startswith("core.") and a.asname})
    return out


def test_every_module_attribute_used_exists():
    """``module.name`` for every core module a file of core, the workbench, the tests or
    bench imports under a name names something that module has (a moved constant that a
    package no longer gives fails here, not in a user's run)."""
    import importlib

    missing = []
    for folder in ("core", "FabrickatorWorkbench", "tests", "bench"):
        for path in (CORE.parent / folder).rglob("*.py"):
            tree = ast.parse(path.read_text())
            aliases = _module_aliases(tree)
            if not aliases:
                continue
            shadowed = {n.id for n in ast.walk(tree) if isinstance(n, ast.Name)
                        and isinstance(n.ctx, ast.Store)} | {
                a.arg for n in ast.walk(tree) if isinstance(n, ast.arguments)
                for a in n.args + n.kwonlyargs + n.posonlyargs}
            for node in ast.walk(tree):
                if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) \
                        and node.value.id in aliases and node.value.id not in shadowed:
                    module = importlib.import_module(aliases[node.value.id])
                    if not hasattr(module, node.attr):
                        missing.append(f"{path.relative_to(CORE.parent)}:{node.lineno} "
                                       f"{aliases[node.value.id]}.{node.attr}")
    assert not missing, missing
