"""Hostile input and environment, created for real: each ends in one line and exit status 2
(128 + the signal when stopped), or in a stated repair; never a traceback, a hang or a
half-written output (issue 16, "One line for every fault")."""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest
import trimesh

from core import pipeline, watch
from core.cli import main
from core.errors import InputError
from core.io import meshes as mesh_io, output_dir

ROOT = Path(__file__).resolve().parents[2]
IS_ROOT = hasattr(os, "geteuid") and os.geteuid() == 0
#: A 20 x 20 x 10 mm box: 3 x 3 cells of 8 mm across (20 / 8 = 2.5, rounded up) and
#: 4 layers of 3.2 mm (10 / 3.2 = 3.125, rounded up): 36 cells.
BOX_MM, BOX_CELLS = (20.0, 20.0, 10.0), 36


@pytest.fixture
def box_stl(tmp_path) -> Path:
    path = tmp_path / "box.stl"
    trimesh.creation.box(BOX_MM).export(path)
    return path


def cli(*args, env=None, timeout=180, prefix=()) -> subprocess.CompletedProcess:
    """``python -m core ARGS`` in a subprocess, as a user runs it (``prefix``: e.g. setpriv)."""
    return subprocess.run([*prefix, sys.executable, "-m", "core", *map(str, args)], cwd=ROOT,
                          capture_output=True, text=True, timeout=timeout,
                          env=dict(os.environ, **(env or {})))


def in_process(capsys, *args) -> tuple[int, str, str]:
    """(status, stdout, stderr) of the CLI's ``main`` on ``args``."""
    try:
        status = main([str(a) for a in args])
    except SystemExit as exit_:           # argparse's usage errors
        status = exit_.code
    out, err = capsys.readouterr()
    return status, out, err


def one_line(status: int, err: str, *words: str, code: int = 2) -> str:
    """Assert exit ``code`` and exactly one stderr line holding ``words``; the line."""
    lines = err.strip().splitlines()
    assert status == code, err
    assert len(lines) == 1, err
    assert "Traceback" not in err
    for word in words:
        assert word in lines[0], lines[0]
    return lines[0]


def assert_complete(out: Path) -> None:
    """``out`` is a whole output: every file its report lists is there, nothing else."""
    doc = json.loads((out / "report.json").read_text())
    assert sorted(p.name for p in out.iterdir()) == sorted(doc["outputs"])
    assert doc["plates"] == BOX_CELLS


def no_leftovers(folder: Path) -> None:
    """No temporary folder or lock of a run is left in ``folder``."""
    assert [p.name for p in folder.iterdir() if p.name.startswith(".")] == []


def dead_pid() -> int:
    """The id of a process that has ended."""
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


# --- special and unreadable files -----------------------------------------------

@pytest.mark.slow
@pytest.mark.parametrize("kind, role", [("fifo", "model"), ("fifo", "region"),
                                        ("socket", "model"), ("device", "model")])
def test_special_files_are_refused_before_opening(tmp_path, box_stl, capsys, kind, role):
    special = tmp_path / "special.stl"
    words = {"fifo": "named pipe", "socket": "socket", "device": "character device"}[kind]
    with contextlib.ExitStack() as stack:
        if kind == "fifo":
            os.mkfifo(special)
        elif kind == "socket":
            sock = stack.enter_context(socket.socket(socket.AF_UNIX))
            sock.bind(str(special))
        else:
            special.symlink_to("/dev/zero")
        args = ([special] if role == "model" else [box_stl, "--high-res-solid", special])
        proc = cli("fabricate", *args, "--out", tmp_path / "out", "--quiet", timeout=60)
    one_line(proc.returncode, proc.stderr, words, "not a regular file")
    assert not (tmp_path / "out").exists()


@pytest.fixture
def as_nobody():
    """(a folder every user may enter, the command prefix that runs as user nobody, its
    environment).  Root reads every file whatever its mode, so the test drops to nobody."""
    if not IS_ROOT or shutil.which("setpriv") is None:
        pytest.skip("needs root and util-linux setpriv to run the CLI as user nobody")
    folder = Path(tempfile.mkdtemp(prefix="fabrickator-test-nobody-"))
    try:
        folder.chmod(0o755)
        home = folder / "home"
        home.mkdir()
        shutil.chown(home, "nobody")
        yield folder, ("setpriv", "--reuid=nobody", "--regid=nogroup", "--clear-groups"), \
            {"HOME": str(home), "XDG_STATE_HOME": str(home / "state")}
    finally:
        for path in folder.rglob("*"):
            with contextlib.suppress(OSError):
                path.chmod(0o755)
        shutil.rmtree(folder, ignore_errors=True)


@pytest.mark.slow
def test_an_unreadable_file_names_the_permission_problem(as_nobody):
    folder, prefix, env = as_nobody
    out = folder / "outputs"
    out.mkdir(mode=0o777)
    out.chmod(0o777)
    secret = folder / "secret.stl"
    trimesh.creation.box(BOX_MM).export(secret)
    secret.chmod(0o000)
    locked = folder / "locked"
    locked.mkdir()
    trimesh.creation.box(BOX_MM).export(locked / "box.stl")
    locked.chmod(0o000)
    box = folder / "box.stl"
    trimesh.creation.box(BOX_MM).export(box)
    box.chmod(0o644)
    for args, words in (([secret], ("permission denied", "may not read this file")),
                        ([locked / "box.stl"], ("permission denied", "folder on its path")),
                        ([box, "--high-res-solid", secret], ("permission denied", "secret.stl"))):
        proc = cli("fabricate", *args, "--out", out / "o", "--quiet", prefix=prefix, env=env)
        one_line(proc.returncode, proc.stderr, *words)
    proc = cli("fabricate", secret, "--out", folder / "o", "--quiet", prefix=prefix, env=env)
    one_line(proc.returncode, proc.stderr, "cannot write into", "permission denied")
    assert list(out.iterdir()) == []


def test_a_watch_folder_that_cannot_be_read_is_refused_before_watching(as_nobody):
    folder, prefix, env = as_nobody
    closed = folder / "closed"
    closed.mkdir()
    closed.chmod(0o000)
    proc = cli("watch", closed, "--out", folder / "home" / "o", "--existing", "--timeout", "1",
               prefix=prefix, env=env)
    one_line(proc.returncode, proc.stderr, "cannot be read")


def test_a_file_name_that_is_not_utf8_is_built_and_printed_escaped(box_stl, tmp_path):
    odd = Path(os.fsdecode(bytes(tmp_path) + b"/b\xff.stl"))
    shutil.copy(box_stl, odd)
    out = Path(os.fsdecode(bytes(tmp_path) + b"/o\xfe"))
    proc = cli("fabricate", odd, "--out", out, "--quiet", "--no-picture")
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr
    assert "o\\udcfe" in proc.stdout
    assert_complete(out)


def test_a_reader_that_quits_early_is_no_bug(box_stl, tmp_path):
    proc = subprocess.Popen([sys.executable, "-m", "core", "fabricate", str(box_stl), "--out",
                             str(tmp_path / "o"), "--quiet", "--no-picture"], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    proc.stdout.close()                      # as `| head -0` does
    assert proc.wait(timeout=180) == 0
    assert proc.stderr.read() == ""
    assert_complete(tmp_path / "o")


# --- options ---------------------------------------------------------------------

@pytest.mark.parametrize("args, words", [
    (("--seed", "-1"), "--seed -1"),
    (("--seed", "1.5"), "--seed"),
    (("--seed", "4294967296"), "--seed"),
    (("--scale", "nan"), "--scale"),
    (("--scale", "0"), "--scale"),
    (("--scale", "-inf"), "--scale"),
    (("--seconds-per-brick", "inf"), "--seconds-per-brick"),
    (("--seconds-per-part", "-1"), "--seconds-per-part"),
    (("--units", "ft"), "--units"),
    (("--stud-fit", "nan"), "--stud-fit"),
])
def test_every_option_is_checked_before_the_run(box_stl, tmp_path, capsys, args, words):
    status, out, err = in_process(capsys, "fabricate", box_stl, "--out", tmp_path / "o", *args)
    one_line(status, err, words)
    assert out == "" and not (tmp_path / "o").exists()


@pytest.mark.parametrize("value", ["nan", "inf", "-1", "0"])
def test_watch_timeout_must_be_finite_and_positive(tmp_path, capsys, value):
    status, _, err = in_process(capsys, "watch", tmp_path, "--out", tmp_path / "o",
                                "--timeout", value)
    one_line(status, err, "--timeout")
    assert "watching" not in err


# --- the output place --------------------------------------------------------------

def test_an_output_place_that_cannot_be_written_is_refused_before_the_run(box_stl, tmp_path, capsys):
    blocker = tmp_path / "a_file"
    blocker.write_text("mine")
    for out, words in ((Path("/proc/fabrickator-out"), "/proc"),
                       (Path("/sys/fabrickator-out"), "/sys"),
                       (blocker, "not a folder"),
                       (blocker / "below" / "deeper", "is a file"),
                       (tmp_path / ("n" * 300), "300 bytes")):
        status, stdout, err = in_process(capsys, "fabricate", box_stl, "--out", out, "--quiet")
        one_line(status, err, *words)
        assert stdout == ""
    assert blocker.read_text() == "mine"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a_file", "box.stl"]


def test_a_long_output_name_that_the_file_system_allows_is_written(box_stl, tmp_path, capsys):
    out = tmp_path / ("n" * 250)
    status, _, err = in_process(capsys, "fabricate", box_stl, "--out", out, "--quiet", "--no-picture")
    assert status == 0, err
    assert_complete(out)
    no_leftovers(tmp_path)


@contextlib.contextmanager
def mounted(*args):
    """``mount ARGS`` for the block (skip when mounting is not permitted)."""
    target = args[-1]
    proc = subprocess.run(["mount", *args], capture_output=True, text=True)
    if proc.returncode != 0:
        pytest.skip(f"mount is not permitted here ({proc.stderr.strip()[:80]})")
    try:
        yield Path(target)
    finally:
        subprocess.run(["umount", "-l", target], capture_output=True)


@pytest.mark.skipif(not IS_ROOT, reason="mounting needs root")
def test_a_read_only_file_system_is_refused_before_the_run(box_stl, tmp_path, capsys):
    place = tmp_path / "ro"
    place.mkdir()
    with mounted("-t", "tmpfs", "-o", "size=1m,ro", "tmpfs", str(place)):
        status, _, err = in_process(capsys, "fabricate", box_stl, "--out", place / "o", "--quiet")
        one_line(status, err, "read-only")
        assert list(place.iterdir()) == []


@pytest.mark.skipif(not IS_ROOT, reason="mounting needs root")
def test_a_full_disk_mid_run_removes_the_temporary_folder_and_says_so(box_stl, tmp_path, capsys):
    place = tmp_path / "small"
    place.mkdir()
    with mounted("-t", "tmpfs", "-o", "size=64k", "tmpfs", str(place)):
        status, _, err = in_process(capsys, "fabricate", box_stl, "--out", place / "o", "--quiet")
        one_line(status, err, "disk is full", "unfinished output was removed")
        assert list(place.iterdir()) == []


def test_an_immutable_folder_is_refused_before_the_run(box_stl, tmp_path, capsys):
    place = tmp_path / "immutable"
    place.mkdir()
    if subprocess.run(["chattr", "+i", str(place)], capture_output=True).returncode != 0:
        pytest.skip("chattr +i is not supported here (needs root and a file system with it)")
    try:
        status, _, err = in_process(capsys, "fabricate", box_stl, "--out", place / "o", "--quiet")
        one_line(status, err, "cannot write into", "not permitted")
    finally:
        subprocess.run(["chattr", "-i", str(place)])
    assert list(place.iterdir()) == []


# --- never delete what the run did not write ---------------------------------------

def test_an_output_holding_the_model_is_refused(box_stl, tmp_path, capsys):
    out = tmp_path / "out"
    assert in_process(capsys, "fabricate", box_stl, "--out", out, "--quiet", "--no-picture")[0] == 0
    model = out / "model.stl"
    shutil.copy(box_stl, model)
    status, _, err = in_process(capsys, "fabricate", model, "--out", out, "--quiet")
    one_line(status, err, "input of this run")
    assert model.read_bytes() == box_stl.read_bytes()


def test_replacing_an_earlier_output_keeps_the_old_one_until_the_new_one_is_in(tmp_path, monkeypatch):
    out = tmp_path / "out"
    out.mkdir()
    (out / "report.json").write_text(json.dumps({"outputs": ["report.json"]}))
    real_rename = os.rename

    def failing(src, dst):
        if Path(src).name.startswith(".out.part-"):
            raise OSError(28, "No space left on device")
        return real_rename(src, dst)

    monkeypatch.setattr(os, "rename", failing)
    with pytest.raises(InputError) as caught:
        with output_dir.OutputFolder(out) as folder:
            (folder.temp / "report.json").write_text("{}")
            folder.install()
    assert "earlier one is kept" in str(caught.value)
    assert json.loads((out / "report.json").read_text()) == {"outputs": ["report.json"]}
    no_leftovers(tmp_path)


def test_an_earlier_output_that_cannot_be_deleted_is_replaced_whole(box_stl, tmp_path, capsys):
    out = tmp_path / "out"
    assert in_process(capsys, "fabricate", box_stl, "--out", out, "--quiet", "--no-picture")[0] == 0
    stuck = out / "iteration" / "stuck"
    stuck.write_text("")
    if subprocess.run(["chattr", "+i", str(stuck)], capture_output=True).returncode != 0:
        pytest.skip("chattr +i is not supported here (needs root and a file system with it)")
    try:
        status, _, err = in_process(capsys, "fabricate", box_stl, "--out", out, "--quiet",
                                    "--no-picture", "--seed", "3")
        assert status == 0 and "could not be removed entirely" in err
        assert json.loads((out / "report.json").read_text())["seed"] == 3
        assert not (out / "iteration" / "stuck").exists()
    finally:
        for path in tmp_path.glob(".out.old-*/iteration/stuck"):
            subprocess.run(["chattr", "-i", str(path)])
    status, _, err = in_process(capsys, "fabricate", box_stl, "--out", out, "--quiet", "--no-picture")
    assert status == 0, err
    assert_complete(out)
    no_leftovers(tmp_path)


def test_leftovers_of_killed_runs_are_cleaned_up(box_stl, tmp_path, capsys):
    out = tmp_path / "out"
    gone = dead_pid()
    (tmp_path / f".out.part-{gone}-abcd").mkdir()
    (tmp_path / f".out.part-{gone}-abcd" / "layout.json").write_text("{}")
    aside = tmp_path / f".out.old-{gone}-efgh"       # killed between its two renames
    aside.mkdir()
    (aside / "report.json").write_text(json.dumps({"outputs": ["report.json"], "seed": 7}))
    (tmp_path / "keep.part-1-x").mkdir()
    status, _, err = in_process(capsys, "fabricate", box_stl, "--out", out, "--quiet", "--no-picture")
    assert status == 0, err
    assert "put back the earlier output" in err
    assert_complete(out)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["box.stl", "keep.part-1-x", "out"]


def test_stale_scratch_folders_of_dead_runs_are_removed(tmp_path):
    dead, alive = tmp_path / f"fabrickator-slice-{dead_pid()}-x", tmp_path / f"fabrickator-slice-{os.getppid()}-y"
    other = tmp_path / "fabrickator-slice-notapid"
    for folder in (dead, alive, other):
        folder.mkdir()
        (folder / "plate.gcode").write_text(";")
    assert output_dir.clean_stale_scratch("fabrickator-slice-", tmp_path) == [dead]
    assert alive.exists() and other.exists() and not dead.exists()


# --- concurrency --------------------------------------------------------------------

def test_a_second_run_into_the_same_output_is_refused_and_the_first_stays_whole(box_stl, tmp_path,
                                                                                capsys):
    big = tmp_path / "big.stl"
    trimesh.creation.box((200, 200, 100)).export(big)
    out = tmp_path / "out"
    first = subprocess.Popen([sys.executable, "-m", "core", "fabricate", str(big), "--out",
                              str(out), "--no-picture", "--effort", "fast"], cwd=ROOT,
                             stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
    try:
        line = first.stderr.readline()          # the first progress line: the lock is held
        assert "load" in line, line
        status, _, err = in_process(capsys, "fabricate", box_stl, "--out", out, "--quiet")
        one_line(status, err, "being written by another run", str(first.pid))
    finally:
        stdout, stderr = first.communicate(timeout=300)
    assert first.returncode == 0, stderr
    doc = json.loads((out / "report.json").read_text())
    assert sorted(p.name for p in out.iterdir()) == sorted(doc["outputs"])
    assert doc["plates"] == 25 * 25 * 32          # 200 / 8 and 100 / 3.2 rounded up
    assert sorted(p.name for p in tmp_path.iterdir()) == ["big.stl", "box.stl", "out"]


# --- tolerances and repairs -----------------------------------------------------------

def test_a_model_far_from_the_origin_legofies_as_at_the_origin(tmp_path):
    far = tmp_path / "far.stl"
    trimesh.creation.box(BOX_MM).apply_translation((1e6, 1e6, 1e6)).export(far)
    fab = pipeline.run(far, slice_parts=False)
    assert fab.grid.count == BOX_CELLS
    assert any("moved by" in r and "to the origin" in r for r in fab.model.repaired)
    assert fab.model.offset_mm == pytest.approx((-1e6, -1e6, -1e6 + 5.0))
    near = tmp_path / "near.stl"
    trimesh.creation.box(BOX_MM).apply_translation((1e4, 1e4, 1e4)).export(near)
    fab = pipeline.run(near, slice_parts=False)
    assert fab.grid.count == BOX_CELLS and fab.model.offset_mm == (0.0, 0.0, 0.0)


def test_a_region_moves_with_its_far_model(tmp_path):
    far = tmp_path / "far.stl"
    trimesh.creation.box(BOX_MM).apply_translation((1e6, 0, 0)).export(far)
    box = "1000000,0,-5,1000010,10,-2.5"              # a quarter of the first layer
    fab = pipeline.run(far, slice_parts=False, connectors=False, fit_grid=False, high_res=[box])
    assert fab.marks["marked_cells"] == 4 and fab.warnings == []


def test_a_long_thin_bar_still_encloses_volume():
    bar = trimesh.creation.box((5e8, 10, 10))        # the bar, once refused as flat
    mesh, repaired = mesh_io.repair(np.asarray(bar.vertices), np.asarray(bar.faces))
    assert mesh.is_watertight and len(mesh.faces) == 12 and repaired == []


def test_an_obj_counting_vertices_from_zero_is_read_as_such(tmp_path, capsys):
    box = trimesh.creation.box(BOX_MM)
    text = "".join("v %g %g %g\n" % tuple(v) for v in box.vertices)
    good = tmp_path / "zero.obj"
    good.write_text(text + "".join("f %d %d %d\n" % tuple(f) for f in box.faces))
    model = mesh_io.load_model(good)
    assert model.watertight and abs(model.mesh.volume - np.prod(BOX_MM)) < 1e-6
    assert any("counting vertices from 0" in r for r in model.repaired)
    status, _, err = in_process(capsys, "fabricate", good, "--out", tmp_path / "good", "--quiet",
                                "--no-picture")
    one_line(status, err, "repaired", "counting vertices from 0", code=0)
    assert json.loads((tmp_path / "good" / "report.json").read_text())["plates"] == BOX_CELLS
    bad = tmp_path / "bad.obj"
    bad.write_text(text + "f 0 1 2\nf 1 2 8\n")
    status, _, err = in_process(capsys, "fabricate", bad, "--out", tmp_path / "o", "--quiet")
    one_line(status, err, "malformed OBJ", "vertex 0")


def mobius(path: Path) -> None:
    """An open, one-sided band (a Möbius strip, 40 mm radius, 20 mm wide) as STL."""
    n, points, faces = 60, [], []
    for a in np.linspace(0, 2 * np.pi, n, endpoint=False):
        for w in (-10.0, 10.0):
            r = 40 + w * np.cos(a / 2)
            points.append((r * np.cos(a), r * np.sin(a), w * np.sin(a / 2)))
    for i in range(n):
        a0, a1 = 2 * i, 2 * i + 1
        b0, b1 = (2 * i + 2, 2 * i + 3) if i + 1 < n else (1, 0)
        faces += [[a0, b0, a1], [a1, b0, b1]]
    trimesh.Trimesh(points, faces, process=False).export(path)


@pytest.mark.slow
def test_an_open_one_sided_surface_is_said_in_the_report_and_one_line(tmp_path, capsys):
    path = tmp_path / "mobius.stl"
    mobius(path)
    status, _, err = in_process(capsys, "fabricate", path, "--out", tmp_path / "o", "--quiet",
                                "--no-picture")
    line = one_line(status, err, "not closed", "Möbius", code=0)
    doc = json.loads((tmp_path / "o" / "report.json").read_text())
    assert doc["model"]["watertight"] is False
    assert doc["model"]["warnings"] == [line.removeprefix("warning: ")]


def test_a_high_res_box_outside_the_model_is_a_warning(box_stl, tmp_path, capsys):
    status, _, err = in_process(capsys, "fabricate", box_stl, "--out", tmp_path / "o", "--quiet",
                                "--no-picture", "--high-res=100,100,100,110,110,110")
    one_line(status, err, "high-res box 100,100,100,110,110,110", "marks no cell", code=0)
    doc = json.loads((tmp_path / "o" / "report.json").read_text())
    assert doc["printed_parts"] == [] and len(doc["warnings"]) == 1


# --- signals -------------------------------------------------------------------------

def _terminal_ctrl_c() -> None:
    """In the child before it starts: SIGINT back to its default."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def running(args, until: str) -> subprocess.Popen:
    """The CLI started with ``args``, returned once a stderr line holds ``until``.  It gets
    Ctrl-C as from a terminal: a suite started in the background of a shell without job
    control inherits SIGINT ignored, and the CLI rightly keeps that (the run went on)."""
    proc = subprocess.Popen([sys.executable, "-m", "core", *map(str, args)], cwd=ROOT,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            preexec_fn=_terminal_ctrl_c)
    lines = []
    for line in proc.stderr:
        lines.append(line)
        if until in line:
            return proc
    proc.wait()
    raise AssertionError(f"the run ended before {until!r}: {''.join(lines)}")


def messages(stderr: str) -> list[str]:
    """The stderr lines that are not progress lines (``[  1.23 s]  40%  layout``)."""
    return [line for line in stderr.splitlines() if not line.startswith("[")]


def test_ctrl_c_ends_in_one_line_and_leaves_no_output(tmp_path):
    big = tmp_path / "big.stl"
    trimesh.creation.box((640, 640, 320)).export(big)
    out = tmp_path / "out"
    proc = running(["fabricate", big, "--out", out], until="layout")
    proc.send_signal(signal.SIGINT)
    stderr = proc.stderr.read()
    assert proc.wait(timeout=120) == 130
    (line,) = messages(stderr)
    assert line.startswith("stopped by Ctrl-C")
    assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["big.stl"]


def _slicers_of(pid: int) -> list[int]:
    """Processes whose command line names a scratch folder of process ``pid``."""
    found = []
    for proc in Path("/proc").iterdir():
        if proc.name.isdigit():
            with contextlib.suppress(OSError):
                if f"-{pid}-".encode() in (proc / "cmdline").read_bytes() and int(proc.name) != pid:
                    found.append(int(proc.name))
    return found


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("prusa-slicer") is None or not Path("/proc").is_dir(),
                    reason="needs PrusaSlicer (apt-get install prusa-slicer) and Linux /proc")
@pytest.mark.parametrize("sig, code", [(signal.SIGTERM, 143), (signal.SIGKILL, -9)])
def test_a_kill_while_slicing_takes_the_slicer_and_its_files_with_it(box_stl, tmp_path, sig, code):
    out = tmp_path / "out"
    proc = running(["fabricate", box_stl, "--out", out, "--high-res=-10,-10,-5,0,0,0"],
                   until="print_time")
    deadline = time.monotonic() + 30
    while not _slicers_of(proc.pid) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert _slicers_of(proc.pid), "no slicer started"
    proc.send_signal(sig)
    stderr = proc.stderr.read()
    assert proc.wait(timeout=60) == code
    # at once: a run of another test beside this one removes a dead run's files
    scratch = list(Path(tempfile.gettempdir()).glob(f"fabrickator-*-{proc.pid}-*"))
    time.sleep(0.5)
    assert _slicers_of(proc.pid) == []
    if sig == signal.SIGTERM:
        (line,) = messages(stderr)
        assert line.startswith("stopped by SIGTERM")
        assert scratch == []
    else:                    # nothing runs after a SIGKILL: the next run removes the files
        assert scratch
        for kind in ("pose", "slice"):
            output_dir.clean_stale_scratch(f"fabrickator-{kind}-")
        assert list(Path(tempfile.gettempdir()).glob(f"fabrickator-*-{proc.pid}-*")) == []
    assert not out.exists()


# --- watch -------------------------------------------------------------------------

def test_watch_checks_its_folder_and_output_before_it_watches(box_stl, tmp_path, capsys):
    for args, words in (((tmp_path / "nope", "--out", tmp_path / "o"), "does not exist"),
                        ((box_stl, "--out", tmp_path / "o"), "not a folder"),
                        ((tmp_path, "--out", box_stl), "not a folder"),
                        ((tmp_path, "--out", "/proc/x"), "/proc"),
                        ((tmp_path, "--out", tmp_path / "o", "--scale", "0"), "--scale")):
        status, _, err = in_process(capsys, "watch", *args, "--timeout", "1")
        one_line(status, err, *words)


def test_ctrl_c_ends_a_watch_in_one_line(tmp_path):
    proc = running(["watch", tmp_path, "--out", tmp_path / "o"], until="watching")
    proc.send_signal(signal.SIGINT)
    stderr = proc.stderr.read()
    assert proc.wait(timeout=60) == 0
    assert stderr.strip().splitlines() == ["stopped after 0 version(s) built"]


class Clock:
    def __init__(self):
        self.now = 0.0

    def __call__(self):
        return self.now


def test_watch_builds_an_obj_written_in_two_halves_only_once_whole(tmp_path):
    box = trimesh.creation.box(BOX_MM)
    text = trimesh.exchange.obj.export_obj(box)
    lines = text.splitlines(keepends=True)
    first = "".join(lines[:len(lines) - 4])        # every vertex and most faces: an OBJ itself
    clock = Clock()
    w = watch.FolderWatcher(tmp_path, settle_s=1.0, clock=clock)
    path = tmp_path / "part.obj"
    path.write_text(first)
    assert watch.is_complete(path)
    for now in (0.0, 1.5, 3.0):
        clock.now = now
        assert w.poll() == []
    path.write_text(text)
    os.utime(path, ns=(1, 10**9))
    for now in (3.5, 5.0, 8.0):
        clock.now = now
        assert w.poll() == []
    clock.now = 8.6
    assert w.poll() == [path]


def test_watch_waits_for_a_whole_ply(tmp_path):
    data = trimesh.exchange.ply.export_ply(trimesh.creation.box(BOX_MM), encoding="binary")
    path = tmp_path / "part.ply"
    path.write_bytes(data[:-13])
    assert not watch.is_complete(path)
    path.write_bytes(data)
    assert watch.is_complete(path)


# --- calibration strip ----------------------------------------------------------------

def test_calibration_strip_keeps_other_files(tmp_path, capsys):
    (tmp_path / "thesis.txt").write_text("precious")
    status, out, err = in_process(capsys, "calibration-strip", "--out", tmp_path)
    one_line(status, err, "thesis.txt")
    assert out == "" and (tmp_path / "thesis.txt").read_text() == "precious"


# --- bugs ---------------------------------------------------------------------------

def test_a_bug_when_no_log_can_be_written_is_still_one_line(monkeypatch):
    from core import errors

    monkeypatch.setattr(errors, "log_folders", lambda: [Path("/proc/fabrickator-no-log")])
    try:
        raise ValueError("boom: the layout stage broke\nand said more")
    except ValueError as exc:
        line = errors.bug_line(exc, "python -m core fabricate")
    assert "\n" not in line
    assert line.startswith("bug: ValueError: boom") and "no log of it could be written" in line
