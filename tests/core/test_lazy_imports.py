"""Lazy heavy imports: a mesh fabricate without printed parts imports no OpenCascade
(OCP) and no cadquery; with printed parts they are imported where they are needed."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
import trimesh

ROOT = Path(__file__).resolve().parents[2]

#: Runs the CLI in this process and prints, as its last line, the exit status and the
#: heavy packages that were imported.
RUN = """
import json, sys
from core import cli
status = cli.main(sys.argv[1:])
heavy = sorted({name.split(".")[0] for name in sys.modules} & {"OCP", "cadquery"})
print(json.dumps({"status": status, "heavy": heavy}))
"""


def run_cli(*args: str) -> dict:
    """``python -m core`` ``args`` in a subprocess: its exit status and heavy imports."""
    proc = subprocess.run([sys.executable, "-c", RUN, *args], cwd=ROOT, capture_output=True,
                          text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout.strip().splitlines()[-1])


@pytest.fixture
def box_stl(tmp_path) -> Path:
    """A 24 x 16 x 9.6 mm box standing on z = 0: 3 x 2 x 3 cells."""
    path = tmp_path / "box.stl"
    box = trimesh.creation.box((24.0, 16.0, 9.6))
    box.apply_translation(-box.bounds[0])
    box.export(path)
    return path


@pytest.mark.slow
def test_mesh_fabricate_without_printed_parts_imports_no_opencascade(box_stl, tmp_path):
    out = tmp_path / "out"
    result = run_cli("fabricate", str(box_stl), "--out", str(out), "--no-picture", "--quiet")
    assert result == {"status": 0, "heavy": []}
    report = json.loads((out / "report.json").read_text())
    assert report["printed_parts"] == [] and report["bricks"]["total"] >= 1


def test_importing_the_stages_imports_no_opencascade():
    names = ("core.cli", "core.pipeline", "core.parts.printed", "core.printing.export", "core.iterate",
             "core.instructions.page", "core.instructions.render", "core.parts.calibration", "core.diff", "core.align")
    code = ("import importlib, sys\n"
            f"for name in {names!r}:\n"
            "    importlib.import_module(name)\n"
            "print(sorted({n.split('.')[0] for n in sys.modules} & {'OCP', 'cadquery'}))")
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                          text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "[]"


@pytest.mark.slow
def test_mesh_fabricate_with_a_high_res_box_still_makes_its_printed_part(box_stl, tmp_path):
    out = tmp_path / "out"
    result = run_cli("fabricate", str(box_stl), "--out", str(out), "--high-res=0,0,6.4,8,8,9.6",
                     "--no-picture", "--quiet")
    assert result["status"] == 0
    assert "cadquery" in result["heavy"]  # the part's id is engraved with cadquery's text
    report = json.loads((out / "report.json").read_text())
    (part,) = report["printed_parts"]
    assert part["volume_mm3"] > 0 and part["engraved"]
    assert (out / "parts" / f"{part['id']}.stl").stat().st_size > 0
    assert (out / "parts" / f"{part['id']}.step").stat().st_size > 0
