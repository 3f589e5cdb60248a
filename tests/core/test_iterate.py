"""Design iteration end to end: snapshot, align, diff, keep the layout, reprint what changed."""

from __future__ import annotations

import importlib.util
import json
import types
from pathlib import Path

import cadquery as cq
import manifold3d as m3
import numpy as np
import pytest
import trimesh
from cadquery import exporters
from scipy.spatial.transform import Rotation

from core import align, high_res, iterate, pipeline, result
from core import report as reporting
from core.errors import InputError
from core.instructions import changes_page
from core.printing import export

ROOT = Path(__file__).resolve().parents[2]
MODELS = ROOT.parent / "shared" / "models"
#: The lens mounts of examples/hmd.py (the demo's high-res boxes, model mm).
LENS_MOUNTS = ["-54,25,25.5,-9,36,70.5", "9,25,25.5,54,36,70.5"]
#: The forehead of examples/hmd.py: the top of the shell at the face side.
FOREHEAD = "-40,0,75,40,12,90"


def _model(name: str) -> Path:
    path = MODELS / name
    if not path.exists():
        pytest.skip(f"{path} not found: the shared test models are not next to the repository")
    return path


def _hmd():
    spec = importlib.util.spec_from_file_location("fabrickator_example_hmd", ROOT / "examples" / "hmd.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _motion(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    axis = rng.normal(size=3)
    out = np.eye(4)
    out[:3, :3] = Rotation.from_rotvec(np.radians(rng.uniform(10, 170)) * axis / np.linalg.norm(axis)).as_matrix()
    out[:3, 3] = rng.uniform(-60, 60, 3)
    return out


def _manifold(mesh: trimesh.Trimesh) -> m3.Manifold:
    return m3.Manifold(m3.Mesh64(vert_properties=np.ascontiguousarray(mesh.vertices, np.float64),
                                 tri_verts=np.ascontiguousarray(mesh.faces, np.uint64)))


def _mesh(solid: m3.Manifold) -> trimesh.Trimesh:
    out = solid.to_mesh64()
    return trimesh.Trimesh(np.asarray(out.vert_properties)[:, :3], np.asarray(out.tri_verts))


def _previous(fab, folder: Path) -> result.Previous:
    result.snapshot(fab, folder)
    return result.load_previous(folder)


def _view(fab) -> types.SimpleNamespace:
    """An iteration's run as the tests read it: the Fabrication and its iteration's parts."""
    it = fab.iteration
    return types.SimpleNamespace(fab=fab, changes=it.changes, diff=it.diff, previous=it.previous,
                                 layout=fab.layout, grid=fab.grid, printed=fab.printed,
                                 model=fab.model, stability=fab.stability)


def _iterate(previous: result.Previous, path: Path, **settings) -> types.SimpleNamespace:
    """The driver's run of the model file ``path`` as an iteration on ``previous``."""
    return _view(pipeline.run(path, previous=previous.folder, slice_parts=False, **settings))


def _page(it, path: Path) -> str:
    return changes_page.changes_page(it.changes, it.layout, path, "test").read_text()


def _save(workplane: cq.Workplane, path: Path) -> Path:
    kind = "STEP" if path.suffix == ".step" else "STL"
    exporters.export(workplane.val(), str(path), exportType=kind,
                     **({} if kind == "STEP" else {"tolerance": 0.05, "angularTolerance": 0.1}))
    return path


def _covers_exactly(it: iterate.Iteration) -> None:
    lab = np.full(it.grid.shape, -1)
    for b in it.layout.bricks:
        assert (lab[b.slices()] == -1).all(), "two bricks on one cell"
        lab[b.slices()] = b.id
    assert np.array_equal(lab >= 0, it.grid.filled)
    ids = [b.id for b in it.layout.bricks]
    assert len(set(ids)) == len(ids)


def _cells_of(b) -> set[tuple[int, int, int]]:
    return {tuple(int(v) for v in np.array(b.cell) + c) for c in np.ndindex(*b.size)}


def _near_edit(it: iterate.Iteration, box_mm) -> None:
    """Every brick taken off or added lies within one brick of the edited box: its
    cells are in the box's cells grown by one cell, or belong to a previous brick
    (or printed part) that meets those."""
    grid = it.grid
    box = np.asarray(box_mm, dtype=float)
    lo = np.floor((box[0] - grid.origin) / grid.cell).astype(int) - 1
    hi = np.ceil((box[1] - grid.origin) / grid.cell).astype(int) + 1
    edit = {c for c in np.ndindex(*(hi - lo))}
    edit = {tuple(int(v) for v in np.array(c) + lo) for c in edit}
    offset = it.diff.offset
    allowed = set(edit)
    part_cells: dict[str, set] = {}
    for b in it.previous.layout.bricks:
        shifted = type(b)(b.id, b.part, b.size, tuple(np.array(b.cell) - offset), b.kind, b.printed_part)
        cells = _cells_of(shifted)
        if b.printed_part:
            part_cells.setdefault(b.printed_part, set()).update(cells)
        if cells & edit:
            allowed |= cells
    for cells in part_cells.values():
        if cells & allowed:
            allowed |= cells
    for e in it.changes["take_off"] + it.changes["add"]:
        cells = {tuple(int(v) for v in np.array(e["cell"]) + c) for c in np.ndindex(*e["size"])}
        assert cells <= allowed, f"brick {e['id']} ({e['part']}) at {e['cell']} is far from the edit"


# --------------------------------------------------------------------------- OpenBot (mesh)


@pytest.fixture(scope="module")
def openbot(tmp_path_factory):
    fab = pipeline.run(_model("openbot_body_bottom.stl"), slice_parts=False)
    return fab, _previous(fab, tmp_path_factory.mktemp("openbot"))


@pytest.mark.slow
def test_moved_openbot_keeps_the_whole_layout(openbot, tmp_path):
    fab, previous = openbot
    path = tmp_path / "moved.stl"
    align.transform_mesh(fab.model.mesh, _motion(4)).export(path)
    it = _iterate(previous, path)
    ch = it.changes
    assert ch["transform"]["confident"] and ch["transform"]["method"] == "planar sides"
    assert ch["cells_added"] == ch["cells_removed"] == 0
    assert ch["bricks_changed"] == ch["bricks_removed"] == 0
    assert ch["bricks_kept"] == len(fab.layout.bricks)
    before = {(b.id, b.part, b.size, b.cell) for b in fab.layout.bricks}
    off = it.diff.offset
    after = {(b.id, b.part, b.size, tuple(int(v) for v in np.array(b.cell) + off)) for b in it.layout.bricks}
    assert before == after
    assert np.allclose(it.model.mesh.bounds, fab.model.mesh.bounds, atol=1e-3)
    page = _page(it, tmp_path / "changes.html")
    assert "no LEGO bricks to take off" in page and "no layer changes" in page


@pytest.mark.slow
def test_openbot_boss_changes_only_bricks_near_it(openbot, tmp_path):
    fab, previous = openbot
    boss = trimesh.creation.cylinder(radius=5, height=14, sections=48)
    boss.apply_translation([20, 10, 9])
    edited = _mesh(_manifold(fab.model.mesh) + _manifold(boss))
    path = tmp_path / "boss.stl"
    align.transform_mesh(edited, _motion(8)).export(path)
    it = _iterate(previous, path)
    ch = it.changes
    assert ch["transform"]["confident"]
    assert ch["cells_added"] > 0 and ch["cells_removed"] == 0
    assert 0 < ch["bricks_changed"] <= 12
    assert ch["bricks_kept"] + ch["bricks_removed"] == len(fab.layout.bricks)
    _covers_exactly(it)
    _near_edit(it, [[15, 5, 2], [25, 15, 16]])
    assert it.stability.components - it.stability.regions <= previous.extra_components


@pytest.mark.slow
def test_openbot_hole_cut_through_the_floor(openbot, tmp_path):
    fab, previous = openbot
    cutter = trimesh.creation.box(bounds=[[-30, -20, -1], [-6, 4, 6]])
    edited = _mesh(_manifold(fab.model.mesh) - _manifold(cutter))
    path = tmp_path / "hole.stl"
    edited.export(path)
    it = _iterate(previous, path)
    ch = it.changes
    assert ch["transform"]["method"] == "identity"
    assert ch["cells_removed"] > 0 and ch["cells_added"] == 0
    assert ch["bricks_removed"] > 0 and ch["bricks_kept"] > 0.8 * len(fab.layout.bricks)
    _covers_exactly(it)
    _near_edit(it, [[-30, -20, -1], [-6, 4, 6]])
    removed = {e["id"] for e in ch["take_off"]}
    kept_ids = {b.id for b in it.layout.bricks}
    assert not removed & kept_ids
    assert min(b.id for b in it.layout.bricks if b.id not in {x.id for x in fab.layout.bricks}) > max(
        x.id for x in fab.layout.bricks)


# --------------------------------------------------------------------------- OpenBot (B-rep, anchor tabs)

#: A screw seat of the OpenBot chassis: a boss standing on the floor through
#: every layer, so its cells touch LEGO only sideways (model mm).
SCREW_SEAT = "-95,-42,0,-81,-28,29.5"


@pytest.fixture(scope="module")
def openbot_step(tmp_path_factory):
    """The OpenBot chassis STEP, fabricated without marks, as a previous output folder."""
    path = _model("openbot_body_bottom.step")
    folder = tmp_path_factory.mktemp("openbot_step")
    fab = pipeline.run(path, slice_parts=False)
    assert not fab.printed
    result.snapshot(fab, folder)
    return path, fab, folder


def _printed_cells(layout) -> set[tuple[int, int, int]]:
    return {c for b in layout.bricks if b.kind == "printed" for c in _cells_of(b)}


def _clamps_vertically(layout) -> bool:
    """Some printed cell has a LEGO cell directly above or below it."""
    lego = {c for b in layout.bricks if b.kind == "lego" for c in _cells_of(b)}
    return any((i, j, k + d) in lego for i, j, k in _printed_cells(layout) for d in (-1, 1))


@pytest.mark.slow
def test_screw_seat_marked_later_gets_anchor_tabs_as_in_a_fresh_run(openbot_step, tmp_path):
    """A region marked in an iteration that touches LEGO only sideways gets anchor
    tabs like a fresh run's (core.high_res.anchor), so its printed part clamps;
    without connectors no tabs are added and the part stays loose."""
    path, base, folder = openbot_step
    fresh = reporting.document(pipeline.run(path, high_res=[SCREW_SEAT], slice_parts=False))
    assert fresh["high_res"]["anchor_cells"] > 0
    assert fresh["stability"]["components"] == fresh["stability"]["regions"]

    fab = pipeline.run(path, high_res=[SCREW_SEAT], previous=folder, slice_parts=False)
    doc = reporting.document(fab)
    it = _view(fab)
    assert it.changes["transform"]["method"] == "identity"
    assert it.changes["cells_added"] == it.changes["cells_removed"] == 0
    assert it.changes["parts_reprinted"] == ["P1"] and [p.id for p in it.printed] == ["P1"]
    marks = doc["high_res"]
    assert marks["marked_cells"] > 0 and 0 < marks["anchor_cells"] <= 4
    seat = {tuple(c) for c in np.argwhere(high_res.marked_cells(it.grid, [SCREW_SEAT]))}
    tabs = _printed_cells(it.layout) - seat
    assert len(tabs) == marks["anchor_cells"]
    assert _clamps_vertically(it.layout)
    assert doc["stability"]["components"] == doc["stability"]["regions"] == fresh["stability"]["regions"]
    _covers_exactly(it)
    _near_edit(it, high_res.parse_box(SCREW_SEAT))

    loose = pipeline.run(path, high_res=[SCREW_SEAT], previous=folder, slice_parts=False,
                         connectors=False)
    doc = reporting.document(loose)
    assert doc["high_res"] == {"marked_cells": marks["marked_cells"], "anchor_cells": 0}
    assert _printed_cells(loose.layout) == seat
    assert not _clamps_vertically(loose.layout)
    assert doc["stability"]["components"] > doc["stability"]["regions"]


@pytest.mark.slow
def test_printed_parts_are_kept_when_nothing_new_is_marked(openbot_step, tmp_path):
    """Anchor tabs only matter where the marks change: iterating again, with no
    new marks, adds no tabs and keeps every brick, both on the anchored version
    and on one whose part was made loose without connectors."""
    path, base, folder = openbot_step
    for connectors in (True, False):
        first = pipeline.run(path, high_res=[SCREW_SEAT], previous=folder, slice_parts=False,
                             connectors=connectors)
        assert (first.marks["anchor_cells"] > 0) == connectors
        second_folder = tmp_path / f"first_{connectors}"
        result.snapshot(first, second_folder)
        again = pipeline.run(path, previous=second_folder, slice_parts=False, connectors=connectors)
        ch = again.iteration.changes
        assert again.marks == first.marks
        assert ch["bricks_changed"] == ch["bricks_removed"] == 0
        assert ch["bricks_kept"] == len(first.layout.bricks)
        assert ch["parts_kept"] == ["P1"] and ch["parts_reprinted"] == []
        assert again.stability.components == first.stability.components


# --------------------------------------------------------------------------- HMD (B-rep, printed parts)


@pytest.fixture(scope="module")
def hmd_step(tmp_path_factory):
    hmd = _hmd()
    folder = tmp_path_factory.mktemp("hmd")
    path = _save(hmd.build_hmd(), folder / "hmd.step")
    fab = pipeline.run(path, high_res=LENS_MOUNTS, slice_parts=False)
    assert [p.id for p in fab.printed] == ["P1", "P2"]
    return hmd, fab, _previous(fab, folder / "out")


@pytest.mark.slow
def test_snapshot_round_trip(hmd_step):
    _, fab, previous = hmd_step
    assert previous.grid.shape == fab.grid.shape and np.array_equal(previous.grid.filled, fab.grid.filled)
    assert [b.to_json() for b in previous.layout.bricks] == [b.to_json() for b in fab.layout.bricks]
    assert previous.brep is not None and len(previous.mesh.faces) == len(fab.model.mesh.faces)
    for p in fab.printed:
        q = previous.parts[p.id]
        assert q.bricks == p.bricks and q.top_ok == p.top_ok and q.bottom_ok == p.bottom_ok
        assert q.studs == p.studs and np.isclose(q.mesh.volume, p.mesh.volume)
        as_json = [json.loads(json.dumps(result._part_record(x))) for x in (p, q)]
        assert as_json[0] == as_json[1]


@pytest.mark.slow
def test_hmd_boss_keeps_both_printed_lens_mounts(hmd_step, tmp_path):
    hmd, fab, previous = hmd_step
    body = hmd.build_hmd().union(
        cq.Workplane("XY", origin=(40, 55, hmd.BODY_HEIGHT - 1)).circle(6).extrude(11))
    it = _iterate(previous, _save(body, tmp_path / "boss.step"))
    ch = it.changes
    assert ch["cells_added"] > 0 and ch["cells_removed"] == 0
    assert ch["parts_reprinted"] == [] and ch["parts_kept"] == ["P1", "P2"]
    _covers_exactly(it)
    _near_edit(it, [[34, 49, hmd.BODY_HEIGHT - 1], [46, 61, hmd.BODY_HEIGHT + 10]])
    assert {p.id for p in it.printed} == {"P1", "P2"}
    assert all(b.kind == "printed" for b in it.layout.bricks if b.printed_part)


@pytest.mark.slow
def test_hmd_widened_bore_reprints_only_that_mount(hmd_step, tmp_path):
    hmd, fab, previous = hmd_step
    cx, cz = hmd.IPD / 2, hmd.LENS_CENTRE_Z
    wider = hmd.build_hmd().cut(cq.Workplane("XZ", origin=(0, hmd.LENS_PLATE_Y + 5, 0))
                                .center(cx, cz).circle(hmd.LENS_DIAMETER / 2 + 1.0).extrude(15))
    moved = align.transform_brep(wider.val().wrapped, _motion(21))
    path = tmp_path / "wider.step"
    export.write_step(moved, path)
    it = _iterate(previous, path)
    ch = it.changes
    assert ch["transform"]["confident"] and ch["transform"]["residual_mm"] < 0.1
    assert ch["parts_reprinted"] == ["P2"] and "P1" in ch["parts_kept"]
    record = {r["id"]: r for r in ch["reprint"]}
    assert record["P2"]["symmetric_difference_mm3"] > record["P2"]["threshold_mm3"]
    assert record["P2"]["replaces"] == "P2" and ch["parts_out"] == ["P2"]
    if record["P1"]["symmetric_difference_mm3"]:
        assert record["P1"]["symmetric_difference_mm3"] <= record["P1"]["threshold_mm3"]
    _covers_exactly(it)
    r = hmd.LENS_DIAMETER / 2 + 1.0
    _near_edit(it, [[cx - r, hmd.LENS_PLATE_Y + 5 - 15, cz - r], [cx + r, hmd.LENS_PLATE_Y + 5, cz + r]])
    new_p2 = next(p for p in it.printed if p.id == "P2")
    old_p2 = previous.parts["P2"]
    assert new_p2.volume_mm3 < old_p2.volume_mm3 - 100
    page = _page(it, tmp_path / "changes.html")
    assert "Take out printed part(s): <b>P2</b>" in page and "Insert printed part <b>P2</b>" in page


def _box_overlaps(lo, hi, box) -> bool:
    return all(lo[n] < box[1][n] - 1e-6 and box[0][n] < hi[n] - 1e-6 for n in range(3))


@pytest.mark.slow
def test_high_res_later_then_forehead_lengthened(hmd_step, tmp_path):
    """Switching LEGO bricks to a printed forehead piece is an iteration (the paper's
    example): only the new part is printed, in place of LEGO bricks.  Then a visor
    lengthens the forehead towards the face, beyond the marked box: the grid grows,
    and as in a fresh run with the same boxes the visor's cells outside every box
    are LEGO; the printed parts stay where the boxes are."""
    hmd, fab, previous = hmd_step
    first = _iterate(previous, _save(hmd.build_hmd(), tmp_path / "same.step"), high_res=[FOREHEAD])
    ch = first.changes
    assert ch["cells_added"] == ch["cells_removed"] == 0
    assert ch["parts_reprinted"] == ["P3"] and ch["parts_kept"] == ["P1", "P2"]
    (inserted,) = ch["parts_in"]
    assert inserted["replaces_part"] is None and inserted["replaces_bricks"]
    assert set(inserted["replaces_bricks"]) <= {e["id"] for e in ch["take_off"]}
    assert all(e["kind"] == "lego" for e in ch["take_off"])
    assert ch["bricks_removed"] < 0.2 * len(fab.layout.bricks)
    _covers_exactly(first)

    second_prev = _previous(first.fab, tmp_path / "first")
    assert set(second_prev.parts) == {"P1", "P2", "P3"}
    visor = hmd.build_hmd().union(cq.Workplane("XY").box(60, 10, 6, centered=(True, False, False))
                                  .translate((0, -9.5, hmd.BODY_HEIGHT - 6)))
    second = _iterate(second_prev, _save(visor, tmp_path / "visor.step"))
    ch = second.changes
    assert ch["cells_added"] > 0 and ch["grid_offset"][1] < 0
    assert set(ch["parts_kept"]) >= {"P1", "P2"} and {p.id for p in second.printed} == {"P1", "P2", "P3"}
    boxes = [high_res.parse_box(b) for b in LENS_MOUNTS + [FOREHEAD]]
    grid = second.grid
    printed = _printed_cells(second.layout)
    for c in printed:
        lo = grid.origin + np.array(c) * grid.cell
        near = [lo - grid.cell, lo + 2 * grid.cell]
        assert any(_box_overlaps(*near, box) for box in boxes), f"printed cell {c} is far from every box"
    added = {tuple(int(v) for v in c) for c in np.argwhere(second.diff.added)}
    outside = {c for c in added
               if not any(_box_overlaps(grid.origin + np.array(c) * grid.cell,
                                        grid.origin + (np.array(c) + 1) * grid.cell, box) for box in boxes)}
    assert outside and len(outside & printed) <= second.fab.marks["anchor_cells"], \
        "the visor outside the boxes must be LEGO, but for the anchor tabs"
    _covers_exactly(second)


# --------------------------------------------------------------------------- HMD (mesh printed part)


@pytest.mark.slow
def test_mesh_printed_part_reprinted_only_when_its_geometry_changes(tmp_path):
    hmd = _hmd()
    base = _save(hmd.build_hmd(), tmp_path / "hmd.stl")
    fab = pipeline.run(base, high_res=LENS_MOUNTS[1:], slice_parts=False)
    previous = _previous(fab, tmp_path / "out")
    boss = hmd.build_hmd().union(cq.Workplane("XY", origin=(-40, 55, hmd.BODY_HEIGHT - 1)).circle(6).extrude(11))
    it = _iterate(previous, _save(boss, tmp_path / "boss.stl"))
    assert it.changes["parts_reprinted"] == [] and it.changes["parts_kept"] == ["P1"]
    cx, cz = hmd.IPD / 2, hmd.LENS_CENTRE_Z
    wider = hmd.build_hmd().cut(cq.Workplane("XZ", origin=(0, hmd.LENS_PLATE_Y + 5, 0))
                                .center(cx, cz).circle(hmd.LENS_DIAMETER / 2 + 1.0).extrude(15))
    it = _iterate(previous, _save(wider, tmp_path / "wider.stl"))
    assert it.changes["parts_reprinted"] == ["P1"]
    (record,) = it.changes["reprint"]
    assert record["symmetric_difference_mm3"] > 100


# --------------------------------------------------------------------------- errors


def test_previous_folder_must_hold_a_snapshot(tmp_path):
    with pytest.raises(InputError, match="no such folder"):
        result.load_previous(tmp_path / "missing")
    (tmp_path / "report.json").write_text("{}")
    with pytest.raises(InputError, match="iteration snapshot"):
        result.load_previous(tmp_path)
    (tmp_path / "iteration").mkdir()
    (tmp_path / "iteration" / "state.json").write_text(json.dumps({"version": 1}))
    with pytest.raises(InputError, match="cannot be read"):
        result.load_previous(tmp_path)
