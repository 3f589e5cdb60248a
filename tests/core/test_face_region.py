"""Face regions (core.face_region): the skin under picked faces, against volumes
computed by hand."""

from __future__ import annotations

import io
import math

import pytest

cq = pytest.importorskip("cadquery")

from OCP.BRepAlgoAPI import BRepAlgoAPI_Common  # noqa: E402
from OCP.BRepTools import BRepTools  # noqa: E402

from core import face_region  # noqa: E402

T = face_region.SKIN_MM


def _brep(shape) -> str:
    stream = io.BytesIO()
    BRepTools.Write_s(shape, stream)
    return stream.getvalue().decode("ascii")


def _inside(skin, solid) -> float:
    """The volume of ``skin`` inside ``solid``."""
    return face_region._volume(BRepAlgoAPI_Common(skin, solid).Shape())


def test_the_skin_of_a_flat_face_is_its_area_times_the_thickness_inside_the_part():
    box = cq.Workplane().box(20, 10, 5).translate((3, -4, 7)).val().wrapped
    faces = face_region.faces_of(box)
    result = face_region.skins(box)
    assert result.fallbacks == []
    # the faces of a 20 x 10 x 5 box: 50, 50, 100, 100, 200, 200 mm²
    assert sorted(round(face_region._volume(s), 6) for s in result.solids) == pytest.approx(
        [50 * T, 50 * T, 100 * T, 100 * T, 200 * T, 200 * T])
    for skin in result.solids:
        assert _inside(skin, box) == pytest.approx(face_region._volume(skin), rel=1e-6)
    assert len(faces) == len(result.solids) == 6
    assert result.volume_mm3() == pytest.approx(2 * (50 + 100 + 200) * T)


def test_the_skin_of_a_round_face_is_the_shell_between_two_radii():
    r, h = 6.0, 10.0
    cylinder = cq.Workplane().cylinder(h, r).val().wrapped
    volumes = sorted(face_region._volume(s) for s in face_region.skins(cylinder).solids)
    cap = math.pi * r * r * T
    side = math.pi * (r * r - (r - T) ** 2) * h
    assert volumes == pytest.approx(sorted([cap, cap, side]), rel=1e-6)
    sphere = cq.Workplane().sphere(8.0).val().wrapped
    (shell,) = face_region.skins(sphere).solids
    assert face_region._volume(shell) == pytest.approx(4 / 3 * math.pi * (8.0 ** 3 - 7.6 ** 3),
                                                       rel=1e-6)
    assert _inside(shell, sphere) == pytest.approx(face_region._volume(shell), rel=1e-6)


def test_brep_text_of_some_faces_gives_the_same_skins():
    box = cq.Workplane().box(20, 10, 5)
    top = box.faces(">Z").val().wrapped
    from_text = face_region.skins(_brep(top))
    assert from_text.volume_mm3() == pytest.approx(200 * T)
    two = cq.Compound.makeCompound([box.faces(">Z").val(), box.faces("<X").val()]).wrapped
    assert face_region.skins(_brep(two)).volume_mm3() == pytest.approx((200 + 50) * T)
    assert face_region._volume(face_region.skins(_brep(two)).compound()) == pytest.approx(250 * T)


def test_a_face_without_an_offset_is_marked_by_its_grown_box():
    # the side of a 0.3 mm radius pin cannot move 0.4 mm inwards
    pin = cq.Workplane().cylinder(5.0, 0.3).val().wrapped
    result = face_region.skins(pin)
    side = [n for n, f in enumerate(face_region.faces_of(pin))
            if face_region._volume(result.solids[n]) > 1.0]
    assert result.fallbacks == side == [0]
    # the side's box, 0.6 x 0.6 x 5, grown by 0.4 on every side
    assert face_region._volume(result.solids[0]) == pytest.approx(1.4 * 1.4 * 5.8, rel=1e-3)


def test_no_face_is_an_error():
    solid_free = cq.Workplane().box(1, 1, 1).edges().vals()[0].wrapped
    with pytest.raises(ValueError):
        face_region.skins(solid_free)
    with pytest.raises(ValueError):
        face_region.read_brep("")
