"""The brick layout: the cells of the grid covered by catalog plates and bricks, as few as
the effort allows, joined into one piece.

:mod:`~core.layout.greedy` merges cells into bricks layer by layer, staggering seams so
that the build holds together; :mod:`~core.layout.search` improves that layout by a large
neighbourhood search whose windows are solved exactly with HiGHS;
:mod:`~core.layout.bounds` gives the exact fewest-parts cover (a lower bound to measure
the layout against); :mod:`~core.layout.reinforce` re-merges the layout around joints
the force check finds failing.  Every layout covers each filled cell exactly once.
"""
