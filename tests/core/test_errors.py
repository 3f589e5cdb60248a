"""Errors mean what they say: InputError for the user's input, anything else is a bug
that is logged with its traceback (core.errors.log_bug) and named in one line."""

from __future__ import annotations

import os
import platform
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pytest
import trimesh

import core
from core import catalog, voxelize
from core.errors import InputError, bug_message, log_bug, log_folders
from core.instructions import render
from core.layout import greedy as layout
from core.model import Grid, Layout
from core.parts.brick_solids import brick_solid, to_trimesh

ROOT = Path(__file__).resolve().parents[2]


def raised(exc: BaseException) -> BaseException:
    """``exc`` after it was raised (so it carries a traceback)."""
    try:
        raise exc
    except BaseException as caught:  # noqa: BLE001 - the test's own exception
        return caught


def deep_failure() -> ValueError:
    """A ValueError raised two calls deep, chained to a KeyError."""
    def inner():
        try:
            {}["missing"]
        except KeyError as key:
            raise ValueError("the grid has 0 layers\nsecond line of detail") from key

    try:
        inner()
    except ValueError as exc:
        return exc


@pytest.fixture
def state(tmp_path, monkeypatch) -> Path:
    """XDG_STATE_HOME pointed at a fresh folder."""
    folder = tmp_path / "state"
    monkeypatch.setenv("XDG_STATE_HOME", str(folder))
    return folder


def test_log_bug_writes_the_traceback_and_versions(state):
    exc = deep_failure()
    path = log_bug(exc, "fabricate box.stl")
    assert path.parent == state / "fabrickator" and path.is_file()
    text = path.read_text(encoding="utf-8")
    assert "Traceback (most recent call last)" in text
    assert "in inner" in text and "ValueError: the grid has 0 layers" in text
    assert "second line of detail" in text
    assert "KeyError: 'missing'" in text  # the chained cause
    assert "context: fabricate box.stl" in text
    assert f"fabrickator: {core.__version__}" in text
    assert f"python: {platform.python_version()}" in text
    assert f"platform: {platform.platform()}" in text
    assert f"argv: {sys.argv!r}" in text


def test_each_bug_gets_its_own_log(state):
    exc = raised(RuntimeError("again"))
    paths = {log_bug(exc, "one"), log_bug(exc, "two"), log_bug(exc, "three")}
    assert len(paths) == 3
    assert sorted(p.read_text().splitlines()[0] for p in paths) == [
        "context: one", "context: three", "context: two"]


def test_log_falls_back_to_the_home_state_folder(tmp_path, monkeypatch):
    monkeypatch.delenv("XDG_STATE_HOME", raising=False)
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    path = log_bug(raised(TypeError("x")), "test")
    assert path.parent == tmp_path / "home" / ".local" / "state" / "fabrickator"


def test_log_falls_back_to_the_temp_folder_when_the_state_folders_cannot_be_written(
        tmp_path, monkeypatch):
    blocker = tmp_path / "a-file"
    blocker.write_text("not a folder")
    monkeypatch.setenv("XDG_STATE_HOME", str(blocker / "state"))
    monkeypatch.setenv("HOME", str(blocker / "home"))
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "tmp"))
    path = log_bug(raised(ValueError("x")), "test")
    assert path.parent == tmp_path / "tmp" / "fabrickator"
    assert "ValueError: x" in path.read_text()
    assert log_folders()[-1] == tmp_path / "tmp" / "fabrickator"


def test_a_relative_state_home_is_ignored(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_STATE_HOME", "relative/state")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert log_folders()[0] == tmp_path / "home" / ".local" / "state" / "fabrickator"


def test_bug_message_is_one_line_naming_the_type_the_message_and_the_log(state):
    exc = deep_failure()
    path = log_bug(exc, "test")
    line = bug_message(exc, path)
    assert "\n" not in line
    assert line.startswith("bug: ValueError: the grid has 0 layers — this is a bug in Fabrickator")
    assert "second line" not in line
    assert "not your input" in line and "please report it" in line
    assert f"the traceback is in {path};" in line


def test_bug_message_of_an_exception_without_text():
    line = bug_message(raised(RuntimeError()), "/tmp/x.log")
    assert line == ("bug: RuntimeError — this is a bug in Fabrickator, not your input; "
                    "the traceback is in /tmp/x.log; please report it")


def _grid(filled: np.ndarray) -> Grid:
    return Grid(np.zeros(3), np.array([8.0, 8.0, 3.2]), filled)


@pytest.mark.parametrize("call, kind", [
    (lambda: brick_solid(0, 2, 3), ValueError),
    (lambda: to_trimesh("not a shape"), TypeError),
    (lambda: voxelize.legofy(trimesh.Trimesh(np.zeros((0, 3)), np.zeros((0, 3), int))), ValueError),
    (lambda: layout.lay_out(_grid(np.ones((2, 2, 2), dtype=np.int8))), TypeError),
    (lambda: render.render_layout(Layout(_grid(np.zeros((1, 1, 1), bool)), []),
                                  "/tmp/x.png", size_px=(1, 1)), ValueError),
])
def test_a_wrong_call_of_ours_is_not_an_input_error(call, kind):
    with pytest.raises(kind) as info:
        call()
    assert not isinstance(info.value, InputError)


@pytest.mark.parametrize("call, words", [
    (lambda: catalog.select("3001,brick9x9"), "brick9x9"),
    (lambda: layout.lay_out(_grid(np.ones((1, 1, 1), bool)), seed=-1), "seed"),
    (lambda: layout.lay_out(_grid(np.ones((1, 1, 1), bool)),
                            tuple(p for p in catalog.select("plates") if p.number != "3024")), "3024"),
])
def test_the_users_choices_stay_input_errors(call, words):
    with pytest.raises(InputError, match=words):
        call()


BOOM = """
import sys
import core.layout.greedy

def boom(*args, **kwargs):
    raise ValueError("boom: the layout stage broke\\nand said more")

core.layout.greedy.lay_out = boom
from core import cli
sys.exit(cli.main(sys.argv[1:]))
"""


def test_cli_reports_a_bug_in_one_line_with_its_log(tmp_path):
    """A stage failing by a bug (not the user's input): exit 1, one line on stderr
    saying it is a bug and naming the log file, which holds the traceback."""
    box = trimesh.creation.box((16.0, 16.0, 9.6))
    box.apply_translation(-box.bounds[0])
    model = tmp_path / "box.stl"
    box.export(model)
    env = {**os.environ, "XDG_STATE_HOME": str(tmp_path / "state")}
    proc = subprocess.run([sys.executable, "-c", BOOM, "fabricate", str(model), "--out",
                           str(tmp_path / "out"), "--no-picture", "--quiet"],
                          cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 1, proc.stderr
    lines = proc.stderr.splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("bug: ValueError: boom: the layout stage broke — "), lines[0]
    assert "Traceback" not in proc.stderr
    logs = list((tmp_path / "state" / "fabrickator").glob("*.log"))
    assert len(logs) == 1, lines[0]
    assert str(logs[0]) in lines[0]
    text = logs[0].read_text()
    assert "Traceback (most recent call last)" in text and "in boom" in text
    assert "ValueError: boom: the layout stage broke" in text
