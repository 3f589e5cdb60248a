"""Hollowing big parts (core/hollow.py) and refusing parts too big for the machine.

Cell counts are counted by hand from the shell rule: a cell is interior when the
box of +-2 studs (x, y) and +-5 layers (z: 2 studs = 16 mm = 5 plates of 3.2 mm)
around it is filled; pillars are the interior cells of the columns (i, j) with
i mod 12 < 2 and j mod 12 < 2.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

from core import catalog, hollow, pipeline, stability
from core import report as reporting
from core.errors import InputError
from core.layout import greedy as layout_stage
from core.model import Grid
from core.request import request

ROOT = Path(__file__).resolve().parents[2]


def box_grid(nx: int, ny: int, nz: int) -> Grid:
    return Grid(np.zeros(3), np.array([8.0, 8.0, 3.2]), np.ones((nx, ny, nz), dtype=bool))


def test_shell_of_a_box_keeps_the_cells_counted_by_hand():
    # 30 x 28 x 40 cells; interior i 2..27 (26), j 2..25 (24), k 5..34 (30) = 18,720 cells
    # pillar columns: i in {12, 13, 24, 25} x j in {12, 13, 24, 25} = 16 columns x 30 layers
    grid = box_grid(30, 28, 40)
    out, pillars, kept_solid = hollow.hollow(grid, 2)
    assert pillars == 16 * 30 and kept_solid == 0
    assert out.count == 30 * 28 * 40 - 26 * 24 * 30 + 16 * 30
    f = out.filled
    assert f[0:2].all() and f[-2:].all() and f[:, 0:2].all() and f[:, -2:].all()
    assert f[:, :, 0:5].all() and f[:, :, -5:].all()
    assert not f[2, 2, 5] and not f[27, 25, 34] and f[12, 13, 20] and not f[14, 13, 20]
    assert grid.filled.all(), "the input grid is not changed"


def test_three_stud_shell_is_thicker():
    # 3 studs: 8 layers (24 mm / 3.2 = 7.5, rounded up); interior 24 x 22 x 24
    assert hollow.layers_for(3, (8.0, 8.0, 3.2)) == 8
    out, pillars, _ = hollow.hollow(box_grid(30, 28, 40), 3)
    # pillar columns: i in 3..26 -> {12, 13, 24, 25}; j in 3..24 -> {12, 13, 24}
    assert pillars == 4 * 3 * 24
    assert out.count == 30 * 28 * 40 - 24 * 22 * 24 + 4 * 3 * 24


def test_high_res_cells_stay_solid():
    grid = box_grid(30, 28, 40)
    keep = np.zeros(grid.shape, dtype=bool)
    keep[5:9, 5:8, 10:16] = True  # 4 x 3 x 6 = 72 interior cells, none in a pillar column
    out, _, kept_solid = hollow.hollow(grid, 2, keep)
    assert kept_solid == 72 and out.filled[keep].all()
    assert out.count == hollow.hollow(grid, 2)[0].count + 72


def test_automatic_setting_hollows_only_big_parts_that_save_a_third():
    small = hollow.decide(box_grid(20, 20, 40), -1)
    assert not small.on and small.kept_cells == 16_000 and "kept solid" in small.why
    big = hollow.decide(box_grid(40, 40, 60), -1)
    # interior 36 x 36 x 50 = 64,800; pillars: i, j in 2..37 -> {12, 13, 24, 25, 36, 37}
    assert big.on and big.studs == 2 and big.solid_cells == 96_000
    assert big.kept_cells == 96_000 - 64_800 + 36 * 50 and "hollowed automatically" in big.why
    solid = hollow.decide(box_grid(40, 40, 60), 0)
    assert not solid.on and solid.grid.count == 96_000
    with pytest.raises(InputError):
        hollow.decide(box_grid(2, 2, 2), -2)


def test_hollow_layout_is_connected_and_needs_fewer_bricks():
    grid = box_grid(18, 18, 24)
    kept, _, _ = hollow.hollow(grid, 2)
    # interior i, j 2..15, k 5..18: 14 x 14 x 14; pillars at i, j in {12, 13}: 4 columns
    assert kept.count == 18 * 18 * 24 - 14 * 14 * 14 + 4 * 14
    hollow_layout = layout_stage.lay_out(kept, catalog.CATALOG, seed=0)
    labels = hollow_layout.labels()
    assert ((labels >= 0) == kept.filled).all(), "the bricks cover exactly the kept cells"
    st = stability.analyse(hollow_layout)
    assert st.regions == 1 and st.components == st.regions
    solid_layout = layout_stage.lay_out(grid, catalog.CATALOG, seed=0)
    assert len(hollow_layout.bricks) < len(solid_layout.bricks)
    assert len(hollow_layout.bricks) >= -(-kept.count // 48), "no part covers more than 48 cells"


@pytest.fixture
def box_stl(tmp_path) -> Path:
    """A 160 x 160 x 64 mm box: 20 x 20 x 20 cells."""
    path = tmp_path / "box.stl"
    trimesh.creation.box((160.0, 160.0, 64.0)).export(path)
    return path


@pytest.mark.slow
def test_pipeline_hollows_on_request_and_reports_it(box_stl):
    # interior 16 x 16 x 10 = 2,560; pillars: i, j in 2..17 -> {12, 13}: 4 columns x 10
    fab = pipeline.run(box_stl, slice_parts=False, hollow=2)
    assert fab.grid.count == 8000 - 2560 + 40
    assert fab.stability.components == fab.stability.regions == 1
    doc = reporting.document(fab)
    h = doc["hollow"]
    assert h["on"] and h["setting"] == 2 and h["cells_solid"] == 8000 and h["cells_kept"] == 5480
    assert h["bricks"]["built"] == doc["bricks"]["lego"]
    # the solid part (8,000 cells) is laid out too, by the driver's fast layout
    solid_grid = pipeline.run(box_stl, slice_parts=False, hollow=0, effort="fast").grid
    fast = len(layout_stage.lay_out(solid_grid, catalog.select(None), seed=0).bricks)
    assert h["bricks"]["solid"] == h["laid_out_both"]["solid_bricks"] == fast > -(-8000 // 48)
    assert h["solid_layout"] == "fast" and "solid_at_least" not in h["bricks"]
    assert h["assembly_s"]["solid"] == round(fast * fab.seconds_per_brick, 1)
    assert f"solid, {fast:,} bricks (fast layout, not improved)" in h["compare"]
    assert "timings_s" in doc and "hollow" in doc["timings_s"] and "layout_solid" in doc["timings_s"]
    default = pipeline.run(box_stl, slice_parts=False)
    assert default.grid.count == 8000 and not default.hollowing.on


@pytest.mark.slow
def test_a_solid_part_beyond_the_limit_is_reported_as_a_lower_bound(box_stl, monkeypatch):
    monkeypatch.setattr(hollow, "SOLID_LAYOUT_MAX_CELLS", 5000)
    fab = pipeline.run(box_stl, slice_parts=False, hollow=2, effort="fast")
    doc = reporting.document(fab)
    h = doc["hollow"]
    assert h["bricks"]["solid_at_least"] == -(-8000 // 48) and "solid" not in h["bricks"]
    assert h["solid_layout"] == "none" and "laid_out_both" not in h
    assert "layout_solid" not in doc["timings_s"]
    assert (f"solid at least {-(-8000 // 48):,} bricks" in h["compare"]
            and "a lower bound: its 8,000 cells are more than the 5,000 laid out solid" in h["compare"])


def test_the_solid_part_is_laid_out_when_the_choice_needs_it_or_it_is_affordable(monkeypatch):
    grid = box_grid(40, 40, 60)                      # 96,000 cells: at least 2,000 bricks
    auto, asked = hollow.decide(grid, -1), hollow.decide(grid, 2)
    assert not hollow.solid_layout_wanted(hollow.decide(grid, 0), 10, 48)
    assert hollow.solid_layout_wanted(auto, 1000, 48) and hollow.solid_layout_wanted(asked, 1000, 48)
    monkeypatch.setattr(hollow, "SOLID_LAYOUT_MAX_CELLS", 50_000)
    assert not hollow.solid_layout_wanted(asked, 1000, 48)
    assert not hollow.solid_layout_wanted(auto, 1333, 48), "surely saves: no need to lay out"
    assert hollow.solid_layout_wanted(auto, 1334, 48), "only the solid layout can tell"
    kept = hollow.compared(asked, grid, 1900, 1600)
    assert kept.on and kept.why == asked.why, "a shell asked for stays, even with more bricks"
    assert (kept.bricks_hollow, kept.bricks_solid) == (1900, 1600)


def test_request_and_command_line_take_hollow(box_stl):
    assert request(str(box_stl)).hollow == -1
    for bad in (-2, 65, 1.5, True):
        with pytest.raises(InputError):
            request(str(box_stl), hollow=bad)
    import argparse

    from core import request as request_mod
    parser = argparse.ArgumentParser()
    request_mod.add_options(parser, ("hollow",))
    assert parser.parse_args([]).hollow == -1
    assert parser.parse_args(["--hollow"]).hollow == 2
    assert parser.parse_args(["--hollow=3"]).hollow == 3


#: Runs the CLI with the address space limited to 3 GB: a grid of the part's size
#: would need far more, so a refusal proves nothing was allocated first.
LIMITED = """
import resource, sys
resource.setrlimit(resource.RLIMIT_AS, (3 << 30, 3 << 30))
from core import cli
sys.exit(cli.main(sys.argv[1:]))
"""


@pytest.mark.slow
@pytest.mark.parametrize("case", ["cube_10m", "mm_file_in_m", "two_cubes_1km_apart"])
def test_too_big_is_refused_in_one_line_before_allocating(tmp_path, case):
    model = tmp_path / f"{case}.stl"
    units = []
    if case == "cube_10m":
        trimesh.creation.box((10_000.0,) * 3).export(model)
        expect = "try --scale 0.1"
    elif case == "mm_file_in_m":
        trimesh.creation.box((120.0, 80.0, 50.0)).export(model)
        units = ["--units", "m"]
        expect = "is it in millimetres? try --units mm"
    else:
        a = trimesh.creation.box((1000.0,) * 3)
        b = a.copy()
        b.apply_translation((1e6, 0, 0))
        trimesh.util.concatenate([a, b]).export(model)
        expect = "remove the stray pieces"
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-c", LIMITED, "fabricate", str(model), *units,
                           "--out", str(out), "--quiet"], cwd=ROOT, capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and "cells" in lines[0], lines
    assert expect in lines[0]
    assert not out.exists()


def test_too_many_filled_cells_to_lay_out_is_refused(monkeypatch, box_stl):
    from core import voxelize
    monkeypatch.setattr(voxelize, "MAX_LAYOUT_CELLS", 5000)
    with pytest.raises(InputError, match="fills at least 8,000 cells.*hollow"):
        pipeline.run(box_stl, slice_parts=False, hollow=0)
    with pytest.raises(InputError, match="fills 8,000 cells"):
        voxelize.check_cells(8000, 0)


def test_automatic_hollowing_needs_a_third_fewer_bricks():
    grid = box_grid(40, 40, 60)
    proposed = hollow.decide(grid, -1)
    # 96,000 cells: a solid layout needs at least 2,000 bricks of at most 48 cells
    assert hollow.surely_saves(proposed, 1333, 48) and not hollow.surely_saves(proposed, 1334, 48)
    kept = hollow.compared(proposed, grid, 1000, 1600)
    assert kept.on and kept.bricks_solid == 1600 and "1,000 instead of 1,600 solid" in kept.why
    sure = hollow.judged(proposed, 1333, 48)
    assert sure.on and "at least 2,000:" in sure.why and hollow.judged(proposed, 1334, 48) is None
    declined = hollow.compared(proposed, grid, 1100, 1600)
    assert not declined.on and declined.grid is grid and declined.kept_cells == 96_000
    assert declined.to_json()["laid_out_both"] == {"hollow_bricks": 1100, "solid_bricks": 1600}


@pytest.mark.slow
def test_the_layout_stage_reports_progress_through_the_pipeline(box_stl):
    heard = []
    pipeline.run(box_stl, slice_parts=False, progress=lambda f, m: heard.append((f, m)))
    names = [m for _, m in heard]
    assert names[:3] == ["load", "legofy", "hollow"]
    inside = [(f, m) for f, m in heard if m.startswith("layout: ")]
    assert inside and all(0.4 <= f <= 0.6 for f, _ in inside)
    assert any("merging plates" in m for _, m in inside)
    assert names.index("layout") < names.index(inside[0][1]) < names.index("stability")


@pytest.mark.slow
def test_a_new_version_of_a_hollowed_part_is_hollowed_as_before(box_stl, tmp_path):
    """Iterating on a hollowed output hollows the new version with the same shell and the
    same pillar lattice, so only the cells near the edit change.  By hand: a notch of
    2 x 2 cells x 5 layers cut from a top corner of the 20 x 20 x 20-cell box takes 20
    cells, and the 20 interior cells within 2 studs and 5 layers of it (i, j 16..17,
    k 10..14; no pillar there) join the shell: 5,480 cells kept, as before the edit."""
    from core import result
    fab = pipeline.run(box_stl, slice_parts=False, hollow=2)
    result.snapshot(fab, tmp_path / "previous")
    notch = trimesh.creation.box((16.0, 16.0, 16.0))
    notch.apply_translation((72.0, 72.0, 24.0))
    notched = trimesh.boolean.difference([trimesh.creation.box((160.0, 160.0, 64.0)), notch],
                                         engine="manifold")
    path = tmp_path / "notched.stl"
    notched.export(path)
    again = pipeline.run(path, previous=tmp_path / "previous", slice_parts=False)
    assert again.iteration is not None
    assert again.hollowing.on and again.hollowing.studs == 2
    assert "as the previous version" in again.hollowing.why
    assert again.grid.count == 5480
    h = reporting.document(again)["hollow"]
    assert h["solid_layout"] == "none" and h["bricks"]["solid_at_least"] == -(-7980 // 48)
    assert "a lower bound: a new version is laid out only where it changed" in h["compare"]
    diff = again.iteration.diff
    assert int(np.count_nonzero(diff.added)) == 20 and len(diff.removed) == 20
    solid = pipeline.run(path, previous=tmp_path / "previous", slice_parts=False, hollow=0)
    assert solid.grid.count == 8000 - 20 and not solid.hollowing.on
