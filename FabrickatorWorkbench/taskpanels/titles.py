"""Task box titles that fit FreeCAD's default Combo View.

A task box is as wide as its title at least, so a long Fabrication label in
the title would widen the task view past the Combo View.  The title keeps a
fixed part and the label elided to what fits.
"""

from __future__ import annotations

from PySide import QtCore, QtGui

#: Widest title (pixels, bold) a task box in a 264 px Combo View shows whole, with its
#: icon and its fold button beside it.
TITLE_WIDTH = 150


def fitting_title(prefix: str, label: str, widget) -> str:
    """``prefix`` and ``label`` as a task box title no wider than :data:`TITLE_WIDTH` in
    ``widget``'s font made bold (task box titles are bold): the label elided with "…"."""
    font = QtGui.QFont(widget.font())
    font.setBold(True)
    metrics = QtGui.QFontMetrics(font)
    room = TITLE_WIDTH - metrics.horizontalAdvance(prefix)
    return prefix + metrics.elidedText(label, QtCore.Qt.ElideRight, max(room, 0))
