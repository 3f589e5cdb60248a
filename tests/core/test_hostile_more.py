"""More hostile input and environment (a second sweep): path names the system refuses,
numbers at the edge of a float, titles the font cannot draw, a 3MF unit that is none,
an empty brick set, watch output places, files a watch skips, a user without a home, a
standard output that cannot be written.  Each ends in one line and exit status 2, or in
a run that does what was asked without extra lines."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

import pytest
import trimesh

from core import watch
from core.errors import InputError, check_path, shown_path
from tests.core.test_hostile import (BOX_CELLS, BOX_MM, IS_ROOT, ROOT, assert_complete,  # noqa: F401
                                     box_stl, cli, in_process, one_line)

LONG = "a" * 5000


# --- 1. path names the system refuses ------------------------------------------------

def test_shown_path_keeps_both_ends_of_a_long_name():
    shown = shown_path("/x/" + LONG + "/end.stl")
    assert len(shown) <= 80 and shown.startswith("/x/aaa") and shown.endswith("end.stl")
    assert shown_path("/short") == "/short"


def test_check_path_turns_system_refusals_into_one_line(tmp_path):
    loop = tmp_path / "loop"
    loop.symlink_to(loop)
    for path, words in ((LONG, "too long"), (loop, "symbolic links")):
        with pytest.raises(InputError) as err:
            check_path(path, "--previous")
        assert "--previous" in str(err.value) and words in str(err.value)
        assert len(str(err.value)) < 200
    check_path(tmp_path / "missing", "--out")          # left to the option's own check


@pytest.mark.parametrize("where", ["previous", "model", "solid", "out", "out-parent"])
def test_fabricate_path_options_with_a_name_too_long(box_stl, tmp_path, capsys, where):
    args = {"previous": (box_stl, "--out", tmp_path / "o", "--previous", LONG),
            "model": (LONG, "--out", tmp_path / "o"),
            "solid": (box_stl, "--out", tmp_path / "o", "--high-res-solid", LONG),
            "out": (box_stl, "--out", tmp_path / LONG),
            "out-parent": (box_stl, "--out", tmp_path / LONG / "o")}[where]
    status, _, err = in_process(capsys, "fabricate", *args, "--quiet", "--no-picture")
    line = one_line(status, err)
    assert "long" in line and len(line) < 300
    assert sorted(p.name for p in tmp_path.iterdir()) == ["box.stl"]


def test_fabricate_path_options_in_a_loop_of_links(box_stl, tmp_path, capsys):
    loop = tmp_path / "loop"
    loop.symlink_to(loop)
    for args, flag in (((loop, "--out", tmp_path / "o"), "MODEL"),
                       ((box_stl, "--out", loop / "o"), "--out"),
                       ((box_stl, "--out", tmp_path / "o", "--previous", loop), "--previous"),
                       ((box_stl, "--out", tmp_path / "o", "--high-res-solid", loop),
                        "--high-res-solid")):
        status, _, err = in_process(capsys, "fabricate", *args, "--quiet", "--no-picture")
        one_line(status, err, flag, "symbolic links")
    assert not (tmp_path / "o").exists()


def test_watch_path_options_are_checked_before_watching(tmp_path, capsys):
    (tmp_path / "in").mkdir()
    for args, flag in (((LONG, "--out", tmp_path / "o"), "FOLDER"),
                       ((tmp_path / "in", "--out", LONG), "--out"),
                       ((tmp_path / "in", "--out", tmp_path / "o", "--previous", LONG), "--previous"),
                       ((tmp_path / "in", "--out", tmp_path / "o", "--high-res-solid", LONG),
                        "--high-res-solid")):
        status, _, err = in_process(capsys, "watch", *args, "--timeout", "1")
        line = one_line(status, err, flag, "too long")
        assert len(line) < 300 and "watching" not in err


def test_watch_refuses_a_previous_that_is_no_output_before_watching(tmp_path, capsys):
    status, _, err = in_process(capsys, "watch", tmp_path, "--out", tmp_path / "o",
                                "--previous", tmp_path / "nope", "--timeout", "1")
    one_line(status, err, "--previous", "no such folder")
    assert "watching" not in err


# --- 2. numbers at the edge of a float --------------------------------------------------

def test_an_absurd_scale_is_refused_before_any_arithmetic(box_stl, tmp_path, capsys):
    for value in ("1e308", "1e-300"):
        status, _, err = in_process(capsys, "fabricate", box_stl, "--out", tmp_path / "o",
                                    f"--scale={value}", "--quiet")
        one_line(status, err, "--scale", "out of range")
    assert not (tmp_path / "o").exists()


def test_a_huge_coordinate_times_the_scale_is_one_line(tmp_path, capsys):
    obj = tmp_path / "huge.obj"
    obj.write_text("v 0 0 0\nv 1e308 0 0\nv 0 1e308 0\nv 0 0 1e308\n"
                   "f 1 2 3\nf 1 2 4\nf 1 3 4\nf 2 3 4\n")
    status, _, err = in_process(capsys, "fabricate", obj, "--out", tmp_path / "o",
                                "--units", "m", "--quiet")
    one_line(status, err, "huge.obj")
    assert "RuntimeWarning" not in err


def test_a_huge_high_res_box_marks_the_whole_part(box_stl, tmp_path, capsys):
    status, _, err = in_process(capsys, "fabricate", box_stl, "--out", tmp_path / "o",
                                "--high-res=-1e300,-1e300,-1e300,1e300,1e300,1e300",
                                "--quiet", "--no-picture")
    assert status == 0, err
    assert "RuntimeWarning" not in err and "marks no cell" not in err
    doc = json.loads((tmp_path / "o" / "report.json").read_text())
    assert doc["printed_parts"], doc.get("warnings")


def test_box_cells_of_a_huge_box_are_the_whole_grid():
    import numpy as np

    from core import high_res
    from core.model import Grid

    grid = Grid(origin=np.zeros(3), cell=np.array([8.0, 8.0, 3.2]),
                filled=np.ones((3, 3, 4), dtype=bool))
    box = high_res.parse_box("-1e300,-1e300,-1e300,1e300,1e300,1e300")
    assert high_res.box_cells(grid, box).all()


def test_a_huge_load_box_carries_the_whole_layout(box_stl, tmp_path):
    proc = cli("fabricate", box_stl, "--out", tmp_path / "o", "--quiet", "--no-picture")
    assert proc.returncode == 0, proc.stderr
    proc = cli("stability", tmp_path / "o" / "layout.json",
               "--load=-1e308,-1e308,-1e308,1e308,1e308,1e308:5", timeout=120)
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr
    assert "stand" in proc.stdout


# --- 3. a title the font cannot draw ------------------------------------------------------

def test_a_model_named_with_an_emoji_draws_its_picture_without_warnings(box_stl, tmp_path):
    odd = tmp_path / "ünï😀 $x^$.stl"
    shutil.copy(box_stl, odd)
    proc = cli("fabricate", odd, "--out", tmp_path / "o", "--quiet",
               env={"LANG": "C", "LC_ALL": "C", "PYTHONUTF8": "0"})   # the name read as ASCII
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == "", proc.stderr
    assert (tmp_path / "o" / "layout.png").stat().st_size > 0


def test_drawable_titles_replace_what_the_font_lacks():
    from core.render import _drawable

    assert _drawable("box \u00fc \udcc3\udcbc \U000e0001") == "box \u00fc ?? ?"


# --- 4. a 3MF unit that is none -------------------------------------------------------------

def _threemf(path: Path, unit: str) -> Path:
    plain = path.with_name("plain.3mf")
    trimesh.creation.box(BOX_MM).export(plain)
    with zipfile.ZipFile(plain) as src, zipfile.ZipFile(path, "w") as dst:
        for name in src.namelist():
            data = src.read(name)
            if name.endswith(".model"):
                assert b'unit="millimeter"' in data
                data = data.replace(b'unit="millimeter"', f'unit="{unit}"'.encode())
            dst.writestr(name, data)
    plain.unlink()
    return path


def test_a_3mf_unit_outside_the_spec_is_refused(tmp_path, capsys):
    model = _threemf(tmp_path / "far.3mf", "parsec")
    status, _, err = in_process(capsys, "fabricate", model, "--out", tmp_path / "o", "--quiet")
    one_line(status, err, "far.3mf", "parsec")
    assert not (tmp_path / "o").exists()


def test_a_3mf_in_millimeter_is_still_read(tmp_path, capsys):
    model = _threemf(tmp_path / "mm.3mf", "millimeter")
    status, _, err = in_process(capsys, "fabricate", model, "--out", tmp_path / "o", "--quiet",
                                "--no-picture")
    assert status == 0, err


# --- 5. an empty brick set --------------------------------------------------------------------

@pytest.mark.parametrize("value", ["", " ", ",,"])
def test_an_empty_parts_value_is_refused(box_stl, tmp_path, capsys, value):
    status, _, err = in_process(capsys, "fabricate", box_stl, "--out", tmp_path / "o",
                                f"--parts={value}", "--quiet")
    one_line(status, err, "--parts")
    assert not (tmp_path / "o").exists()


# --- 6. watch output places ------------------------------------------------------------------

def test_watch_refuses_the_output_places_fabricate_refuses(tmp_path, capsys):
    folder = tmp_path / "in"
    folder.mkdir()
    (folder / "mine.txt").write_text("mine")
    other = tmp_path / "other"
    other.mkdir()
    (other / "notes.txt").write_text("mine")
    for out, words in (("/", "root folder"), (folder, "watched folder"),
                       (other, "other files")):
        status, _, err = in_process(capsys, "watch", folder, "--out", out, "--timeout", "1")
        one_line(status, err, "--out", *words.split(" ", 1)[:1])
        assert "watching" not in err
    assert (folder / "mine.txt").read_text() == "mine"
    assert sorted(p.name for p in other.iterdir()) == ["notes.txt"]


def test_watch_takes_a_root_of_earlier_outputs(box_stl, tmp_path, capsys):
    root = tmp_path / "root"
    status, _, err = in_process(capsys, "fabricate", box_stl, "--out", root / "box-1",
                                "--quiet", "--no-picture")
    assert status == 0, err
    (tmp_path / "in").mkdir()
    status, _, err = in_process(capsys, "watch", tmp_path / "in", "--out", root,
                                "--timeout", "0.5")
    assert status == 0, err
    assert err.startswith("watching")


# --- 7. a file a watch skips -------------------------------------------------------------------

def test_watch_names_a_file_that_is_no_model_and_keeps_watching(tmp_path):
    folder = tmp_path / "in"
    folder.mkdir()
    (folder / "x.stl").write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(range(256)) * 8)
    proc = cli("watch", folder, "--out", tmp_path / "o", "--existing", "--timeout", "15",
               timeout=120)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert lines[0].startswith("watching")
    skipped = [line for line in lines if "x.stl" in line]
    assert len(skipped) == 1 and skipped[0].startswith("skipped: x.stl:"), lines
    assert "STL" in skipped[0]
    assert lines[-1] == "stopped after 0 version(s) built" or len(lines) == 2


def test_folder_watcher_reports_an_incomplete_file_once_until_it_changes(tmp_path):
    clock = [0.0]
    skipped = []
    (tmp_path / "x.stl").write_bytes(b"not an stl at all")
    watcher = watch.FolderWatcher(tmp_path, include_existing=True, clock=lambda: clock[0],
                                  on_skip=lambda path, why: skipped.append((path.name, why)))
    for _ in range(30):
        assert watcher.poll() == []
        clock[0] += 0.5
    assert len(skipped) == 1 and skipped[0][0] == "x.stl"
    box = trimesh.creation.box(BOX_MM)
    box.export(tmp_path / "x.stl")
    found = []
    for _ in range(10):
        found += watcher.poll()
        clock[0] += 0.5
    assert found == [tmp_path / "x.stl"] and len(skipped) == 1


# --- 8. a user without a home --------------------------------------------------------------------

def test_a_user_without_a_home_and_a_read_only_package_builds(box_stl):
    if not IS_ROOT or shutil.which("setpriv") is None:
        pytest.skip("needs root and util-linux setpriv to run the CLI as user nobody")
    if os.access(ROOT / "core", os.W_OK, effective_ids=False) and os.stat(ROOT / "core").st_mode & 0o002:
        pytest.skip("the package folder is writable by everyone")
    scratch = Path(tempfile.mkdtemp(prefix="fabrickator-test-nohome-"))
    try:
        scratch.chmod(0o777)
        tmp = scratch / "tmp"                     # a fresh temporary folder: nothing cached yet
        tmp.mkdir(mode=0o777)
        tmp.chmod(0o777)
        model = scratch / "box.stl"
        shutil.copy(box_stl, model)
        model.chmod(0o644)
        proc = cli("fabricate", model, "--out", scratch / "out", "--quiet", timeout=600,
                   prefix=("setpriv", "--reuid=65534", "--regid=65534", "--clear-groups"),
                   env={"HOME": "/nonexistent", "TMPDIR": str(tmp), "XDG_CACHE_HOME": "",
                        "XDG_CONFIG_HOME": "", "NUMBA_CACHE_DIR": "", "MPLCONFIGDIR": ""})
        assert proc.returncode == 0, proc.stderr
        assert proc.stderr == "", proc.stderr
        assert (scratch / "out" / "report.json").is_file()
    finally:
        shutil.rmtree(scratch, ignore_errors=True)


# --- 9. a standard output that cannot be written ---------------------------------------------------

def _run_with_stdout(args, stdout) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "core", *map(str, args)], cwd=ROOT,
                          stdout=stdout, stderr=subprocess.PIPE, text=True, timeout=300)


def test_a_closed_stdout_finishes_quietly(box_stl, tmp_path):
    proc = subprocess.run(f'"{sys.executable}" -m core fabricate --quiet --no-picture '
                          f'"{box_stl}" --out "{tmp_path / "o"}" >&-', shell=True, cwd=ROOT,
                          stderr=subprocess.PIPE, text=True, timeout=300)
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr
    assert_complete(tmp_path / "o")


def test_a_stdout_that_cannot_be_written_is_one_line(box_stl, tmp_path):
    with open(os.devnull, "rb") as read_only:            # writing it fails (EBADF)
        proc = _run_with_stdout(["fabricate", "--quiet", "--no-picture", box_stl,
                                 "--out", tmp_path / "o"], read_only)
    one_line(proc.returncode, proc.stderr, "standard output could not be written")
    assert_complete(tmp_path / "o")
