"""Printing: how long the printed parts take, sliced by PrusaSlicer, and the files a printer gets.

:mod:`~core.printing.slicer_profile` resolves the printer, print and filament presets
from PrusaSlicer's installed vendor bundle; :mod:`~core.printing.printers` chooses the
maker's printer (any installed vendor's, or a config PrusaSlicer saved) and checks parts
against its bed; :mod:`~core.printing.print_time` finds each
part's fastest pose and slices plates for the real time (with a calibrated estimate
where no slicer runs); :mod:`~core.printing.slice_cache` keeps PrusaSlicer's answers by
content so an unchanged plate is never sliced twice; :mod:`~core.printing.export` writes
each part's STL and STEP and the 3MF plates that were timed.
"""
