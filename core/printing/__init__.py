"""Printing: how long the printed parts take, sliced by PrusaSlicer, and the files a printer gets.

:mod:`~core.printing.slicer_profile` resolves the printer, print and filament presets
from PrusaSlicer's installed vendor bundle; :mod:`~core.printing.plate` reads the bed and
sets the parts apart on it as a 3MF with its settings; :mod:`~core.printing.estimate` is
the calibrated time estimate that stands in where no slicer runs (and the
:class:`~core.printing.estimate.PrintEstimate` every timing returns);
:mod:`~core.printing.poses` gives the poses a part may print in and the supports each needs;
:mod:`~core.printing.print_time` finds each part's fastest pose and slices plates for the
real time; :mod:`~core.printing.printers` chooses the maker's printer (any installed
vendor's, or a config PrusaSlicer saved) and checks parts against its bed;
:mod:`~core.printing.slice_cache` keeps PrusaSlicer's answers by content so an unchanged
plate is never sliced twice; :mod:`~core.printing.export` writes each part's STL and STEP
and the 3MF plates that were timed.
"""
