"""One-line messages in FreeCAD's Report view (the console in freecadcmd).

Every message starts with ``Fabrickator:`` and is a single line: bad input
and failed recomputes say what went wrong in words, never as a traceback.
Only a bug (:func:`bug`) adds its traceback after its line.
"""

from __future__ import annotations

import traceback

import FreeCAD as App


def _line(text: str) -> str:
    one = " ".join(str(text).split())
    return (one if one.startswith("Fabrickator") else f"Fabrickator: {one}") + "\n"


def message(text: str) -> None:
    """An informational line."""
    App.Console.PrintMessage(_line(text))


def warning(text: str) -> None:
    """A warning line."""
    App.Console.PrintWarning(_line(text))


def error(text: str) -> None:
    """An error line."""
    App.Console.PrintError(_line(text))


def failure(what: str, exc: BaseException) -> str:
    """Report that ``what`` failed because of ``exc`` as one error line; returns the line.

    :class:`core.errors.InputError` carries a message for the user; any
    other exception is named by its type and first line.
    """
    text = str(exc).strip().splitlines()
    reason = text[0] if text else type(exc).__name__
    if type(exc).__name__ != "InputError":
        reason = f"{type(exc).__name__}: {reason}"
    line = f"{what} failed: {reason}"
    error(line)
    return line


def bug(what: str, exc: BaseException) -> str:
    """Report that ``what`` failed by a bug (``exc`` is not bad input): one error line
    saying so, then the traceback, in the Report view; returns the line."""

    text = str(exc).strip().splitlines()
    line = (f"{what} failed by a bug in Fabrickator ({type(exc).__name__}"
            + (f": {text[0]}" if text else "") + "); please report it with this traceback:")
    error(line)
    App.Console.PrintError("".join(traceback.format_exception(type(exc), exc, exc.__traceback__)))
    return line
