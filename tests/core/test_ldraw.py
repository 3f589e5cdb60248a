"""Tests of core.instructions.ldraw: conventions, the MPD writer and its round trip through the parser."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from core import pipeline
from core.catalog import BY_NUMBER, CATALOG
from core.errors import InputError
from core.instructions import build_order, ldraw
from core.model import Brick, Grid, Layout

from conftest import HMD_HIGH_RES

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def hmd(tmp_path_factory, hmd_step):
    fab = pipeline.run(hmd_step, high_res=HMD_HIGH_RES, slice_parts=False)
    order = fab.order
    assert [b.step for b in fab.layout.bricks] == [b.step for b in build_order.numbered(fab.layout, order).bricks]
    path = ldraw.write(fab.layout, fab.printed, order.steps,
                       tmp_path_factory.mktemp("ldraw") / "assembly.mpd", title="hmd")
    return fab, order, path


def local_box(number: str) -> np.ndarray:
    """Corners (8, 3) of a part's body in its own LDraw frame: top centre origin, long side X."""
    part = BY_NUMBER[number]
    w, d = part.footprint
    xs, zs = (-10 * d, 10 * d), (-10 * w, 10 * w)
    ys = (0, 8 * part.layers)
    return np.array([[x, y, z] for x in xs for y in ys for z in zs], dtype=float)


def test_model_to_ldraw_is_a_proper_rotation_with_minus_y_up():
    origin, shift = np.array([5.0, -3.0, 2.0]), (40, 20)
    pts = np.array([[5.0, -3.0, 2.0], [6.0, -3.0, 2.0], [5.0, -2.0, 2.0], [5.0, -3.0, 3.0]])
    q = ldraw.model_to_ldu(pts, origin, shift)
    axes = q[1:] - q[0]
    assert np.allclose(np.abs(axes), 2.5 * np.eye(3)[[0, 2, 1]])
    assert np.linalg.det(axes) > 0           # no mirror
    assert axes[2][1] == pytest.approx(-2.5)  # model up is LDraw -Y
    assert np.allclose(ldraw.ldu_to_model(q, origin, shift), pts)


def test_2x4_brick_is_3001_along_x_and_turned_by_90_degrees():
    shape = (4, 4, 3)
    pos, rot = ldraw.brick_placement((0, 1, 0), (4, 2, 3), ldraw.centring_shift(shape))
    # centre x = 2 studs, centre y = 2 studs, both minus the centring shift of 2 studs; top at -24
    assert np.array_equal(rot, np.eye(3)) and np.allclose(pos, [0, -24, 0])
    pos, rot = ldraw.brick_placement((1, 0, 0), (2, 4, 3), ldraw.centring_shift(shape))
    assert np.array_equal(rot, ldraw.TURNED) and np.allclose(pos, [0, -24, 0])
    assert np.isclose(np.linalg.det(ldraw.TURNED), 1.0)


@pytest.mark.slow
def test_every_reference_covers_exactly_its_brick(hmd):
    """Part body (LDraw convention) placed by the reference == the brick's cells in LDU."""
    fab, _, path = hmd
    grid = fab.layout.grid
    shift = ldraw.centring_shift(grid.shape)
    doc = ldraw.parse(path)
    refs = [r for step in doc.main.steps for r in step if r.name.endswith(".dat")]
    lego = [b for b in fab.layout.bricks if b.kind == "lego"]
    assert len(refs) == len(lego)
    boxes = set()
    for r in refs:
        world = local_box(r.name[:-4]) @ r.rotation.T + r.position
        boxes.add(tuple(np.round(np.concatenate([world.min(axis=0), world.max(axis=0)]), 6)))
    for b in lego:
        lo = grid.origin + np.array(b.cell) * grid.cell
        hi = lo + np.array(b.size) * grid.cell
        corners = ldraw.model_to_ldu(np.array([lo, hi]), grid.origin, shift)
        key = tuple(np.round(np.concatenate([corners.min(axis=0), corners.max(axis=0)]), 6))
        assert key in boxes, f"brick {b.id} {b.part} has no reference covering it"


@pytest.mark.slow
def test_round_trip_bricks_steps_and_colours(hmd):
    fab, order, path = hmd
    doc = ldraw.parse(path)
    assert len(doc.main.steps) == len(order.steps)
    back = ldraw.placed_bricks(doc, fab.layout.grid.shape)
    got = sorted((d["part"], d["cell"], d["size"], d["step"], d["color"]) for d in back)
    want = sorted((b.part, tuple(b.cell), tuple(b.size), b.step, ldraw.LEGO_COLOR)
                  for b in fab.layout.bricks if b.kind == "lego")
    assert got == want


@pytest.mark.slow
def test_printed_parts_are_embedded_once_in_their_step(hmd):
    fab, order, path = hmd
    doc = ldraw.parse(path)
    grid = fab.layout.grid
    shift = ldraw.centring_shift(grid.shape)
    for part in fab.printed:
        name = ldraw.subfile_name(part.id)
        refs = [(n, r) for n, step in enumerate(doc.main.steps, start=1) for r in step if r.name == name]
        assert len(refs) == 1
        n, r = refs[0]
        assert r.color == ldraw.PRINTED_COLOR
        assert n == next(s.number for s in order.steps if s.printed_part == part.id)
        sub = doc.embedded(name)
        assert sub is not None and sub.bfc_ccw
        assert len(sub.triangles) == len(part.mesh.faces)
        mm = ldraw.ldu_to_model(sub.triangles, grid.origin, shift)
        want = np.asarray(part.mesh.vertices)[np.asarray(part.mesh.faces)]
        assert np.abs(mm - want).max() < 1e-3
        # winding kept: the volume from the LDraw triangles (back in mm) is the part's
        v = np.einsum("ij,ij->i", mm[:, 0], np.cross(mm[:, 1], mm[:, 2])).sum() / 6.0
        assert v == pytest.approx(part.volume_mm3, rel=1e-3)


@pytest.mark.slow
def test_file_layout_is_mpd_with_steps(hmd):
    _, order, path = hmd
    text = path.read_text()
    lines = text.splitlines()
    assert lines[0] == "0 FILE assembly.ldr"
    assert text.count("0 NOFILE") == 1 + text.count("0 FILE printed_")
    assert sum(1 for line in lines if line.strip() == "0 STEP") == len(order.steps)


def test_every_catalog_part_round_trips_in_both_orientations():
    bricks, x = [], 0
    for part in CATALOG:
        for sx, sy in part.orientations():
            bricks.append(Brick(len(bricks), part.number, (sx, sy, part.layers), (x, 0, 0), step=len(bricks) + 1))
            x += sx + 1
    filled = np.zeros((x, 8, 3), dtype=bool)
    for b in bricks:
        filled[b.slices()] = True
    lay = Layout(Grid(np.array([1.0, 2.0, 3.0]), np.array([8.0, 8.0, 3.2]), filled), bricks)
    text = _write_text(lay, [[b.id] for b in bricks])
    back = ldraw.placed_bricks(ldraw.parse(text), filled.shape)
    assert [(d["part"], d["cell"], d["size"], d["step"]) for d in back] == \
           [(b.part, b.cell, b.size, b.step) for b in bricks]


def _write_text(lay, steps) -> str:
    import tempfile
    with tempfile.TemporaryDirectory() as tmp:
        return ldraw.write(lay, [], steps, Path(tmp) / "a.mpd").read_text()


def test_writer_refuses_incomplete_or_repeated_steps():
    bricks = [Brick(0, "3024", (1, 1, 1), (0, 0, 0)), Brick(1, "3024", (1, 1, 1), (0, 0, 1))]
    lay = Layout(Grid(np.zeros(3), np.array([8.0, 8.0, 3.2]), np.ones((1, 1, 2), bool)), bricks)
    with pytest.raises(ValueError, match="no assembly step"):
        _write_text(lay, [[0]])
    with pytest.raises(ValueError, match="already"):
        _write_text(lay, [[0], [0, 1]])
    bricks[1].kind, bricks[1].printed_part = "printed", "P9"
    with pytest.raises(ValueError, match="P9"):
        _write_text(lay, [[0], [1]])


@pytest.mark.parametrize("text, message", [
    ("7 16 0 0 0", "unknown line type"),
    ("1 16 0 0 0 1 0 0 0 1 0 0 0 3001.dat", "needs 15 fields"),
    ("3 16 0 0 0 1 0 0 0 1", "needs 11 fields"),
    ("1 16 0 0 x 1 0 0 0 1 0 0 0 1 3001.dat", "not a number"),
    ("1 16 0 0 0 0 0 0 0 0 0 0 0 0 3001.dat", "singular"),
    ("3 16 0 0 0 1 0 0 0 1 nan", "not finite"),
    ("0 FILE a.ldr\n0 NOFILE\n3 16 0 0 0 1 0 0 0 1 0", "outside"),
    ("0 just a comment", "no content"),
])
def test_parser_names_the_bad_line(text, message):
    with pytest.raises(InputError, match=message):
        ldraw.parse(text)


def test_placed_bricks_rejects_what_a_layout_cannot_hold():
    base = "1 71 0 -24 0 {rot} {name}"
    with pytest.raises(InputError, match="not a catalog part"):
        ldraw.placed_bricks(ldraw.parse(base.format(rot="1 0 0 0 1 0 0 0 1", name="3040.dat")), (4, 2, 3))
    with pytest.raises(InputError, match="rotation"):
        ldraw.placed_bricks(ldraw.parse(base.format(rot="0.6 0 0.8 0 1 0 -0.8 0 0.6", name="3001.dat")), (4, 2, 3))
    with pytest.raises(InputError, match="stud grid"):
        ldraw.placed_bricks(ldraw.parse("1 71 5 -24 0 1 0 0 0 1 0 0 0 1 3001.dat"), (4, 2, 3))


def box_library(folder: Path) -> Path:
    """A minimal LDraw parts library: every catalog part as a plain box (LDraw convention)."""
    (folder / "parts").mkdir(parents=True)
    (folder / "p").mkdir()
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    for part in CATALOG:
        c = local_box(part.number)
        lines = [f"0 {part.name}", f"0 Name: {part.number}.dat", "0 Author: Fabrickator tests"]
        lines += ["4 16 " + " ".join(f"{v:g}" for i in f for v in c[i]) for f in faces]
        (folder / "parts" / f"{part.number}.dat").write_text("\r\n".join(lines) + "\r\n")
    return folder


def orange_pixels(path: Path) -> int:
    from PIL import Image
    a = np.asarray(Image.open(path).convert("RGB")).astype(int)
    return int(((a[..., 0] > 180) & (a[..., 1] > 60) & (a[..., 1] < 170) & (a[..., 2] < 90)).sum())


@pytest.mark.slow
def test_leocad_reads_steps_and_embedded_printed_parts(hmd, tmp_path):
    """LeoCAD (Debian leocad) renders the MPD step by step with a box parts library:
    nothing orange before the first printed part's step, orange from that step on."""
    leocad, xvfb = shutil.which("leocad"), shutil.which("xvfb-run")
    if leocad is None or xvfb is None:
        pytest.skip("leocad or xvfb-run not installed (apt-get install leocad xvfb)")
    _, order, path = hmd
    first = min(s.number for s in order.steps if s.printed_part)
    lib = box_library(tmp_path / "ldraw")
    run = subprocess.run([xvfb, "-a", leocad, "-l", str(lib), "-i", str(tmp_path / "s.png"),
                          "-w", "320", "-h", "240", "-f", str(first - 1), "-t", str(first),
                          "--viewpoint", "home", str(path)],
                         capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert run.returncode == 0, run.stderr[-2000:]
    before, at = (tmp_path / f"s{first - 1:02d}.png", tmp_path / f"s{first:02d}.png")
    assert before.is_file() and at.is_file(), sorted(p.name for p in tmp_path.iterdir())
    assert orange_pixels(before) == 0
    assert orange_pixels(at) > 200
    obj = tmp_path / "model.obj"
    run = subprocess.run([xvfb, "-a", leocad, "-l", str(lib), "-obj", str(obj), str(path)],
                         capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert run.returncode == 0, run.stderr[-2000:]
    v = np.array([line.split()[1:4] for line in obj.read_text().splitlines() if line.startswith("v ")],
                 dtype=float)
    # LeoCAD exports LDraw (x, y, z) as (x, z, -y): its boxes span exactly the LEGO bricks' cells
    grid = hmd[0].layout.grid
    shift = ldraw.centring_shift(grid.shape)
    lego_cells = np.zeros(grid.shape, bool)
    for b in hmd[0].layout.bricks:
        if b.kind == "lego":
            lego_cells[b.slices()] = True
    idx = np.argwhere(lego_cells)
    lo = np.array([20 * idx[:, 0].min() - shift[0], 20 * idx[:, 1].min() - shift[1], 8 * idx[:, 2].min()])
    hi = np.array([20 * (idx[:, 0].max() + 1) - shift[0], 20 * (idx[:, 1].max() + 1) - shift[1],
                   8 * (idx[:, 2].max() + 1)])
    assert np.allclose(v.min(axis=0), lo) and np.allclose(v.max(axis=0), hi)


def propped_tower(capped: bool) -> tuple[Layout, dict]:
    """A 2x4 brick (step 4) on a tower of a 2x2 brick and two 2x2 plates (steps 1-3), over
    air by two studs, with (``capped``) a 2x2 brick on top in step 5; and a prop 5 plates
    tall (a 1x1 brick on two 1x1 plates) under its stud (3, 0), stood before step 4 and
    taken away after it."""
    bricks = [Brick(0, "3003", (2, 2, 3), (0, 0, 0), step=1), Brick(1, "3022", (2, 2, 1), (0, 0, 3), step=2),
              Brick(2, "3022", (2, 2, 1), (0, 0, 4), step=3), Brick(3, "3001", (4, 2, 3), (0, 0, 5), step=4)]
    bricks += [Brick(4, "3003", (2, 2, 3), (0, 0, 8), step=5)] if capped else []
    filled = np.zeros((4, 2, 11 if capped else 8), dtype=bool)
    for b in bricks:
        filled[b.slices()] = True
    prop = {"step": 4, "cell": [3, 0, 5], "plates": 5, "parts": {"3005": 1, "3024": 2}, "under": 3,
            "removed_after": 4, "closed_in": False}
    return Layout(Grid(np.zeros(3), np.array([8.0, 8.0, 3.2]), filled), bricks), prop


def test_a_prop_is_in_its_step_stacked_from_the_table_and_leocad_hides_it_when_it_goes(tmp_path):
    """A 2x4 brick on a tower of a 2x2 brick and two 2x2 plates, over air by two studs: a
    prop 5 plates tall (a 1x1 brick on two 1x1 plates) under its stud (3, 0), stood before
    step 4 and taken away after it.  Its three parts are in step 4, plates at the bottom
    (plate layers 0 and 1, the brick 2..4), each after LeoCAD's ``STEP_HIDE 5``; the
    bricks round-trip as before."""
    lay, prop = propped_tower(capped=False)
    bricks, filled = lay.bricks, lay.grid.filled
    text = ldraw.write(lay, [], [[0], [1], [2], [3]], tmp_path / "a.mpd", props=[prop]).read_text()
    assert "0 // prop under brick 3: stand it before this step; take it away after step 4" in text
    assert text.count("0 !LEOCAD PIECE STEP_HIDE 5") == 3
    back = ldraw.placed_bricks(ldraw.parse(text), filled.shape)
    props = [d for d in back if d["step_hide"] is not None]
    assert [(d["part"], d["cell"], d["size"], d["step"], d["color"]) for d in props] == [
        ("3024", (3, 0, 0), (1, 1, 1), 4, ldraw.PROP_COLOR), ("3024", (3, 0, 1), (1, 1, 1), 4, ldraw.PROP_COLOR),
        ("3005", (3, 0, 2), (1, 1, 3), 4, ldraw.PROP_COLOR)]
    assert all(d["step_hide"] == 5 for d in props)
    assert sorted((d["part"], d["cell"], d["step"]) for d in back if d["step_hide"] is None) == \
        sorted((b.part, b.cell, b.step) for b in bricks)
    assert not any(filled[3, 0, :5])                   # the prop stands in air, under the brick


def test_the_bridge_built_on_props_has_them_in_the_mpd_until_it_is_closed(tmp_path):
    """The 80 cm bridge on a table (test_forces): each prop the build order stands is a 1x1
    brick on the table under its cell, in the step it is stood before, hidden in LeoCAD from
    the step after the bridge is closed (the last); the MPD lists the layout's bricks too."""
    from test_forces import built_without_and_with_props, long_bridge
    lay = long_bridge(12)
    _, order = built_without_and_with_props(lay, "table")
    assert order.props
    lay = build_order.numbered(lay, order)
    path = ldraw.write(lay, [], order.steps, tmp_path / "bridge.mpd", props=order.props)
    back = ldraw.placed_bricks(ldraw.parse(path), lay.grid.shape)
    props = sorted((d["cell"], d["step"], d["step_hide"]) for d in back if d["part"] == "3005")
    assert props == sorted(((p["cell"][0], p["cell"][1], 0), p["step"], len(order.steps) + 1)
                           for p in order.props)
    assert sorted((d["part"], d["cell"], d["step"]) for d in back if d["part"] != "3005") == \
        sorted((b.part, tuple(b.cell), b.step) for b in lay.bricks)


def test_leocad_shows_a_prop_in_its_step_and_hides_it_once_it_is_taken_away(tmp_path):
    """LeoCAD renders the tower of the prop test with one more brick on top (step 5): seen
    from the front, the corner under the arm's far end is the prop in step 4 and air in
    step 5, after the prop is taken away."""
    leocad, xvfb = shutil.which("leocad"), shutil.which("xvfb-run")
    if leocad is None or xvfb is None:
        pytest.skip("leocad or xvfb-run not installed (apt-get install leocad xvfb)")
    from PIL import Image
    lay, prop = propped_tower(capped=True)
    path = ldraw.write(lay, [], [[b.id] for b in lay.bricks], tmp_path / "a.mpd", props=[prop])
    run = subprocess.run([xvfb, "-a", leocad, "-l", str(box_library(tmp_path / "ldraw")), "-i",
                          str(tmp_path / "s.png"), "-w", "320", "-h", "240", "-f", "4", "-t", "5",
                          "--viewpoint", "front", str(path)], capture_output=True, text=True, timeout=120,
                         cwd=tmp_path)
    assert run.returncode == 0, run.stderr[-2000:]
    corner = []
    for step in (4, 5):
        alpha = np.asarray(Image.open(tmp_path / f"s{step:02d}.png").convert("RGBA"))[..., 3]
        h, w = alpha.shape
        corner.append(float((alpha[int(h * 0.85):, int(w * 0.72):int(w * 0.82)] > 0).mean()))
    assert corner == [1.0, 0.0]
