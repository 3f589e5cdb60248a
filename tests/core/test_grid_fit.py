"""Tests of core.grid_fit: the grid shifted so that high-res regions print the least."""

from pathlib import Path

import numpy as np
import pytest
import trimesh

from core import grid_fit, high_res, pipeline, voxelize
from core import report as reporting
from core.errors import InputError

ROOT = Path(__file__).resolve().parents[2]
MODELS = ROOT.parent / "shared" / "models"
#: The two lens bores of vr_phone_headset.stl (bench/bench_printed.py).
VR_LENS_BORES = ["9,-1,14,57,15,62", "84,-1,13,132,15,61"]
#: A "lens plate" 12 mm deep (y 6..18) through a 100 x 40 x 32 mm block.
PLATE = np.array([[0.0, 6.0, 0.0], [100.0, 18.0, 32.0]])


def _block() -> trimesh.Trimesh:
    return trimesh.creation.box(bounds=[[0.0, 0.0, 0.0], [100.0, 40.0, 32.0]])


def test_centred_grid_cuts_the_plate_in_three_fitted_in_two():
    block = _block()
    fit = grid_fit.fit(block, [PLATE])
    # centred: y boundaries 0, 8, 16, 24 -> the plate touches three cell rows;
    # a shift of 2..6 mm puts a boundary at or below y 6 and one at or above 18.
    assert -6.0 <= fit.shift_mm[1] <= -2.0
    assert fit.fitted_mm3 == pytest.approx(fit.centred_mm3 * 2 / 3, rel=1e-6)
    assert fit.centred_mm3 == pytest.approx(100 * 24 * 32, rel=0.02)
    grid = voxelize.legofy(block, origin=fit.origin, shape=fit.shape)
    rows = np.nonzero(high_res.marked_cells(grid, [PLATE]).any(axis=(0, 2)))[0]
    assert len(rows) == 2
    assert np.all(grid.origin <= block.bounds[0] + 1e-9)
    assert np.all(grid.origin + np.array(fit.shape) * grid.cell >= block.bounds[1] - 1e-9)


def test_no_region_or_nothing_to_gain_keeps_the_centred_frame():
    block = _block()
    centred_origin, centred_shape = voxelize.grid_frame(block.bounds)
    for boxes in ([], [[[0.0, 0.0, 0.0], [100.0, 40.0, 32.0]]]):
        fit = grid_fit.fit(block, boxes)
        assert fit.shift_mm == (0.0, 0.0)
        assert np.allclose(fit.origin, centred_origin) and fit.shape == centred_shape


@pytest.mark.slow
def test_region_solid_fits_like_the_same_box(tmp_path):
    solid = tmp_path / "plate.stl"
    trimesh.creation.box(bounds=PLATE).export(solid)
    by_box = grid_fit.fit(_block(), [PLATE])
    by_solid = grid_fit.fit(_block(), solids=[solid])
    assert -6.0 <= by_solid.shift_mm[1] <= -2.0
    assert by_solid.fitted_mm3 == pytest.approx(by_box.fitted_mm3, rel=0.05)
    with pytest.raises(InputError):
        grid_fit.fit(_block(), solids=[tmp_path / "missing.stl"])


@pytest.mark.slow
def test_pipeline_prints_less_with_the_fitted_grid(tmp_path):
    path = tmp_path / "block.stl"
    _block().export(path)
    box = ",".join(str(v) for v in PLATE.ravel())
    fitted = pipeline.run(path, high_res=[box], slice_parts=False)
    centred = pipeline.run(path, high_res=[box], slice_parts=False, fit_grid=False)
    volume = [sum(p.volume_mm3 for p in fab.printed) for fab in (fitted, centred)]
    assert volume[0] < 0.75 * volume[1]
    assert fitted.fit.shift_mm != (0.0, 0.0) and centred.fit is None
    doc = reporting.document(fitted)
    assert doc["grid"]["fit"]["shift_mm"] == list(fitted.fit.shift_mm)
    assert "shifted" in doc["grid"]["alignment"]
    covered = sum(int(np.prod(b.size)) for b in fitted.layout.bricks)
    assert covered == fitted.grid.count


@pytest.mark.slow
def test_vr_headset_lens_bores_print_less():
    path = MODELS / "vr_phone_headset.stl"
    if not path.exists():
        pytest.skip(f"{path} not found: the shared test models are not next to the repository")
    fitted = pipeline.run(path, high_res=VR_LENS_BORES, slice_parts=False)
    centred = pipeline.run(path, high_res=VR_LENS_BORES, slice_parts=False, fit_grid=False)
    assert fitted.fit.fitted_mm3 < 0.8 * fitted.fit.centred_mm3
    volume = [sum(p.volume_mm3 for p in fab.printed) for fab in (fitted, centred)]
    assert volume[0] < 0.85 * volume[1]
    assert fitted.stability.components == fitted.stability.regions


@pytest.mark.slow
def test_faces_a_hair_past_a_cell_boundary_are_snapped_onto_it(tmp_path):
    path = tmp_path / "slab.stl"
    trimesh.creation.box(bounds=[[0.0, 0.0, 0.0], [40.0, 40.0, 3 * 3.2 + 2e-5]]).export(path)
    fab = pipeline.run(path, slice_parts=False)
    assert not fab.grid.filled[:, :, 3:].any()
    assert fab.grid.filled[:, :, :3].all()


@pytest.mark.slow
def test_iterating_on_a_fitted_grid_changes_nothing_when_the_part_did_not(tmp_path):
    path = tmp_path / "block.stl"
    _block().export(path)
    box = ",".join(str(v) for v in PLATE.ravel())
    first = tmp_path / "v1"
    pipeline.fabricate(path, first, high_res=[box], slice_parts=False, picture=False)
    doc = pipeline.fabricate(path, tmp_path / "v2", previous=first, slice_parts=False, picture=False)
    changes = doc["changes"]
    assert changes["cells_added"] == changes["cells_removed"] == changes["bricks_changed"] == 0
    assert changes["parts_reprinted"] == []


@pytest.mark.slow
def test_cli_says_how_the_grid_moved_and_no_grid_fit_keeps_it_centred(tmp_path):
    import json
    import subprocess
    import sys

    path = tmp_path / "block.stl"
    _block().export(path)
    box = "--high-res=" + ",".join(str(v) for v in PLATE.ravel())
    env = {"FABRICKATOR_SLICER": "none", "PATH": "/usr/bin:/bin"}
    runs = {}
    for name, extra in (("fitted", []), ("centred", ["--no-grid-fit"])):
        out = tmp_path / name
        run = subprocess.run([sys.executable, "-m", "core", "fabricate", str(path), "--out", str(out),
                              box, "--no-picture", "--quiet", *extra],
                             cwd=ROOT, capture_output=True, text=True, env=env)
        assert run.returncode == 0, run.stderr
        runs[name] = (run.stdout, json.loads((out / "report.json").read_text()))
    stdout, doc = runs["fitted"]
    assert "grid shifted" in stdout and doc["grid"]["fit"]["shift_mm"][1] < 0
    stdout, doc = runs["centred"]
    assert "grid shifted" not in stdout and "fit" not in doc["grid"]
    assert "centred" in doc["grid"]["alignment"]
