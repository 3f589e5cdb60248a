"""Print time: PrusaSlicer's estimate with the presets of its vendor bundle, and the fallback model.

Tests that slice skip when prusa-slicer is not installed (Debian package
``prusa-slicer``); tests on real models skip when ../shared/models is absent.
:func:`calibration_plates` is also the set ``ESTIMATE_COEFFS`` in
core/printing/print_time.py was fitted on.
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

from core import pipeline
from core.errors import InputError
from core.parts import engraving
from core.printing import print_time as pt, slicer_profile
from core.printing.estimate import estimate_seconds
from core.printing.plate import ARRANGE_GAP_MM, arrange, bed_rectangle, build_volume
from core.printing.poses import needs_supports, support_need, support_seconds
from core.report import print_method_words
from core.request import Request

ROOT = Path(__file__).resolve().parents[2]
MODELS = ROOT.parent / "shared" / "models"
CALIBRATION_MODELS = ("xyz_calibration_cube.stl", "openbot_phone_mount.stl", "relativty_lens_mount.stl",
                      "phone_charger_stand.stl", "openbot_motor_bracket.stl", "soap_dispenser_holder.stl")

#: PrusaSlicer's time for the same plate varies this much (relative) between runs
#: on a busy machine (its support generation runs in threads): 2h 19m 6s / 7s.
SAME_SLICE = 0.002

needs_slicer = pytest.mark.skipif(pt.slicer_path() is None,
                                  reason="prusa-slicer not installed (apt-get install prusa-slicer) "
                                         "or disabled by FABRICKATOR_SLICER")


def studded(nx: int, ny: int, layers: int) -> trimesh.Trimesh:
    """A solid LEGO-like block: nx x ny studs, ``layers`` plates high, studs on top."""
    body = trimesh.creation.box((8.0 * nx, 8.0 * ny, 3.2 * layers))
    body.apply_translation(-body.bounds[0])
    studs = []
    for i in range(nx):
        for j in range(ny):
            stud = trimesh.creation.cylinder(radius=2.4, height=1.7, sections=32)
            stud.apply_translation((8.0 * i + 4.0, 8.0 * j + 4.0, 3.2 * layers + 0.85))
            studs.append(stud)
    return trimesh.boolean.union([body, *studs], engine="manifold")


def calibration_plates(models: Path = MODELS) -> dict[str, list[trimesh.Trimesh]]:
    """Named plates (lists of meshes) spanning the shapes Fabrickator prints.

    Boxes of several proportions, cylinders, a thin tube, an open cup, a
    sphere, studded LEGO-like parts, multi-part plates, and the models of
    CALIBRATION_MODELS found in ``models`` (all fit the MK3S bed as they are).
    """
    cube = trimesh.creation.box((20, 20, 20))
    tube = trimesh.creation.annulus(r_min=22, r_max=25, height=50, sections=96)
    cup = trimesh.boolean.difference([trimesh.creation.box((50, 50, 40)),
                                      trimesh.creation.box((46, 46, 40)).apply_translation((0, 0, 2))],
                                     engine="manifold")
    cylinder = trimesh.creation.cylinder(radius=15, height=40, sections=96)
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=20)
    brick = studded(4, 2, 3)
    plates = {
        "cube20": [cube],
        "box60x40x10": [trimesh.creation.box((60, 40, 10))],
        "box10x10x80": [trimesh.creation.box((10, 10, 80))],
        "box100x80x30": [trimesh.creation.box((100, 80, 30))],
        "cylinder_r15_h40": [cylinder],
        "disc_r40_h10": [trimesh.creation.cylinder(radius=40, height=10, sections=96)],
        "tube_r25_h50": [tube],
        "cup50": [cup],
        "sphere_r20": [sphere],
        "brick2x4": [brick],
        "plate4x6": [studded(6, 4, 1)],
        "tower2x2x12": [studded(2, 2, 12)],
        "two_cubes": [cube, cube.copy()],
        "four_bricks": [brick.copy() for _ in range(4)],
        "mixed": [cylinder, tube, sphere],
    }
    for name in CALIBRATION_MODELS:
        if (models / name).exists():
            plates[name] = [trimesh.load(models / name, force="mesh")]
    return plates


@pytest.mark.parametrize("text, seconds", [
    ("45s", 45), ("13m 45s", 13 * 60 + 45), ("1h 2m 3s", 3723), ("2h 0m 5s", 7205),
    ("1d 0h 1m 0s", 86460), ("3d 4h 5m 6s", ((3 * 24 + 4) * 60 + 5) * 60 + 6), ("7m", 420), (" 1h 5s ", 3605),
])
def test_parse_duration(text, seconds):
    assert pt.parse_duration(text) == seconds


@pytest.mark.parametrize("text", ["", "abc", "1x", "5 minutes", "1h2"])
def test_parse_duration_rejects(text):
    with pytest.raises(ValueError):
        pt.parse_duration(text)


def test_gcode_seconds_reads_normal_mode(tmp_path):
    gcode = tmp_path / "a.gcode"
    gcode.write_text("G1 X0\n; estimated printing time (silent mode) = 9h 0m 0s\n"
                     "; estimated printing time (normal mode) = 1h 2m 3s\n; layer_height = 0.2\n")
    assert pt.gcode_seconds(gcode) == 3723
    gcode.write_text("G1 X0\n")
    with pytest.raises(ValueError):
        pt.gcode_seconds(gcode)


def test_flat_profile_is_resolved():
    config = pt.load_profile()
    assert "inherits" not in config
    expected = {"layer_height": "0.2", "first_layer_height": "0.2", "printer_model": "MK3S",
                "filament_type": "PLA", "nozzle_diameter": "0.4", "fill_pattern": "gyroid",
                "fill_density": "15%", "perimeters": "2", "temperature": "215", "printer_technology": "FFF",
                "print_settings_id": "0.20mm QUALITY @MK3", "filament_settings_id": "Prusament PLA",
                "printer_settings_id": "Original Prusa i3 MK3S & MK3S+"}
    assert {key: config.get(key) for key in expected} == expected
    assert np.allclose(build_volume(config), (250, 210, 210))
    assert pt.profile_label(config) == "MK3S, 0.20mm QUALITY, PLA"


#: A small vendor bundle in PrusaSlicer's format: abstract presets, multiple and
#: chained inheritance, a comment, a vendor section, browser-only keys.
FAKE_BUNDLE = """# a vendor bundle
[vendor]
name = Fake Research
config_version = 9.9.9

[print:*common*]
layer_height = 0.3
perimeters = 3
fill_density = 20%
compatible_printers_condition = printer_model=="MK3S"

[print:*0.20mm*]
inherits = *common*
layer_height = 0.2

[print:*MK3*]
; a comment
perimeters = 2
fill_pattern = gyroid

[print:0.20mm QUALITY @MK3]
inherits = *0.20mm*; *MK3*
fill_density = 15%

[filament:*PLA*]
filament_type = PLA
temperature = 210

[filament:Prusament PLA]
inherits = *PLA*
temperature = 215
renamed_from = "Prusament PLA old"

[printer:*common*]
printer_technology = FFF
bed_shape = 0x-4,250x-4,250x210,0x210
max_print_height = 200
nozzle_diameter = 0.4

[printer:Original Prusa i3 MK3]
inherits = *common*
printer_model = MK3
max_print_height = 210

[printer:Original Prusa i3 MK3S & MK3S+]
inherits = Original Prusa i3 MK3
printer_model = MK3S
"""


def fake_slicer(root: Path, bundle: str = FAKE_BUNDLE, place: str = "share/PrusaSlicer/profiles") -> Path:
    """A PrusaSlicer-like install under ``root``: bin/prusa-slicer (a script that is never
    run here) and the vendor bundle at ``place``."""
    binary = root / "bin" / "prusa-slicer"
    binary.parent.mkdir(parents=True, exist_ok=True)
    binary.write_text("#!/bin/sh\nexit 1\n")
    binary.chmod(0o755)
    (root / place).mkdir(parents=True, exist_ok=True)
    (root / place / "PrusaResearch.ini").write_text(bundle)
    return binary


def test_inheritance_order():
    sections = slicer_profile.parse_bundle(FAKE_BUNDLE)
    assert ("vendor", "name") not in sections and len(sections) == 9
    quality = slicer_profile.resolve(sections, "print", "0.20mm QUALITY @MK3")
    # *common* under *0.20mm*, then *MK3* over both, then the preset's own keys
    assert {k: quality[k] for k in ("layer_height", "perimeters", "fill_density", "fill_pattern")} == \
        {"layer_height": "0.2", "perimeters": "2", "fill_density": "15%", "fill_pattern": "gyroid"}
    printer = slicer_profile.resolve(sections, "printer", "Original Prusa i3 MK3S & MK3S+")
    assert printer["printer_model"] == "MK3S" and printer["max_print_height"] == "210"
    assert printer["bed_shape"] == "0x-4,250x-4,250x210,0x210"


def test_the_default_profile_is_resolved_from_the_bundle_beside_the_slicer(tmp_path):
    binary = fake_slicer(tmp_path / "usr")
    link = tmp_path / "path" / "prusa-slicer"
    link.parent.mkdir()
    link.symlink_to(binary)
    assert slicer_profile.find_bundle(link) == (tmp_path / "usr/share/PrusaSlicer/profiles/PrusaResearch.ini")
    config = pt.load_profile(slicer=str(link))
    assert config["layer_height"] == "0.2" and config["temperature"] == "215"
    assert config["print_settings_id"] == "0.20mm QUALITY @MK3"
    assert not slicer_profile.BUNDLE_ONLY & set(config)
    assert np.allclose(build_volume(config), (250, 214, 210))
    assert np.allclose(bed_rectangle(config), [[0, -4], [250, 210]])
    # the AppImage / Windows layout: resources/profiles beside the binary's folder
    other = fake_slicer(tmp_path / "app", FAKE_BUNDLE.replace("temperature = 215", "temperature = 220"),
                        "resources/profiles")
    assert pt.load_profile(slicer=str(other))["temperature"] == "220"
    # a given profile file wins over the bundle
    assert pt.load_profile(pt.FALLBACK_PROFILE, slicer=str(link)) == pt.load_profile(pt.FALLBACK_PROFILE)


def test_a_bundle_without_the_presets_falls_back_to_the_committed_profile(tmp_path):
    broken = FAKE_BUNDLE.replace("[printer:Original Prusa i3 MK3]", "[printer:Original Prusa i3 MK2]")
    binary = fake_slicer(tmp_path, broken)
    with pytest.raises(slicer_profile.BundleError, match=r"Original Prusa i3 MK3\] \(inherited by"):
        slicer_profile.bundle_profile(slicer_profile.find_bundle(binary))
    assert pt.load_profile(slicer=str(binary)) == pt.load_profile(pt.FALLBACK_PROFILE)
    looped = FAKE_BUNDLE.replace("[print:*common*]", "[print:*common*]\ninherits = 0.20mm QUALITY @MK3")
    with pytest.raises(slicer_profile.BundleError, match="cycle"):
        slicer_profile.flat_profile(slicer_profile.parse_bundle(looped))
    # no slicer at all: the fallback too
    assert pt.load_profile(slicer="none") == pt.load_profile(pt.FALLBACK_PROFILE)


def test_the_installed_bundle_gives_the_presets():
    bundle = slicer_profile.find_bundle(pt.slicer_path())
    if bundle is None:
        pytest.skip("no PrusaSlicer vendor bundle installed beside prusa-slicer (apt-get install prusa-slicer)")
    text = bundle.read_text(encoding="utf-8")
    config = slicer_profile.bundle_profile(bundle)
    assert config == pt.load_profile()
    assert config["printer_model"] == "MK3S" and config["printer_technology"] == "FFF"
    assert "inherits" not in config and not any("*" in v for k, v in config.items() if k.endswith("_settings_id"))
    assert np.allclose(build_volume(config), (250, 210, 210))
    assert slicer_profile.config_version(text) != "?"


def test_profile_generator_matches_committed_profile(tmp_path):
    bundle = slicer_profile.find_bundle(pt.slicer_path())
    committed = pt.FALLBACK_PROFILE.read_text()
    if bundle is None:
        pytest.skip("no PrusaSlicer vendor bundle installed beside prusa-slicer")
    version = slicer_profile.config_version(bundle.read_text(encoding="utf-8"))
    if f"(config_version {version})" not in committed.splitlines()[0]:
        pytest.skip(f"the installed bundle is version {version}; the fallback was made from another")
    out = tmp_path / "flat.ini"
    tool = ROOT / "tools" / "make_prusa_profile.py"
    run = subprocess.run([sys.executable, str(tool), str(bundle), str(out)], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    assert out.read_text() == committed


def test_arrange_sets_overlapping_parts_apart_on_the_bed():
    config = pt.load_profile(pt.FALLBACK_PROFILE)
    cube = trimesh.creation.box((20, 20, 20))              # centred on the origin: off the bed
    laid = arrange([cube, cube.copy(), trimesh.creation.box((30, 40, 5))], config)
    bed = bed_rectangle(config)
    boxes = [m.bounds for m in laid]
    assert all(np.all(b[0, :2] >= bed[0]) and np.all(b[1, :2] <= bed[1]) and b[0, 2] == 0 for b in boxes)
    for n, a in enumerate(boxes):
        for b in boxes[n + 1:]:
            assert not (np.all(a[0, :2] < b[1, :2] + ARRANGE_GAP_MM - 1e-6)
                        and np.all(b[0, :2] < a[1, :2] + ARRANGE_GAP_MM - 1e-6))
    centre = (np.min([b[0, :2] for b in boxes], axis=0) + np.max([b[1, :2] for b in boxes], axis=0)) / 2
    assert np.allclose(centre, bed.mean(axis=0))
    assert cube.bounds[0, 0] == -10                         # the input is not changed
    # parts already apart on the bed (a plate core.printing.export laid out) stay where they are
    apart = [trimesh.creation.box((20, 20, 20)).apply_translation((20, 20, 10)),
             trimesh.creation.box((20, 20, 20)).apply_translation((60, 20, 10))]
    assert all(np.allclose(a.bounds, b.bounds) for a, b in zip(apart, arrange(apart, config)))
    with pytest.raises(ValueError, match="could not fit"):
        arrange([trimesh.creation.box((200, 150, 5))] * 2, config)


def test_the_slicer_is_run_without_its_own_arrange_on_parts_set_apart(tmp_path, monkeypatch):
    # A stand-in slicer records its arguments and the plate's objects, and writes a time.
    log = tmp_path / "argv.txt"
    binary = tmp_path / "bin" / "prusa-slicer"
    binary.parent.mkdir()
    binary.write_text(f"""#!{sys.executable}
import sys, shutil
args = sys.argv[1:]
open({str(log)!r}, "w").write("\\n".join(args))
shutil.copy(args[-1], {str(tmp_path / "seen.3mf")!r})
out = args[args.index("--output") + 1]
open(out, "w").write("; generated by PrusaSlicer 2.9.2+UNKNOWN\\n"
                     "; estimated printing time (normal mode) = 1h 2m 3s\\n")
""")
    binary.chmod(0o755)
    cube = trimesh.creation.box((20, 20, 20))
    result = pt.slice_plate([cube, cube.copy()], tmp_path / "work", slicer=str(binary), supports=False)
    assert result.seconds == 3723 and result.method.startswith("prusa-slicer 2.9.2 (")
    assert "--dont-arrange" in log.read_text().split("\n") and "--merge" not in log.read_text()
    seen = trimesh.load(tmp_path / "seen.3mf")
    boxes = [g.bounds for g in seen.dump()]
    assert len(boxes) == 2 and all(b[0, 2] >= -1e-9 for b in boxes)
    assert boxes[0][1, 0] + ARRANGE_GAP_MM - 1e-6 <= boxes[1][0, 0] or \
        boxes[1][1, 0] + ARRANGE_GAP_MM - 1e-6 <= boxes[0][0, 0]


def test_missing_profile_is_an_input_error(tmp_path):
    with pytest.raises(InputError, match="profile"):
        pt.print_time([trimesh.creation.box((5, 5, 5))], tmp_path, profile=tmp_path / "nope.ini")


def test_missing_mesh_file_is_an_input_error(tmp_path):
    with pytest.raises(InputError, match="nope.stl"):
        pt.print_time([tmp_path / "nope.stl"], tmp_path)


def test_empty_plate_takes_no_time(tmp_path):
    assert pt.print_time([], tmp_path).seconds == 0.0
    assert estimate_seconds([]) == 0.0


def test_env_none_forces_estimate(tmp_path, monkeypatch):
    monkeypatch.setenv(pt.SLICER_ENV, "none")
    assert pt.slicer_path() is None
    result = pt.print_time([trimesh.creation.box((20, 20, 20))], tmp_path)
    assert result.method.startswith("estimate")
    assert "FABRICKATOR_SLICER=none" in result.method
    assert result.gcode_path is None
    assert 10 * 60 < result.seconds < 60 * 60


def test_env_points_to_missing_binary(tmp_path, monkeypatch):
    monkeypatch.setenv(pt.SLICER_ENV, str(tmp_path / "no-such-slicer"))
    assert pt.slicer_path() is None
    method = pt.print_time([trimesh.creation.box((20, 20, 20))], tmp_path).method
    assert method.startswith("estimate") and "not found" in method
    assert "(the slicer chosen is not found)" in print_method_words(method, method)


def test_the_requests_choice_wins_over_the_environment(tmp_path, monkeypatch):
    monkeypatch.setenv(pt.SLICER_ENV, "none")
    fake = fake_slicer(tmp_path)
    assert pt.slicer_path(str(fake)) == str(fake)
    assert pt.slicer_path(None) is None
    monkeypatch.setenv(pt.SLICER_ENV, str(fake))
    assert pt.slicer_path("None") is None and pt.slicer_path(None) == str(fake)
    assert pt.slicer_path(str(tmp_path / "no-such-slicer")) is None
    assert pt.requested(None) == "auto" and pt.requested("none") == "none"


@pytest.fixture(scope="module")
def marked_block(tmp_path_factory) -> Path:
    """A block 32 x 16 x 9.6 mm (4 x 2 x 3 cells) in a file."""
    path = tmp_path_factory.mktemp("block") / "block.stl"
    block = trimesh.creation.box((32.0, 16.0, 9.6))
    block.apply_translation(-block.bounds[0])
    block.export(path)
    return path


def _run_without_touching_the_environment(req: Request):
    """``pipeline.run(req)`` with every write to ``os.environ`` failing the test; also
    checks that the environment is the same afterwards.  Fontconfig's file is set
    beforehand, as engraving sets it once per process
    (:func:`core.parts.engraving._use_system_fontconfig`)."""
    def refused(*_):
        raise AssertionError("the run changed os.environ")

    with pytest.MonkeyPatch.context() as guard:
        if not {"FONTCONFIG_FILE", "FONTCONFIG_PATH"} & set(os.environ):
            guard.setenv("FONTCONFIG_FILE", engraving.SYSTEM_FONTS_CONF)
        before = dict(os.environ)
        guard.setattr(type(os.environ), "__setitem__", refused)
        guard.setattr(type(os.environ), "__delitem__", refused)
        fab = pipeline.run(req)
        assert dict(os.environ) == before
    return fab


#: The request's high-res box: the block's corner brick becomes a printed part.
CORNER = ("0,0,6.4,8,8,9.6",)


def test_a_request_for_no_slicer_gives_the_estimate_without_the_environment(marked_block, monkeypatch):
    monkeypatch.delenv(pt.SLICER_ENV, raising=False)
    fab = _run_without_touching_the_environment(Request(
        model=str(marked_block), high_res=CORNER, effort="fast", fit_grid=False, picture=False,
        slicer="none").checked())
    assert pt.SLICER_ENV not in os.environ
    assert fab.printed and fab.print_full is not None and fab.print_parts is not None
    for method in (fab.print_full.method, fab.print_parts.method):
        assert method.startswith("estimate") and "slicer disabled" in method
    assert fab.print_full.gcode_path is None
    assert "(slicing is switched off)" in print_method_words(fab.print_full.method, fab.print_parts.method)


def test_a_request_naming_a_missing_slicer_gives_the_estimate(marked_block, tmp_path, monkeypatch):
    missing = str(tmp_path / "no-such-slicer")
    monkeypatch.setenv(pt.SLICER_ENV, "prusa-slicer")
    fab = _run_without_touching_the_environment(Request(
        model=str(marked_block), high_res=CORNER, effort="fast", fit_grid=False, picture=False,
        slicer=missing).checked())
    assert os.environ[pt.SLICER_ENV] == "prusa-slicer"
    for method in (fab.print_full.method, fab.print_parts.method):
        assert method.startswith("estimate") and f"slicer {missing} not found" in method
    words = print_method_words(fab.print_full.method, fab.print_parts.method)
    assert "(the slicer chosen is not found)" in words


def test_estimate_grows_with_size_and_parts():
    small = estimate_seconds([trimesh.creation.box((10, 10, 10))])
    big = estimate_seconds([trimesh.creation.box((40, 40, 40))])
    two = estimate_seconds([trimesh.creation.box((10, 10, 10))] * 2)
    assert 0 < small < two < big


def test_estimate_reads_files(tmp_path):
    path = tmp_path / "box.stl"
    box = trimesh.creation.box((30, 20, 10))
    box.export(path)
    assert estimate_seconds([path]) == pytest.approx(estimate_seconds([box]))


@pytest.mark.slow
@needs_slicer
def test_slicing_a_cube(tmp_path):
    result = pt.print_time([trimesh.creation.box((20, 20, 20))], tmp_path)
    # All six faces of a cube are alike: one pose is sliced, upright.
    assert result.method.startswith("prusa-slicer 2.")
    assert result.method.endswith("(MK3S, 0.20mm QUALITY, PLA); posed upright, the fastest of 1 sliced poses")
    assert result.pose == "upright" and not result.supports
    assert Path(result.gcode_path).is_file()
    assert 10 * 60 < result.seconds < 60 * 60


@pytest.mark.slow
@needs_slicer
def test_two_cubes_share_a_plate(tmp_path):
    cube = trimesh.creation.box((20, 20, 20))
    one = pt.print_time([cube], tmp_path, pose_search=False)
    two = pt.print_time([cube, cube.copy().apply_translation((100, 0, 0))], tmp_path, pose_search=False)
    assert two.method == one.method
    assert one.gcode_path != two.gcode_path
    assert one.seconds < two.seconds < 2 * one.seconds + 120


@pytest.mark.slow
@needs_slicer
def test_part_over_build_height_falls_back(tmp_path):
    tall = trimesh.creation.box((20, 20, 230))
    result = pt.print_time([tall], tmp_path, pose_search=False)
    assert result.method.startswith("estimate")
    assert "exceeds the build volume" in result.method
    assert result.seconds > 0
    # Posed, it lies down and fits.
    lying = pt.print_time([tall], tmp_path)
    assert lying.method.startswith("prusa-slicer") and lying.pose != "upright"


@needs_slicer
def test_parts_that_do_not_fit_together_fall_back(tmp_path):
    plate = trimesh.creation.box((200, 150, 5))
    result = pt.print_time([plate, plate.copy()], tmp_path, pose_search=False)
    assert result.method.startswith("estimate")
    assert "could not fit" in result.method
    assert result.seconds > 0


@pytest.mark.slow
@needs_slicer
def test_estimate_agrees_with_slicer_on_calibration_plates(tmp_path):
    plates = calibration_plates()
    if not any(name in plates for name in CALIBRATION_MODELS):
        pytest.skip(f"test models not found at {MODELS}")
    errors = {}
    for name, plate in plates.items():
        sliced = pt.slice_plate(plate, tmp_path, supports=False)
        assert sliced.method.startswith("prusa-slicer"), (name, sliced.method)
        errors[name] = estimate_seconds(plate) / sliced.seconds - 1.0
    assert all(abs(e) <= 0.35 for e in errors.values()), errors


@pytest.mark.slow
@needs_slicer
def test_part_on_a_corner_is_sliced_again_with_supports(tmp_path):
    # A box balanced on one corner: PrusaSlicer finds no extrusions in the first layer.
    corner = trimesh.creation.box((20, 10, 10))
    corner.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 4, [0, 1, 0])
                           @ trimesh.transformations.rotation_matrix(np.pi / 4, [1, 0, 0]))
    result = pt.print_time([corner], tmp_path, pose_search=False)
    assert result.method.startswith("prusa-slicer 2.")
    assert result.method.endswith("(MK3S, 0.20mm QUALITY, PLA; with supports)")
    assert Path(result.gcode_path).is_file()
    assert "support material" in Path(result.gcode_path).read_text(errors="replace").lower()


@pytest.mark.slow
@needs_slicer
def test_cone_on_its_tip_needs_a_raft(tmp_path):
    cone = trimesh.creation.cone(radius=10, height=20, sections=64)
    cone.apply_transform(trimesh.transformations.rotation_matrix(np.pi, [1, 0, 0]))
    result = pt.print_time([cone], tmp_path, pose_search=False)
    assert result.method.startswith("prusa-slicer 2.")
    assert "with supports and a 2-layer raft" in result.method
    assert "raft_layers = 2" in Path(result.gcode_path).read_text(errors="replace")
    assert result.seconds > 0


@pytest.mark.slow
@needs_slicer
def test_plain_parts_need_no_retry(tmp_path):
    result = pt.print_time([trimesh.creation.cylinder(radius=10, height=20, sections=64)], tmp_path,
                           pose_search=False)
    assert result.method.startswith("prusa-slicer 2.") and result.method.endswith("(MK3S, 0.20mm QUALITY, PLA)")
    assert not result.supports and result.pose is None
    assert len(list(Path(result.gcode_path).parent.glob("*.gcode"))) == 1


def tee(bar_up: bool = True) -> trimesh.Trimesh:
    """A T: a 10 x 10 x 20 stem carrying a 30 x 10 x 4 bar (upside down when not
    ``bar_up``: the bar on the bed), 200 mm^2 overhanging 20 mm high when upright."""
    stem = trimesh.creation.box((10, 10, 20)).apply_translation((0, 0, 10))
    bar = trimesh.creation.box((30, 10, 4)).apply_translation((0, 0, 22))
    shape = trimesh.boolean.union([stem, bar], engine="manifold")
    if not bar_up:
        shape.apply_transform(trimesh.transformations.rotation_matrix(np.pi, [1, 0, 0]))
    return shape


@pytest.mark.parametrize("slope_deg, supported", [(30, True), (45, True), (60, False), (75, False)])
def test_overhang_slopes_under_the_threshold_need_support(slope_deg, supported):
    # A block 10 mm wide standing on a 10 mm foot, its right side an overhang of slope_deg from
    # horizontal reaching out 10 mm: its underside faces down at that slope.
    rise = 10 * math.tan(math.radians(slope_deg))
    profile = np.array([(0, 0), (10, 0), (20, rise), (20, rise + 5), (0, rise + 5)])  # convex, in x-z
    points = [(x, y, z) for x, z in profile for y in (0.0, 10.0)]
    block = trimesh.convex.convex_hull(points)
    area, height, _ = support_need(block)
    assert (area > 0) == supported == needs_supports(block)
    if supported:
        assert area == pytest.approx(10 * 10 / math.cos(math.radians(slope_deg)), rel=1e-6)
        assert 0 < height < rise


def test_a_brick_cavity_is_bridged_not_supported():
    # A 2x2 brick's hollow underside: its ceiling spans 13.6 mm between walls going down.
    shell = trimesh.boolean.difference([trimesh.creation.box((16, 16, 9.6)),
                                        trimesh.creation.box((13.6, 13.6, 8.6)).apply_translation((0, 0, -0.6))],
                                       engine="manifold")
    assert support_need(shell)[0] == 0 and not needs_supports(shell)
    assert needs_supports(tee()) and not needs_supports(tee(bar_up=False))


def test_the_plate_config_adds_supports_to_the_profile():
    plain, supported = pt.plate_config(), pt.plate_config(supports=True)
    assert plain == pt.load_profile() and plain["support_material"] == "0"
    assert supported == {**plain, **pt.SUPPORT_SETTINGS} and supported["support_material"] == "1"


def test_without_a_slicer_the_estimate_counts_supports_and_poses(tmp_path, monkeypatch):
    monkeypatch.setenv(pt.SLICER_ENV, "none")
    upright = tee()
    area, height, _ = support_need(upright)
    as_given = pt.print_time([upright], tmp_path, pose_search=False)
    assert as_given.supports and "with supports" in as_given.method and as_given.pose is None
    assert as_given.seconds == pytest.approx(estimate_seconds([upright]) + support_seconds(area, height))
    posed = pt.print_time([upright], tmp_path)
    assert posed.method.startswith("estimate") and "posed" in posed.method and "by the estimate" in posed.method
    assert posed.pose != "upright" and not posed.supports


def test_forbidden_directions_are_never_turned_down():
    # The side the T's cheapest pose lies on may not face down: it then takes another.
    free = pt.fastest_pose(tee(), slicer="none")
    bottom = -free.matrix[2, :3]
    kept = pt.fastest_pose(tee(), slicer="none", keep_up=[(bottom, -0.5)])
    assert kept.name != free.name and float(kept.matrix[2, :3] @ bottom) >= -0.5
    assert kept.cost >= free.cost
    with pytest.raises(ValueError):
        pt.fastest_pose(tee(), slicer="none", keep_up=[((0, 0, 1), 0.5), ((0, 0, -1), 0.5)])


@pytest.mark.slow
@needs_slicer
def test_supports_make_an_overhang_print_longer(tmp_path):
    plain = pt.slice_plate([tee()], tmp_path, supports=False)
    supported = pt.slice_plate([tee()], tmp_path, supports=True)
    assert not plain.supports and supported.supports
    assert supported.method.endswith("; with supports)")
    assert ";TYPE:Support material" in Path(supported.gcode_path).read_text(errors="replace")
    assert supported.seconds > plain.seconds
    # As given, print_time sees the overhang and switches supports on by itself.
    decided = pt.print_time([tee()], tmp_path, pose_search=False)
    assert decided.supports and decided.seconds == pytest.approx(supported.seconds, rel=SAME_SLICE)


@pytest.mark.slow
@needs_slicer
def test_the_fastest_pose_needs_no_supports_when_that_is_faster(tmp_path):
    upright = pt.slice_plate([tee()], tmp_path, supports=True)
    result = pt.print_time([tee()], tmp_path)
    assert result.method.startswith("prusa-slicer") and "sliced poses" in result.method
    assert result.pose != "upright" and not result.supports
    assert result.seconds < upright.seconds
    pose = pt.fastest_pose(tee(), tmp_path)
    assert pose.name == result.pose and not pose.supports
    assert pose.slicer_s == pytest.approx(result.seconds, rel=SAME_SLICE)
    assert pose.cost == pose.slicer_s


@pytest.mark.slow
@needs_slicer
def test_an_unchanged_plate_is_sliced_once_and_a_changed_one_again(tmp_path, monkeypatch):
    monkeypatch.setenv("FABRICKATOR_CACHE", str(tmp_path / "cache"))
    runs = []
    real_run = subprocess.run

    def counting(command, *args, **kwargs):
        if any("prusa-slicer" in str(part) for part in command):
            runs.append(command)
        return real_run(command, *args, **kwargs)

    monkeypatch.setattr(pt.subprocess, "run", counting)
    cube = trimesh.creation.box((20, 20, 20))
    first = pt.slice_plate([cube], tmp_path / "a")
    again = pt.slice_plate([cube.copy()], tmp_path / "b")
    assert len(runs) == 1 and not first.cached and again.cached
    assert (again.seconds, again.method, again.supports) == (first.seconds, first.method, first.supports)
    assert again.gcode_path is None
    taller = trimesh.creation.box((20, 20, 24))
    other = pt.slice_plate([taller], tmp_path / "c")
    assert len(runs) == 2 and not other.cached and other.seconds > first.seconds
    supported = pt.slice_plate([cube], tmp_path / "d", supports=True)
    assert len(runs) == 3 and not supported.cached


def test_the_slice_cache_is_off_when_told_and_survives_a_broken_entry(tmp_path, monkeypatch):
    from core.printing import slice_cache
    monkeypatch.setenv("FABRICKATOR_CACHE", "none")
    assert slice_cache.folder() is None and slice_cache.get("x") is None
    slice_cache.put("x", {"seconds": 1.0})
    monkeypatch.setenv("FABRICKATOR_CACHE", str(tmp_path))
    slice_cache.put("k", {"seconds": 5.0, "method": "m", "supports": False})
    assert slice_cache.get("k")["seconds"] == 5.0
    (tmp_path / "slices" / "k.json").write_text("{not json")
    assert slice_cache.get("k") is None
