"""Force stage: does the layout stand, with what it carries?

The graph test of :mod:`core.stability` says which bricks hold together; this stage says
whether they *hold*: a static equilibrium of rigid bodies (every LEGO brick, every printed
part) whose joints have the strength of real LEGO, solved as linear programs with HiGHS
(after StableLego, Liu et al. 2024, and Luo et al. 2015). Gravity acts at each body's centre
of mass (:data:`core.catalog.MASS_G`, :func:`joints.printed_mass_g`); a brick's ``load_g``
(layout.json) and :class:`Load` boxes (``--load``) add masses.

**Joints.** Where a cell of one body lies directly under a cell of another, the lower one's
stud is gripped at contact points (:func:`joints.contact_directions`,
:data:`joints.CONTACT_RADIUS` from its axis), each taking compression without limit and
tension (the clutch) up to ``clutch_n`` where both stud and socket are whole (a printed
part's incomplete one presses but does not hold); each stud also takes shear. Bodies side by
side do not push on each other (on the safe side). The bottom layer rests on a ``table``
(compression, friction :data:`joints.TABLE_FRICTION`) or a ``baseplate`` (its studs grip). A
LEGO brick is also a beam: its bending moment between studs stays within
:func:`joints.bending_capacity_nmm` (ABS).

**Program.** Forces that put every body in equilibrium and minimise the worst *utilisation*
``u``: tension / clutch, bending moment / strength. A second pass keeps that worst and
minimises the sum of every joint's (all studs between two bodies) own worst, so that each
joint carries only what it must. The layout stands when ``u <= 1``; a body that no
equilibrium holds (it floats, or tips whatever the joints do) is *unsupported*, ``u``
infinite.

**Big builds.** Past :data:`limits.EXACT_BODIES` bodies the parts that hang are solved
first, on supports that only press (:meth:`decompose.Decompositions._by_parts`); where one
does not stand, the whole program decides, up to :data:`limits.MAX_BODIES`; past it, height
bands top down (:meth:`decompose.Decompositions._by_bands`). Their forces balance every
body, so when all stand the build stands, with at most their worst (an upper bound); a band
that does not leaves it unchecked.

The modules, bottom up: :mod:`~core.forces.joints` (the joints' strength and the bodies'
masses), :mod:`~core.forces.solver` (HiGHS), :mod:`~core.forces.limits` (how big a program
may be), :mod:`~core.forces.bodies`, :mod:`~core.forces.program` and
:mod:`~core.forces.decompose` (the parts of one model), :mod:`~core.forces.analyse` (the
stage), :mod:`~core.forces.build_steps` (each build prefix) and :mod:`~core.forces.verdict`
(the answer and its words). This package exports the stage's public names; the limits are
read from :mod:`core.forces.limits` at each call.
"""

from core.forces.analyse import analyse
from core.forces.build_steps import BuildChecker
from core.forces.joints import (CLUTCH_N, FAIL_ABOVE, GROUNDS, G, bending_capacity_nmm,
                               printed_mass_g)
from core.forces.verdict import (FORCE_MEANS, Forces, build_unchecked, graph_only_why,
                                 verdict_words, worst_words)

__all__ = ["BuildChecker", "CLUTCH_N", "FAIL_ABOVE", "FORCE_MEANS", "Forces", "G", "GROUNDS",
           "analyse", "bending_capacity_nmm", "build_unchecked", "graph_only_why", "printed_mass_g",
           "verdict_words", "worst_words"]
