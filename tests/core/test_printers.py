"""Choosing the printer: PrusaSlicer's vendor bundles, their compatibility conditions, a user's config."""

from __future__ import annotations

import html
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
import trimesh

from core import pipeline
from core.errors import InputError
from core.printing import print_time, printers, slicer_profile
from core.printing.plate import SLIC3R_CONFIG, bed_rectangle, build_volume, config_text
from core.request import Request

from conftest import HMD_HIGH_RES

ROOT = Path(__file__).resolve().parents[2]
FOLDER = printers.bundle_folder()
needs_bundles = pytest.mark.skipif(FOLDER is None, reason="no PrusaSlicer vendor bundles installed")

MINI = "Original Prusa MINI & MINI+"
ENDER = "Creality Ender-3 (0.4 mm nozzle)"


def cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "core", *args], cwd=ROOT, capture_output=True,
                          text=True, timeout=300)


def one_line(proc: subprocess.CompletedProcess) -> str:
    assert proc.returncode == 2, proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if not ln.startswith("[")]
    assert len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr
    return lines[0]


MK3_NOTES = r"Do not remove!\nPRINTER_VENDOR_PRUSA3D\nPRINTER_MODEL_MK3\n"


@pytest.mark.parametrize("text, expected", [
    ('printer_model=="MINI"', False),
    ('printer_model!="MINI"', True),
    ("printer_notes=~/.*PRINTER_MODEL_MK3.*/", True),      # spans the \n lines, as boost's regex
    ("printer_notes=~/.*PRINTER_MODEL_MK2.*/", False),
    ("printer_notes!~/.*PRINTER_MODEL_MK2.*/", True),
    ("nozzle_diameter[0]==0.4", True),                      # "0.40" == 0.4 as numbers
    ("nozzle_diameter[1]==0.6", True),
    ("nozzle_diameter[0]>0.35 and nozzle_diameter[0]<=0.4", True),
    ("nozzle_diameter[0]>=0.6 or printer_model==\"MK3S\"", True),
    ("single_extruder_multi_material", False),
    ("! single_extruder_multi_material", True),
    ("not (printer_model==\"MK3S\" and nozzle_diameter[0]==0.4)", False),
    ("num_extruders==2 && ! (printer_model==\"MINI\")", True),
    ("(printer_model==\"MINI\" or printer_model==\"MK3S\") and nozzle_diameter[0]==0.4", True),
    ("", True),
])
def test_condition_by_hand(text, expected):
    config = {"printer_model": "MK3S", "printer_notes": MK3_NOTES, "nozzle_diameter": "0.40,0.6",
              "single_extruder_multi_material": "0"}
    assert printers.holds(printers.condition(text), config) is expected


@pytest.mark.parametrize("text", ["printer_model==", "(a==1", "a==1 b==2", "a=1"])
def test_condition_refuses_what_is_not_one(text):
    with pytest.raises(printers.ConditionError):
        printers.condition(text)


@needs_bundles
def test_every_installed_condition_parses():
    found = [(b.vendor, name, sec[key]) for b in printers.bundles(FOLDER)
             for (_, name), sec in b.sections.items()
             for key in ("compatible_printers_condition", "compatible_prints_condition") if key in sec]
    assert len(found) > 100
    for vendor, name, text in found:
        printers.condition(text)


@needs_bundles
def test_every_installed_printer_gets_a_print_and_a_filament():
    names = [n for b in printers.bundles(FOLDER) for n in printers.fff_printers(b)]
    assert len(names) > 100 and MINI in names and ENDER in names
    assert "Original Prusa SL1" not in names                 # a resin printer
    for name in names:
        chosen = printers.choose(name, folder=FOLDER)
        assert chosen.config["printer_settings_id"] == name
        assert chosen.config["print_settings_id"] == chosen.print_preset


VENDOR_INI = """[vendor]
name = Tiny
config_version = 1.0.0
[printer:Tiny One]
printer_technology = FFF
printer_model = ONE
nozzle_diameter = 0.4
bed_shape = 0x0,100x0,100x100,0x100
max_print_height = 100
printer_notes = PRINTER_VENDOR_TINY
[print:0.20mm Tiny]
layer_height = 0.2
compatible_printers_condition = printer_model=="ONE"
[filament:Tiny PLA]
filament_type = PLA
compatible_printers_condition = printer_model=="TWO"
"""

TEMPLATES_INI = """[vendor]
name = Templates
config_version = 2.0.1
templates_profile = 1
[filament:*common*]
start_filament_gcode =
compatible_printers_condition = printer_notes!~/.*NO_TEMPLATES.*/
[filament:Generic PETG]
inherits = *common*
filament_type = PETG
[filament:Generic PLA]
inherits = *common*
filament_type = PLA
"""


def test_the_template_bundle_offers_filaments_to_every_printer(tmp_path):
    """PrusaSlicer 2.6+ offers Templates.ini's filaments to any printer its condition allows;
    a printer whose own bundle has none for it gets the template PLA, and the bare empty
    filament G-code PrusaSlicer 2.9 cannot read is written as the list of one empty one."""
    (tmp_path / "Tiny.ini").write_text(VENDOR_INI)
    with pytest.raises(InputError, match="no filament"):
        printers.choose("Tiny One", folder=tmp_path)
    (tmp_path / "Templates.ini").write_text(TEMPLATES_INI)
    chosen = printers.choose("Tiny One", folder=tmp_path)
    assert (chosen.print_preset, chosen.filament, chosen.vendor) == ("0.20mm Tiny", "Generic PLA", "Tiny")
    assert "start_filament_gcode = \"\"\n" in config_text(chosen.config)
    assert printers.choose("Tiny One", filament="Generic PETG", folder=tmp_path).config["filament_type"] == "PETG"
    assert [n for b in printers.bundles(tmp_path) for n in printers.fff_printers(b)] == ["Tiny One"]


@needs_bundles
@pytest.mark.skipif(FOLDER is None or not (FOLDER / "Templates.ini").exists(),
                    reason="this PrusaSlicer has no template bundle (before 2.6)")
def test_a_printer_with_a_template_filament_slices(tmp_path):
    """Geeetech's E180 has no filament in its own bundle (PrusaSlicer 2.9): it is timed with
    the template PLA, and PrusaSlicer slices that config."""
    chosen = printers.choose("Geeetech E180", folder=FOLDER)
    assert chosen.filament == "Generic PLA"
    (tmp_path / "e180.ini").write_text(config_text(chosen.config))
    trimesh.creation.box((20.0, 20.0, 10.0)).export(tmp_path / "box.stl")
    run = subprocess.run([print_time.slicer_path(), "--loglevel", "1", "--load", str(tmp_path / "e180.ini"),
                          "--export-gcode", "--output", str(tmp_path / "box.gcode"), str(tmp_path / "box.stl")],
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
    assert print_time.gcode_seconds(tmp_path / "box.gcode") > 60


@needs_bundles
@pytest.mark.skipif(print_time.slicer_path() is None, reason="PrusaSlicer is not installed")
def test_a_printer_asking_for_binary_gcode_is_timed_from_text_gcode(tmp_path):
    """PrusaSlicer 2.7+ bundles ask for binary G-code on the MINI (``binary_gcode = 1``),
    whose time lies in compressed metadata: the plate is sliced to text G-code, and the
    slicer's own time comes back (not the estimate)."""
    mini = printers.choose(MINI, folder=FOLDER).config
    if "binary_gcode" not in mini:
        pytest.skip("this PrusaSlicer's bundle has no binary G-code setting (before 2.7)")
    assert print_time.plate_config(mini)["binary_gcode"] == "0"
    cube = trimesh.creation.box((20.0, 20.0, 20.0))
    cube.apply_translation(-cube.bounds[0])
    result = print_time.slice_plate([cube], tmp_path, mini)
    assert result.method.startswith("prusa-slicer") and result.seconds > 60
    assert "; estimated printing time (normal mode)" in Path(result.gcode_path).read_text(errors="replace")


@needs_bundles
def test_the_mk3s_named_is_todays_default_profile():
    chosen = printers.choose(slicer_profile.PRESETS["printer"], folder=FOLDER)
    assert (chosen.print_preset, chosen.filament) == ("0.20mm QUALITY @MK3", "Prusament PLA")
    assert chosen.config == slicer_profile.bundle_profile(FOLDER / slicer_profile.VENDOR_BUNDLE)


@needs_bundles
def test_mini_and_ender_get_their_own_presets():
    """The bundles say (read by hand): the MINI's 0.20 mm print is "0.20mm QUALITY @MINI",
    its filament Prusament PLA and its bed 180 mm; the Ender-3's is Creality's own."""
    mini = printers.choose(MINI, folder=FOLDER)
    assert (mini.print_preset, mini.filament, mini.vendor) == ("0.20mm QUALITY @MINI", "Prusament PLA",
                                                               "Prusa Research")
    assert mini.config["bed_shape"] == "0x0,180x0,180x180,0x180"
    assert mini.config["max_print_height"] == "180"
    ender = printers.choose(ENDER, folder=FOLDER)
    assert ender.vendor == "Creality" and ender.print_preset.startswith("0.20 mm")
    assert "@CREALITY" in ender.print_preset and ender.filament == "Generic PLA @CREALITY"
    assert float(ender.config["layer_height"]) == 0.2
    other = printers.choose(MINI, "0.15mm QUALITY @MINI", "Prusament PETG @MINI", folder=FOLDER)
    assert float(other.config["layer_height"]) == 0.15 and other.config["filament_type"] == "PETG"


@needs_bundles
def test_incompatible_or_unknown_names_name_the_nearest():
    with pytest.raises(InputError, match="nearest.*Original Prusa MINI & MINI\\+"):
        printers.choose("Original Prusa MINI", folder=FOLDER)
    with pytest.raises(InputError, match="print preset for"):
        printers.choose(MINI, "0.20mm QUALITY @MK3", folder=FOLDER)


def test_default_request_chooses_no_printer():
    req = Request(model="x.stl")
    assert printers.chosen(req) is None and printers.profile(req) is None
    with pytest.raises(InputError, match="--printer"):
        printers.chosen(Request(model="x.stl", filament="Prusament PLA"))


def _flat(tmp_path, layer="0.3") -> Path:
    path = tmp_path / "mine.ini"
    path.write_text("# generated by PrusaSlicer 2.5.0\nbed_shape = 0x0,200x0,200x200,0x200\n"
                    f"layer_height = {layer}\nmax_print_height = 150\nnozzle_diameter = 0.4\n"
                    "printer_settings_id = My printer\nprint_settings_id = My print\n"
                    "filament_settings_id = \"My PLA\"\n")
    return path


def test_user_config_is_taken_as_it_is(tmp_path):
    chosen = printers.from_file(_flat(tmp_path))
    assert (chosen.printer, chosen.print_preset, chosen.filament) == ("My printer", "My print", "My PLA")
    assert chosen.config["layer_height"] == "0.3" and chosen.vendor == "user config"
    assert chosen.to_json()["build_volume_mm"] == [200.0, 200.0, 150.0]


def test_foreign_configs_are_refused(tmp_path):
    with pytest.raises(InputError, match="cannot read"):
        printers.from_file(tmp_path / "absent.ini")
    bundle = tmp_path / "bundle.ini"
    bundle.write_text("[printer:X]\nbed_shape = 0x0,1x1\n")
    with pytest.raises(InputError, match="sections"):
        printers.from_file(bundle)
    other = tmp_path / "other.ini"
    other.write_text("[core]\n" * 0 + "editor = vim\n")
    with pytest.raises(InputError, match="lacks layer_height"):
        printers.from_file(other)


@pytest.mark.slow
@needs_bundles
def test_cli_lists_and_refuses(tmp_path):
    listed = cli("printers")
    assert listed.returncode == 0, listed.stderr
    lines = listed.stdout.splitlines()
    assert any(ln.startswith("Prusa Research (bundle ") for ln in lines)
    assert any(ln.split() == MINI.split() + ["180", "x", "180", "x", "180", "mm"] for ln in lines)
    box = tmp_path / "box.stl"
    trimesh.creation.box((16.0, 16.0, 9.6)).export(box)
    line = one_line(cli("fabricate", str(box), "--out", str(tmp_path / "o"), "--printer", "Ender 3"))
    assert "unknown printer 'Ender 3'" in line and line.count("'Creality") + line.count("'") >= 6
    line = one_line(cli("fabricate", str(box), "--out", str(tmp_path / "o"),
                        "--slicer-config", str(tmp_path / "none.ini")))
    assert "--slicer-config" in line and "cannot read" in line
    assert not (tmp_path / "o").exists()


def _resliced(plate: Path, folder: Path) -> float:
    """PrusaSlicer's own time of a written plate, sliced by hand as a user would."""
    gcode = folder / (plate.stem + ".gcode")
    run = subprocess.run([print_time.slicer_path(), "--loglevel", "1", "--dont-arrange", "--export-gcode",
                          "--output", str(gcode), str(plate)], capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr[-2000:]
    return print_time.gcode_seconds(gcode)


@pytest.fixture(scope="module")
def mk3s_demo(hmd_step, tmp_path_factory) -> dict:
    """The demo's report on the default printer."""
    return pipeline.fabricate(hmd_step, tmp_path_factory.mktemp("mk3s") / "out", high_res=HMD_HIGH_RES,
                              effort="fast", picture=False)


@pytest.mark.slow
@needs_bundles
@pytest.mark.skipif(print_time.slicer_path() is None, reason="PrusaSlicer is not installed")
@pytest.mark.parametrize("name", [MINI, ENDER])
def test_demo_is_timed_on_the_printer(name, hmd_step, tmp_path, mk3s_demo):
    """Each written plate, re-sliced by hand, gives the report's printed-parts time (2 %);
    the plates carry the printer's presets, the instructions name it, and the times are
    not the MK3S's."""
    out = tmp_path / "out"
    doc = pipeline.fabricate(hmd_step, out, high_res=HMD_HIGH_RES, effort="fast", picture=False,
                             printer=name)
    chosen = printers.choose(name, folder=FOLDER)
    assert doc["printer"]["printer"] == name and doc["printer"]["bundle_version"] == chosen.bundle_version
    plates = sorted((out / "parts").glob("plate*.3mf"))
    assert plates
    total = 0.0
    for plate in plates:
        with zipfile.ZipFile(plate) as archive:
            settings = archive.read(SLIC3R_CONFIG).decode()
        assert f"; printer_settings_id = {name}\n" in settings
        assert f"; print_settings_id = {chosen.print_preset}\n" in settings
        total += _resliced(plate, tmp_path)
    times = doc["print_time_s"]
    assert total == pytest.approx(times["printed_parts"], rel=0.02)
    assert "prusa-slicer" in times["method"]
    assert times["printed_parts"] != mk3s_demo["print_time_s"]["printed_parts"]
    assert times["full_model"] != mk3s_demo["print_time_s"]["full_model"]
    page = (out / "instructions.html").read_text(encoding="utf-8")
    assert f"printed on: {html.escape(chosen.label)}" in page


def test_fits_by_hand():
    assert printers.fits((170, 100, 180), (180, 180, 180))
    assert printers.fits((100, 200, 10), (250, 210, 210))
    assert printers.fits((240, 200, 10), (210, 250, 210))          # a quarter turn about z
    assert not printers.fits((190, 10, 10), (180, 180, 180))
    assert not printers.fits((10, 10, 181), (180, 180, 180))
    tower = trimesh.creation.box((20.0, 20.0, 200.0))
    assert not printers.fits_some_pose(tower, (180, 180, 180))
    assert printers.fits_some_pose(tower, (250, 210, 210))          # lying down


def test_enlarged_bed_takes_the_longest_side():
    config = {"bed_shape": "0x0,180x0,180x180,0x180", "max_print_height": "180", "x": "1"}
    big = printers.enlarged(config, (20.0, 30.0, 200.0))
    assert list(build_volume(big)) == [220.0, 220.0, 220.0] and big["x"] == "1"
    assert config["bed_shape"] == "0x0,180x0,180x180,0x180"


@pytest.mark.slow
@needs_bundles
@pytest.mark.skipif(print_time.slicer_path() is None, reason="PrusaSlicer is not installed")
def test_reference_time_of_a_model_larger_than_the_printer(tmp_path):
    """A 200 mm tower fits the MINI in no pose: sliced on a bed enlarged to fit, and said so;
    on the MK3S it lies down and is sliced on its own bed."""
    tower = trimesh.creation.box((20.0, 20.0, 200.0))
    mini = printers.choose(MINI, folder=FOLDER).config
    result = printers.reference_time(tower, tmp_path, profile=mini)
    assert result.enlarged_bed and result.method.startswith("prusa-slicer")
    assert "180 x 180 x 180 mm in no pose" in result.method and result.seconds > 0
    mk3s = printers.reference_time(tower, tmp_path)
    assert not mk3s.enlarged_bed and mk3s.method.startswith("prusa-slicer")


def _fabricate_marked_whole(tmp_path, size, *extra) -> subprocess.CompletedProcess:
    """``fabricate`` a box of ``size`` mm, marked whole, on the MINI (no slicer: quick)."""
    import os

    model = tmp_path / "box.stl"
    box = trimesh.creation.box(size)
    box.apply_translation(-box.bounds[0])
    box.export(model)
    region = "--high-res=-1,-1,-1," + ",".join(f"{v + 1:g}" for v in size)
    return subprocess.run([sys.executable, "-m", "core", "fabricate", str(model), "--out", str(tmp_path / "o"),
                           region, "--printer", MINI, "--quiet", *extra], cwd=ROOT, capture_output=True,
                          text=True, timeout=900, env={**os.environ, "FABRICKATOR_SLICER": "none"})


@pytest.mark.slow
@needs_bundles
def test_part_wider_than_the_printer_is_refused(tmp_path):
    """A 200 x 24 x 9.6 mm bar marked whole is wider than the MINI's 180 mm bed in every
    layer: one line naming the part and the volume, exit 2, no output."""
    line = one_line(_fabricate_marked_whole(tmp_path, (200.0, 24.0, 9.6)))
    assert "printed part P1" in line and "180 x 180 x 180 mm" in line and MINI in line
    assert not (tmp_path / "o").exists()


@pytest.mark.slow
@needs_bundles
def test_part_taller_than_the_printer_is_split_along_brick_seams(tmp_path):
    """A 24 x 24 x 192 mm tower marked whole (one part, 60 layers) is taller than the MINI's
    180 mm: it comes out as parts that each fit the MINI in their print pose, stacked on
    each other's studs, that together hold the tower's volume (their studs and sockets
    aside: within 2 %), and the report says so."""
    import json

    done = _fabricate_marked_whole(tmp_path, (24.0, 24.0, 192.0))
    assert done.returncode == 0, done.stderr
    doc = json.loads((tmp_path / "o" / "report.json").read_text())
    parts = doc["printed_parts"]
    assert len(parts) >= 2
    volume = 0.0
    for part in parts:
        mesh = trimesh.load(tmp_path / "o" / part["stl"], force="mesh")
        assert np.all(np.sort(mesh.extents) <= 180 + 1e-6), (part["id"], mesh.extents)
        volume += mesh.volume
    assert volume == pytest.approx(24 * 24 * 192, rel=0.02)
    assert any("split along brick seams" in note for note in doc["notes"])
    assert doc["print_time_s"]["full_model_on_enlarged_bed"] is True


@pytest.mark.slow
@needs_bundles
@pytest.mark.skipif(print_time.slicer_path() is None, reason="PrusaSlicer is not installed")
def test_a_config_prusaslicer_saved_is_sliced_as_it_is(tmp_path):
    """PrusaSlicer itself saves the MINI's config at 0.30 mm layers; fabricate with it: the
    report and the plate's settings say 0.3, and re-slicing the plate by hand gives the
    report's printed-parts time."""
    start = tmp_path / "mini.ini"
    start.write_text(config_text(printers.choose(MINI, folder=FOLDER).config))
    user = tmp_path / "user.ini"
    saved = subprocess.run([print_time.slicer_path(), "--loglevel", "1", "--load", str(start),
                            "--layer-height", "0.3", "--first-layer-height", "0.3", "--save", str(user)],
                           capture_output=True, text=True, timeout=120)
    assert saved.returncode == 0 and user.read_text().startswith("# generated by PrusaSlicer"), saved.stderr
    box = tmp_path / "box.stl"
    mesh = trimesh.creation.box((40.0, 24.0, 19.2))
    mesh.apply_translation(-mesh.bounds[0])
    mesh.export(box)
    out = tmp_path / "out"
    doc = pipeline.fabricate(str(box), out, high_res=["0,0,12,16,24,19.2"], picture=False,
                             slicer_config=str(user))
    assert doc["printer"]["printer"] == MINI and doc["printer"]["layer_height_mm"] == 0.3
    assert doc["printer"]["vendor"] == "user config" and doc["printer"]["source"] == str(user.resolve())
    plate = out / "parts" / "plate-1.3mf"
    with zipfile.ZipFile(plate) as archive:
        assert "; layer_height = 0.3\n" in archive.read(SLIC3R_CONFIG).decode()
    assert _resliced(plate, tmp_path) == pytest.approx(doc["print_time_s"]["printed_parts"], rel=0.02)


def test_a_round_bed_packs_into_its_inscribed_square():
    """A delta's bed_shape is a circle's corners: the parts go in the square inside it
    (radius 100 about (0, 0): 141.4 mm a side); a rectangle stays its bounding box."""
    import math

    circle = ",".join(f"{100 * math.cos(a):.4f}x{100 * math.sin(a):.4f}"
                      for a in [2 * math.pi * n / 72 for n in range(72)])
    bed = bed_rectangle({"bed_shape": circle})
    assert bed.ravel().tolist() == pytest.approx([-70.7107, -70.7107, 70.7107, 70.7107], abs=1e-3)
    assert bed_rectangle({"bed_shape": "0x0,250x0,250x210,0x210"}).tolist() == [[0, 0], [250, 210]]
    with pytest.raises(InputError, match="bed_shape"):
        bed_rectangle({"bed_shape": ""})


def test_the_default_printer_is_named_too(tmp_path, monkeypatch):
    """Without --printer the report still names what it slices on: the MK3S presets of the
    installed bundle (its version read from the file), or the fallback profile without a
    slicer, or the profile file given."""
    req = Request(model="x.stl")
    bundle = slicer_profile.find_bundle(shutil.which("prusa-slicer"))
    if bundle is not None:
        found = printers.described(req)
        assert (found.printer, found.print_preset, found.filament) == tuple(
            slicer_profile.PRESETS[k] for k in ("printer", "print", "filament"))
        assert found.source == str(bundle) and found.bundle_version in bundle.read_text()
    monkeypatch.setenv("FABRICKATOR_SLICER", "none")
    fallback = printers.described(req)
    assert fallback.vendor == "fallback profile" and fallback.printer == slicer_profile.PRESETS["printer"]
    own = printers.described(Request(model="x.stl", profile=str(_flat(tmp_path))))
    assert (own.printer, own.print_preset, own.filament, own.vendor) == (
        "My printer", "My print", "My PLA", "user profile")
