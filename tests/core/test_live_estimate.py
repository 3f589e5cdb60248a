"""The brush panel's live estimate (core.live_estimate) against the parts core.parts.printed cuts.

The reference for a painted change is independent of the estimate's grouping and
measuring: the pipeline's own grouping of the printed bricks
(:func:`core.high_res.groups`), the parts :func:`core.parts.printed.build_parts` cuts for
it (studs, sockets, play and engraving included: the estimate cuts each part the
same way, without the id), and
:func:`core.printing.estimate.estimate_seconds` of those parts on one plate as they were
cut (upright).  The last result's print time is that same reference for the parts
as they are, so the estimate's change is checked, not its anchor.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import trimesh

from core import high_res, live_estimate, pipeline
from core import report as reporting
from core.errors import InputError
from core.parts import printed
from core.printing import print_time
from core.printing.estimate import estimate_seconds
from core.request import Request

#: How far (relative) the estimate may be from the reference: the estimate does not
#: engrave the id.
TOLERANCE = 0.01


@pytest.fixture(scope="module")
def fab(tmp_path_factory):
    """A block 48 x 32 x 12.8 mm with a round boss (r 10, 9.6 high) on top, the boss
    marked high-res, fabricated without a slicer."""
    folder = tmp_path_factory.mktemp("live")
    block = trimesh.creation.box((48.0, 32.0, 12.8))
    block.apply_translation((0.0, 0.0, 6.4))
    boss = trimesh.creation.cylinder(radius=10.0, height=9.6, sections=64)
    boss.apply_translation((4.0, 0.0, 12.8 + 4.8))
    model = trimesh.boolean.union([block, boss])
    path = folder / "block.stl"
    model.export(path)
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv(print_time.SLICER_ENV, "none")
        return pipeline.run(Request(model=str(path), high_res=("-8,-12,12.9,16,12,22.4",),
                                    effort="fast", fit_grid=False))


def reference_s(fab, ids) -> tuple[float, int]:
    """estimate_seconds of the parts core.parts.printed cuts for the printed bricks ``ids``
    (one plate, as cut), and how many parts."""
    layout = dataclasses.replace(fab.layout, bricks=[
        dataclasses.replace(b, kind="lego", printed_part=None) for b in fab.layout.bricks])
    groups = high_res.groups(layout, sorted(ids))
    parts = printed.build_parts(layout, groups, printed.model_solid(fab.model), fab.interface,
                                engrave=True)
    return estimate_seconds([p.mesh for p in parts]), len(parts)


def printed_ids(fab) -> set[int]:
    return {b.id for b in fab.layout.bricks if b.kind == "printed"}


def estimator(fab, last_s: float | None = None):
    """The estimator of ``fab``: its parts upright; their print time ``last_s`` (the
    reference of the parts as they are, given to the first part) or, for None, the
    pipeline's own."""
    own = last_s is None
    parts = [live_estimate.LastPart(p.id, tuple(p.bricks),
                                    float(p.print_s) if own else (last_s if n == 0 else 0.0))
             for n, p in enumerate(fab.printed)]
    return live_estimate.Estimator(fab.layout, fab.model.mesh, parts, fab.print_full.seconds,
                                   fab.seconds_per_brick, fab.seconds_per_part, fab.interface)


def lego_neighbours(fab, ids) -> list[int]:
    """The LEGO bricks touching the bricks ``ids`` face to face, nearest the boss first."""
    return high_res.lego_beside(fab.layout, ids)


def test_the_fixture_has_one_printed_part_and_lego_around_it(fab):
    assert [p.id for p in fab.printed] == ["P1"]
    assert lego_neighbours(fab, printed_ids(fab))


def test_painting_nothing_gives_the_last_result(fab):
    est = estimator(fab)
    for mode in live_estimate.MODES:
        assert est.estimate([], mode) == est.last()
    last = est.last()
    assert last.print_s == pytest.approx(fab.print_parts.seconds)
    assert last.speedup == pytest.approx(reporting.speedups(fab)["fabrication"])
    assert last.assembly_s == pytest.approx(reporting.assembly_seconds(fab))
    assert last.parts == len(fab.printed)


def test_bricks_painted_next_to_a_part_join_it_as_the_printed_parts_would(fab):
    before, _ = reference_s(fab, printed_ids(fab))
    est = estimator(fab, before)
    near = lego_neighbours(fab, printed_ids(fab))
    for count in range(1, len(near) + 1):
        painted = near[:count]
        expected, parts = reference_s(fab, printed_ids(fab) | set(painted))
        got = est.estimate(painted, "high-res")
        assert got.parts == parts
        assert got.print_s == pytest.approx(expected, rel=TOLERANCE), painted


def test_a_separate_painted_group_is_a_new_part(fab):
    before, _ = reference_s(fab, printed_ids(fab))
    est = estimator(fab, before)
    touching = set(lego_neighbours(fab, printed_ids(fab))) | printed_ids(fab)
    apart = [b.id for b in fab.layout.bricks if b.id not in touching][:1]
    assert apart, "the fixture has no brick apart from the part"
    expected, parts = reference_s(fab, printed_ids(fab) | set(apart))
    got = est.estimate(apart, "high-res")
    assert (got.parts, parts) == (2, 2)
    assert got.print_s == pytest.approx(expected, rel=TOLERANCE)
    assert got.assembly_s == pytest.approx(est.last().assembly_s - fab.seconds_per_brick
                                           + fab.seconds_per_part)


def test_painting_more_takes_longer_and_speeds_up_less(fab):
    est = estimator(fab)
    near = lego_neighbours(fab, printed_ids(fab))
    times = [est.last().print_s] + [est.estimate(near[:n]).print_s for n in range(1, len(near) + 1)]
    gains = [est.last().speedup] + [est.estimate(near[:n]).speedup for n in range(1, len(near) + 1)]
    assert all(b > a for a, b in zip(times, times[1:])), times
    assert all(b < a for a, b in zip(gains, gains[1:])), gains


def test_unmarking_printed_bricks_as_the_printed_parts_would(fab):
    before, _ = reference_s(fab, printed_ids(fab))
    est = estimator(fab, before)
    marked = sorted(printed_ids(fab))
    for painted in (marked[:1], marked[-1:]):
        rest = printed_ids(fab) - set(painted)
        expected, parts = reference_s(fab, rest) if rest else (0.0, 0)
        got = est.estimate(painted, "unmark")
        assert got.parts == parts
        assert got.print_s == pytest.approx(expected, rel=TOLERANCE), painted
    nothing = est.estimate(marked, "unmark")
    assert (nothing.print_s, nothing.parts) == (0.0, 0)
    assert nothing.assembly_s == pytest.approx(len(fab.layout.bricks) * fab.seconds_per_brick)


def test_split_makes_a_part_per_painted_brick(fab):
    est = estimator(fab)
    marked = sorted(printed_ids(fab))
    split = est.estimate(marked[:1], "split")
    assert split.parts == (2 if len(marked) > 1 else 1)
    assert est.estimate(marked[:1], "merge") == est.last()


def test_bad_input_says_what(fab):
    est = estimator(fab)
    with pytest.raises(InputError, match="not in the layout"):
        est.estimate([10 ** 6])
    with pytest.raises(ValueError, match="no estimate"):
        est.estimate([], "paint")
    part = fab.printed[0]
    stray = live_estimate.LastPart("P9", (10 ** 6,), 1.0)
    with pytest.raises(InputError, match="not in the layout"):
        live_estimate.Estimator(fab.layout, fab.model.mesh, [stray], 1.0, 10.0, 30.0)
    open_mesh = fab.model.mesh.copy()
    open_mesh.update_faces(np.arange(len(open_mesh.faces)) > 0)
    with pytest.raises(InputError):
        live_estimate.Estimator(fab.layout, open_mesh, [], None, 10.0, 30.0)
    assert part.id == "P1"


def test_without_a_whole_model_time_the_speed_up_is_against_the_models_estimate(fab):
    """Before any part is printed the last result has no whole-model time: the speed-up is
    then against print_time's calibrated estimate of the model itself, and says so."""
    est = live_estimate.Estimator(fab.layout, fab.model.mesh, [], None, 10.0, 30.0)
    got = est.estimate(lego_neighbours(fab, printed_ids(fab))[:1])
    whole = estimate_seconds([fab.model.mesh])
    assert got.print_s > 0 and got.parts == 1 and got.whole_estimated
    assert got.speedup == pytest.approx(whole / got.fabrication_s, rel=1e-9)
    assert "against the whole model's estimate" in live_estimate.words(got, est.last(), sliced=False)


def test_the_words_say_estimate_and_last_figure():
    got = live_estimate.Figures(4320.0, 600.0, 4350.0, 3.4, 2)
    last = live_estimate.Figures(3480.0, 600.0, 3510.0, 4.1, 2)
    assert live_estimate.words(got, last, sliced=True) == (
        "Estimate with these changes: print 1 h 12 min, speed-up 3.4x (estimate) · "
        "last sliced: print 58 min, speed-up 4.1x")
    assert live_estimate.words(None, last, sliced=False) == (
        "Last run (estimated): print 58 min, speed-up 4.1x")


def test_the_pose_of_a_report_gives_the_up_direction():
    on_side = {"matrix": [[0, 0, -1, 85], [1, 0, 0, 64], [0, -1, 0, 40], [0, 0, 0, 1]]}
    assert live_estimate.up_of_pose(on_side) == (0.0, -1.0, 0.0)
    assert live_estimate.up_of_pose(None) == live_estimate.UPRIGHT
    assert live_estimate.is_sliced("prusa-slicer 2.5.0 (MK3S)")
    assert not live_estimate.is_sliced("estimate (volume/surface/layers model); slicer disabled")
    assert not live_estimate.is_sliced("full model: prusa-slicer 2.5.0 (MK3S); printed parts: "
                                       "estimate (volume/surface/layers model; slicer failed)")


def test_snapshot_mesh_reads_a_folder_and_says_when_there_is_none(fab, tmp_path):
    from core import result

    folder = result.snapshot(fab, tmp_path)
    mesh = live_estimate.snapshot_mesh(folder)
    assert mesh.volume == pytest.approx(fab.model.mesh.volume)
    with pytest.raises(InputError, match="no readable model mesh"):
        live_estimate.snapshot_mesh(tmp_path / "nothing")
