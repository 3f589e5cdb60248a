"""More hostile input and environment (a second sweep): path names the system refuses,
numbers at the edge of a float, titles the font cannot draw, a 3MF unit that is none,
an empty brick set, watch output places, files a watch skips, a user without a home, a
standard output that cannot be written, a standard error that is closed, too little
memory.  Each ends in one line and exit status 2, or in a run that does what was asked
without extra lines."""

from __future__ import annotations

import errno
import json
import os
import resource
import shlex
import shutil
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

import numpy as np
import pytest
import trimesh

from core import watch
from core.errors import (ADDRESS_SPACE_NEEDED, InputError, check_path, memory_shortage,
                         shown_path)
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


@pytest.mark.slow
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


@pytest.mark.slow
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
    from core.instructions.render import _drawable

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

@pytest.mark.slow
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
    assert "not a valid STL file" in skipped[0] and skipped[0].count("x.stl") == 1
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

@pytest.mark.slow
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


# --- 10. a standard error that is closed ------------------------------------------------------------

def shell(args, redirect: str, timeout: float = 300) -> subprocess.CompletedProcess:
    """``python -m core ARGS REDIRECT`` as the shell runs it (``2>&-`` closes stderr)."""
    command = " ".join(shlex.quote(str(a)) for a in (sys.executable, "-m", "core", *args))
    return subprocess.run(f"{command} {redirect}", shell=True, cwd=ROOT, capture_output=True,
                          text=True, timeout=timeout)


@pytest.mark.slow
@pytest.mark.parametrize("redirect", ["2>&-", ">&- 2>&-", "<&- 2>&-", "2</dev/null"])
def test_bad_input_with_stderr_closed_still_exits_2(tmp_path, redirect):
    proc = shell(["fabricate", tmp_path / "missing.stl", "--out", tmp_path / "o"], redirect)
    assert proc.returncode == 2 and proc.stderr == "", proc.stderr
    assert not (tmp_path / "o").exists()
    proc = shell(["fabricate", "--no-such-option"], redirect)
    assert proc.returncode == 2 and proc.stderr == "", proc.stderr


@pytest.mark.slow
@pytest.mark.parametrize("redirect", ["2>&-", ">&- 2>&-", "2</dev/null"])
def test_a_run_with_stderr_closed_finishes_and_exits_0(box_stl, tmp_path, redirect):
    proc = shell(["fabricate", box_stl, "--out", tmp_path / "o", "--no-picture"], redirect)
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr
    assert_complete(tmp_path / "o")
    assert ("bricks" in proc.stdout) == (">&-" not in redirect.split()), proc.stdout


@pytest.mark.skipif(not Path("/proc/self/fd").is_dir(), reason="needs /proc/self/fd")
def test_closed_standard_streams_get_the_null_device(tmp_path):
    probe = tmp_path / "fds.txt"
    code = ("import os, sys; from core import cli; cli._open_standard_streams(); "
            f"f = open({str(probe)!r}, 'w'); "
            "f.write(' '.join([os.readlink(f'/proc/self/fd/{n}') for n in range(3)]"
            " + [str(s is None) for s in (sys.stdin, sys.stdout, sys.stderr)]))")
    proc = subprocess.run(f"{shlex.quote(sys.executable)} -c {shlex.quote(code)} <&- >&- 2>&-",
                          shell=True, cwd=ROOT, timeout=120)
    assert proc.returncode == 0
    assert probe.read_text() == "/dev/null /dev/null /dev/null False False False"


# --- 11. too little memory ---------------------------------------------------------------------------

def limited(args, limit_mb: int, timeout: float) -> subprocess.CompletedProcess:
    """``python -m core ARGS`` with its address space limited to ``limit_mb`` MB (``ulimit -v``)."""
    def limit():
        hard = resource.getrlimit(resource.RLIMIT_AS)[1]
        resource.setrlimit(resource.RLIMIT_AS, (limit_mb << 20, hard))

    return subprocess.run([sys.executable, "-m", "core", *map(str, args)], cwd=ROOT,
                          capture_output=True, text=True, timeout=timeout, preexec_fn=limit)


def works_or_not_enough_memory(proc: subprocess.CompletedProcess, out: Path | None) -> None:
    """Either the run did what was asked, or it ended in one line naming the memory and
    left no output."""
    if proc.returncode == 0:
        assert "Traceback" not in proc.stderr, proc.stderr
        return
    one_line(proc.returncode, proc.stderr, "not enough memory", "ulimit -v")
    if out is not None:
        assert not out.exists() and not [p for p in out.parent.iterdir() if p.name.startswith(".")]


@pytest.mark.parametrize("limit_mb", [200, 300, 500, 1000])
def test_fabricate_with_a_small_address_space_never_hangs(box_stl, tmp_path, limit_mb):
    model = ROOT / "examples" / "build" / "hmd.step"        # loads OpenCascade too
    out = tmp_path / "o"
    proc = limited(["fabricate", model if model.is_file() else box_stl, "--out", out, "--quiet"],
                   limit_mb, timeout=300)
    works_or_not_enough_memory(proc, out)
    if limit_mb << 20 < ADDRESS_SPACE_NEEDED["fabricate"]:
        assert proc.returncode == 2 and f"limited to {limit_mb:,} MB" in proc.stderr


@pytest.fixture(scope="module")
def box_layout(tmp_path_factory) -> Path:
    """The layout.json of a fabricated box."""
    folder = tmp_path_factory.mktemp("box-layout")
    trimesh.creation.box(BOX_MM).export(folder / "box.stl")
    proc = cli("fabricate", folder / "box.stl", "--out", folder / "o", "--quiet", "--no-picture")
    assert proc.returncode == 0, proc.stderr
    return folder / "o" / "layout.json"


@pytest.mark.parametrize("limit_mb", [200, 300, 500, 1000])
def test_stability_with_a_small_address_space_never_hangs(box_layout, tmp_path, limit_mb):
    proc = limited(["stability", box_layout, "--out", tmp_path / "verdict.json"], limit_mb,
                   timeout=300)
    works_or_not_enough_memory(proc, None)
    if limit_mb << 20 < ADDRESS_SPACE_NEEDED["stability"]:
        assert proc.returncode == 2 and not (tmp_path / "verdict.json").exists()
    else:
        assert proc.returncode == 0 and "stands" in proc.stdout


@pytest.mark.slow
def test_memory_running_out_mid_run_is_one_line_and_leaves_nothing(tmp_path):
    cube = tmp_path / "cube.stl"                         # 2.7 million cells, hollowed
    trimesh.creation.box((1500.0, 1500.0, 1500.0)).export(cube)
    proc = limited(["fabricate", cube, "--out", tmp_path / "o", "--quiet"],
                   (ADDRESS_SPACE_NEEDED["fabricate"] >> 20) + 64, timeout=600)
    one_line(proc.returncode, proc.stderr, "not enough memory", "ulimit -v")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cube.stl"]


def _raised_from(cause: BaseException, outer: BaseException) -> BaseException:
    try:
        try:
            raise cause
        except BaseException as inner:
            raise outer from inner
    except BaseException as err:
        return err


def test_memory_shortage_names_what_the_system_refused():
    llvm = _raised_from(OSError("/x/libllvmlite.so: failed to map segment from shared object"),
                        OSError("Could not find/load shared object file"))
    for exc, words in ((MemoryError("Unable to allocate 155. MiB for an array"), "155. MiB"),
                       (ImportError("libscipy_openblas.so: failed to map segment from shared "
                                    "object"), "libscipy_openblas.so"),
                       (llvm, "libllvmlite.so"),
                       (RuntimeError("can't start new thread"), "thread could not be started"),
                       (OSError(errno.ENOMEM, "Cannot allocate memory"), "Cannot allocate")):
        line = memory_shortage(exc)
        assert line.startswith("not enough memory: ") and words in line and "\n" not in line
    for exc in (ValueError("boom"), ImportError("No module named 'x'"), RuntimeError("boom"),
                OSError(errno.ENOENT, "No such file or directory")):
        assert memory_shortage(exc) is None


@pytest.mark.skipif(not Path("/proc/self/status").is_file(), reason="needs /proc/self/status")
@pytest.mark.parametrize("given, expected", [({}, "1"), ({"OPENBLAS_NUM_THREADS": "3"}, "3"),
                                             ({"OMP_NUM_THREADS": "2"}, "None")])
def test_one_openblas_thread_unless_the_user_chose(given, expected):
    env = {k: v for k, v in os.environ.items()
           if k not in ("OPENBLAS_NUM_THREADS", "GOTO_NUM_THREADS", "OMP_NUM_THREADS")}
    code = ("import core, os, numpy, scipy.linalg; print(os.environ.get('OPENBLAS_NUM_THREADS'), "
            "open('/proc/self/status').read().split('Threads:')[1].split()[0])")
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env={**env, **given},
                          capture_output=True, text=True, timeout=120)
    value, threads = proc.stdout.split()
    assert value == expected
    if expected == "1":
        assert threads == "1"              # neither numpy's nor scipy's OpenBLAS started one


# --- 12. a watched file that is no model ---------------------------------------------------------

def _no_models(folder: Path) -> dict[str, bytes]:
    """Files under a model's name that are none, none of which looks complete."""
    noise = np.random.default_rng(7).bytes(3000)
    files = {"picture.stl": b"\x89PNG\r\n\x1a\n" + bytes(range(256)) * 8,
             "noise.obj": noise + b"x", "noise.ply": noise, "noise.3mf": noise}
    for name, data in files.items():
        (folder / name).write_bytes(data)
        assert not watch.is_complete(folder / name)
    return files


def test_watch_skips_a_file_that_is_no_model_once_with_the_line_fabricate_gives(tmp_path, capsys):
    folder = tmp_path / "in"
    folder.mkdir()
    files = _no_models(folder)
    clock, skipped = [0.0], []
    watcher = watch.FolderWatcher(folder, include_existing=True, clock=lambda: clock[0],
                                  on_skip=lambda path, why: skipped.append((path.name, why)))
    for _ in range(60):                                   # 30 s, polled every 0.5 s
        assert watcher.poll() == []
        clock[0] += 0.5
    assert sorted(name for name, _ in skipped) == sorted(files)
    for name, why in skipped:
        assert why.startswith(f"{name}: ") and "not a complete file" not in why
        status, _, err = in_process(capsys, "fabricate", folder / name, "--out", tmp_path / "o",
                                    "--quiet")
        assert one_line(status, err) == f"error: {why}"


def test_watch_says_a_readable_file_looks_incomplete(tmp_path):
    (tmp_path / "part.obj").write_bytes(b"v 0 0 0\nv 10 0 0\nv 0 10 0\nv 0 0 10\n"
                                        b"f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4")
    why = watch.skip_reason(tmp_path / "part.obj", 10)
    assert why.startswith("part.obj: unchanged for 10 s but not a complete file: an OBJ file "
                          "must end with a line break"), why


@pytest.mark.slow
def test_watch_names_each_file_that_is_no_model_once(tmp_path):
    folder = tmp_path / "in"
    folder.mkdir()
    files = _no_models(folder)
    (folder / "ends.obj").write_bytes(np.random.default_rng(8).bytes(3000) + b"\n")
    proc = cli("watch", folder, "--out", tmp_path / "o", "--existing", "--timeout", "20",
               "--quiet", timeout=180)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stderr.strip().splitlines()
    for name in files:
        named = [line for line in lines if name in line]
        assert len(named) == 1 and named[0].startswith(f"skipped: {name}: "), lines
        assert named[0].count(name) == 1 and "not a complete file" not in named[0]
    assert [line for line in lines if "ends.obj" in line] == [
        "error: ends.obj: not a valid OBJ file (binary content that is not OBJ data)"], lines
    assert "Traceback" not in proc.stderr


# --- a stop signal during a long force program ----------------------------------------

@pytest.mark.slow
def test_sigterm_during_a_force_program_stops_the_run_at_once(tmp_path):
    """A force program may run for minutes (HiGHS, in C); a SIGTERM must still end the run
    in one line at once: the program runs in a worker thread that HiGHS's user interrupt
    stops.  Before, the run went on to the end of the program (17.8 s here)."""
    import signal
    import time

    from tests.core.test_forces import slab_over_box

    layout = tmp_path / "layout.json"
    layout.write_text(json.dumps(slab_over_box(outer=(64, 64, 66), wall=2, rim=8).to_json()))
    run = subprocess.Popen([sys.executable, "-m", "core", "stability", str(layout)], cwd=ROOT,
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    time.sleep(12)                           # well into its programs (90 s in all)
    assert run.poll() is None
    sent = time.perf_counter()
    run.send_signal(signal.SIGTERM)
    out, err = run.communicate(timeout=60)
    assert time.perf_counter() - sent < 3
    assert run.returncode == 128 + signal.SIGTERM
    assert err.strip().splitlines() == ["stopped by SIGTERM: nothing half-written was left behind"]
    assert out == ""


def test_a_broken_step_file_prints_nothing_but_the_one_line(tmp_path):
    """OpenCascade's STEP parser prints its complaints (``**** ERR StepFile ...``) on
    standard output from C++: a broken STEP file still ends in one line, on stderr, and
    nothing on stdout."""
    junk = tmp_path / "junk.step"
    junk.write_text("ISO-10303-21;\nHEADER;\ngarbage (((;\nENDSEC;\nDATA;\n#1=FOO(;\nENDSEC;\n"
                    "END-ISO-10303-21;\n")
    run = cli("fabricate", junk, "--out", tmp_path / "out", "--quiet")
    one_line(run.returncode, run.stderr, "junk.step", "not a valid STEP file")
    assert run.stdout == "" and not (tmp_path / "out").exists()
