"""The brick layout: the cells of the grid covered by catalog plates and bricks, as few as
the effort allows, joined into one piece.

:mod:`~core.layout.greedy` merges cells into bricks layer by layer, staggering seams so that
the build holds together: :mod:`~core.layout.brick_cells` chooses where bricks (three plate
layers) may go, :mod:`~core.layout.merge_kernels` (numba) places the parts by a score, and
:mod:`~core.layout.repair` holds the layout under construction and re-merges it around seams
and weak bricks.  :mod:`~core.layout.search` improves that layout by a large neighbourhood
search and measures it against the lower bounds (``layout_quality``): the search's state,
sites and windows are :mod:`~core.layout.neighbourhood`'s, each window is solved exactly with
HiGHS by :mod:`~core.layout.window_program`, and :mod:`~core.layout.quality` is the key a
layout is judged on (its brick graph, weak points, thin weak points).
:mod:`~core.layout.bounds` gives the exact fewest-parts cover (a lower bound to measure the
layout against), :mod:`~core.layout.connected_bound` the fewest bricks of layouts in one
piece; :mod:`~core.layout.reinforce` re-merges the layout around joints the force check finds
failing.  Every layout covers each filled cell exactly once.
"""
