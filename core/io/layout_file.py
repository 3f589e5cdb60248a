"""Reading a ``layout.json`` that a user gives (the ``stability`` command): every field
checked before a :class:`~core.model.Layout` is made of it, so that a malformed or
impossible build ends in one line naming the brick, never in a wrong verdict."""

from __future__ import annotations

import math

import numpy as np

from core.colours import COLORS
from core.errors import InputError
from core.model import Layout


#: Most grams a brick's ``load_g`` may carry in a layout.json (a tonne).
MAX_LOAD_G = 1_000_000.0
#: Largest cell edge (mm) a layout.json may declare (LEGO's is 8 x 8 x 3.2).
MAX_CELL_MM = 1000.0
#: Largest distance (mm) of a layout.json's grid origin from the model's origin.
MAX_ORIGIN_MM = 1e9


def layout_from_document(data, parts_folder=None) -> Layout:
    """The :class:`~core.model.Layout` of a parsed ``layout.json`` document, checked first.

    Raises :class:`InputError` (one line, without the file's name, naming the brick by its
    id) for a document that is not a layout or describes no real build: a missing or
    malformed ``cell_mm`` (three numbers above 0, at most :data:`MAX_CELL_MM`),
    ``origin_mm`` (three finite numbers) or ``shape`` (three whole numbers >= 1, at most
    :data:`core.voxelize.MAX_GRID_CELLS` cells); no bricks; a brick with an id that is not
    a whole number >= 0 or is used twice, a part that is not in the catalog, a kind that is
    not ``lego`` or ``printed``, a size that is not the part's (either way round in x, y),
    a cell that is not three whole numbers >= 0 or that puts the brick outside ``shape``, a
    negative or fractional step, a ``load_g`` that is not a finite number from 0 to
    :data:`MAX_LOAD_G`; two bricks sharing a cell; a ``printed_part`` that is not a plain
    file name (no path separator, no ``..``), named by a brick whose kind is not
    ``printed``, or (with ``parts_folder``) whose ``<name>.stl`` is not a file there; a
    ``colour`` that is not an LDraw code of :data:`core.colours.COLORS` or an ``owned`` that is
    not true or false (both optional, from a run with an inventory).
    """
    if not isinstance(data, dict):
        raise InputError(f"not a layout.json: the document is {_json_type(data)}, not an object "
                         f"with cell_mm, origin_mm, shape and bricks")
    for key in ("cell_mm", "origin_mm", "shape", "bricks"):
        if key not in data:
            raise InputError(f"not a layout.json: it has no {key!r}")
    shape = _checked_grid(data)
    bricks = data["bricks"]
    if not isinstance(bricks, list):
        raise InputError(f"bricks must be a list of bricks, got {_json_type(bricks)}")
    if not bricks:
        raise InputError("has no bricks: there is nothing to check")
    filled = np.zeros(shape, dtype=bool)
    seen: dict[int, int] = {}
    boxes: list[tuple[int, tuple[int, ...], tuple[int, ...]]] = []
    for n, b in enumerate(bricks):
        bid, cell, size = _checked_brick(n, b, shape, seen, parts_folder)
        where = tuple(slice(c, c + s) for c, s in zip(cell, size))
        if filled[where].any():
            other = next(o for o, c0, s0 in boxes
                         if all(a < c1 + t1 and c1 < a + t for a, t, c1, t1 in zip(cell, size, c0, s0)))
            raise InputError(f"brick {bid} overlaps brick {other}: two bricks cannot fill one cell")
        filled[where] = True
        boxes.append((bid, cell, size))
    del filled
    try:
        return Layout.from_json(data)
    except (ValueError, KeyError, TypeError, IndexError) as exc:   # every field was checked above
        raise InputError(f"not a layout.json ({type(exc).__name__}: {exc})") from None


def _checked_grid(data: dict) -> tuple[int, int, int]:
    """The ``shape`` of a layout document that has ``cell_mm``, ``origin_mm`` and ``shape``,
    once all three are as :func:`layout_from_document` asks; else :class:`InputError`."""
    from core.voxelize import MAX_GRID_CELLS

    cell_mm = _numbers(data["cell_mm"])
    if cell_mm is None or not all(0 < v <= MAX_CELL_MM for v in cell_mm):
        raise InputError(f"cell_mm must be three numbers above 0 and at most {MAX_CELL_MM:g} mm, "
                         f"got {_show(data['cell_mm'])}")
    origin = _numbers(data["origin_mm"])
    if origin is None or not all(abs(v) <= MAX_ORIGIN_MM for v in origin):
        raise InputError(f"origin_mm must be three finite numbers (mm, at most {MAX_ORIGIN_MM:g} "
                         f"from 0), got {_show(data['origin_mm'])}")
    shape = _wholes(data["shape"])
    if shape is None or min(shape) < 1:
        raise InputError(f"shape must be three whole numbers >= 1, got {_show(data['shape'])}")
    if shape[0] * shape[1] * shape[2] > MAX_GRID_CELLS:
        raise InputError(f"shape {shape[0]} x {shape[1]} x {shape[2]} is "
                         f"{shape[0] * shape[1] * shape[2]:.3g} cells, more than the "
                         f"{MAX_GRID_CELLS:,} a grid may have")
    return shape


def _checked_brick(n: int, b, shape: tuple[int, int, int], seen: dict[int, int],
                   parts_folder) -> tuple[int, tuple[int, int, int], tuple[int, int, int]]:
    """(id, cell, size) of the brick ``b`` at index ``n`` of a layout document whose grid is
    ``shape``, once its own fields are as :func:`layout_from_document` asks (overlaps with
    other bricks aside); else :class:`InputError`.  ``seen`` (id -> index of the bricks
    before it) gets its id."""
    from core.catalog import BY_NUMBER

    if not isinstance(b, dict):
        raise InputError(f"the brick at index {n} is {_json_type(b)}, not an object")
    bid = _whole(b.get("id"))
    if bid is None or bid < 0:
        raise InputError(f"the brick at index {n}: id must be a whole number >= 0, "
                         f"got {_show(b.get('id'))}")
    name = f"brick {bid}"
    if bid in seen:
        raise InputError(f"{name}: the id is used twice (the bricks at index {seen[bid]} and {n})")
    seen[bid] = n
    for key in ("part", "size", "cell", "kind", "printed_part"):
        if key not in b:
            raise InputError(f"{name}: it has no {key!r}")
    part = BY_NUMBER.get(b["part"]) if isinstance(b["part"], str) else None
    if part is None:
        raise InputError(f"{name}: unknown part {_show(b['part'])} "
                         f"(not a catalog design number like \"3001\")")
    if b["kind"] not in ("lego", "printed"):
        raise InputError(f"{name}: unknown kind {_show(b['kind'])} (use \"lego\" or \"printed\")")
    size = _wholes(b["size"])
    if size is None:
        raise InputError(f"{name}: size must be three whole numbers, got {_show(b['size'])}")
    real = [(w, d, part.layers) for w, d in part.orientations()]
    if size not in real:
        ways = " or ".join(" x ".join(map(str, r)) for r in real)
        raise InputError(f"{name}: size {' x '.join(map(str, size))} is not that of part "
                         f"{part.number} ({part.name}), which is {ways} cells")
    cell = _wholes(b["cell"])
    if cell is None or min(cell) < 0:
        raise InputError(f"{name}: cell must be three whole numbers >= 0, got {_show(b['cell'])}")
    if any(c + s > m for c, s, m in zip(cell, size, shape)):
        raise InputError(f"{name}: lies outside the grid: cell {list(cell)} plus size "
                         f"{list(size)} passes shape {list(shape)}")
    step = b.get("step")
    if step is not None and (_whole(step) is None or _whole(step) < 0):
        raise InputError(f"{name}: step must be a whole number >= 0 or null, got {_show(step)}")
    if "load_g" in b:
        load = _number(b["load_g"])
        if load is None or not 0 <= load <= MAX_LOAD_G:
            raise InputError(f"{name}: load_g must be a number of grams from 0 to "
                             f"{MAX_LOAD_G:g}, got {_show(b['load_g'])}")
    _check_printed_part(name, b["kind"], b["printed_part"], parts_folder)
    colour = b.get("colour")
    if "colour" in b and (isinstance(colour, bool) or not isinstance(colour, (int, float))
                          or colour not in COLORS):
        raise InputError(f"{name}: colour must be an LDraw colour code Fabrickator knows "
                         f"(such as 71, Light Bluish Grey), got {_show(b['colour'])}")
    if "owned" in b and not isinstance(b["owned"], bool):
        raise InputError(f"{name}: owned must be true or false, got {_show(b['owned'])}")
    return bid, cell, size


def _check_printed_part(name: str, kind, printed, parts_folder) -> None:
    """InputError unless a brick's ``printed_part`` is null or a plain file name of a printed
    brick whose ``<printed>.stl`` lies in ``parts_folder`` (when given)."""
    import os
    import stat

    if printed is None:
        return
    if not isinstance(printed, str) or not printed.strip():
        raise InputError(f"{name}: printed_part must be a part's name or null, got {_show(printed)}")
    if ("/" in printed or "\\" in printed or "\0" in printed or ".." in printed
            or printed.startswith(".") or (os.altsep and os.altsep in printed)):
        raise InputError(f"{name}: printed_part {_show(printed)} is not a plain name "
                         f"(no path separators, no '..', not starting with '.')")
    if kind != "printed":
        raise InputError(f"{name}: names printed part {_show(printed)} but its kind is "
                         f"{_show(kind)}, not \"printed\"")
    if parts_folder is None:
        return
    stl = os.path.join(os.fspath(parts_folder), f"{printed}.stl")
    try:
        regular = stat.S_ISREG(os.stat(stl).st_mode)
    except (OSError, ValueError):
        regular = False
    if not regular:
        raise InputError(f"{name}: printed part {printed}'s mesh parts/{printed}.stl is missing "
                         f"beside the layout (the force check weighs it)")


def _json_type(value) -> str:
    """A JSON value's type in words, e.g. ``a list``."""
    return {dict: "an object", list: "a list", str: "a string", bool: "a boolean",
            type(None): "null"}.get(type(value), "a number")


def _show(value) -> str:
    """A short one-line rendering of a JSON value for an error message."""
    import reprlib

    short = reprlib.Repr()
    short.maxstring = short.maxother = 40
    short.maxlist = short.maxdict = 6
    return short.repr(value)


def _number(value) -> float | None:
    """``value`` as a finite float if it is a JSON number (not a boolean), else None."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    try:
        out = float(value)
    except OverflowError:
        return None
    return out if math.isfinite(out) else None


def _whole(value) -> int | None:
    """``value`` as an int if it is a whole JSON number (3 or 3.0), else None."""
    number = _number(value)
    if number is None or not number.is_integer():
        return None
    return int(value) if isinstance(value, int) else int(number)


def _numbers(value) -> tuple[float, float, float] | None:
    """Three finite numbers, or None."""
    if not isinstance(value, list) or len(value) != 3:
        return None
    out = tuple(_number(v) for v in value)
    return None if None in out else out


def _wholes(value) -> tuple[int, int, int] | None:
    """Three whole numbers, or None."""
    if not isinstance(value, list) or len(value) != 3:
        return None
    out = tuple(_whole(v) for v in value)
    return None if None in out else out
