"""What a person builds from: the build order, the instructions page, the LDraw model, the
bill of materials and the pictures.

:mod:`~core.instructions.build_order` numbers the assembly steps bottom up, each partial
build checked to stand (props where it would not); :mod:`~core.instructions.page` writes
the self-contained ``instructions.html``, its bricks painted back to front in the order of
:mod:`~core.instructions.drawing_order`; :mod:`~core.instructions.ldraw` the
``assembly.mpd`` that LeoCAD and Studio open; :mod:`~core.instructions.bom` ``bom.csv``
and the BrickLink wanted list; :mod:`~core.instructions.render` and
:mod:`~core.instructions.picture` the isometric pictures; :mod:`~core.instructions.changes_page`
the page of what changed in an iteration.
"""
