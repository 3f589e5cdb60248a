"""Bad input to ``python -m core stability LAYOUT.json [--out REPORT.json]``: each ends in one
line on stderr naming the problem and exit status 2; never a traceback, a hang, a "bug:" line,
a half-written report or a file the tool did not write overwritten.  Layouts the tool itself
writes (with and without printed parts) are still accepted."""

from __future__ import annotations

import copy
import errno
import json
import os
import stat
import subprocess
import sys
from pathlib import Path

import pytest
import trimesh

from core import forces
from core.cli import main

ROOT = Path(__file__).resolve().parents[2]

#: A hand-made layout: a 2x4 brick (3001) under a 2x4 plate (3020), 4 x 2 x 4 cells.
LAYOUT = {
    "cell_mm": [8.0, 8.0, 3.2], "origin_mm": [0.0, 0.0, 0.0], "shape": [4, 2, 4],
    "bricks": [
        {"id": 0, "part": "3001", "size": [4, 2, 3], "cell": [0, 0, 0], "kind": "lego",
         "printed_part": None, "step": 1},
        {"id": 1, "part": "3020", "size": [4, 2, 1], "cell": [0, 0, 3], "kind": "lego",
         "printed_part": None, "step": 2},
    ],
}


def cli(*args, timeout=120) -> subprocess.CompletedProcess:
    """``python -m core ARGS`` in a subprocess, as a user runs it (for what could hang)."""
    return subprocess.run([sys.executable, "-m", "core", *map(str, args)], cwd=ROOT,
                          capture_output=True, text=True, timeout=timeout)


def run(capsys, *args) -> tuple[int, str, str]:
    """(status, stdout, stderr) of the CLI's ``main`` on ``args``."""
    try:
        status = main([str(a) for a in args])
    except SystemExit as exit_:
        status = exit_.code
    out, err = capsys.readouterr()
    return status, out, err


def one_line(status: int, err: str, *words: str) -> str:
    """Exit status 2 and exactly one stderr line holding ``words`` (no traceback, no bug)."""
    lines = err.strip().splitlines()
    assert status == 2, err
    assert len(lines) == 1, err
    assert "Traceback" not in err and not lines[0].startswith("bug:"), err
    for word in words:
        assert word in lines[0], lines[0]
    return lines[0]


def write(folder: Path, doc, name: str = "layout.json") -> Path:
    path = folder / name
    path.write_text(json.dumps(doc))
    return path


def with_printed(folder: Path) -> dict:
    """LAYOUT with the plate printed as part P1, its mesh in ``folder/parts/P1.stl``."""
    doc = copy.deepcopy(LAYOUT)
    doc["bricks"][1].update(kind="printed", printed_part="P1")
    (folder / "parts").mkdir(exist_ok=True)
    box = trimesh.creation.box((32.0, 16.0, 3.2))
    box.apply_translation(-box.bounds[0] + [0, 0, 9.6])
    box.export(folder / "parts" / "P1.stl")
    return doc


@pytest.fixture(scope="module")
def written(tmp_path_factory) -> Path:
    """An output folder fabricate wrote: a 40 x 24 x 19.2 mm box with a high-res corner
    (so its layout.json has printed bricks and parts/P1.stl)."""
    folder = tmp_path_factory.mktemp("written")
    box = trimesh.creation.box((40.0, 24.0, 19.2))
    box.apply_translation(-box.bounds[0])
    box.export(folder / "box.stl")
    out = folder / "out"
    proc = cli("fabricate", folder / "box.stl", "--out", out, "--quiet", "--no-picture",
               "--high-res=0,0,12,16,8,19.2", timeout=600)
    assert proc.returncode == 0, proc.stderr
    return out


# ---- what the tool writes is still accepted -------------------------------------------------

@pytest.mark.slow
def test_layouts_the_tool_writes_pass(written, tmp_path, capsys):
    doc = json.loads((written / "layout.json").read_text())
    assert any(b["kind"] == "printed" for b in doc["bricks"])
    report = tmp_path / "report.json"
    status, out, err = run(capsys, "stability", written / "layout.json", "--out", report)
    assert status == 0, err
    assert "stands" in out
    assert json.loads(report.read_text())["checked"] is True
    # the same layout without its printed parts (all LEGO) passes too
    for b in doc["bricks"]:
        b.update(kind="lego", printed_part=None)
    status, _, err = run(capsys, "stability", write(tmp_path, doc), "--out", report)
    assert status == 0, err


def test_hand_made_layouts_pass_rotated_and_printed(tmp_path, capsys):
    doc = copy.deepcopy(LAYOUT)
    doc["shape"] = [2, 4, 4]
    for b in doc["bricks"]:
        b["size"] = [2, 4, b["size"][2]]                 # both turned by 90°
    doc["bricks"][0]["load_g"] = 50.0
    status, _, err = run(capsys, "stability", write(tmp_path, doc))
    assert status == 0, err
    status, _, err = run(capsys, "stability", write(tmp_path, with_printed(tmp_path)))
    assert status == 0, err


# ---- files that are not files, or are absurd ------------------------------------------------

def test_fifo_is_refused_without_hanging(tmp_path):
    fifo = tmp_path / "layout.json"
    os.mkfifo(fifo)
    proc = cli("stability", fifo, timeout=60)
    assert proc.returncode == 2 and len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    assert "named pipe" in proc.stderr


@pytest.mark.skipif(not os.path.exists("/dev/zero") or not stat.S_ISCHR(os.stat("/dev/zero").st_mode),
                    reason="needs the /dev/zero device")
def test_endless_device_is_refused():
    proc = cli("stability", "/dev/zero", timeout=60)
    assert proc.returncode == 2 and len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    assert "character device" in proc.stderr


def test_folder_missing_and_huge_files_are_refused(tmp_path, capsys):
    one_line(*run(capsys, "stability", tmp_path)[::2], "directory")
    one_line(*run(capsys, "stability", tmp_path / "none.json")[::2], "no such file")
    huge = tmp_path / "huge.json"
    with open(huge, "wb") as stream:                  # sparse: no real disk used
        stream.truncate(101 * 2**20)
    one_line(*run(capsys, "stability", huge)[::2], "larger than 100 MB")


# ---- documents that crashed -----------------------------------------------------------------

def test_short_cell_and_deep_nesting_are_input_errors(tmp_path, capsys):
    doc = copy.deepcopy(LAYOUT)
    doc["bricks"][0]["cell"] = [0, 0]
    one_line(*run(capsys, "stability", write(tmp_path, doc))[::2], "brick 0", "cell")
    deep = tmp_path / "deep.json"
    deep.write_text("[" * 100_000 + "]" * 100_000)
    one_line(*run(capsys, "stability", deep)[::2], "nested too deeply")


# ---- invalid layouts that used to get a verdict ---------------------------------------------

def _brick(n, **change):
    def edit(doc):
        doc["bricks"][n].update(change)
    return edit


def _grid(**change):
    def edit(doc):
        doc.update(change)
    return edit


def _overlap(doc):
    doc["bricks"][1]["cell"] = [0, 0, 2]
    doc["shape"] = [4, 2, 4]


def _dup_id(doc):
    doc["bricks"][1]["id"] = 0


def _no_bricks(doc):
    doc["bricks"] = []


BAD = {
    "load_nan": (_brick(0, load_g=float("nan")), ["brick 0", "load_g"]),
    "load_negative": (_brick(0, load_g=-100), ["brick 0", "load_g"]),
    "load_infinite": (_brick(1, load_g=float("inf")), ["brick 1", "load_g"]),
    "load_1e308": (_brick(0, load_g=1e308), ["brick 0", "load_g"]),
    "cell_mm_zero": (_grid(cell_mm=[0, 0, 0]), ["cell_mm"]),
    "cell_mm_negative": (_grid(cell_mm=[-8, 8, 3.2]), ["cell_mm"]),
    "cell_mm_nan": (_grid(cell_mm=[float("nan"), 8, 3.2]), ["cell_mm"]),
    "unknown_part": (_brick(0, part="99999"), ["brick 0", "unknown part"]),
    "part_null": (_brick(1, part=None), ["brick 1", "unknown part"]),
    "unknown_kind": (_brick(0, kind="alien"), ["brick 0", "kind"]),
    "overlap": (_overlap, ["brick 1", "overlaps brick 0"]),
    "negative_cell": (_brick(1, cell=[-1, 0, 3]), ["brick 1", "cell"]),
    "huge_cell": (_brick(1, cell=[10**12, 0, 3]), ["brick 1", "outside the grid"]),
    "fractional_cell": (_brick(0, cell=[0.5, 0, 0]), ["brick 0", "cell"]),
    "size_zero": (_brick(0, size=[0, 0, 0]), ["brick 0", "size"]),
    "size_negative": (_brick(0, size=[-4, 2, 3]), ["brick 0", "size"]),
    "size_not_the_parts": (_brick(0, size=[4, 2, 1]), ["brick 0", "3001"]),
    "duplicate_ids": (_dup_id, ["brick 0", "used twice"]),
    "printed_part_path": (_brick(1, kind="printed", printed_part="../../etc/passwd"),
                          ["brick 1", "not a plain name"]),
    "printed_part_separator": (_brick(1, kind="printed", printed_part="a/b"),
                               ["brick 1", "not a plain name"]),
    "printed_part_missing_stl": (_brick(1, kind="printed", printed_part="P9"),
                                 ["brick 1", "P9.stl", "missing"]),
    "negative_step": (_brick(0, step=-1), ["brick 0", "step"]),
    "shape_huge": (_grid(shape=[10**9, 10**9, 10**9]), ["shape"]),
    "no_bricks": (_no_bricks, ["has no bricks"]),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_invalid_layout_is_refused_naming_the_brick(case, tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(forces, "analyse", _never)
    edit, words = BAD[case]
    doc = copy.deepcopy(LAYOUT)
    edit(doc)
    path = write(tmp_path, doc)
    one_line(*run(capsys, "stability", path)[::2], str(path), *words)


def test_printed_part_whose_stl_is_not_a_mesh_is_refused(tmp_path, capsys):
    doc = with_printed(tmp_path)
    (tmp_path / "parts" / "P1.stl").write_text("not a mesh")
    one_line(*run(capsys, "stability", write(tmp_path, doc))[::2], "P1")


def _never(*args, **kwargs):
    raise AssertionError("the force check ran on input that should have been refused")


# ---- --out ----------------------------------------------------------------------------------

def test_out_equal_to_the_layout_is_refused(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(forces, "analyse", _never)
    path = write(tmp_path, LAYOUT)
    before = path.read_bytes()
    one_line(*run(capsys, "stability", path, "--out", path)[::2], "--out", "layout")
    (tmp_path / "link.json").symlink_to(path.name)
    one_line(*run(capsys, "stability", path, "--out", tmp_path / "link.json")[::2], "--out")
    assert path.read_bytes() == before


def test_out_over_a_foreign_file_or_folder_is_refused(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(forces, "analyse", _never)
    path = write(tmp_path, LAYOUT)
    foreign = tmp_path / "notes.json"
    foreign.write_text('{"mine": true}')
    one_line(*run(capsys, "stability", path, "--out", foreign)[::2], "not a stability report")
    assert foreign.read_text() == '{"mine": true}'
    one_line(*run(capsys, "stability", path, "--out", tmp_path)[::2], "directory")
    one_line(*run(capsys, "stability", path, "--out", tmp_path / "no" / "r.json")[::2], "no such folder")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["layout.json", "notes.json"]


def test_an_earlier_report_is_replaced(tmp_path, capsys):
    path = write(tmp_path, LAYOUT)
    report = tmp_path / "report.json"
    assert run(capsys, "stability", path, "--out", report)[0] == 0
    first = json.loads(report.read_text())
    assert first["stable"] is True
    first["mass_g"] = -1                              # recognisably stale
    report.write_text(json.dumps(first))
    status, _, err = run(capsys, "stability", path, "--out", report)
    assert status == 0, err
    assert json.loads(report.read_text())["mass_g"] > 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["layout.json", "report.json"]


@pytest.mark.skipif(not os.path.exists("/dev/full") or not stat.S_ISCHR(os.stat("/dev/full").st_mode),
                    reason="needs the /dev/full device")
def test_out_to_dev_full_is_refused(tmp_path, capsys):
    path = write(tmp_path, LAYOUT)
    one_line(*run(capsys, "stability", path, "--out", "/dev/full")[::2], "/dev/full")
    assert stat.S_ISCHR(os.stat("/dev/full").st_mode)


def test_a_failed_write_leaves_no_half_report(tmp_path, capsys, monkeypatch):
    path = write(tmp_path, LAYOUT)
    report = tmp_path / "report.json"
    assert run(capsys, "stability", path, "--out", report)[0] == 0
    before = report.read_bytes()

    def full(fd):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(os, "fsync", full)
    one_line(*run(capsys, "stability", path, "--out", report)[::2], "cannot write",
             os.strerror(errno.ENOSPC))
    assert report.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["layout.json", "report.json"]


def test_seconds_that_are_not_a_time_above_zero_are_refused(tmp_path, capsys):
    path = write(tmp_path, LAYOUT)
    for bad in ("abc", "0", "-3", "nan", "inf"):
        status, out, err = run(capsys, "stability", path, "--seconds", bad)
        assert out == "", (bad, out)
        one_line(status, err, "--seconds")
    status, out, err = run(capsys, "stability", path, "--seconds", "30")
    assert status == 0 and "stand" in out, err
