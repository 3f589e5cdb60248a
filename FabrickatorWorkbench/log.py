"""One-line messages in FreeCAD's Report view (the console in freecadcmd).

Every message starts with ``Fabrickator:`` and is a single line: bad input
and failed recomputes say what went wrong in words, never as a traceback.
"""

from __future__ import annotations

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
