"""Export of printed parts and the CLI's --high-res contract."""

import json
import subprocess
import sys
from pathlib import Path

import cadquery as cq
import manifold3d as m3
import numpy as np
import pytest
import trimesh

from core import export, printed
from core.mesh_io import LoadedModel
from core.model import Brick, Grid, Layout

ROOT = Path(__file__).resolve().parents[2]
DEMO = ROOT / "examples" / "build" / "hmd.step"


def _manifold(mesh):
    return m3.Manifold(m3.Mesh64(vert_properties=np.ascontiguousarray(mesh.vertices, np.float64),
                                 tri_verts=np.ascontiguousarray(mesh.faces, np.uint64)))


def test_exported_parts_are_watertight_and_inside_the_model(tmp_path):
    model = trimesh.creation.icosphere(subdivisions=4, radius=14.0)
    model.apply_translation([12, 12, 8])
    source = printed.model_solid(LoadedModel(mesh=model, path="s.stl", format="stl",
                                             triangles=len(model.faces), watertight=True))
    g = Grid(origin=np.zeros(3), cell=np.array([8.0, 8.0, 3.2]), filled=np.ones((3, 3, 6), bool))
    lay = Layout(g, [Brick(0, "3003", (2, 2, 3), (0, 0, 0)), Brick(1, "3004", (1, 2, 3), (2, 0, 0)),
                     Brick(2, "3003", (2, 2, 3), (1, 1, 3))])
    parts = printed.build_parts(lay, [[0, 1], [2]], source)
    names = export.export_parts(parts, tmp_path / "parts")
    assert names == ["P1.stl", "P1.step", "P2.stl", "P2.step", "plate.3mf"]
    outside_model = _manifold(model)
    for p in parts:
        mesh = trimesh.load(tmp_path / p.stl, force="mesh")
        assert mesh.is_watertight
        assert (_manifold(mesh) - outside_model).volume() == pytest.approx(0.0, abs=1e-3)
        step = cq.importers.importStep(str(tmp_path / p.step)).val()
        assert step.isValid() and len(step.Solids()) == p.pieces
        assert step.Volume() == pytest.approx(mesh.volume, rel=1e-6)
    plate = trimesh.load(tmp_path / "parts" / "plate.3mf")
    assert len(plate.geometry) == 2 and plate.bounds[0][2] == pytest.approx(0.0, abs=1e-9)


def test_cli_high_res_box_on_the_demo_makes_parts(tmp_path):
    if not DEMO.exists():
        subprocess.run([sys.executable, str(ROOT / "examples" / "hmd.py"), str(DEMO.parent)],
                       check=True, cwd=ROOT)
    out = tmp_path / "out"
    run = subprocess.run([sys.executable, "-m", "core", "fabricate", str(DEMO), "--out", str(out),
                          "--high-res=-10,0,70,10,16,90", "--no-picture", "--quiet"],
                         cwd=ROOT, capture_output=True, text=True,
                         env={"FABRICKATOR_SLICER": "none", "PATH": "/usr/bin:/bin"})
    assert run.returncode == 0, run.stderr
    doc = json.loads((out / "report.json").read_text())
    assert (out / "parts" / "P1.stl").exists() and (out / "parts" / "P1.step").exists()
    part = doc["printed_parts"][0]
    assert part["id"] == "P1" and part["stl"] == "parts/P1.stl" and part["volume_mm3"] > 0
    assert doc["bricks"]["printed"] == len(part["bricks"]) > 0
    assert doc["print_time_s"]["method"].startswith("estimate")
    assert doc["speedup"] > 0 and doc["assembly_s"] > 0
    layout = json.loads((out / "layout.json").read_text())
    kinds = {b["id"]: (b["kind"], b["printed_part"]) for b in layout["bricks"]}
    assert all(kinds[i] == ("printed", "P1") for i in part["bricks"])
