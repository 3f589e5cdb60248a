"""Fabrickator's user preferences, kept in FreeCAD's parameter tree.

They live under ``User parameter:BaseApp/Preferences/Mod/Fabrickator`` and
are edited on the preferences page (:class:`PreferencePage`, the form
``resources/ui/preferences.ui``).  New Fabrications take their defaults
from here; each Fabrication then keeps its own values as properties.

The brick colours ("Palette": :data:`core.colours.PALETTES`, BOM colours
or random colours, see :mod:`core.colours`) say how bricks are drawn in the
3D view; the stud and socket fit and the seconds per brick default to the core's one
table of defaults, :data:`core.request.DEFAULTS` (the CLI's options, these
preferences and the Fabrication's properties all read it): an unset
preference follows that table, so a change of the table reaches every user
who has not chosen a value.
"""

from __future__ import annotations

import os

import FreeCAD as App

from core.colours import PALETTES
from core.parts.interfaces import Fit
from core.request import DEFAULTS as DEFAULTS_TABLE

#: Parameter group of the preferences.
PATH = "User parameter:BaseApp/Preferences/Mod/Fabrickator"

#: name -> (type, default).  Types follow FreeCAD's parameter kinds; a default of
#: None is the setting TABLE_FIELDS names in the core's one table of defaults
#: (:data:`core.request.DEFAULTS`).  Slicing on recompute is off by default here
#: (it takes seconds per recompute), unlike the command line's.
DEFAULTS = {
    "BrickSet": ("String", "all"),
    "StudFit": ("Float", None),
    "SocketFit": ("Float", None),
    "SlicerPath": ("String", ""),
    "SlicerProfile": ("String", ""),
    "Printer": ("String", ""),
    "SecondsPerBrick": ("Float", None),
    "SliceOnRecompute": ("Bool", False),
    "Palette": ("String", None),
}

#: Preferences whose default is a setting of :data:`core.request.DEFAULTS`.
TABLE_FIELDS = {"StudFit": "stud_fit", "SocketFit": "socket_fit",
                "SecondsPerBrick": "seconds_per_brick", "Palette": "palette"}

#: Widget (object name in preferences.ui) of each preference on the page.
WIDGETS = {"BrickSet": "brickSet", "StudFit": "studFit", "SocketFit": "socketFit",
           "SecondsPerBrick": "secondsPerBrick", "SlicerPath": "slicerPath",
           "SlicerProfile": "slicerProfile", "Printer": "printer", "SliceOnRecompute": "sliceOnRecompute",
           "Palette": "palette"}


def group():
    """The parameter group object."""
    return App.ParamGet(PATH)


def setting_default(field: str):
    """The default of setting ``field`` ("stud_fit", "seconds_per_brick", ...) in the core's
    one table of defaults, :data:`core.request.DEFAULTS`."""
    return DEFAULTS_TABLE[field]


def default(name: str):
    """The default of preference ``name``: DEFAULTS' value, or the table's for TABLE_FIELDS."""
    _, value = DEFAULTS[name]
    return setting_default(TABLE_FIELDS[name]) if name in TABLE_FIELDS else value


def is_set(name: str) -> bool:
    """Whether the user has stored a value for ``name`` (else :func:`default` applies)."""
    kind, _ = DEFAULTS[name]
    return name in getattr(group(), f"Get{kind}s")()


def get(name: str):
    """The value of preference ``name`` (its default when unset)."""
    kind, _ = DEFAULTS[name]
    if not is_set(name):
        return default(name)
    return getattr(group(), f"Get{kind}")(name)


def set(name: str, value) -> None:  # noqa: A001 - the natural name next to get()
    """Store ``value`` for preference ``name``."""
    kind, _ = DEFAULTS[name]
    getattr(group(), f"Set{kind}")(name, value)


def reset(name: str) -> None:
    """Forget the stored value of ``name``: :func:`get` gives its default again."""
    kind, _ = DEFAULTS[name]
    getattr(group(), f"Rem{kind}")(name)


def values() -> dict:
    """All preferences as a dict."""
    return {name: get(name) for name in DEFAULTS}


def palette() -> str:
    """The brick colours of the 3D view: a key of :data:`core.colours.PALETTES`
    (a stored value that is none of them counts as the default)."""
    value = get("Palette")
    return value if value in PALETTES else default("Palette")


def fit():
    """The :class:`core.parts.interfaces.Fit` of the preferences: their stud and socket fit,
    everything else Fit's defaults (not checked: :meth:`Fit.check` says what is wrong)."""
    return Fit(stud_fit=float(get("StudFit")), socket_fit=float(get("SocketFit")))


class PreferencePage:
    """The Fabrickator page of FreeCAD's preferences dialog (GUI only).

    FreeCAD calls :meth:`loadSettings` when the page opens and
    :meth:`saveSettings` on OK/Apply.  Each widget of WIDGETS shows
    :func:`get` (so an unset fit shows Fit's default) and is stored with
    :func:`set` only when it differs from what :func:`get` gave, so an unset
    preference keeps following its default.
    """

    def __init__(self, parent=None):
        import FreeCADGui as Gui

        path = os.path.join(os.path.dirname(os.path.abspath(__file__)), "resources", "ui",
                            "preferences.ui")
        self.form = Gui.PySideUic.loadUi(path)
        combo = self.widget("Palette")
        for key, text in PALETTES.items():
            combo.addItem(App.Qt.translate("Fabrickator", text), key)
        self.shown: dict = {}

    def widget(self, name: str):
        """The page's widget of preference ``name``."""
        from PySide import QtGui

        return self.form.findChild(QtGui.QWidget, WIDGETS[name])

    def loadSettings(self):
        _fill_printers(self.widget("Printer"), get("SlicerPath") or None)
        for name in WIDGETS:
            value = get(name)
            self.shown[name] = value
            _set_widget(self.widget(name), value)

    def saveSettings(self):
        for name in WIDGETS:
            value = _widget_value(self.widget(name), DEFAULTS[name][0])
            if value != self.shown.get(name):
                set(name, value)
                self.shown[name] = value


def _fill_printers(combo, slicer: str | None) -> None:
    """List in ``combo`` (editable) every printer of the vendor bundles installed with
    ``slicer``, after an empty entry (the default printer), each with its build volume as
    tooltip; typing part of a name offers the names that contain it."""
    from PySide import QtCore

    from core.printing import printers  # loads numpy and trimesh

    combo.clear()
    combo.addItem("")
    combo.setItemData(0, "Original Prusa i3 MK3S (the default)", QtCore.Qt.ToolTipRole)
    for vendor, entries in printers.listing(printers.bundle_folder(slicer)).items():
        for name, size in entries:
            combo.addItem(name)
            combo.setItemData(combo.count() - 1, f"{vendor}: {' x '.join(f'{round(v, 1):g}' for v in size)} mm",
                              QtCore.Qt.ToolTipRole)
    combo.lineEdit().setPlaceholderText("Original Prusa i3 MK3S (the default); type to search")
    completer = combo.completer()
    completer.setCaseSensitivity(QtCore.Qt.CaseInsensitive)
    completer.setFilterMode(QtCore.Qt.MatchContains)
    completer.setCompletionMode(completer.PopupCompletion)


def _set_widget(widget, value) -> None:
    """Show ``value`` in a QLineEdit, QDoubleSpinBox, QCheckBox, QComboBox (an editable one's
    text, else the item whose data is ``value``) or Gui::FileChooser."""
    from PySide import QtGui

    if isinstance(widget, QtGui.QComboBox) and widget.isEditable():
        widget.setEditText(str(value))
    elif isinstance(widget, QtGui.QComboBox):
        widget.setCurrentIndex(max(0, widget.findData(value)))
    elif isinstance(widget, QtGui.QCheckBox):
        widget.setChecked(bool(value))
    elif isinstance(widget, QtGui.QDoubleSpinBox):
        widget.setValue(float(value))
    elif isinstance(widget, QtGui.QLineEdit):
        widget.setText(str(value))
    else:
        widget.setProperty("fileName", str(value))


def _widget_value(widget, kind: str):
    """The value ``widget`` shows, as a preference of FreeCAD parameter kind ``kind``."""
    from PySide import QtGui

    if isinstance(widget, QtGui.QComboBox) and widget.isEditable():
        return widget.currentText().strip()
    if isinstance(widget, QtGui.QComboBox):
        return str(widget.currentData())
    if isinstance(widget, QtGui.QCheckBox):
        return bool(widget.isChecked())
    if isinstance(widget, QtGui.QDoubleSpinBox):
        return float(widget.value())
    if isinstance(widget, QtGui.QLineEdit):
        return widget.text().strip()
    return str(widget.property("fileName") or "")
