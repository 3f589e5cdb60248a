"""Tests of the bundled demo model examples/hmd.py (built, exported, checked)."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import cadquery as cq
import numpy as np
import pytest
import trimesh

ROOT = Path(__file__).resolve().parents[2]
HMD_SCRIPT = ROOT / "examples" / "hmd.py"


def load_hmd():
    """examples/ is not a package: import hmd.py from its path."""
    spec = importlib.util.spec_from_file_location("fabrickator_example_hmd", HMD_SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def hmd():
    return load_hmd()


@pytest.fixture(scope="module")
def solid(hmd):
    return hmd.build_hmd()


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    out = tmp_path_factory.mktemp("hmd")
    run = subprocess.run([sys.executable, str(HMD_SCRIPT), str(out)], cwd=ROOT,
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    return out, run.stdout


@pytest.mark.slow
def test_script_writes_step_and_stl(exported):
    out, stdout = exported
    for name in ("hmd.step", "hmd.stl"):
        assert (out / name).stat().st_size > 1000
        assert str(out / name) in stdout


def test_script_without_outdir_says_how():
    run = subprocess.run([sys.executable, str(HMD_SCRIPT)], capture_output=True, text=True,
                         timeout=120)
    assert run.returncode == 2 and "usage" in run.stderr


def test_solid_is_one_valid_solid_of_the_designed_size(hmd, solid):
    assert len(solid.solids().vals()) == 1
    shape = solid.val()
    assert shape.isValid()
    bb = shape.BoundingBox()
    size = np.array([bb.xlen, bb.ylen, bb.zlen])
    np.testing.assert_allclose(size, [hmd.BODY_WIDTH, hmd.BODY_DEPTH, hmd.BODY_HEIGHT], atol=1e-6)
    # Hollow: far less than the full box.
    assert shape.Volume() < 0.35 * size.prod()


def test_stl_is_watertight_with_the_solids_volume(exported, solid, hmd):
    out, _ = exported
    mesh = trimesh.load(out / "hmd.stl")
    assert mesh.is_watertight and mesh.is_winding_consistent
    assert mesh.volume == pytest.approx(solid.val().Volume(), rel=2e-3)
    np.testing.assert_allclose(mesh.extents, [hmd.BODY_WIDTH, hmd.BODY_DEPTH, hmd.BODY_HEIGHT],
                               atol=0.06)


def test_step_reads_back(exported, solid):
    out, _ = exported
    back = cq.importers.importStep(str(out / "hmd.step")).val()
    assert back.isValid()
    assert back.Volume() == pytest.approx(solid.val().Volume(), rel=1e-6)


def test_lens_mounts(hmd, solid):
    shape = solid.val()
    plate_y = hmd.LENS_PLATE_Y + hmd.LENS_PLATE_THICKNESS / 2
    seat_y = hmd.LENS_PLATE_Y - hmd.RING_HEIGHT + hmd.LENS_SEAT_DEPTH / 2
    ring_r = hmd.LENS_DIAMETER / 2 + hmd.RING_WALL / 2
    step_r = hmd.LENS_DIAMETER / 2 - hmd.LENS_SEAT_STEP / 2
    assert hmd.LENS_DIAMETER / 2 + hmd.RING_WALL < hmd.IPD / 2     # the rings do not merge
    for x in (-hmd.IPD / 2, hmd.IPD / 2):
        z = hmd.LENS_CENTRE_Z

        def inside(dx, y):
            return shape.isInside(cq.Vector(x + dx, y, z))

        assert not inside(0, plate_y)                  # the aperture is open
        assert inside(step_r, plate_y)                 # the step the lens rests on
        assert not inside(step_r, seat_y)              # the seat has the full lens diameter
        assert inside(ring_r, seat_y)                  # the ring around the seat
        assert not inside(ring_r + hmd.RING_WALL, seat_y)


def test_open_face_and_nose_cut(hmd, solid):
    shape = solid.val()
    assert not shape.isInside(cq.Vector(0, 1.0, hmd.BODY_HEIGHT / 2))       # open face side
    assert shape.isInside(cq.Vector(0, hmd.BODY_DEPTH - 1.0, hmd.BODY_HEIGHT / 2))  # front plate
    assert not shape.isInside(cq.Vector(0, 10.0, 1.0))                      # nose cut, bottom
    assert shape.isInside(cq.Vector(0, hmd.BODY_DEPTH - 10.0, 1.0))         # bottom wall behind it
