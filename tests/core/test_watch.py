"""Watch folder: new and changed model files, reported once completely written;
the Blender add-on that writes them (headless, where Blender is installed)."""

from __future__ import annotations

import os
import shutil
import subprocess
import textwrap
from pathlib import Path

import numpy as np
import pytest
import trimesh

from core import watch
from core.errors import InputError

ROOT = Path(__file__).resolve().parents[2]
ADDON = ROOT / "tools" / "blender" / "fabrickator_blender.py"


class Clock:
    """A settable clock for the watcher."""

    def __init__(self):
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def _stl_bytes() -> bytes:
    return trimesh.exchange.stl.export_stl(trimesh.creation.box(extents=[10, 10, 10]))


def test_binary_stl_is_complete_only_with_all_its_triangles(tmp_path):
    data = _stl_bytes()
    path = tmp_path / "part.stl"
    path.write_bytes(data[:-50])
    assert not watch.is_complete(path)
    path.write_bytes(data)
    assert watch.is_complete(path)
    path.write_bytes(b"")
    assert not watch.is_complete(path)


def test_ascii_stl_step_and_3mf_completeness(tmp_path):
    text = trimesh.exchange.stl.export_stl_ascii(trimesh.creation.box(extents=[1, 1, 1]))
    path = tmp_path / "a.stl"
    path.write_text(text[: len(text) // 2])
    assert not watch.is_complete(path)
    path.write_text(text)
    assert watch.is_complete(path)
    step = tmp_path / "a.step"
    step.write_text("ISO-10303-21;\nHEADER;\nENDSEC;\nDATA;\n")
    assert not watch.is_complete(step)
    step.write_text("ISO-10303-21;\nHEADER;\nENDSEC;\nDATA;\nENDSEC;\nEND-ISO-10303-21;\n")
    assert watch.is_complete(step)
    three = tmp_path / "a.3mf"
    data = trimesh.exchange.threemf.export_3MF(trimesh.creation.box())
    three.write_bytes(data[:-30])
    assert not watch.is_complete(three)
    three.write_bytes(data)
    assert watch.is_complete(three)


def test_watcher_reports_a_file_once_it_has_settled(tmp_path):
    clock = Clock()
    w = watch.FolderWatcher(tmp_path, settle_s=1.0, clock=clock)
    path = tmp_path / "v1.stl"
    data = _stl_bytes()
    path.write_bytes(data[:100])
    assert w.poll() == []
    clock.now = 5.0
    assert w.poll() == []  # settled but incomplete
    path.write_bytes(data)
    os.utime(path, ns=(1, 10**9))
    clock.now = 5.5
    assert w.poll() == []  # just changed
    clock.now = 6.0
    assert w.poll() == []  # not yet settled long enough
    clock.now = 6.6
    assert w.poll() == [path]
    clock.now = 20.0
    assert w.poll() == []  # reported once
    path.write_bytes(data + b"")
    os.utime(path, ns=(1, 2 * 10**9))
    assert w.poll() == []
    clock.now = 22.0
    assert w.poll() == [path]  # a new version of the same name


def test_watcher_skips_existing_hidden_and_other_files(tmp_path):
    data = _stl_bytes()
    (tmp_path / "old.stl").write_bytes(data)
    clock = Clock()
    w = watch.FolderWatcher(tmp_path, settle_s=0.0, clock=clock)
    (tmp_path / ".hidden.stl").write_bytes(data)
    (tmp_path / "part.stl.part").write_bytes(data)
    (tmp_path / "notes.txt").write_text("x")
    w.poll()
    clock.now = 1.0
    assert w.poll() == []
    os.replace(tmp_path / ".hidden.stl", tmp_path / "renamed.stl")
    w.poll()
    clock.now = 2.0
    assert w.poll() == [tmp_path / "renamed.stl"]
    everything = watch.FolderWatcher(tmp_path, settle_s=0.0, include_existing=True, clock=clock)
    everything.poll()
    assert everything.poll() == [tmp_path / "old.stl", tmp_path / "renamed.stl"]


def test_watch_generator_yields_and_stops(tmp_path):
    clock = Clock()
    data = _stl_bytes()

    def sleep(seconds):
        clock.now += seconds
        if abs(clock.now - 1.0) < 1e-9:
            (tmp_path / "new.stl").write_bytes(data)

    got = list(watch.watch(tmp_path, settle_s=1.0, poll_s=0.5, timeout_s=5.0, sleep=sleep, clock=clock))
    assert got == [tmp_path / "new.stl"]
    assert clock.now >= 5.0
    stopped = list(watch.watch(tmp_path, stop=lambda: True, sleep=sleep, clock=clock))
    assert stopped == []


def test_missing_folder_is_refused(tmp_path):
    with pytest.raises(InputError, match="does not exist"):
        watch.FolderWatcher(tmp_path / "nope")
    (tmp_path / "file").write_text("x")
    with pytest.raises(InputError):
        next(watch.watch(tmp_path / "file"))


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("blender") is None,
                    reason="Blender is not installed (Debian: apt-get install blender)")
def test_blender_addon_exports_on_leaving_edit_mode(tmp_path):
    """Blender headless: enable the add-on, edit a cube in Edit Mode, go back to
    Object Mode; the watcher then sees the exported STL, in mm, with the edit."""
    addons = tmp_path / "scripts" / "addons"
    addons.mkdir(parents=True)
    shutil.copy(ADDON, addons / ADDON.name)
    out = tmp_path / "out"
    out.mkdir()
    script = tmp_path / "run.py"
    script.write_text(textwrap.dedent(f"""
        import addon_utils, bpy
        addon_utils.enable("fabrickator_blender", default_set=True, handle_error=None)
        prefs = bpy.context.preferences.addons["fabrickator_blender"].preferences
        prefs.folder = {str(out)!r}
        prefs.mm_per_unit = 10.0
        bpy.ops.mesh.primitive_cube_add(size=2.0, location=(1, 2, 3))
        bpy.context.active_object.name = "Part"
        bpy.ops.object.mode_set(mode="EDIT")
        bpy.context.view_layer.update()
        bpy.ops.mesh.select_all(action="SELECT")
        bpy.ops.transform.resize(value=(1.5, 1, 1))
        bpy.ops.object.mode_set(mode="OBJECT")
        bpy.context.view_layer.update()
    """))
    clock = Clock()
    w = watch.FolderWatcher(out, settle_s=0.0, clock=clock)
    env = dict(os.environ, BLENDER_USER_SCRIPTS=str(tmp_path / "scripts"))
    run = subprocess.run(["blender", "-b", "--factory-startup", "--python", str(script)],
                         env=env, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
    assert "Fabrickator: exported Part" in run.stdout
    w.poll()
    clock.now = 1.0
    (found,) = w.poll()
    assert found == out / "Part.stl"
    mesh = trimesh.load(found)
    assert mesh.is_watertight and len(mesh.faces) == 12
    assert np.allclose(mesh.bounds, [[-5, 10, 20], [25, 30, 40]], atol=1e-4)
    assert not any(p.name.startswith(".") for p in out.iterdir())
