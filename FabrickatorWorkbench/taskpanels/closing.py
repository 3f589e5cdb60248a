"""Closing a task panel so that none of its widgets' Python wrappers outlive the widgets.

FreeCAD's ``Gui.PySideUic.loadUi`` keeps a reference of its own to every form it
loads (measured on FreeCAD 1.0: the loaded form's reference count is one higher than
``QUiLoader.load``'s), and the form's wrapper holds a wrapper of each named widget in
it.  Qt deletes the form with its task box when the dialog closes, but those wrappers
stay, and PySide hands one out again for a new widget made at the same address: a new
panel's radio button then says "Internal C++ object already deleted", or comes as a
plain ``QWidget``.
"""

from __future__ import annotations

import FreeCADGui as Gui


def close_dialog(panel) -> None:
    """Close FreeCAD's task dialog that shows ``panel``; ``panel.form`` becomes None.

    The form is first taken out of its task box, which gives it to Python: Qt no longer
    deletes it with the task box, and Python deletes it (and its widgets) only once no
    reference to it is left, so no wrapper of a deleted widget remains.
    """
    panel.form.setParent(None)
    Gui.Control.closeDialog()
    panel.form = None
