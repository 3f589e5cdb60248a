"""The job's settings: one table of defaults that the command line reads, and one-line errors."""

from __future__ import annotations

import pytest

from core import cli, pipeline, request
from core.errors import InputError
from core.instructions import build_order
from core.parts.interfaces import Fit


def test_the_command_line_defaults_are_the_table():
    args = cli._parser().parse_args(["fabricate", "part.stl", "--out", "out"])
    built = request.from_options(args, "part.stl")
    assert built == request.Request(model="part.stl").checked()
    for name, value in request.DEFAULTS.items():
        if hasattr(args, name) and name != "model":
            assert getattr(built, name) == (tuple(value) if isinstance(value, tuple) else value), name


def test_effort_and_lower_bound_options():
    args = cli._parser().parse_args(["fabricate", "part.stl", "--out", "out", "--effort", "best",
                                     "--lower-bound"])
    built = request.from_options(args, "part.stl")
    assert built.effort == "best" and built.lower_bound is True
    assert request.DEFAULTS["effort"] == "normal" and request.DEFAULTS["lower_bound"] is False
    with pytest.raises(SystemExit):
        cli._parser().parse_args(["fabricate", "part.stl", "--out", "out", "--effort", "fastest"])


def test_the_slicer_option_is_the_requests_choice():
    parse = cli._parser().parse_args
    assert request.DEFAULTS["slicer"] is None
    assert request.from_options(parse(["fabricate", "p.stl", "--out", "o"]), "p.stl").slicer is None
    off = parse(["fabricate", "p.stl", "--out", "o", "--slicer", "NONE"])
    assert request.from_options(off, "p.stl").slicer == "none"
    given = parse(["watch", "in", "--out", "o", "--slicer", " /opt/slicer/prusa-slicer "])
    assert request.from_options(given, "watched").slicer == "/opt/slicer/prusa-slicer"


def test_the_other_defaults_read_the_table():
    assert build_order.SECONDS_PER_BRICK == request.DEFAULTS["seconds_per_brick"] == 10.0
    assert build_order.SECONDS_PER_PART == request.DEFAULTS["seconds_per_part"] == 30.0
    assert request.DEFAULTS["stud_fit"] == Fit.stud_fit and request.DEFAULTS["socket_fit"] == Fit.socket_fit


@pytest.mark.parametrize("settings, words", [
    ({"seed": -1}, "--seed"), ({"seed": 1.5}, "--seed"), ({"scale": 0.0}, "--scale"),
    ({"scale": float("nan")}, "--scale"), ({"seconds_per_brick": -3}, "--seconds-per-brick"),
    ({"seconds_per_part": True}, "--seconds-per-part"), ({"stud_fit": 5.0}, "stud"),
    ({"flavour": "red"}, "unknown setting"), ({"effort": "fastest"}, "--effort"),
    ({"colour": "plaid"}, "--colour"), ({"inventory_only": True}, "--inventory-only"),
    ({"slicer": " "}, "--slicer"), ({"slicer": 3}, "--slicer"),
])
def test_bad_settings_are_one_line_input_errors(settings, words):
    with pytest.raises(InputError) as err:
        request.request("part.stl", **settings)
    assert words in str(err.value) and "\n" not in str(err.value)


def test_a_request_is_immutable_and_replace_gives_a_new_one():
    job = request.request("part.stl", seed=3)
    other = job.replace(seed=4)
    assert job.seed == 3 and other.seed == 4
    with pytest.raises(Exception):
        job.seed = 5  # type: ignore[misc]


def test_the_driver_takes_a_request_or_a_path(tmp_path):
    import trimesh

    path = tmp_path / "box.stl"
    trimesh.creation.box(extents=(24, 16, 9.6)).export(path)
    by_request = pipeline.run(request.request(str(path), slice_parts=False, seed=2))
    by_path = pipeline.run(path, slice_parts=False, seed=2)
    assert [b.to_json() for b in by_request.layout.bricks] == [b.to_json() for b in by_path.layout.bricks]
    assert by_request.request == by_path.request
    assert all(b.step is not None for b in by_path.layout.bricks)
