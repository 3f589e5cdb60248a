"""The calibration strip (python -m core calibration-strip), measured on the files it writes.

Known answers: the default strip has the seven values -0.10 .. +0.20 mm in
steps of 0.05; a stud of value v is 4.8 + v across, a socket 4.8 + v between
opposite walls, 2.0 mm deep under a 1.0 mm roof, the stud 1.7 mm high on the
3.0 mm block.  Everything is read off the STL with sections, not taken from
core.parts.calibration.
"""

from __future__ import annotations

import contextlib
import io
import re
from pathlib import Path

import numpy as np
import pytest
import trimesh

from core.cli import main
from core.errors import InputError
from core.parts import calibration
from core.parts.interfaces import Fit

DEFAULT_VALUES = [-0.10, -0.05, 0.0, 0.05, 0.10, 0.15, 0.20]
BLOCK_TOP = 2.0 + 1.0          # socket depth + roof
STUD_TOP = BLOCK_TOP + 1.7     # + stud height
FILES = ("calibration_strip.stl", "calibration_strip.3mf", "README.txt")


def inside(points: np.ndarray, ring: np.ndarray) -> np.ndarray:
    """Even-odd test: which of the (n, 2) ``points`` lie inside the closed (m, 2) ``ring``."""
    a, b = ring, np.roll(ring, -1, axis=0)
    x, y = points[:, None, 0], points[:, None, 1]
    crosses = (a[:, 1] > y) != (b[:, 1] > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        at = a[:, 0] + (y - a[:, 1]) * (b[:, 0] - a[:, 0]) / (b[:, 1] - a[:, 1])
    return (crosses & (x < at)).sum(axis=1) % 2 == 1


def section_loops(mesh: trimesh.Trimesh, z: float):
    """The closed loops (x, y corners) of the mesh's horizontal section at ``z``, as
    (outer boundaries, holes): a loop inside an odd number of others is a hole."""
    section = mesh.section(plane_origin=(0.0, 0.0, z), plane_normal=(0.0, 0.0, 1.0))
    if section is None:
        return [], []
    loops = [np.asarray(d)[:-1, :2] for d in section.discrete]
    depth = [sum(bool(inside(loop[:1], other)[0]) for other in loops if other is not loop)
             for loop in loops]
    return ([l for l, d in zip(loops, depth) if d % 2 == 0],
            [l for l, d in zip(loops, depth) if d % 2 == 1])


def stud_diameters(mesh):
    """(x centre, diameter) of every loop of the section at half the stud's height,
    left to right; the diameter is twice the mean distance of the loop's corners
    from their centroid (corners lie on the circle)."""
    out = []
    for ring in section_loops(mesh, BLOCK_TOP + 1.7 / 2)[0]:
        centre = ring.mean(axis=0)
        out.append((centre[0], 2 * np.linalg.norm(ring - centre, axis=1).mean()))
    return sorted(out)


def socket_widths(mesh, z=1.0):
    """(x centre, width in x, width in y) of every hole of the section at ``z``, left to right."""
    return sorted((ring[:, 0].mean(), np.ptp(ring[:, 0]), np.ptp(ring[:, 1]))
                  for ring in section_loops(mesh, z)[1])


def run(capsys, *args):
    """(exit status, stdout lines, stderr) of ``python -m core calibration-strip ARGS``."""
    try:
        status = main(["calibration-strip", *map(str, args)])
    except SystemExit as exc:
        status = exc.code
    out, err = capsys.readouterr()
    return status, out.splitlines(), err


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """The default strip written by the CLI: (folder, stdout lines)."""
    folder = tmp_path_factory.mktemp("strip")
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(["calibration-strip", "--out", str(folder)]) == 0
    return folder, out.getvalue().splitlines()


@pytest.fixture(scope="module")
def mesh(written):
    return trimesh.load(written[0] / "calibration_strip.stl", force="mesh")


@pytest.mark.slow
def test_one_line_per_file_written(written):
    folder, lines = written
    assert lines == [str(folder / name) for name in FILES]
    for name in FILES:
        assert (folder / name).stat().st_size > 0


def test_stl_is_one_watertight_solid_in_its_print_pose(mesh):
    assert mesh.is_watertight
    assert mesh.is_winding_consistent
    assert len(mesh.split(only_watertight=False)) == 1
    assert mesh.volume > 0
    assert mesh.bounds[0][2] == pytest.approx(0.0, abs=1e-6)
    assert mesh.bounds[1][2] == pytest.approx(STUD_TOP, abs=1e-4)
    assert mesh.bounds[1][0] - mesh.bounds[0][0] < 120  # fits any bed


def test_3mf_is_the_same_solid(written, mesh):
    other = trimesh.load(written[0] / "calibration_strip.3mf", force="mesh")
    assert other.is_watertight
    assert other.volume == pytest.approx(mesh.volume, rel=1e-6)
    assert np.allclose(other.bounds, mesh.bounds, atol=1e-4)


def test_one_stud_per_value_of_four_point_eight_plus_the_value(mesh):
    studs = stud_diameters(mesh)
    assert len(studs) == len(DEFAULT_VALUES)
    diameters = [d for _, d in studs]
    assert diameters == pytest.approx([4.8 + v for v in DEFAULT_VALUES], abs=0.002)


def test_one_socket_per_value_of_four_point_eight_plus_the_value(mesh):
    sockets = socket_widths(mesh)
    assert len(sockets) == len(DEFAULT_VALUES)
    for (_, wx, wy), value in zip(sockets, DEFAULT_VALUES):
        assert wx == pytest.approx(4.8 + value, abs=1e-4)
        assert wy == pytest.approx(4.8 + value, abs=1e-4)


def test_sockets_open_on_the_underside_two_mm_deep_under_a_roof(mesh):
    assert len(socket_widths(mesh, 0.01)) == len(DEFAULT_VALUES)   # open on the bed
    assert len(socket_widths(mesh, 1.99)) == len(DEFAULT_VALUES)
    assert socket_widths(mesh, 2.01) == []                         # the 1.0 mm roof
    assert len(section_loops(mesh, 0.5)[0]) == 1                   # blocks joined by the band


def test_each_column_stud_above_its_socket_and_alone(mesh):
    studs, sockets = stud_diameters(mesh), socket_widths(mesh)
    for (xs, _), (xh, _, _) in zip(studs, sockets):
        assert xs == pytest.approx(xh, abs=1e-3)
    spacing = np.diff([x for x, _ in studs])
    assert np.allclose(spacing, spacing[0], atol=1e-3)
    # no LEGO brick (studs every 8 mm) can clamp two neighbouring columns
    assert spacing[0] > 8.0 + 1.5
    assert abs(spacing[0] - 8 * round(spacing[0] / 8)) > 1.5


def test_every_column_has_its_label_beside_it(mesh):
    studs = stud_diameters(mesh)
    spacing = studs[1][0] - studs[0][0]
    # above the 1.2 mm band only the blocks and the raised letters; one outer loop per glyph
    letters = [ring for ring in section_loops(mesh, 1.5)[0] if np.ptp(ring[:, 0]) < 5]
    for (x, _), value in zip(studs, DEFAULT_VALUES):
        mine = [ring for ring in letters if abs(ring[:, 0].mean() - x) < spacing / 2]
        text = "0.00" if value == 0 else f"{value:+.2f}"
        assert len(mine) == len(text), (value, len(mine))
        assert all(ring[:, 1].min() > 7.8 for ring in mine)  # on the band, beside the block
        xs = np.concatenate([ring[:, 0] for ring in mine])
        assert (xs.min() + xs.max()) / 2 == pytest.approx(x, abs=0.5)


def test_readme_says_how_to_read_it_and_names_the_options(written):
    text = (written[0] / "README.txt").read_text()
    for word in ("--stud-fit", "--socket-fit", "calibration_strip.stl", "Preferences",
                 "upside down", "3024"):
        assert word in text
    listed = re.search(r"Left to right, as the numbers read: (.+?)\.\s", text, re.S)
    assert listed
    assert [float(v) for v in listed.group(1).split(",")] == pytest.approx(DEFAULT_VALUES)


@pytest.mark.slow
def test_range_and_step_options(tmp_path, capsys):
    # 0.1 + 2 * 0.05 is 0.20000000000000004 in floats: the label and the stud say 0.20
    status, lines, err = run(capsys, "--out", tmp_path, "--from", 0.1, "--to", 0.3, "--step", 0.05)
    assert status == 0, err
    assert len(lines) == 3
    mesh = trimesh.load(tmp_path / "calibration_strip.stl", force="mesh")
    expected = [4.9, 4.95, 5.0, 5.05, 5.1]
    assert [d for _, d in stud_diameters(mesh)] == pytest.approx(expected, abs=0.002)
    assert [w for _, w, _ in socket_widths(mesh)] == pytest.approx(expected, abs=1e-4)
    assert "+0.10, +0.15, +0.20, +0.25, +0.30." in (tmp_path / "README.txt").read_text()


@pytest.mark.parametrize("args, words", [
    (("--step", 0), "must be positive"),
    (("--step", -0.05), "must be positive"),
    (("--step", 0.001), "finer"),
    (("--from", 0.3, "--to", 0.1), "empty"),
    (("--from", "nan"), "finite"),
    (("--to", 5), "outside"),
    (("--from", -0.8, "--to", 0.8, "--step", 0.05), "columns"),
    (("--step", "abc"), "invalid float"),
])
def test_bad_arguments_are_one_line_and_status_two(tmp_path, capsys, args, words):
    status, lines, err = run(capsys, "--out", tmp_path / "out", *args)
    assert status == 2
    assert lines == []
    assert len(err.strip().splitlines()) == 1 and words in err
    assert "Traceback" not in err
    assert not (tmp_path / "out").exists()


def test_an_unwritable_out_is_one_line_and_status_two(tmp_path, capsys):
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    for out in (blocker, blocker / "below"):
        status, lines, err = run(capsys, "--out", out)
        assert status == 2 and lines == []
        assert len(err.strip().splitlines()) == 1 and str(out) in err



def test_fits_are_saved_per_printer_and_filament(tmp_path, monkeypatch):
    import json

    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path / "cfg"))
    path = calibration.fits_file()
    assert path == tmp_path / "cfg" / "fabrickator" / "fits.json" and not path.exists()
    assert calibration.saved_fit("Printer A", "PLA") is None
    calibration.save_fit("Printer A", "PLA", Fit(stud_fit=0.1, socket_fit=-0.05))
    calibration.save_fit("Printer B", "PETG", Fit(stud_fit=0.0, socket_fit=0.15))
    assert json.loads(path.read_text()) == {
        "Printer A": {"PLA": {"stud_fit": 0.1, "socket_fit": -0.05}},
        "Printer B": {"PETG": {"stud_fit": 0.0, "socket_fit": 0.15}}}
    assert calibration.saved_fit("Printer A", "PLA") == Fit(stud_fit=0.1, socket_fit=-0.05)
    assert calibration.saved_fit("Printer A", "PETG") is None
    path.write_text("[1, 2]")
    with pytest.raises(InputError, match="saved fits"):
        calibration.saved_fit("Printer A", "PLA")


@pytest.mark.slow
def test_fabricate_uses_the_fit_saved_for_the_printer(tmp_path):
    """save-fit, then fabricate on that printer: the report's fit is the saved one and says
    where it came from; a fit given on the command line wins; the default printer keeps
    the default fit."""
    import json
    import os
    import subprocess
    import sys

    import trimesh

    from core.printing import printers
    if printers.bundle_folder() is None:
        pytest.skip("no PrusaSlicer vendor bundles installed")
    env = {**os.environ, "XDG_CONFIG_HOME": str(tmp_path / "cfg"), "FABRICKATOR_SLICER": "none"}
    root = Path(__file__).resolve().parents[2]
    mini = "Original Prusa MINI & MINI+"

    def run(*args):
        return subprocess.run([sys.executable, "-m", "core", *args], cwd=root, env=env,
                              capture_output=True, text=True, timeout=600)

    saved = run("save-fit", "--printer", mini, "--stud-fit", "0.1", "--socket-fit", "-0.05")
    assert saved.returncode == 0, saved.stderr
    assert "Prusament PLA" in saved.stdout and str(tmp_path / "cfg") in saved.stdout
    box = tmp_path / "box.stl"
    mesh = trimesh.creation.box((40.0, 24.0, 19.2))
    mesh.apply_translation(-mesh.bounds[0])
    mesh.export(box)
    region = "--high-res=0,0,12,16,24,19.2"
    fits = {}
    for name, extra in (("mini", ["--printer", mini]), ("given", ["--printer", mini, "--stud-fit", "0"]),
                        ("default", [])):
        done = run("fabricate", str(box), region, "--quiet", "--out", str(tmp_path / name), *extra)
        assert done.returncode == 0, done.stderr
        fits[name] = json.loads((tmp_path / name / "report.json").read_text())["fit"]
        said = [line for line in done.stdout.splitlines() if line.startswith("printed on: ")]
        printer = ("Original Prusa i3 MK3S & MK3S+ (0.20mm QUALITY @MK3, Prusament PLA)"
                   if name == "default" else f"{mini} (0.20mm QUALITY @MINI, Prusament PLA)")
        assert said == [f"printed on: {printer}, 1 plate; fit: stud {fits[name]['stud_fit']:+g}, "
                        f"socket {fits[name]['socket_fit']:+g} mm ({fits[name]['source']})"]
    assert fits["mini"]["stud_fit"] == 0.1 and fits["mini"]["socket_fit"] == -0.05
    assert fits["mini"]["source"].startswith(f"saved for {mini} / Prusament PLA in {tmp_path}")
    assert fits["given"]["stud_fit"] == 0.0 and fits["given"]["socket_fit"] == -0.05
    assert fits["given"]["source"].startswith("stud_fit given, the rest saved for")
    assert fits["default"] == {"stud_fit": Fit().stud_fit, "socket_fit": Fit().socket_fit,
                               "source": "default"}
