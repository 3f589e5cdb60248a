"""The force stage against every real build of StableLego (Liu et al. 2024, arXiv 2402.10711;
github intelligent-control-lab/StableLego, MIT licence): the structures of its ``test_lego/``
folder, built on a baseplate and photographed standing or collapsing in its README.

Each structure is transcribed from its JSON: ``x, y`` the brick's corner in studs, ``z`` its
level from the baseplate, the footprint from ``lego_library.json`` and ``ori`` (1: long in x).
The bricks weigh their catalog weight; StableLego's library gives the 1-wide bricks the same
masses and its 2x4 0.16 g less.  Its 200 g weight (library id 1) stands on 2x2 studs: here a
2x2 brick carrying the rest of the 200 g as its ``load_g``.

Left out: ``stick_heavy_good_test_horizontal_force``, a test of the side push between two
bricks of one layer, which this model leaves out, with no photograph of its real build.
"""

from __future__ import annotations

import numpy as np
import pytest

from core import forces
from core.catalog import MASS_G
from core.forces import joints
from core.model import Brick, Grid, Layout

#: LEGO bricks by footprint (x, y studs).
PART = {(1, 2): "3004", (2, 1): "3004", (4, 1): "3010", (6, 1): "3009", (8, 1): "3008",
        (4, 2): "3001", (2, 2): "3003"}

#: StableLego's stick: 1-wide bricks from one 1x8 on the baseplate out to 47 studs, two 1x4
#: stacked at its tip (id, footprint x, x, z).
STICK = [(1, 8, 0, 0), (2, 4, 6, 1), (13, 4, 8, 2), (3, 8, 10, 3), (4, 8, 16, 2), (5, 6, 22, 3),
         (6, 6, 26, 2), (7, 6, 30, 3), (8, 6, 34, 2), (9, 6, 38, 3), (10, 6, 42, 2),
         (11, 4, 44, 3), (12, 4, 44, 4)]
#: The third 1x4 at the tip that makes it heavy, and the 1x2 under brick 2 that saves it.
THIRD_LOAD = (14, 4, 44, 5)
PROP = (15, 2, 8, 0)


def layout_of(rows) -> Layout:
    """A layout of rows (id, footprint x, footprint y, x, y, z levels, total mass g or None)."""
    bricks = []
    for bid, nx, ny, x, y, z, mass in rows:
        part = PART[(nx, ny)]
        extra = 0.0 if mass is None else mass - MASS_G[part]
        bricks.append(Brick(bid, part, (nx, ny, 3), (x, y, 3 * z), load_g=extra))
    top = np.max([np.add(b.cell, b.size) for b in bricks], axis=0)
    filled = np.zeros(tuple(int(v) for v in top), dtype=bool)
    for b in bricks:
        assert not filled[b.slices()].any(), "bricks overlap"
        filled[b.slices()] = True
    return Layout(Grid(np.zeros(3), np.array([8.0, 8.0, 3.2]), filled), bricks)


def stair(levels: int) -> list:
    """``stair_19``, ``stair_20``: 2x4 bricks, each two studs further along."""
    return [(n + 1, 4, 2, 2 * n, 0, n, None) for n in range(levels)]


def stick(*extra) -> list:
    return [(bid, nx, 1, x, 0, z, None) for bid, nx, x, z in STICK + list(extra)]


def weight(top: list) -> list:
    """``external_weight_*``: 2x4 bricks stepping out, the 200 g weight on the last."""
    return [(n + 1, 4, 2, x, 0, z, None) for n, (x, z) in enumerate(top)]


STRUCTURES = {
    # name: (rows, stands in the real build, the brick whose joint lets go in the photograph)
    "stair_19": (stair(19), True, None),
    "stair_20": (stair(20), False, 2),
    "stair_20_good": (stair(20) + [(21, 1, 2, 4, 0, 0, None)], True, None),
    "stick_light": (stick(), True, None),
    "stick_heavy": (stick(THIRD_LOAD), False, 2),
    "stick_heavy_good": (stick(THIRD_LOAD, PROP), True, None),
    "external_weight_good": (weight([(0, 0), (2, 1), (4, 2)]) + [(4, 2, 2, 5, 0, 3, 200.0)],
                             True, None),
    "external_weight_fail": (weight([(0, 0), (2, 1), (4, 2)]) + [(5, 4, 2, 6, 0, 3, None),
                                                                (4, 2, 2, 7, 0, 4, 200.0)],
                             False, 2),
}


@pytest.mark.parametrize("name", sorted(STRUCTURES))
def test_every_stablelego_build_gets_its_real_verdict(name):
    """Stands where the real build stands; where it collapses, the first failing joint is the
    one that let go in the photograph (the second brick lifting off the first)."""
    rows, stands, breaks_at = STRUCTURES[name]
    result = forces.analyse(layout_of(rows), ground="baseplate")
    assert result.stable == stands, (name, result.max_utilisation, result.failing_bricks)
    if not stands:
        assert result.failing_bricks == [breaks_at]
        assert result.failures[0]["mode"] == "clutch"


def test_the_contact_radius_lies_inside_what_both_real_builds_allow():
    """The contact radius is the model's one fitted constant.  By hand, for the joints that
    decide: the staircase's second brick (3 points per stud, 2 studs by 2) holds
    2 T (3 + (1 + 5 sqrt(1/2)) r) studs against 19 bricks' overhang, so 20 levels fall for
    r < 0.2305; the stick's brick 13 on brick 2 (4 points per stud, 2 studs) holds
    T (4 + 8 r) against the arm beyond it, which stands with three 1x4 at the tip only for
    r > 0.2025.  The radius keeps a margin from both ends."""
    lo, hi = 0.2025, 0.2305
    assert lo + 0.25 * (hi - lo) <= joints.CONTACT_RADIUS <= hi - 0.25 * (hi - lo)
    for r, twenty_falls, stick_stands in ((lo - 0.002, True, False), (hi + 0.002, False, True)):
        with pytest.MonkeyPatch.context() as mp:
            mp.setattr(joints, "CONTACT_RADIUS", r)
            assert (not forces.analyse(layout_of(stair(20)), ground="baseplate").stable) == twenty_falls
            good = forces.analyse(layout_of(stick(THIRD_LOAD, PROP)), ground="baseplate")
            assert good.stable == stick_stands
