"""The force stage against known answers: a real build (StableLego's staircase),
hand calculations of a cantilever, and PrusaSlicer's own filament weights."""

from __future__ import annotations

import dataclasses
import math
import re
import shutil
import subprocess

import numpy as np
import pytest
import trimesh

from core import forces
from core.catalog import MASS_G
from core.errors import InputError
from core.forces import joints, limits, solver, verdict
from core.forces.analyse import _Model
from core.forces.solver import Program
from core.model import Brick, Grid, Layout
from core.request import parse_load

CELL = np.array([8.0, 8.0, 3.2])
#: The clutch in grams-force (the programs' unit): 0.98 N.
T_GF = forces.CLUTCH_N / (forces.G / 1000.0)


def layout_of(bricks: list[Brick]) -> Layout:
    """A layout of ``bricks`` on a grid just large enough, origin at 0."""
    top = np.max([np.add(b.cell, b.size) for b in bricks], axis=0)
    filled = np.zeros(tuple(int(v) for v in top), dtype=bool)
    for b in bricks:
        assert not filled[b.slices()].any(), "bricks overlap"
        filled[b.slices()] = True
    return Layout(Grid(np.zeros(3), CELL.copy(), filled), bricks)


def staircase(levels: int) -> Layout:
    """StableLego's staircase: 2x4 bricks, each two studs further along than the one below."""
    return layout_of([Brick(n + 1, "3001", (4, 2, 3), (2 * n, 0, 3 * n)) for n in range(levels)])


def test_staircase_stands_at_19_and_falls_at_20_at_the_second_brick():
    """StableLego (validated on real builds): 19 levels stand, 20 collapse, failing at the
    second brick, with T = 100 g per contact."""
    assert forces.analyse(staircase(19), ground="baseplate").stable
    twenty = forces.analyse(staircase(20), ground="baseplate")
    assert not twenty.stable
    assert twenty.failing_bricks == [2]
    assert twenty.failures[0]["mode"] == "clutch"


def staircase_by_hand(n: int) -> float:
    """The joint under the second brick carries bricks 2..N as one overhang.  It tips about
    its contact point furthest along x (the tube contact of its second stud, at x = 3.5 +
    r * sqrt(1/2) studs); every contact point nearer the start pulls with the clutch at
    most.  Worst utilisation = moment of the overhang / moment of the full clutch."""
    r = joints.CONTACT_RADIUS
    d = r * math.sqrt(0.5)
    pivot = 3.5 + d
    # per row of studs (y = 0 and y = 1 alike): stud at 2.5 has its end wall (x - r),
    # outer wall (x) and tube (x + d); stud at 3.5: outer wall (x), tubes (x - d), (x + d)
    xs = [2.5 - r, 2.5, 2.5 + d, 3.5, 3.5 - d, 3.5 + d]
    resist = 2 * sum(pivot - x for x in xs) * T_GF
    com = np.mean([2 * m + 2 for m in range(1, n)])          # bricks 2..N, centres in studs
    return (n - 1) * MASS_G["3001"] * (com - pivot) / resist


def test_staircase_utilisation_is_the_hand_calculation():
    result = forces.analyse(staircase(20), ground="baseplate")
    assert result.max_utilisation == pytest.approx(staircase_by_hand(20), rel=1e-4)
    assert result.utilisation[2] == pytest.approx(staircase_by_hand(20), rel=1e-4)


def test_staircase_on_a_table_tips_over():
    """Without a baseplate nothing holds the first brick down: the staircase's centre of
    mass is far beyond its footprint (x = 0..4 studs), so it tips over."""
    result = forces.analyse(staircase(6), ground="table")
    assert not result.stable
    assert math.isinf(result.max_utilisation)
    assert result.unsupported and {f["mode"] for f in result.failures} == {"tips"}


def test_staircase_on_a_table_tips_when_its_centre_of_mass_leaves_the_footprint():
    """By hand: the first brick rests on x = 0..4 studs (less 0.1 mm of play each side).
    Two levels have their centre of mass at x = 3 (bricks centred at 2 and 4): they stand.
    Three levels have it at x = 4, past the edge: they tip over, whatever the studs hold."""
    assert forces.analyse(staircase(2), ground="table").stable
    three = forces.analyse(staircase(3), ground="table")
    assert not three.stable and three.unsupported == [1, 2, 3]


@pytest.mark.parametrize("ground", ["table", "baseplate"])
def test_tower_of_1x1_bricks_stands(ground):
    tower = layout_of([Brick(n + 1, "3005", (1, 1, 3), (0, 0, 3 * n)) for n in range(12)])
    result = forces.analyse(tower, ground=ground)
    assert result.stable and not result.failing_bricks
    assert result.max_utilisation < 1e-3
    assert result.mass_g == pytest.approx(12 * MASS_G["3005"])


PLATES_1_WIDE = {1: "3024", 2: "3023", 3: "3623", 4: "3710", 6: "3666", 8: "3460"}


def cantilever(length: int) -> Layout:
    """A 1x1 brick on the baseplate, and a 1 x ``length`` plate on it by its first stud."""
    return layout_of([Brick(1, "3005", (1, 1, 3), (0, 0, 0)),
                      Brick(2, PLATES_1_WIDE[length], (length, 1, 1), (0, 0, 3))])


@pytest.mark.parametrize("length", [2, 3, 4, 6, 8])
def test_cantilever_with_a_weight_at_its_tip_breaks_past_the_hand_length(length):
    """The plate hangs on one stud gripped at four points r studs from its axis.  It
    tips about the point towards the tip (x = 0.5 + r studs); the point opposite pulls with
    lever 2 r, the two beside with r each: the joint holds 4 r T studs.  The plate's
    weight acts at L/2, the tip load (20 g) at L - 0.5."""
    tip = 20.0
    r = joints.CONTACT_RADIUS
    pivot = 0.5 + r
    capacity = (2 * r + r + r) * T_GF
    demand = MASS_G[PLATES_1_WIDE[length]] * (length / 2 - pivot) + tip * (length - 0.5 - pivot)
    box = f"{(length - 1) * 8},0,12.8,{length * 8},8,16:{tip}"
    result = forces.analyse(cantilever(length), ground="baseplate", loads=[box])
    assert result.utilisation[2] == pytest.approx(demand / capacity, rel=1e-4)
    assert result.stable == (demand <= capacity)
    # by hand: 1x4 holds 20 g at its tip, 1x6 does not
    assert result.stable == (length <= 4)


def bridge(part: str, layers: int) -> Layout:
    """Two 2x2 towers two bricks high on a table, 6 studs apart, spanned by a 2x8 ``part``."""
    bricks = [Brick(n + 1, "3003", (2, 2, 3), (x, 0, 3 * h))
              for n, (x, h) in enumerate([(0, 0), (0, 1), (6, 0), (6, 1)])]
    bricks.append(Brick(5, part, (8, 2, layers), (0, 0, 6)))
    return layout_of(bricks)


def test_bridge_of_one_plate_holds_less_than_a_brick():
    """A load on the middle two columns of studs: the plate (3.2 mm tall) breaks by bending
    long before the brick (9.6 mm) does.  The load a bridge holds is load / utilisation
    (its own weight is small against 5 kg)."""
    held = {}
    for part, layers in (("3034", 1), ("3007", 3)):
        top = (6 + layers) * 3.2
        result = forces.analyse(bridge(part, layers), ground="table",
                                loads=[f"24,0,{top},40,16,{top + 10}:5000"])
        held[part] = 5000 / result.max_utilisation
        assert result.utilisation[5] == pytest.approx(result.max_utilisation, rel=1e-5)
    assert held["3034"] < held["3007"]
    # by hand, as a beam on two supports without end moments: the reactions at the
    # innermost contact points (tubes 0.2 * sqrt(1/2) studs beyond the studs at 1.5 and
    # 6.5), the load at 3.5 and 4.5: M(4) = P / 2 * (6.5 - d - 4) - P / 2 * 0.5.  The
    # joints can add end moments, so the plate holds at least that, and not twice over.
    d = joints.CONTACT_RADIUS * math.sqrt(0.5)
    arm = 0.5 * (6.5 - d - 4) - 0.5 * 0.5
    strength = forces.bending_capacity_nmm(2, 1) / (forces.G / 1000) / 8.0
    simple = strength / arm
    assert simple * 0.99 <= held["3034"] <= 2 * simple


def test_printed_part_weight_turns_a_marginal_layout_unstable():
    """A 1x4 cantilever loaded to 99.5 % of its clutch stands; a printed part at its tip
    (a 20 mm cube's worth of PLA, printed with 2 perimeters and 15 % infill) breaks it."""
    r = joints.CONTACT_RADIUS
    pivot = 0.5 + r
    capacity = 4 * r * T_GF
    tip = (0.995 * capacity - MASS_G["3710"] * (2 - pivot)) / (3.5 - pivot)
    base = [Brick(1, "3005", (1, 1, 3), (0, 0, 0)), Brick(2, "3710", (4, 1, 1), (0, 0, 3))]
    box = f"24,0,12.8,32,8,16:{tip}"
    assert forces.analyse(layout_of(base), ground="baseplate", loads=[box]).stable
    printed = base + [Brick(3, "printed", (1, 1, 3), (3, 0, 4), kind="printed", printed_part="P1")]
    result = forces.analyse(layout_of(printed), ground="baseplate", loads=[box])
    assert not result.stable
    assert 2 in result.failing_bricks


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("prusa-slicer") is None, reason="PrusaSlicer is not installed")
@pytest.mark.parametrize("size", [(20.0, 20.0, 20.0), (40.0, 16.0, 9.6)])
def test_printed_mass_matches_prusaslicers_filament_weight(tmp_path, size):
    """The mass a printed part weighs in the force check is within 5 % of the filament
    PrusaSlicer itself says it uses, with the profile the parts are sliced with."""
    from core.printing import print_time
    mesh = trimesh.creation.box(size)
    stl = tmp_path / "part.stl"
    mesh.export(stl)
    gcode = tmp_path / "part.gcode"
    subprocess.run(["prusa-slicer", "--export-gcode", "--load", str(print_time.FALLBACK_PROFILE),
                    "-o", str(gcode), str(stl)], check=True, capture_output=True, timeout=300)
    grams = float(re.search(r"; filament used \[g\] = ([\d.]+)", gcode.read_text())[1])
    profile = print_time.load_profile(print_time.FALLBACK_PROFILE)
    assert forces.printed_mass_g(mesh.volume, mesh.area, profile) == pytest.approx(grams, rel=0.05)


def test_loads_and_load_g_add_their_mass():
    tower = layout_of([Brick(1, "3003", (2, 2, 3), (0, 0, 0), load_g=170.0)])
    result = forces.analyse(tower, ground="table", loads=["0,0,9.6,16,16,20:30"])
    assert result.mass_g == pytest.approx(MASS_G["3003"] + 170 + 30)
    assert result.stable


@pytest.mark.parametrize("text, words", [
    ("1,2,3:5", "six numbers"), ("a,b,c,d,e,f:5", "numbers"), ("0,0,0,1,1,1:-2", "more than 0"),
    ("0,0,0,0,1,1:2", "empty"), ("0,0,0,1,1,1", "X0,Y0"), ("0,0,0,nan,1,1:3", "finite")])
def test_bad_loads_name_the_problem(text, words):
    with pytest.raises(InputError, match=words):
        parse_load(text)


def test_a_load_that_touches_no_brick_is_refused():
    tower = layout_of([Brick(1, "3005", (1, 1, 3), (0, 0, 0))])
    with pytest.raises(InputError, match="touches no brick"):
        forces.analyse(tower, loads=["100,100,100,110,110,110:10"])


def test_floating_bricks_are_unsupported():
    """A brick joined to nothing that stands on the ground floats."""
    layout = layout_of([Brick(1, "3005", (1, 1, 3), (0, 0, 0)), Brick(2, "3005", (1, 1, 3), (3, 0, 6))])
    result = forces.analyse(layout, ground="table")
    assert not result.stable
    assert result.unsupported == [2]
    assert result.failures[0]["mode"] == "floats"


def test_verdict_only_agrees_with_the_detail():
    for levels in (19, 20):
        quick = forces.analyse(staircase(levels), ground="baseplate", detail=False)
        full = forces.analyse(staircase(levels), ground="baseplate")
        assert quick.stable == full.stable
        assert quick.max_utilisation == pytest.approx(full.max_utilisation, rel=1e-5)
        assert quick.utilisation == {}


def test_analyse_does_not_change_the_layout():
    layout = staircase(5)
    before = layout.to_json()
    forces.analyse(layout, ground="baseplate", loads=["0,0,0,8,8,3:10"])
    assert layout.to_json() == before


@pytest.mark.parametrize("settings, words", [({"ground": "floor"}, "table or baseplate"),
                                              ({"clutch_n": 0}, "above 0"),
                                              ({"clutch_n": float("nan")}, "above 0")])
def test_bad_settings_name_the_problem(settings, words):
    with pytest.raises(InputError, match=words):
        forces.analyse(staircase(2), **settings)


def t_layout() -> Layout:
    """On a table: a 1x2 brick (x 3..5), a lone 1x1 brick further on (x 10), then in the
    layer above a 1x4 arm over the first brick's left stud (x 0..4) and a 1x2 counterweight
    over its right stud (x 4..6)."""
    return layout_of([Brick(1, "3004", (2, 1, 3), (3, 0, 0)), Brick(2, "3005", (1, 1, 3), (10, 0, 0)),
                      Brick(3, "3010", (4, 1, 3), (0, 0, 3)), Brick(4, "3004", (2, 1, 3), (4, 0, 3))])


def test_build_order_whose_third_step_tips_is_reordered():
    """Planned one brick a step, bottom-up: the arm (step 3) would tip the 1x2 brick over (by
    hand: centre of mass (0.81 * 4 + 1.57 * 2) / 2.38 = 2.68, left of its footprint's edge
    at 3); with the counterweight first (centre 4.5) and then the arm (3.27) it stands."""
    from core.instructions import build_order
    layout = t_layout()
    planned = build_order.plan(layout, bricks_per_step=1)
    assert [s.bricks for s in planned.steps] == [[1], [2], [3], [4]]
    checker = forces.BuildChecker(layout, ground="table")
    assert checker.stands(np.array([True, True, True, False])) == (False, math.inf)
    order = build_order.standing(layout, planned, checker.stands)
    assert [s.bricks for s in order.steps] == [[1], [2], [4], [3]]
    assert [s.number for s in order.steps] == [1, 2, 3, 4]
    assert order.unstable == [] and order.moved == 1
    assert all(u <= 1 for u in order.utilisation)


def test_build_order_that_cannot_stand_names_the_step():
    """Without the counterweight nothing keeps the arm from tipping the brick over: the
    order stays and the step is named."""
    from core.instructions import build_order
    layout = layout_of(t_layout().bricks[:3])
    planned = build_order.plan(layout, bricks_per_step=1)
    order = build_order.standing(layout, planned, forces.BuildChecker(layout, ground="table").stands)
    assert [s.bricks for s in order.steps] == [[1], [2], [3]]
    assert [u["step"] for u in order.unstable] == [3]
    assert order.unstable[0]["utilisation"] is None and "tips over" in order.unstable[0]["why"]


def long_bridge(span_plates: int) -> Layout:
    """Two 2x2 bricks whose outer ends are ``8 * span_plates + 4`` studs apart, joined by two
    layers of 2x8 plates, the upper one half a plate along (2x4 plates at its ends)."""
    length = 8 * span_plates + 4
    part = {8: "3034", 4: "3020"}
    bricks = [Brick(1, "3003", (2, 2, 3), (0, 0, 0)), Brick(2, "3003", (2, 2, 3), (length - 2, 0, 0))]
    for k, first in ((3, 8), (4, 4)):
        x, s = 0, first
        while x < length:
            bricks.append(Brick(len(bricks) + 1, part[s], (s, 2, 1), (x, 0, k)))
            x += s
            s = min(8, length - x)
    return layout_of(bricks)


def test_a_bridge_is_built_out_from_both_towers(monkeypatch):
    """An 80 cm bridge of two plate layers between two towers stands (worst 0.11).  Built
    from one tower across, it carries the whole span as a cantilever and fails half way
    (known since StableLego's staircase: the clutch holds a limited overhang).  Built out
    from both towers in turn (each unit by its reach), every step carries at most half the
    span, and stands."""
    from core.instructions import build_order
    lay = long_bridge(12)
    assert forces.analyse(lay, ground="baseplate").stable
    both = build_order.standing(lay, build_order.plan(lay, bricks_per_step=1),
                                forces.BuildChecker(lay, ground="baseplate").stands)
    assert both.unstable == [] and max(both.utilisation) < 0.8
    # the lower layer's middle plate (x 48..55) is 43 studs from the nearest cell over a tower
    # (x 1 or 98): reach 43 // 4 = 10; the towers have 0
    reach = build_order.reach(lay)
    assert reach.max() == 10 and list(reach[:2]) == [0, 0]
    monkeypatch.setattr(build_order, "REACH_STUDS", 10 ** 6)
    one = build_order.standing(lay, build_order.plan(lay, bricks_per_step=1),
                               forces.BuildChecker(lay, ground="baseplate").stands)
    assert len(one.unstable) >= 5 and max(one.utilisation) > 2


def test_a_prop_under_the_arm_lets_it_stand_and_stays():
    """The arm that tips the 1x2 brick over (test above) rests, with a 1x1 brick stood on the
    table under its far stud, on that prop (x 0..1) and on the brick (x 3..5): its centre
    (x 2) lies between them, so it stands in pure compression (utilisation 0).  The
    finished build tips without the prop, so the prop stays."""
    from core.instructions import build_order, page as instructions
    layout = layout_of(t_layout().bricks[:3])
    checker = forces.BuildChecker(layout, ground="table")
    assert checker.stands(np.ones(3, bool), np.array([[0, 0, 3]])) == (True, 0.0)
    assert checker.stands(np.ones(3, bool)) == (False, math.inf)
    order = build_order.standing(layout, build_order.plan(layout, bricks_per_step=1),
                                 checker.stands, props=True)
    assert order.unstable == [] and order.utilisation == [0.0, 0.0, 0.0]
    assert order.props == [{"step": 3, "cell": [0, 0, 3], "plates": 3, "parts": {"3005": 1},
                            "under": 3, "on": "table", "box_mm": [[0, 0, 0], [8, 8, 9.6]], "removed_after": None,
                            "closed_in": False}]
    words = instructions.step_warnings(order, layout)[3]
    assert words.startswith("Prop: before step 3, stand a prop 3 plate(s) tall (1 x Brick 1 x 1 "
                            "(3005)) on the table under stud 1,1 of the Brick 1 x 4")
    assert "the finished build still needs it" in words


def test_the_finished_build_is_judged_with_the_props_it_keeps_and_what_it_carries():
    """The arm's finished build (test above) keeps its prop: with it, it stands in pure
    compression.  Judged with a load on the arm's middle studs (x 1..3), the prop and the
    brick carry it and the arm bends between them: its utilisation grows with the load
    (twice the load, twice the utilisation: its own weight only presses), and 100 kg break it."""
    from core.instructions import build_order
    layout = layout_of(t_layout().bricks[:3])
    checker = forces.BuildChecker(layout, ground="table")
    order = build_order.standing(layout, build_order.plan(layout, bricks_per_step=1),
                                 checker.stands, props=True)
    bare = build_order.finished_with_props(layout, order, checker.stands)
    assert bare == {"props_left_in": 1, "checked": True, "stands": True, "max_utilisation": 0.0}

    def loaded(grams):
        loaded = forces.BuildChecker(layout, ground="table", loads=[f"8,0,19.2,24,8,25:{grams}"])
        return build_order.finished_with_props(layout, order, loaded.stands)

    five, ten, heavy = loaded(5000), loaded(10000), loaded(100000)
    assert five["stands"] and ten["stands"] and 0.01 < five["max_utilisation"] < ten["max_utilisation"]
    assert ten["max_utilisation"] == pytest.approx(2 * five["max_utilisation"], rel=0.01)
    assert heavy["stands"] is False and heavy["max_utilisation"] > 1
    # between, by the same line: 6.5 times the 10 kg stands, above what is fragile
    near = loaded(65000)
    assert near["stands"] and 0.8 < near["max_utilisation"] <= 1
    assert build_order.finished_words(near, {"ground": "table", "mass_g": 65002.0}).endswith(
        "(fragile: its hardest joint works above 0.8 of what it holds)")
    assert "fragile" not in build_order.finished_words(heavy, {"ground": "table", "mass_g": 1.0})
    force = {"ground": "table", "mass_g": 10002.0}
    assert build_order.finished_words(ten, force) == (
        f"with its 1 prop(s) left in, it stands on a table with 10002 g: worst joint utilisation "
        f"{ten['max_utilisation']:.2f}")
    unpropped = dataclasses.replace(order, props=[dict(p, removed_after=3) for p in order.props])
    assert build_order.finished_with_props(layout, unpropped, checker.stands) is None


def built_without_and_with_props(lay: Layout, ground: str):
    """The checked build orders of ``lay`` (one brick a step) without props and with them."""
    from core.instructions import build_order
    plan = build_order.plan(lay, bricks_per_step=1)
    return tuple(build_order.standing(lay, plan, forces.BuildChecker(lay, ground=ground).stands,
                                      props=props, ground=ground) for props in (False, True))


def test_a_bridge_too_long_for_its_halves_is_closed_on_a_baseplate_over_a_prop():
    """A 1.3 m bridge on a baseplate: built out from both towers, its halves still fail
    just before they meet (three steps do not stand).  A prop under the middle holds it
    until it is closed, by the last step, then goes."""
    lay = long_bridge(16)
    bare, order = built_without_and_with_props(lay, "baseplate")
    assert len(bare.unstable) >= 1
    assert order.unstable == [] and max(order.utilisation) <= 1
    assert len(order.props) == 1
    prop = order.props[0]
    assert prop["step"] == bare.unstable[0]["step"]
    assert prop["removed_after"] == len(order.steps)                    # once it is closed
    assert abs(prop["cell"][0] - lay.grid.shape[0] / 2) <= 8             # near the middle
    from core.instructions import build_order
    assert prop["on"] == "baseplate"
    assert " on the baseplate under stud " in build_order.prop_words(build_order.numbered(lay, order), prop)


def test_a_bridge_on_a_table_is_built_on_props_taken_away_when_it_is_closed():
    """On a table, each half-built side of the 80 cm bridge tips its tower over (every step
    from the fourth does not stand).  With props, every step stands; each prop is one 1x1
    brick (the 3 plates under the bridge) in a cell that stays empty in the finished build;
    they all go once the bridge is closed, which then stands on its towers alone."""
    lay = long_bridge(12)
    bare, order = built_without_and_with_props(lay, "table")
    assert len(bare.unstable) >= 20
    assert order.unstable == [] and max(order.utilisation) < 0.1
    assert 1 <= len(order.props) <= 12
    filled = lay.grid.filled
    for p in order.props:
        i, j, k = p["cell"]
        assert k == 3 and p["plates"] == 3 and p["parts"] == {"3005": 1}
        assert not filled[i, j, :k].any() and filled[i, j, k]
        assert p["removed_after"] == len(order.steps)
    assert forces.analyse(lay, ground="table").stable


def test_props_in_a_channel_the_bridge_closes_stay_inside():
    """The 80 cm bridge on a table between two walls a brick high, one stud beside it on
    either side: the air under the bridge is closed in by the walls, the towers and the
    bridge itself.  Its props stand in that air; when the bridge is closed, and stands
    without them, nothing can take them out: they stay, and the words say so."""
    from core.instructions import page as instructions
    bridge = long_bridge(12)
    length = bridge.grid.shape[0]
    bricks = [dataclasses.replace(b, cell=(b.cell[0], b.cell[1] + 1, b.cell[2])) for b in bridge.bricks]
    for y in (0, 3):
        x = 0
        while x < length:
            s = min(8, length - x)
            bricks.append(Brick(len(bricks) + 1, {8: "3008", 4: "3010"}[s], (s, 1, 3), (x, y, 0)))
            x += s
    lay = layout_of(bricks)
    _, order = built_without_and_with_props(lay, "table")
    assert order.unstable == [] and order.props
    assert all(p["closed_in"] and p["removed_after"] is None for p in order.props)
    words = instructions.step_warnings(order, lay)
    assert all("it stays inside" in words[p["step"]] for p in order.props)


def test_build_checker_agrees_with_the_analysis_on_every_prefix():
    layout = staircase(21)
    checker = forces.BuildChecker(layout, ground="baseplate")
    for n in (1, 5, 19, 20, 21, 12):
        present = np.arange(21) < n
        prefix = layout_of(layout.bricks[:n])
        ok, worst = checker.stands(present)
        full = forces.analyse(prefix, ground="baseplate", detail=False)
        assert ok == full.stable
        assert worst == pytest.approx(full.max_utilisation, rel=1e-5, abs=1e-9)


def test_instructions_warn_at_the_step_that_does_not_stand():
    from core.instructions import build_order, page as instructions
    layout = layout_of(t_layout().bricks[:3])
    order = build_order.standing(layout, build_order.plan(layout, bricks_per_step=1),
                                 forces.BuildChecker(layout, ground="table").stands)
    layout = build_order.numbered(layout, order)
    steps = instructions._step_data(layout, order, [])
    assert [s.get("w", "")[:24] for s in steps] == ["", "", "Does not stand on its ow"]
    text, _ = instructions.page(layout, order)
    assert "Does not stand on its own" in text


def test_a_build_too_heavy_on_one_side_tips_until_it_rests_on_its_lower_points():
    """A 1x8 brick over a 1x2 brick by one end: the centre of mass (x = (0.81 * 1 + 3.03 * 4)
    / 3.84 = 3.4 studs) is past the 1x2 brick (x 0..2), so the build tips over until the far
    end of the 1x8 brick's underside (9.6 mm up, 48 mm further along) touches the table: it
    does not stand as built, and would rest leaning atan(9.6 / 48) = 11.3 degrees."""
    layout = layout_of([Brick(1, "3004", (2, 1, 3), (0, 0, 0)), Brick(2, "3008", (8, 1, 3), (0, 0, 3))])
    result = forces.analyse(layout, ground="table")
    assert not result.stable and result.unsupported == [1, 2]
    (topple,) = result.topples
    assert topple["would_lean_deg"] == pytest.approx(math.degrees(math.atan(9.6 / 48.0)), abs=0.01)
    assert "resting leaning" not in topple["why"] and "tips over" in topple["why"]


def test_a_build_that_would_lean_further_tips_too():
    """A 1x4 brick over a 1x1 brick by one end would lean atan(9.6 / 24) = 21.8 degrees."""
    layout = layout_of([Brick(1, "3005", (1, 1, 3), (0, 0, 0)), Brick(2, "3010", (4, 1, 3), (0, 0, 3))])
    result = forces.analyse(layout, ground="table")
    assert not result.stable and result.unsupported == [1, 2]
    # the report says why: centre of mass at (0.43 * 4 + 1.57 * 16) / 2.0 = 13.4 mm, the 1x1
    # brick's outline ends at 7.9 mm (0.1 mm of play)
    (topple,) = result.topples
    assert topple["would_lean_deg"] == pytest.approx(math.degrees(math.atan(9.6 / 24.0)), abs=0.05)
    assert topple["beyond_bottom_mm"] == pytest.approx((0.43 * 4 + 1.57 * 16) / 2.0 - 7.9, abs=0.06)
    assert "on a baseplate" in topple["why"]


def count_programs(monkeypatch) -> list:
    """A list that gets an item for every force program solved from now on."""
    solved = []
    real = Program.solve

    def counted(self, *args, **kwargs):
        solved.append(1)
        return real(self, *args, **kwargs)

    monkeypatch.setattr(Program, "solve", counted)
    return solved


@pytest.mark.parametrize("bricks", [
    [Brick(1, "3004", (2, 1, 3), (0, 0, 0)), Brick(2, "3008", (8, 1, 3), (0, 0, 3))],
    [Brick(1, "3005", (1, 1, 3), (0, 0, 0)), Brick(2, "3010", (4, 1, 3), (0, 0, 3)),
     Brick(3, "3005", (1, 1, 3), (3, 0, 6))],
    [Brick(1, "3005", (1, 1, 3), (0, 0, 0)), Brick(2, "3010", (4, 1, 3), (0, 0, 3)),
     Brick(3, "3005", (1, 1, 3), (6, 0, 0))]])
def test_a_build_that_tips_as_a_whole_is_judged_without_a_program_as_the_program_judges(
        monkeypatch, bricks):
    """A build whose every structure tips over on a table fails whatever its joints do: the
    same bricks, utilisations and words as the whole program's answer, without solving it
    (a bunny scaled x3 tips: judged in 0.1 s, where its hanging part was never checked).
    A build with a structure that stands beside one that tips (the third) gets the program."""
    layout = layout_of(bricks)
    solved = count_programs(monkeypatch)
    quick = forces.analyse(layout, ground="table")
    quick_count = len(solved)
    monkeypatch.setattr(_Model, "_falls_over", lambda self: None)
    whole = forces.analyse(layout, ground="table")
    assert not whole.stable and whole.topples
    assert quick.to_json() | {"seconds": 0} == whole.to_json() | {"seconds": 0}
    assert quick_count == (len(solved) - quick_count if len(bricks) == 3 and bricks[2].cell[2] == 0
                           else 0)
    assert forces.analyse(layout, ground="baseplate").topples == []


def arm_of_plates() -> Layout:
    """A 2x2 tower two bricks high and, on it, a 1-wide arm 10 studs long, three plate layers
    thick, laid as 1x2 plates in a running bond (and 1x2 plates capping the tower)."""
    bricks = [Brick(1, "3003", (2, 2, 3), (0, 0, 0)), Brick(2, "3003", (2, 2, 3), (0, 0, 3))]
    rows = {6: [(0, 2), (2, 4), (4, 6), (6, 8), (8, 10)],
            7: [(0, 1), (1, 3), (3, 5), (5, 7), (7, 9), (9, 10)],
            8: [(0, 2), (2, 4), (4, 6), (6, 8), (8, 10)]}
    for k, segments in rows.items():
        for a, b in segments:
            bricks.append(Brick(len(bricks) + 1, {1: "3024", 2: "3023"}[b - a], (b - a, 1, 1), (a, 0, k)))
        bricks.append(Brick(len(bricks) + 1, "3023", (2, 1, 1), (0, 1, k)))
    return layout_of(bricks)


def test_reinforce_re_merges_around_the_failing_joint():
    """45 g at the arm's tip pulls the arm's 1x2 plates off the tower (utilisation > 1);
    merged again around the failing joint the arm holds, covering the same cells."""
    from core.layout import reinforce
    layout = arm_of_plates()
    load = ["72,0,28.8,80,8,40:45"]
    assert not forces.analyse(layout, ground="baseplate", loads=load).stable
    result = reinforce.reinforce(layout, ground="baseplate", loads=load)
    assert result.before["stable"] is False and result.after["stable"] is True
    assert result.after["max_utilisation"] < 1
    assert forces.analyse(result.layout, ground="baseplate", loads=load).stable
    covered = np.zeros(layout.grid.shape, dtype=int)
    for b in result.layout.bricks:
        covered[b.slices()] += 1
    assert np.array_equal(covered, layout.grid.filled.astype(int))
    assert result.after["components"] == 1
    assert len({b.id for b in result.layout.bricks}) == len(result.layout.bricks)


def test_the_detail_after_the_verdict_solves_the_verdict_once():
    """forces.Analysis asked for the verdict alone and then the detail gives the detail a
    fresh analyse gives, for less work (the verdict's program is not solved again); the
    verdict asked again costs nothing."""
    load = ["72,0,28.8,80,8,40:45"]
    check = forces.Analysis(arm_of_plates(), ground="baseplate", loads=load)
    alone = check.verdict(detail=False)
    detail = check.verdict()
    fresh = forces.analyse(arm_of_plates(), ground="baseplate", loads=load)
    assert not fresh.stable and fresh.work > 0
    assert (detail.stable, detail.max_utilisation) == (fresh.stable, fresh.max_utilisation)
    assert detail.utilisation == fresh.utilisation and detail.failing_bricks == fresh.failing_bricks
    assert 0 < detail.work < fresh.work
    again = check.verdict(detail=False)
    assert again.work == 0 and again.max_utilisation == alone.max_utilisation == fresh.max_utilisation


def test_fast_effort_tries_each_reinforce_site_once(monkeypatch):
    """Each reinforce try is a force check of the whole build: ``fast`` tries one window per
    site, ``normal`` every window size and seed of reinforce.EFFORT_TRIES; with windows that
    never help, both stop after their first round."""
    from core.layout import reinforce
    load = ["72,0,28.8,80,8,40:45"]
    layout = arm_of_plates()
    tried = []
    monkeypatch.setattr(reinforce, "_relaid", lambda lay, site, radius, parts, seed, frozen:
                        tried.append(site) or lay)
    sites = len(reinforce._sites(layout, forces.analyse(layout, ground="baseplate", loads=load),
                                 np.zeros(layout.grid.shape, bool))[:reinforce.SITES])
    assert sites >= 2
    fast = reinforce.reinforce(layout, ground="baseplate", loads=load, effort="fast")
    assert fast.attempts == sites and fast.kept == 0 and fast.layout is layout
    normal = reinforce.reinforce(layout, ground="baseplate", loads=load, effort="normal")
    assert normal.attempts == sites * len(reinforce.RADIUS) * len(reinforce.SEEDS)
    assert len(tried) == fast.attempts + normal.attempts


def test_the_verdict_alone_never_judges_a_layout_worse_than_the_detail():
    """reinforce screens candidates on the verdict alone (detail=False): it has the same
    worst utilisation as the detail, and stands whenever the detail does."""
    from core.layout import reinforce
    load = ["72,0,28.8,80,8,40:45"]
    layout = arm_of_plates()
    for candidate in (layout, reinforce.reinforce(layout, ground="baseplate", loads=load).layout):
        for loads in ((), load):
            alone = forces.analyse(candidate, ground="baseplate", loads=loads, detail=False)
            full = forces.analyse(candidate, ground="baseplate", loads=loads)
            assert alone.max_utilisation == pytest.approx(full.max_utilisation, rel=1e-9)
            assert alone.stable >= full.stable


def test_reinforce_leaves_a_standing_layout_alone():
    from core.layout import reinforce
    layout = arm_of_plates()
    result = reinforce.reinforce(layout, ground="baseplate")
    assert result.layout is layout and result.attempts == 0


def test_reinforce_leaves_a_build_judged_in_height_bands_alone(monkeypatch):
    """The 19-level staircase works its second brick at 0.93, above LOADED: a site to work
    around.  Judged in height bands each brick has only its band's worst (and each judgement
    would be bands again): reinforce leaves it as it is."""
    from core.layout import reinforce
    layout = staircase(19)
    assert reinforce.reinforce(layout, ground="baseplate").attempts > 0
    monkeypatch.setattr(limits, "MAX_HANGING", 0)
    monkeypatch.setattr(limits, "EXACT_BODIES", 0)
    monkeypatch.setattr(limits, "MAX_BODIES", 2)
    monkeypatch.setattr(limits, "BAND_BODIES", 3)
    result = reinforce.reinforce(layout, ground="baseplate")
    assert result.forces.bands and result.forces.max_utilisation > reinforce.LOADED
    assert result.attempts == 0 and result.layout is layout


def test_a_build_beyond_the_bodies_the_programs_solve_is_reported_unchecked(monkeypatch):
    monkeypatch.setattr(limits, "MAX_BODIES", 10)
    monkeypatch.setattr(limits, "MAX_BANDED", 10)          # nor in height bands
    result = forces.analyse(staircase(12), ground="baseplate")
    doc = result.to_json()
    assert doc["checked"] is False and doc["stable"] is None and "12 bricks" in doc["unchecked_why"]
    # a build all in compression needs no program, whatever its size
    tower = layout_of([Brick(n + 1, "3005", (1, 1, 3), (0, 0, 3 * n)) for n in range(12)])
    assert forces.analyse(tower).to_json()["checked"] is True


def test_given_seconds_a_build_beyond_the_bodies_is_solved_whole_as_the_hand_calculation(monkeypatch):
    """Past MAX_BODIES, with neither parts nor bands, the staircase is unchecked; given seconds,
    one program solves it, and finds StableLego's answer: 12 levels stand at the hand
    calculation's utilisation, 20 fall."""
    monkeypatch.setattr(limits, "MAX_BODIES", 10)
    monkeypatch.setattr(limits, "MAX_BANDED", 10)
    assert forces.analyse(staircase(12), ground="baseplate").unchecked
    twelve = forces.analyse(staircase(12), ground="baseplate", seconds=60)
    assert twelve.stable and twelve.max_utilisation == pytest.approx(staircase_by_hand(12), rel=1e-4)
    assert not forces.analyse(staircase(20), ground="baseplate", seconds=60, detail=False).stable
    for bad in (0, -1.0, math.nan, math.inf, True, "9"):
        with pytest.raises(InputError, match="--seconds"):
            forces.analyse(staircase(2), seconds=bad)


@pytest.mark.parametrize("ground", ["table", "baseplate"])
def test_a_step_borne_on_full_columns_keeps_what_the_programs_say(ground):
    """Built step by step, a staircase (which needs programs) with a tower beside it and
    bricks on the staircase's own columns: a step that adds only bricks borne on full
    columns is answered without a program, as it stands, with at most the last proven
    set's utilisation, at least the program's own; every other step as the program."""
    stair = staircase(6).bricks
    tower = [Brick(10 + n, "3001", (4, 2, 3), (20, 0, 3 * n)) for n in range(5)]
    on_stair = [Brick(20, "3003", (2, 2, 3), (0, 0, 3)), Brick(21, "3022", (2, 2, 1), (0, 0, 6))]
    layout = layout_of(stair + tower + on_stair)
    order = [b.id for b in stair[:2]] + [b.id for b in tower] + [20, 21] + [b.id for b in stair[2:]]
    index = {b.id: n for n, b in enumerate(layout.bricks)}
    checker = forces.BuildChecker(layout, ground=ground)
    exact = forces.BuildChecker(layout, ground=ground)
    monkey = pytest.MonkeyPatch()
    monkey.setattr(exact, "_borne_bound", lambda present: None)
    present = np.zeros(len(layout.bricks), dtype=bool)
    shortcuts = 0
    for brick in order:
        present[index[brick]] = True
        solves = checker.solves
        ok, worst = checker.stands(present.copy())
        ok_exact, worst_exact = exact.stands(present.copy())
        assert ok == ok_exact
        if checker.solves == solves and not checker._supported(present):
            shortcuts += 1
            assert worst_exact - 1e-9 <= worst <= limits.FRAGILE
        else:
            assert worst == pytest.approx(worst_exact, rel=1e-6, abs=1e-9)
    monkey.undo()
    assert shortcuts == 7          # the five tower bricks and the two on the first stair


def test_build_checker_knows_a_supported_prefix_from_any_earlier_question():
    """The checker keeps 'every present cell rests on a present cell' up to date brick by
    brick; asked in any order (prefixes, trials taken back, random sets), its answer is the
    direct count over all brick pairs."""
    from core import catalog
    from core.layout import greedy as layout_stage
    rng = np.random.default_rng(3)
    # columns of random heights: every cell rests on a cell, so built bottom up every
    # prefix is supported
    filled = np.arange(9)[None, None, :] < rng.integers(1, 10, (6, 5))[:, :, None]
    lay = layout_stage.lay_out(Grid(np.zeros(3), np.array([8.0, 8.0, 3.2]), filled),
                               catalog.CATALOG, seed=0)
    checker = forces.BuildChecker(lay)
    lab = lay.labels()
    below, above = lab[:, :, :-1].ravel(), lab[:, :, 1:].ravel()
    n = len(lay.bricks)
    upward = np.argsort([b.cell[2] for b in lay.bricks], kind="stable")
    sets = [np.isin(np.arange(n), upward[:m]) for m in range(n + 1)]       # built bottom up
    sets += [rng.random(n) < rng.random() for _ in range(200)]
    answers = []
    for present in sets:
        on = (above >= 0) & present[np.maximum(above, 0)]
        direct = not np.any(on & ((below < 0) | ~present[np.maximum(below, 0)]))
        assert checker._supported(present) == direct
        answers.append(direct)
    assert all(answers[:n + 1]) and not all(answers)


def slab_over_box(outer=(22, 22, 24), wall=2, rim=4) -> Layout:
    """A hollow box standing on the table under a slab of six plate layers reaching
    ``rim`` studs out all round: the slab hangs, the walls stand in pure compression."""
    from core import catalog
    from core.layout import greedy as layout_stage
    filled = np.zeros(outer, dtype=bool)
    filled[rim:-rim, rim:-rim, :-6] = True
    filled[rim + wall:-rim - wall, rim + wall:-rim - wall, :-6] = False
    filled[:, :, -6:] = True
    return layout_stage.lay_out(Grid(np.zeros(3), CELL.copy(), filled), catalog.CATALOG, seed=0)


def test_a_big_build_is_checked_by_its_hanging_parts_as_the_whole_program_says(monkeypatch):
    """Past EXACT_BODIES the verdict comes from the hanging parts on supports that only
    press: it must agree with the whole program, and its worst utilisation is an upper
    bound of the whole program's (here the slab's own bending decides both)."""
    lay = slab_over_box()
    whole = forces.analyse(lay)
    assert whole.sub_structures == 0 and whole.stable and 0.01 < whole.max_utilisation < 1
    monkeypatch.setattr(limits, "EXACT_BODIES", 0)
    # most of this small build hangs: the whole program, unless told otherwise
    assert forces.analyse(lay, detail=False).sub_structures == 0
    monkeypatch.setattr(limits, "PART_SHARE", 1.0)
    parted = forces.analyse(lay)
    assert parted.sub_structures == 1
    assert parted.stable == whole.stable
    assert whole.max_utilisation - 1e-6 <= parted.max_utilisation <= whole.max_utilisation * 1.01
    doc = parted.to_json()
    assert doc["method"] == verdict.SUB_MEANS and doc["checked"] is True
    # the walls under the slab stand in pure compression: nothing pulls on them
    slab_from = lay.grid.shape[2] - 6
    walls = [b.id for b in lay.bricks if b.cell[2] + b.size[2] <= slab_from - 3 * limits.MARGIN_LEVELS]
    assert walls and all(parted.utilisation[b] == 0.0 for b in walls)
    assert set(parted.utilisation) == {b.id for b in lay.bricks}
    # a build the whole program can solve is not cut in plan; past MAX_BODIES it is, and
    # the pieces of the slab that would tip off the walls are merged with a neighbour
    monkeypatch.setattr(limits, "WINDOW_BODIES", 25)
    assert forces.analyse(lay, detail=False).sub_structures == 1
    monkeypatch.setattr(limits, "MAX_BODIES", 10)
    merged = forces.analyse(lay, detail=False)
    assert merged.stable and merged.sub_structures >= 1
    assert merged.max_utilisation >= whole.max_utilisation - 1e-6


def test_a_big_build_standing_easily_gives_each_brick_its_worst_without_phase_two(monkeypatch):
    """Past EXACT_BODIES, a whole build standing below DETAIL_ABOVE gives each brick the
    worst utilisation (an upper bound of its own) without the second program: the same
    verdict and worst as with it, one program solved instead of two."""
    lay = slab_over_box()
    exact = forces.analyse(lay)
    assert exact.stable and exact.sub_structures == 0 and exact.max_utilisation < limits.DETAIL_ABOVE
    solved = count_programs(monkeypatch)
    monkeypatch.setattr(limits, "EXACT_BODIES", 0)
    quick = forces.analyse(lay)
    assert len(solved) == 1 and quick.sub_structures == 0
    assert quick.stable and quick.max_utilisation == pytest.approx(exact.max_utilisation, rel=1e-6)
    assert set(quick.utilisation) == set(exact.utilisation)
    assert all(quick.utilisation[b] >= u - 1e-6 for b, u in exact.utilisation.items())
    assert set(quick.utilisation.values()) == {quick.max_utilisation}


def test_a_program_past_its_work_leaves_the_build_unchecked_saying_so(monkeypatch):
    """No force program runs for minutes: past PROGRAM_WORK the whole build is reported
    unchecked (the graph's verdict stands alone), and so is a build checked in parts."""
    lay = slab_over_box()
    monkeypatch.setattr(limits, "PROGRAM_WORK", 1)
    whole = forces.analyse(lay)
    assert whole.unchecked and "ran past the 1 solver iterations it is given" in whole.unchecked
    assert whole.to_json()["checked"] is False and whole.to_json()["stable"] is None
    monkeypatch.setattr(limits, "EXACT_BODIES", 0)
    monkeypatch.setattr(limits, "PART_SHARE", 1.0)
    parted = forces.analyse(lay, detail=False)
    assert parted.unchecked and "ran past" in parted.unchecked


def test_the_whole_programs_limit_is_its_work_not_the_clock(monkeypatch):
    """The whole program is given solver iterations (the interior point's weighed by the
    program's size), not seconds: with a clock that runs an hour per reading it gets the
    same verdict; given exactly the work it needs it stands as before, given one
    interior-point iteration less it is unchecked.  The work is HiGHS's own count."""
    import time as clock
    lay = slab_over_box()
    calm = forces.analyse(lay, detail=False)
    assert calm.stable and calm.unchecked is None and calm.work > 0
    hours = iter(range(10 ** 9))
    monkeypatch.setattr(clock, "perf_counter", lambda: 3600.0 * next(hours))
    busy = forces.analyse(lay, detail=False)
    assert busy.seconds >= 3600 and busy.unchecked is None
    assert (busy.stable, busy.max_utilisation, busy.work) == (calm.stable, calm.max_utilisation, calm.work)
    monkeypatch.setattr(limits, "PROGRAM_WORK", calm.work)
    assert forces.analyse(lay, detail=False).max_utilisation == calm.max_utilisation
    prog, _ = _Model(lay, "table", [], (), None, forces.CLUTCH_N, None)._program(detail=False)
    step = solver.ipm_iteration_work(prog.matrix().nnz)
    assert calm.work % step == 0                 # interior-point iterations alone, no simplex
    monkeypatch.setattr(limits, "PROGRAM_WORK", calm.work - step)
    short = forces.analyse(lay, detail=False)
    assert short.unchecked and f"ran past the {calm.work - step:,} solver iterations" in short.unchecked


@pytest.mark.slow
def test_a_hollow_cubes_roof_is_checked_in_pieces_that_rest_on_walls_and_pillars(monkeypatch):
    """A 21 cm hollow cube's roof (on its walls and the hollow stage's pillars) cut in plan
    into groups: each stands on what is under it, so the cube stands, with a worst
    utilisation at least the whole program's."""
    from core import catalog, hollow
    from core.layout import greedy as layout_stage
    solid = Grid(np.zeros(3), CELL.copy(), np.ones((26, 26, 40), dtype=bool))
    lay = layout_stage.lay_out(hollow.hollow(solid, 2)[0], catalog.CATALOG, seed=0)
    monkeypatch.setattr(limits, "EXACT_BODIES", limits.MAX_BODIES)
    whole = forces.analyse(lay, detail=False)
    assert whole.stable and whole.sub_structures == 0
    monkeypatch.setattr(limits, "EXACT_BODIES", 0)
    monkeypatch.setattr(limits, "PART_SHARE", 1.0)
    monkeypatch.setattr(limits, "MAX_BODIES", 10)
    monkeypatch.setattr(limits, "WINDOW_BODIES", 30)
    cut = forces.analyse(lay)
    assert cut.stable and cut.sub_structures > 1
    assert whole.max_utilisation - 1e-6 <= cut.max_utilisation < 1
    assert max(cut.utilisation.values()) == pytest.approx(cut.max_utilisation)


def test_a_hanging_part_that_does_not_stand_on_its_supports_gets_the_whole_program(monkeypatch):
    """A plate hanging by one stud off a 1x1 brick needs that stud's pull: on a support that
    only presses it cannot stand, so the verdict is the whole program's (the hand figure
    of the cantilever test); past MAX_BODIES it is reported unchecked, saying where."""
    monkeypatch.setattr(limits, "EXACT_BODIES", 0)
    monkeypatch.setattr(limits, "PART_SHARE", 1.0)
    tip = "40,0,12.8,48,8,16:20"
    result = forces.analyse(cantilever(6), ground="baseplate", loads=[tip])
    assert result.sub_structures == 0 and not result.stable and 2 in result.failing_bricks
    monkeypatch.setattr(limits, "EXACT_BODIES", 500)
    exact = forces.analyse(cantilever(6), ground="baseplate", loads=[tip])
    assert result.utilisation == exact.utilisation
    assert result.failing_bricks == exact.failing_bricks
    monkeypatch.setattr(limits, "EXACT_BODIES", 0)
    assert forces.build_unchecked(result) is None
    monkeypatch.setattr(limits, "MAX_BODIES", 1)
    unchecked = forces.analyse(cantilever(6), ground="baseplate", loads=[tip])
    assert unchecked.unchecked and "hanging part of 1 brick from layer 4 (cell 0, 0)" in unchecked.unchecked
    assert forces.build_unchecked(unchecked) and forces.build_unchecked(result) is None


def test_a_ledge_on_a_thin_wall_is_checked_with_the_wall_under_it(monkeypatch):
    """A ledge four studs wide on top of a wall two studs thick: on supports that only
    press, the ledge and the wall's top levels tip over the wall's inner edge; taking more
    of the wall in (its own studs pull) it stands, no better than the whole program says.
    Past MAX_BODIES, without that, only height bands give a verdict."""
    from core import catalog
    from core.layout import greedy as layout_stage
    filled = np.zeros((16, 6, 42), dtype=bool)
    filled[:, :2, :39] = True
    filled[:, :, 39:] = True
    lay = layout_stage.lay_out(Grid(np.zeros(3), CELL.copy(), filled), catalog.CATALOG, seed=0)
    whole = forces.analyse(lay, detail=False)
    assert whole.sub_structures == 0 and whole.stable
    monkeypatch.setattr(limits, "EXACT_BODIES", 0)
    monkeypatch.setattr(limits, "PART_SHARE", 1.0)
    monkeypatch.setattr(limits, "MAX_BODIES", 1)
    parted = forces.analyse(lay, detail=False)
    assert parted.unchecked is None and parted.sub_structures >= 1 and parted.stable
    assert parted.max_utilisation >= whole.max_utilisation - 1e-6
    monkeypatch.setattr(limits, "DEEPER_LEVELS", ())
    banded = forces.analyse(lay, detail=False)
    assert banded.bands and banded.stable and banded.max_utilisation >= whole.max_utilisation - 1e-6
    monkeypatch.setattr(limits, "MAX_BANDED", 1)
    assert forces.analyse(lay, detail=False).unchecked


@pytest.mark.slow
@pytest.mark.parametrize("margin", [limits.MARGIN_LEVELS, limits.BUILD_MARGIN_LEVELS])
def test_build_prefixes_checked_on_the_hanging_part_agree_with_the_whole_program(monkeypatch, margin):
    """Past EXACT_BODIES each partial build is solved on the layout's hanging part (with
    ``margin`` levels under it) while every present brick outside it rests on present
    cells: step by step the same verdicts as the whole program, and a worst utilisation
    no lower."""
    from core.instructions import build_order
    lay = slab_over_box()
    order = build_order.plan(lay)
    monkeypatch.setattr(limits, "EXACT_BODIES", limits.MAX_BODIES)
    whole = build_order.standing(lay, order, forces.BuildChecker(lay).stands)
    monkeypatch.setattr(limits, "EXACT_BODIES", 0)
    monkeypatch.setattr(limits, "PART_SHARE", 1.0)
    monkeypatch.setattr(limits, "BUILD_MARGIN_LEVELS", margin)
    checker = forces.BuildChecker(lay)
    part = build_order.standing(lay, order, checker.stands)
    assert checker._sub is not None and checker._part is not None
    assert [s.bricks for s in part.steps] == [s.bricks for s in whole.steps]
    assert part.unstable == whole.unstable
    got, want = np.array(part.utilisation), np.array(whole.utilisation)
    assert np.all(got >= want - 1e-6) and np.any(want > 0.01)
    # the count of present bricks outside the hanging part with a gap under them
    lab = lay.labels()
    below, above = lab[:, :, :-1].ravel(), lab[:, :, 1:].ravel()
    rng = np.random.default_rng(5)
    for present in [rng.random(len(lay.bricks)) < rng.random() for _ in range(30)]:
        checker._supported(present)
        on = (above >= 0) & present[np.maximum(above, 0)] & checker._outside[np.maximum(above, 0)]
        gaps = on & (below >= 0) & (below != above) & ~present[np.maximum(below, 0)]
        pairs = {(int(a), int(b)) for a, b in zip(below[gaps], above[gaps])}
        assert checker._missing_outside == len(pairs)


def test_steps_past_the_work_budget_are_checked_by_the_graph_and_the_report_says_why():
    """Once the partial builds' programs have done the checker's budget of work, later steps that
    need one are NaN (checked by the brick graph); the steps before keep the programs'
    answers, the steps in pure compression stay 0, and the report gives the budget reason."""
    import dataclasses
    from core import report as reporting
    from core.instructions import build_order
    lay = slab_over_box()
    order = build_order.plan(lay)
    full_checker = forces.BuildChecker(lay)
    full = build_order.standing(lay, order, full_checker.stands)
    assert full_checker.why is None and full_checker.solves > 1
    checker = forces.BuildChecker(lay, budget=0)
    cut = build_order.standing(lay, order, checker.stands)
    assert checker.solves == 1 and checker.why and "more than the 0 they are given" in checker.why
    f, c = np.array(full.utilisation), np.array(cut.utilisation)
    assert [s.bricks for s in cut.steps] == [s.bricks for s in full.steps]
    first = int(np.flatnonzero(f > 0)[0])
    assert c[first] == pytest.approx(f[first]) and np.all(c[:first] == 0)
    assert np.all(np.isnan(c[f > 0][1:])) and np.all(c[f == 0] == 0)
    doc = reporting.build_stability(dataclasses.replace(cut, graph_only_why=checker.why), len(lay.bricks))
    assert doc["graph_only_why"] == checker.why and doc["first_graph_only_step"] > first + 1


def test_the_work_budget_counts_solver_iterations_so_a_slow_machine_gets_the_same_steps(monkeypatch):
    """The budget of the partial builds' programs is solver iterations, not seconds: with a
    clock that runs an hour per reading (a very busy machine) the same steps are checked by
    programs and the same ones by the graph as on this one.  The work is HiGHS's own count
    of its iterations: the first (cold) program's interior-point and crossover iterations."""
    import time as clock
    from core.instructions import build_order
    lay = slab_over_box()
    order = build_order.plan(lay)
    first = forces.BuildChecker(lay)
    first_steps = build_order.standing(lay, order, first.stands)
    assert first.why is None and first.work > 0
    budget = first.work * 2 // 3
    calm = forces.BuildChecker(lay, budget=budget)
    calm_steps = build_order.standing(lay, order, calm.stands)
    hours = iter(range(10 ** 9))
    monkeypatch.setattr(clock, "perf_counter", lambda: 3600.0 * next(hours))
    busy = forces.BuildChecker(lay, budget=budget)
    busy_steps = build_order.standing(lay, order, busy.stands)
    assert busy.solves == calm.solves > 10 and busy.seconds > 3600 * 10 and calm.seconds < 3600
    c, b = np.array(calm_steps.utilisation), np.array(busy_steps.utilisation)
    assert np.isnan(c).any() and not np.isnan(np.array(first_steps.utilisation)).any()
    np.testing.assert_array_equal(np.isnan(c), np.isnan(b))
    np.testing.assert_allclose(c[~np.isnan(c)], b[~np.isnan(b)])
    assert calm.why == busy.why and f"more than the {budget:,} they are given" in calm.why


def test_past_max_bodies_steps_stand_in_compression_or_are_checked_by_the_graph(monkeypatch):
    """Past MAX_BODIES no program is solved for a build step: a step whose every brick rests
    on bricks or the ground gets 0, as the programs give it; a step that would need one is
    NaN (joined to the ground: the graph's verdict), and the report counts those steps."""
    from core import report as reporting
    from core.instructions import build_order
    lay = slab_over_box()
    order = build_order.plan(lay)
    full = build_order.standing(lay, order, forces.BuildChecker(lay).stands)
    monkeypatch.setattr(limits, "MAX_BODIES", 10)
    checker = forces.BuildChecker(lay)
    graph = build_order.standing(lay, order, checker.stands)
    assert checker.solves == 0 and not graph.unstable and not full.unstable
    assert [s.bricks for s in graph.steps] == [s.bricks for s in full.steps]
    g, f = np.array(graph.utilisation), np.array(full.utilisation)
    assert np.all((g == 0) | np.isnan(g)) and np.any(g == 0) and np.any(np.isnan(g))
    assert np.all(f[g == 0] == 0) and np.all(np.isnan(g[f > 0]))
    doc = reporting.build_stability(graph, len(lay.bricks))
    first = int(np.flatnonzero(np.isnan(g))[0]) + 1
    assert doc["graph_only_steps"] == int(np.isnan(g).sum()) and doc["first_graph_only_step"] == first
    assert doc["worst_step_utilisation"] == 0 and doc["stands_every_step"]
    assert "brick graph only" in doc["graph_only_why"]
    assert "graph_only_steps" not in reporting.build_stability(full, len(lay.bricks))
    # the builder reads it once, at the first step of each run of such steps
    from core.instructions import page as instructions
    notes = {n for n, text in instructions.step_warnings(graph, lay).items() if "Not force-checked" in text}
    runs = {n + 1 for n in range(len(g)) if np.isnan(g[n]) and (n == 0 or not np.isnan(g[n - 1]))}
    assert notes == runs and first in notes


def test_joined_to_the_ground_step_by_step_agrees_with_the_whole_graph():
    """The step-by-step search from the last set found joined to the ground gives the same
    answer as the components of the whole graph, on sets growing in random orders (most
    of them with a floating brick) and on sets that shrink."""
    lay = slab_over_box(outer=(14, 14, 12), rim=2)
    checker = forces.BuildChecker(lay)
    rng = np.random.default_rng(3)
    n, answers = len(lay.bricks), []
    for _ in range(4):
        present = np.zeros(n, dtype=bool)
        for b in np.array_split(rng.permutation(n), 12):
            present[b] = True
            want = checker._held_all(present)
            answers.append(want)
            assert checker._held(present) == want
    for _ in range(10):
        present = rng.random(n) < rng.random()
        assert checker._held(present) == checker._held_all(present)
    assert any(answers) and not all(answers)


def test_a_hanging_part_beyond_what_is_checked_in_parts_is_reported_at_once(monkeypatch):
    monkeypatch.setattr(limits, "EXACT_BODIES", 0)
    monkeypatch.setattr(limits, "MAX_BODIES", 1)
    monkeypatch.setattr(limits, "MAX_HANGING", 1)
    monkeypatch.setattr(limits, "MAX_BANDED", 1)
    result = forces.analyse(slab_over_box(), detail=False)
    assert result.unchecked and "hanging part has" in result.unchecked and "more than the 1 " in result.unchecked


def test_a_hanging_piece_no_cut_splits_is_not_solved_whole_past_max_bodies(monkeypatch):
    """A slab on one central pillar: cut in two across either side, each half's weight falls
    outside the pillar, so the slab stays one piece.  Past MERGED_BODIES that piece is not
    solved as one program (a bunny scaled x3 hangs almost whole: 360 s for one program):
    past what height bands take too, it is reported unchecked at once, saying where and
    why."""
    from core import catalog
    from core.layout import greedy as layout_stage
    filled = np.zeros((20, 20, 18), dtype=bool)
    filled[9:11, 9:11, :] = True
    filled[:, :, -6:] = True
    lay = layout_stage.lay_out(Grid(np.zeros(3), CELL.copy(), filled), catalog.CATALOG, seed=0)
    monkeypatch.setattr(limits, "EXACT_BODIES", 0)
    monkeypatch.setattr(limits, "MAX_BODIES", 10)
    monkeypatch.setattr(limits, "WINDOW_BODIES", 5)
    monkeypatch.setattr(limits, "MERGED_BODIES", 10)
    monkeypatch.setattr(limits, "MAX_BANDED", 10)

    def no_program(self, *args, **kwargs):
        raise AssertionError("a program was solved")

    monkeypatch.setattr(Program, "solve", no_program)
    result = forces.analyse(lay, detail=False)
    assert result.unchecked and result.stable is False
    assert "no cut in plan splits" in result.unchecked and "more than the 10 solved" in result.unchecked
    assert "from layer" in result.unchecked


def test_verdict_words_say_at_most_for_hanging_parts_and_infinite_for_a_float():
    """The one sentence the CLI and FreeCAD both show: an upper bound says 'at most' and how
    many hanging parts found it; no figure says why."""
    doc = {"stable": True, "ground": "table", "mass_g": 54985.2, "max_utilisation": 0.1712,
           "sub_structures": 18}
    assert forces.verdict_words(doc) == ("stands on a table with 54985 g: worst joint "
                                         "utilisation at most 0.17 (checked by its 18 hanging "
                                         "part(s))")
    whole = dict(doc, sub_structures=0, stable=False, max_utilisation=1.2345)
    assert forces.worst_words(whole, 3) == "1.234"
    assert forces.verdict_words(whole).startswith("does not stand on a table")
    assert forces.worst_words(dict(doc, max_utilisation=None)).startswith("infinite")


def test_a_build_past_max_bodies_is_checked_in_height_bands_as_the_hand_calculation(monkeypatch):
    """Past MAX_BODIES, when its hanging parts do not settle it, a build is solved in height
    bands, top down, each on the bricks under it with the forces of the bands above fixed.
    On the staircase (one way to hold each brick) that is exactly the whole program: 12 and
    19 levels stand with the same worst, 20 fall, and then bands prove nothing: unchecked."""
    monkeypatch.setattr(limits, "MAX_HANGING", 0)          # its hanging parts are not tried
    monkeypatch.setattr(limits, "EXACT_BODIES", 0)
    monkeypatch.setattr(limits, "BAND_BODIES", 3)
    for levels in (12, 19):
        whole = forces.analyse(staircase(levels), ground="baseplate", detail=False)
        monkeypatch.setattr(limits, "MAX_BODIES", 2)
        banded = forces.analyse(staircase(levels), ground="baseplate")
        monkeypatch.setattr(limits, "MAX_BODIES", 2500)
        assert banded.stable and banded.bands >= levels // 3 and banded.sub_structures == 0
        assert banded.max_utilisation == pytest.approx(whole.max_utilisation, rel=1e-6)
        assert set(banded.utilisation) == {b.id for b in staircase(levels).bricks}
        assert max(banded.utilisation.values()) == pytest.approx(banded.max_utilisation)
        doc = banded.to_json()
        assert doc["method"] == verdict.BAND_MEANS and doc["bands"] == banded.bands
        assert "height bands" in forces.worst_words(doc)
    monkeypatch.setattr(limits, "MAX_BODIES", 2)
    twenty = forces.analyse(staircase(20), ground="baseplate")
    assert twenty.unchecked and "height bands" in twenty.unchecked
    assert "does not stand on the bricks under it" in twenty.unchecked


def test_height_bands_bound_the_whole_programs_worst_from_above(monkeypatch):
    """A slab over a hollow box on a table, in bands of about 20 bricks: it stands, and the
    worst the bands' forces reach is at least the whole program's least; past half the
    work they did, the build is unchecked."""
    lay = slab_over_box()
    whole = forces.analyse(lay, detail=False)
    assert whole.stable
    monkeypatch.setattr(limits, "MAX_HANGING", 0)
    monkeypatch.setattr(limits, "EXACT_BODIES", 0)
    monkeypatch.setattr(limits, "MAX_BODIES", 10)
    monkeypatch.setattr(limits, "BAND_BODIES", 20)
    banded = forces.analyse(lay)
    assert banded.stable and banded.bands > 2
    assert whole.max_utilisation - 1e-6 <= banded.max_utilisation < 1
    assert set(banded.utilisation) == {b.id for b in lay.bricks}
    monkeypatch.setattr(limits, "PROGRAM_WORK", banded.work // 2)
    late = forces.analyse(lay, detail=False)
    assert late.unchecked and "its bands' programs ran past the" in late.unchecked
