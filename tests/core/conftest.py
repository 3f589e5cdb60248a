"""Fixtures shared by the core tests."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
#: The demo's high-res boxes: the two lens mounts of examples/hmd.py (model mm).
HMD_HIGH_RES = ["-54,25,25.5,-9,36,70.5", "9,25,25.5,54,36,70.5"]


def pytest_configure(config):
    config.addinivalue_line(
        "markers", "slow: runs PrusaSlicer, reads the shared models or runs a whole pipeline "
        "(left out of make test-quick)")


@pytest.fixture(scope="session")
def hmd_step(tmp_path_factory) -> Path:
    """The bundled example's STEP: examples/build/hmd.step, or built for the test session."""
    built = ROOT / "examples" / "build" / "hmd.step"
    if built.is_file():
        return built
    spec = importlib.util.spec_from_file_location("fabrickator_example_hmd", ROOT / "examples" / "hmd.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    step, _ = module.export_hmd(tmp_path_factory.mktemp("hmd"))
    return Path(step)


@pytest.fixture(autouse=True)
def _bug_logs_in_tmp(tmp_path, monkeypatch):
    """Bug logs of the runs a test makes (core.errors.log_bug) go under its tmp_path,
    not into the user's ~/.local/state."""
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "state"))


@pytest.fixture(autouse=True)
def _no_slice_cache(monkeypatch):
    """Each test slices afresh (core.printing.slice_cache off), so what it checks comes from the
    slicer itself and never from an earlier test's answer; a test of the cache sets
    FABRICKATOR_CACHE to a folder of its own."""
    monkeypatch.setenv("FABRICKATOR_CACHE", "none")
