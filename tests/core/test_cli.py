"""The headless contract end to end: ``python -m core fabricate`` as a user runs it."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

ROOT = Path(__file__).resolve().parents[2]
MODELS = ROOT.parent / "shared" / "models"


def fabricate(*args: str) -> subprocess.CompletedProcess:
    """Run the CLI in a subprocess, as a user would."""
    return subprocess.run([sys.executable, "-m", "core", "fabricate", *args],
                          cwd=ROOT, capture_output=True, text=True, timeout=300)


def assert_refused(proc: subprocess.CompletedProcess, *words: str) -> None:
    """Exit status 2, one line on stderr naming the problem, no traceback."""
    assert proc.returncode == 2, proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if not ln.startswith("[")]
    assert len(lines) == 1, proc.stderr
    assert "Traceback" not in proc.stderr
    for word in words:
        assert word.lower() in lines[0].lower(), lines[0]


@pytest.fixture
def box_stl(tmp_path) -> Path:
    """A 40 x 24 x 19.2 mm box standing on z = 0: 5 x 3 x 6 cells."""
    path = tmp_path / "box.stl"
    box = trimesh.creation.box((40.0, 24.0, 19.2))
    box.apply_translation(-box.bounds[0])
    box.export(path)
    return path


def test_box_end_to_end(box_stl, tmp_path):
    out = tmp_path / "out"
    proc = fabricate(str(box_stl), "--out", str(out))
    assert proc.returncode == 0, proc.stderr
    report = json.loads((out / "report.json").read_text())
    layout = json.loads((out / "layout.json").read_text())
    assert report["grid"]["shape"] == [5, 3, 6]
    assert report["grid"]["cell_mm"] == [8.0, 8.0, 3.2]
    assert report["plates"] == 90
    assert report["model"]["watertight"] is True
    assert report["bricks"]["total"] == len(layout["bricks"])
    assert report["stability"]["components"] == 1
    occupied = np.zeros((5, 3, 6), int)
    for b in layout["bricks"]:
        (i, j, k), (sx, sy, sz) = b["cell"], b["size"]
        occupied[i:i + sx, j:j + sy, k:k + sz] += 1
        assert b["kind"] == "lego" and b["part"].isdigit()
    assert (occupied == 1).all()
    assert (out / "layout.png").stat().st_size > 1000
    assert set(report["timings_s"]) >= {"load", "legofy", "layout", "stability"}
    steps = {b["step"] for b in layout["bricks"]}
    assert None not in steps and steps == set(range(1, report["assembly"]["steps"] + 1))
    for name in ("instructions.html", "assembly.mpd", "bom.csv", "bricklink.xml"):
        assert (out / name).stat().st_size > 100, name
        assert name in report["outputs"]


@pytest.mark.slow
def test_lower_bound_says_how_far_the_layout_is_from_the_fewest_bricks(box_stl, tmp_path):
    """The 5 x 3 stud box two bricks high: a course of 15 studs needs three catalog parts
    (no two footprints that fit make 15), so six bricks at least, and the layout has six,
    in one piece with no weak point: the summary says it is 1.000 times the fewest."""
    out = tmp_path / "out"
    proc = fabricate(str(box_stl), "--out", str(out), "--lower-bound", "--no-picture")
    assert proc.returncode == 0, proc.stderr
    line = next(ln for ln in proc.stdout.splitlines() if ln.startswith("lower bound:"))
    assert line == ("lower bound: any layout needs at least 6 bricks (proven); a layout in one "
                    "piece per region, with no weak point at least 6 (proven): these 6 are 1.000 "
                    "times that (report.json layout_quality.lower_bound)")
    bound = json.loads((out / "report.json").read_text())["layout_quality"]["lower_bound"]
    assert bound["one_piece"]["bound"] == 6 and bound["one_piece"]["proven"]
    plain = fabricate(str(box_stl), "--out", str(tmp_path / "plain"), "--no-picture")
    assert "lower bound:" not in plain.stdout


def test_best_also_lays_out_from_the_relaxed_brick_layers(box_stl, tmp_path):
    """``--effort best`` on a fresh layout also lays the box out from the brick layers of the
    exact cover's relaxation (timed as its own phase) and keeps the better: six bricks, the
    fewest, in one piece with no weak point, like ``normal``."""
    out = tmp_path / "out"
    proc = fabricate(str(box_stl), "--out", str(out), "--effort", "best", "--no-picture")
    assert proc.returncode == 0, proc.stderr
    report = json.loads((out / "report.json").read_text())
    assert "layout_relaxed" in report["timings_s"]
    quality = report["layout_quality"]
    assert "layout_relaxed" in quality["seconds"]
    assert (quality["bricks"], quality["components"], quality["weak_points"]) == (6, 1, 0)


def test_seed_is_deterministic(box_stl, tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    assert fabricate(str(box_stl), "--out", str(a), "--seed", "3", "--no-picture").returncode == 0
    assert fabricate(str(box_stl), "--out", str(b), "--seed", "3", "--no-picture").returncode == 0
    assert (a / "layout.json").read_text() == (b / "layout.json").read_text()


def test_plates_only(box_stl, tmp_path):
    out = tmp_path / "out"
    assert fabricate(str(box_stl), "--out", str(out), "--parts", "plates",
                     "--no-picture").returncode == 0
    layout = json.loads((out / "layout.json").read_text())
    assert all(b["size"][2] == 1 for b in layout["bricks"])


def test_missing_file(tmp_path):
    assert_refused(fabricate(str(tmp_path / "nope.stl"), "--out", str(tmp_path / "o")),
                   "nope.stl")
    assert not (tmp_path / "o").exists()


def test_empty_file(tmp_path):
    empty = tmp_path / "empty.stl"
    empty.write_bytes(b"")
    assert_refused(fabricate(str(empty), "--out", str(tmp_path / "o")), "empty")
    assert not (tmp_path / "o").exists()


def test_garbage_file(tmp_path):
    junk = tmp_path / "junk.stl"
    junk.write_bytes(b"\x00\x13 this is not a mesh \xff" * 10)
    assert_refused(fabricate(str(junk), "--out", str(tmp_path / "o")))
    assert not (tmp_path / "o").exists()


def test_nan_coordinates(tmp_path):
    bad = tmp_path / "nan.stl"
    bad.write_text("solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex nan 1 0\n"
                   "vertex 0 1 0\nendloop\nendfacet\nendsolid t\n")
    assert_refused(fabricate(str(bad), "--out", str(tmp_path / "o")), "nan")


def test_an_empty_slicer_is_refused(box_stl, tmp_path):
    assert_refused(fabricate(str(box_stl), "--out", str(tmp_path / "o"), "--slicer", ""),
                   "--slicer", "binary name or path, or none")
    assert not (tmp_path / "o").exists()


@pytest.mark.slow
def test_bad_parts_and_units(box_stl, tmp_path):
    assert_refused(fabricate(str(box_stl), "--out", str(tmp_path / "o"), "--parts", "3001"),
                   "3024")
    assert_refused(fabricate(str(box_stl), "--out", str(tmp_path / "o"), "--units", "ft"))
    assert_refused(fabricate(str(box_stl), "--out", str(tmp_path / "o"), "--scale", "-1"))
    assert_refused(fabricate(str(box_stl), "--out", str(tmp_path / "o"), "--up", "w"),
                   "--up 'w' is not an axis: use one of z, y, -y, x, -x, -z")


def test_up_turns_the_model_before_the_layout(tmp_path):
    """A 16 x 16 x 48 mm column lying along y in the file: with --up y it stands 48 mm tall
    (15 plate layers of 3.2 mm) on a 2 x 2 stud footprint, and report.json records the axis."""
    column = tmp_path / "column.stl"
    trimesh.creation.box((16.0, 48.0, 16.0)).export(column)
    out = tmp_path / "o"
    proc = fabricate(str(column), "--out", str(out), "--no-picture", "--up", "y")
    assert proc.returncode == 0, proc.stderr
    layout = json.loads((out / "layout.json").read_text())
    assert layout["shape"] == [2, 2, 15]
    model = json.loads((out / "report.json").read_text())["model"]
    assert (model["units"], model["scale"], model["up"], model["bbox_mm"]) == ("mm", 1.0, "y", [16.0, 16.0, 48.0])


def test_out_folder_with_foreign_files_is_kept(box_stl, tmp_path):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "thesis.txt").write_text("precious")
    assert_refused(fabricate(str(box_stl), "--out", str(out)), "other files")
    assert (out / "thesis.txt").read_text() == "precious"


@pytest.mark.slow
def test_rerun_replaces_previous_output(box_stl, tmp_path):
    out = tmp_path / "out"
    assert fabricate(str(box_stl), "--out", str(out), "--no-picture").returncode == 0
    assert fabricate(str(box_stl), "--out", str(out), "--no-picture", "--seed", "1").returncode == 0
    assert json.loads((out / "report.json").read_text())["seed"] == 1
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []


def test_unit_warning(tmp_path):
    tiny = tmp_path / "tiny.stl"
    trimesh.creation.box((0.16, 0.15, 0.12)).export(tiny)
    proc = fabricate(str(tiny), "--out", str(tmp_path / "o"), "--no-picture")
    assert proc.returncode == 0, proc.stderr
    assert "--units" in proc.stderr


@pytest.mark.slow
def test_triangle_soup_refused(tmp_path):
    soup = MODELS / "broken_triangle_soup.stl"
    if not soup.exists():
        pytest.skip(f"{MODELS} is absent: the shared benchmark models are not here")
    assert_refused(fabricate(str(soup), "--out", str(tmp_path / "o")), "volume")
    assert not (tmp_path / "o").exists()


def _l_block(extra: bool) -> trimesh.Trimesh:
    """An L-shaped block 48 x 32 x 19.2 mm; ``extra`` adds a 16 x 16 x 9.6 mm boss on top of one end."""
    parts = [trimesh.creation.box((48.0, 16.0, 19.2)), trimesh.creation.box((16.0, 32.0, 19.2))]
    parts[1].apply_translation((-16.0, 8.0, 0.0))
    if extra:
        parts.append(trimesh.creation.box((16.0, 16.0, 9.6)))
        parts[-1].apply_translation((16.0, 0.0, 14.4))
    mesh = trimesh.boolean.union(parts, engine="manifold")
    mesh.apply_translation(-mesh.bounds[0])
    return mesh


@pytest.mark.slow
def test_previous_keeps_the_layout_of_a_moved_and_edited_part(tmp_path):
    first, second = tmp_path / "v1.stl", tmp_path / "v2.stl"
    _l_block(False).export(first)
    moved = _l_block(True)
    moved.apply_transform(trimesh.transformations.rotation_matrix(0.7, [1.0, 2.0, 3.0]))
    moved.apply_translation((30.0, -12.0, 7.0))
    moved.export(second)
    assert fabricate(str(first), "--out", str(tmp_path / "o1"), "--no-picture").returncode == 0
    proc = fabricate(str(second), "--previous", str(tmp_path / "o1"), "--out", str(tmp_path / "o2"),
                     "--no-picture")
    assert proc.returncode == 0, proc.stderr
    report = json.loads((tmp_path / "o2" / "report.json").read_text())
    ch = report["changes"]
    assert ch["transform"]["confident"]
    assert ch["transform"]["rotation_deg"] == pytest.approx(np.degrees(0.7), abs=0.05)
    assert ch["cells_added"] == 2 * 2 * 3 and ch["cells_removed"] == 0
    before = json.loads((tmp_path / "o1" / "layout.json").read_text())["bricks"]
    assert ch["bricks_kept"] >= len(before) - 2 and ch["add"]
    assert "changes:" in proc.stdout and (tmp_path / "o2" / "changes.html").exists()


def test_previous_that_is_not_an_output_is_refused(box_stl, tmp_path):
    assert_refused(fabricate(str(box_stl), "--previous", str(tmp_path), "--out", str(tmp_path / "o")),
                   "--previous", "not an output folder")


@pytest.mark.slow
def test_watch_fabricates_each_new_version(box_stl, tmp_path):
    folder = tmp_path / "inbox"
    folder.mkdir()
    (folder / "part.stl").write_bytes(box_stl.read_bytes())
    proc = subprocess.run([sys.executable, "-m", "core", "watch", str(folder), "--out",
                           str(tmp_path / "runs"), "--existing", "--timeout", "4", "--quiet"],
                          cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    report = json.loads((tmp_path / "runs" / "part-1" / "report.json").read_text())
    assert report["plates"] == 90 and "written to" in proc.stdout
