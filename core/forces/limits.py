"""How big a build the force programs take whole, and how bigger ones are cut.

Each limit bounds a program's size or work; :mod:`core.forces.decompose` cuts a build
past them into its hanging parts or height bands.
"""

from __future__ import annotations

import math



#: Most bodies the force programs are solved for (beyond, a build that needs any pull and
#: that its hanging parts and height bands do not settle is reported unchecked): a
#: program's time grows faster than its build.
MAX_BODIES = 2500


#: A build of more bodies than this, some of them hanging, is checked by its hanging parts
#: (:meth:`_Model._by_parts`) before the whole program is solved.
EXACT_BODIES = 300


#: Up to MAX_BODIES, the hanging part is solved on its own only when it and its supports
#: are at most this share of the bodies (a build that hangs almost whole: the whole program).
PART_SHARE = 0.7


#: Most hanging bodies checked in parts.  A hanging piece that no cut splits is solved whole
#: only up to MERGED_BODIES: beyond, its one program takes many minutes.
MAX_HANGING = 20000


#: Work (:func:`solver_work`) one program of a whole build (or of a hanging part) may do
#: before the build is reported unchecked, and the height bands of one build in all
#: (:meth:`_Model._by_bands`).  Counted in iterations, not seconds, so that the verdict does
#: not depend on the machine's load; about two minutes on a 2-core machine.  The interior
#: point needs minutes on solid, overhanging builds of thousands of bricks.
PROGRAM_WORK = 120_000


#: Solver iterations the programs of one build's partial builds may run in all
#: (:class:`BuildChecker`); past them the steps that need one are checked by the brick graph
#: only (without a bound, the steps of a solid, overhanging build of thousands of bricks
#: would each solve a whole program).  Counted in iterations, not seconds, so that the
#: answer does not depend on the machine's load: about a minute of warm-started iterations
#: on a 2-core machine.
BUILD_BUDGET = 100_000


#: Levels of bricks under a hanging part that its program takes in (they may pull).
MARGIN_LEVELS = 2


#: Levels of bricks under the hanging part that the build steps' program of it takes in
#: (:class:`BuildChecker`; :data:`MARGIN_LEVELS` where that makes it too big a share): on
#: its supports, which only press, a slab being built on a wall two studs thick tips with
#: 2 levels, and each such step then needs the whole program.
BUILD_MARGIN_LEVELS = 4


#: Most bodies in one program of a hanging part (bigger ones are cut in plan)...
WINDOW_BODIES = 250


#: ...and of a group solved again with its neighbours when it does not stand alone...
MERGED_BODIES = 1200


#: Bodies in one height band of a build past MAX_BODIES that its hanging parts do not settle
#: (:meth:`_Model._by_bands`)...
BAND_BODIES = 400


#: ...up to this many bodies in all.
MAX_BANDED = 20000


#: ...while the bodies of all the groups solved stay within this many times the hanging ones
#: (cut too small, a roof's groups would be merged over and over).
EFFORT = 4


#: Levels of seated bodies a group that does not stand on its supports takes in, step by
#: step (:meth:`_Model._deepened`).
DEEPER_LEVELS = (4, 12, 32)


#: Below this worst utilisation a hanging part's bricks (and past EXACT_BODIES, a whole
#: build's) are each given its worst (an upper bound; their own utilisations would cost a
#: second program and stay in the dark range).
DETAIL_ABOVE = 0.25


#: Below this worst utilisation every brick of a build of any size is given the worst (an
#: upper bound): on the stress picture's scale, dark 0 to red 1, each is dark either way.
DARK_BELOW = 0.05


#: A build prefix the hanging part's program finds above this is checked by the whole program
#: (build steps above it are fragile: the instructions warn).
FRAGILE = 0.8


#: Phase 2 bounds every joint's utilisation by phase 1's worst times 1 + this: held exactly
#: there the program has almost no interior, and HiGHS's interior point slows down many
#: times.  The utilisations it reports are then cut at the worst.
CAP_SLACK = 1e-4


#: Largest load factor the verdict looks for: a structure that carries this many times its
#: weight needs no clutch at all (worst utilisation 0).
LOAD_FACTOR_CAP = 1e5


def worst_of(factor: float) -> float:
    """The worst utilisation of a largest load factor: its inverse; 0 for a structure that
    needs no clutch at all (the factor reached :data:`LOAD_FACTOR_CAP`), inf when it cannot
    carry even 1 / LOAD_FACTOR_CAP of its weight (it tips or floats)."""
    if factor >= LOAD_FACTOR_CAP * (1 - 1e-9):
        return 0.0
    return 1.0 / factor if factor > 1.0 / LOAD_FACTOR_CAP else math.inf
