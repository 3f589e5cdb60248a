"""Force stage: does the layout stand, with what it carries?

The graph test of :mod:`core.stability` says which bricks hold together; this stage says
whether they *hold*: a static equilibrium of rigid bodies (every LEGO brick, every printed
part) whose joints have the strength of real LEGO, solved as linear programs with HiGHS
(after StableLego, Liu et al. 2024, and Luo et al. 2015). Gravity acts at each body's centre
of mass; a brick's ``load_g`` (layout.json) and :class:`Load` boxes (``--load``) add masses.

**Joints.** Where a cell of one body lies directly under a cell of another, the lower one's
stud is gripped at contact points (:func:`joints.contact_directions`), each taking
compression without limit and tension (the clutch) up to ``clutch_n`` where stud and socket
are whole; each stud also takes shear. Bodies side by side do not push on each other (on
the safe side). The bottom layer rests on a ``table`` (compression and friction) or a
``baseplate`` (its studs grip). A LEGO brick is also a beam: its bending moment between
studs stays within :func:`joints.bending_capacity_nmm` (ABS).

**Program.** Forces that put every body in equilibrium and minimise the worst *utilisation*
``u`` (tension / clutch, bending moment / strength), then, keeping it, the sum of every
joint's own worst. The layout stands when ``u <= 1``; a body that no equilibrium holds
(it floats, or tips whatever the joints do) is *unsupported*, ``u`` infinite.

**Big builds.** Past :data:`limits.EXACT_BODIES` bodies the hanging parts are solved first,
on supports that only press; where one does not stand, the whole program decides, up to
:data:`limits.MAX_BODIES`; past it, height bands top down (:mod:`decompose`). Their forces
balance every body, so when all stand the build stands, with at most their worst; a band
that does not leaves it unchecked.

Modules, bottom up: ``joints`` (strengths, masses), ``solver`` (HiGHS), ``limits`` (how
big a program may be; read at each call), ``bodies``, ``program``, ``decompose``,
``analyse`` (the stage), ``build_steps`` (each build prefix), ``verdict`` (the answer, in
words). This package exports the stage's public names.
"""

from core.forces.analyse import Analysis, analyse
from core.forces.build_steps import BuildChecker
from core.forces.joints import (CLUTCH_N, FAIL_ABOVE, GROUNDS, G, bending_capacity_nmm,
                               printed_mass_g)
from core.forces.verdict import (FORCE_MEANS, Forces, build_unchecked, graph_only_why,
                                 verdict_words, worst_words)

__all__ = ["Analysis", "BuildChecker", "CLUTCH_N", "FAIL_ABOVE", "FORCE_MEANS", "Forces", "G", "GROUNDS",
           "analyse", "bending_capacity_nmm", "build_unchecked", "graph_only_why", "printed_mass_g",
           "verdict_words", "worst_words"]
