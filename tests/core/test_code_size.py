"""The limits on the size of the code's rooms: no file of ``core/`` or
``FabrickatorWorkbench/`` over 800 lines, no class over 400 and no function over 100,
unless a comment says why: ``# One file on purpose: ...`` among a file's comments, or
``# One class on purpose: ...`` / ``# One function on purpose: ...`` in the comment just
above the definition (or above its decorators). A module's docstring is at most about
30 lines and tells no history ("N -> M"); the README is at most 200 lines."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
LIMITS = {"file": 800, "class": 400, "function": 100, "module docstring": 32, "README": 200}
HISTORY = re.compile(r"[0-9]+ -> [0-9]+")
FILES = sorted(p for folder in ("core", "FabrickatorWorkbench") for p in (ROOT / folder).rglob("*.py"))


def _reason_above(lines: list[str], node, kind: str) -> bool:
    row = min([node.lineno] + [d.lineno for d in getattr(node, "decorator_list", [])]) - 2
    while row >= 0 and lines[row].strip().startswith("#"):
        if lines[row].strip().startswith(f"# One {kind} on purpose:"):
            return True
        row -= 1
    return False


def oversized(path: Path) -> list[str]:
    """The rooms of the file at ``path`` over their limits without a reason, as ``kind name
    (lines)``."""
    text = path.read_text(encoding="utf-8")
    lines = text.splitlines()
    out = []
    if len(lines) > LIMITS["file"] and "# One file on purpose:" not in text:
        out.append(f"file ({len(lines)} lines)")
    for node in ast.walk(ast.parse(text)):
        kind = ("class" if isinstance(node, ast.ClassDef) else
                "function" if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) else None)
        if kind is None:
            continue
        size = node.end_lineno - node.lineno + 1
        if size > LIMITS[kind] and not _reason_above(lines, node, kind):
            out.append(f"{kind} {node.name} ({size} lines)")
    return out


def test_the_checker_finds_a_long_function_and_takes_its_reason(tmp_path):
    body = "\n".join(f"    x{i} = {i}" for i in range(LIMITS["function"]))
    long = tmp_path / "long.py"
    long.write_text(f"@staticmethod\ndef long():\n{body}\n", encoding="utf-8")
    assert oversized(long) == [f"function long ({LIMITS['function'] + 1} lines)"]
    long.write_text(f"# One function on purpose: a table.\n@staticmethod\ndef long():\n{body}\n",
                    encoding="utf-8")
    assert oversized(long) == []


@pytest.mark.parametrize("path", FILES, ids=lambda p: str(p.relative_to(ROOT)))
def test_no_room_is_oversized_without_its_reason(path):
    assert oversized(path) == []


@pytest.mark.parametrize("path", FILES, ids=lambda p: str(p.relative_to(ROOT)))
def test_a_module_docstring_is_short_and_tells_no_history(path):
    text = path.read_text(encoding="utf-8")
    doc = ast.get_docstring(ast.parse(text), clean=False) or ""
    assert len(doc.splitlines()) <= LIMITS["module docstring"]
    assert HISTORY.findall(text) == []


def test_the_readme_is_short():
    assert len((ROOT / "README.md").read_text(encoding="utf-8").splitlines()) <= LIMITS["README"]
