"""Data flows one way: no module of core imports one that comes after it in the pipeline."""

from __future__ import annotations

import ast
from pathlib import Path

CORE = Path(__file__).resolve().parents[2] / "core"

#: The modules of core in pipeline order: shared data and utilities first, then the
#: stages as the driver runs them (regions are read before the grid is fitted to them),
#: then the exports, then the drivers and tools that use them all.  The exact-cover
#: program (lower_bound) comes before the layout, which reads brick layers off its relaxation.
ORDER = [
    "errors", "output_dir", "colours", "model", "interfaces", "request", "catalog", "connectivity", "brick_solids",
    "thickness", "mesh_io", "voxelize", "hollow", "high_res", "suggest", "grid_fit", "lower_bound", "layout", "improve", "align", "diff",
    "connectors", "printed", "stability", "forces", "reinforce", "result", "build_order", "slicer_profile", "slice_cache", "print_time", "export", "render", "picture",
    "ldraw", "bom", "instructions", "changes_page", "picking", "face_region",
    "iterate", "pipeline", "live_estimate", "watch", "calibration", "layout_file", "cli", "__main__", "__init__",
]


def _imports(path: Path) -> set[str]:
    """The core modules ``path`` imports, at module level or inside functions."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module == "core":
            out |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith("core."):
            out.add(node.module.split(".")[1])
        elif isinstance(node, ast.Import):
            out |= {a.name.split(".")[1] for a in node.names if a.name.startswith("core.")}
    return out & set(ORDER)


def test_every_core_module_has_its_place():
    assert sorted(p.stem for p in CORE.glob("*.py")) == sorted(ORDER)


def test_no_module_imports_a_later_one():
    place = {name: n for n, name in enumerate(ORDER)}
    later = {name: sorted(m for m in _imports(CORE / f"{name}.py") if place[m] > place[name])
             for name in ORDER}
    assert not {k: v for k, v in later.items() if v}, "imports of modules later in the pipeline"
