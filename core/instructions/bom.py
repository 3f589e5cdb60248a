"""Bill of materials: what to get before building, as a CSV and a BrickLink wanted list.

``bom.csv`` has one row per LEGO design number and colour (kind ``lego``:
design number, name, colour, count; the colour each brick is ordered in is
:func:`core.colours.ordered_code`'s, the same in every display palette), one
row per part the build's props are stacked from (kind ``prop``: the most of it
standing at once, :func:`prop_counts`) and one row per printed part (kind
``printed``: its ID, bricks replaced, volume, print time and STL file).
A printed part's print time is the slicer's share when the pipeline sliced
(``PrintedPart.print_s``), else the calibrated estimate of
:func:`core.printing.print_time.estimate_seconds` for that part alone, and the
``print_method`` column says which.

``bricklink.xml`` is a BrickLink wanted list (Wanted > Upload, BrickLink
XML format: no XML declaration, ``INVENTORY`` of ``ITEM`` s with
``ITEMTYPE`` P, ``ITEMID`` the design number, ``COLOR`` the BrickLink colour
id and ``MINQTY``) of the LEGO bricks still missing after what the user
``owned`` (the props' parts included).
"""

from __future__ import annotations

import csv
import os
from dataclasses import dataclass
from pathlib import Path
from xml.sax.saxutils import escape

from core import colours
from core.catalog import BY_NUMBER
from core.errors import InputError
from core.model import Layout

#: Columns of bom.csv, in order.
COLUMNS = ("kind", "part", "name", "color", "ldraw_color", "bricklink_color", "count",
           "bricks_replaced", "volume_mm3", "print_s", "print_method", "file")


@dataclass
class BomLine:
    """One row of the bill of materials (see :data:`COLUMNS`)."""

    kind: str
    part: str
    name: str
    color: str
    ldraw_color: int
    bricklink_color: int | None
    count: int
    bricks_replaced: int | None = None
    volume_mm3: float | None = None
    print_s: float | None = None
    print_method: str = ""
    file: str = ""

    def row(self) -> list:
        return [self.kind, self.part, self.name, self.color, self.ldraw_color,
                "" if self.bricklink_color is None else self.bricklink_color, self.count,
                "" if self.bricks_replaced is None else self.bricks_replaced,
                "" if self.volume_mm3 is None else f"{self.volume_mm3:.1f}",
                "" if self.print_s is None else f"{self.print_s:.0f}",
                self.print_method, self.file]


def lego_counts(layout: Layout) -> dict[str, int]:
    """LEGO design number -> number of LEGO (not printed) bricks of it in ``layout``."""
    counts: dict[str, int] = {}
    for b in layout.bricks:
        if b.kind != "printed":
            counts[b.part] = counts.get(b.part, 0) + 1
    return counts


def lego_colour_counts(layout: Layout) -> dict[tuple[str, int], int]:
    """(design number, LDraw colour) -> number of LEGO bricks of it in ``layout``, in the
    colour each is ordered in (:func:`core.colours.ordered_code`)."""
    counts: dict[tuple[str, int], int] = {}
    for b in layout.bricks:
        if b.kind != "printed":
            key = (b.part, colours.ordered_code(b))
            counts[key] = counts.get(key, 0) + 1
    return counts


def prop_counts(props) -> dict[str, int]:
    """Design number -> how many the props (:attr:`core.instructions.build_order.BuildOrder.props`) use
    at most at one time: a prop taken away frees its parts for a later one."""
    events = sorted([(p["step"], 1, p) for p in props]
                    + [(p["removed_after"] + 0.5, -1, p) for p in props if p["removed_after"] is not None],
                    key=lambda e: (e[0], e[1]))
    now: dict[str, int] = {}
    most: dict[str, int] = {}
    for _, sign, p in events:
        for number, count in p["parts"].items():
            now[number] = now.get(number, 0) + sign * count
            most[number] = max(most.get(number, 0), now[number])
    return most


def _part_name(number: str) -> str:
    part = BY_NUMBER.get(number)
    return part.name if part is not None else f"Part {number}"


def lines(layout: Layout, printed_parts=(), props=()) -> list[BomLine]:
    """The bill of materials of ``layout``, its props and its printed parts.

    LEGO rows come in catalog order (plates before bricks of each size), then
    the props' parts (:func:`prop_counts`); printed rows in part order.  Promises:
    the LEGO counts add up to the layout's LEGO bricks, and there is one printed
    row per printed part.
    """
    from core.printing.print_time import ESTIMATE_METHOD, estimate_seconds

    counts = lego_colour_counts(layout)
    order = {n: i for i, n in enumerate(BY_NUMBER)}
    out = [BomLine("lego", number, _part_name(number), colours.name(code), code,
                   colours.bricklink_id(code), count)
           for (number, code), count in sorted(counts.items(),
                                               key=lambda kv: (order.get(kv[0][0], 1e9), kv[0]))]
    code = colours.BOM_COLOR
    out += [BomLine("prop", number, f"{_part_name(number)} (for props while building)",
                    colours.name(code), code, colours.bricklink_id(code), count)
            for number, count in sorted(prop_counts(props).items(),
                                        key=lambda kv: (order.get(kv[0], 1e9), kv[0]))]
    printed_name = colours.name(colours.PRINTED_COLOR)
    for p in printed_parts:
        if p.print_s is not None:
            seconds, method = float(p.print_s), "slicer (share of the plate)"
        else:
            seconds, method = estimate_seconds([p.mesh]), ESTIMATE_METHOD
        out.append(BomLine("printed", p.id, f"Printed part {p.id}", f"{printed_name} (display)",
                           colours.PRINTED_COLOR, None, 1, len(p.bricks), float(p.volume_mm3), seconds,
                           method, p.stl or f"parts/{p.id}.stl"))
    return out


def write_csv(rows: list[BomLine], path: str | os.PathLike) -> Path:
    """Write ``rows`` as ``bom.csv`` (header :data:`COLUMNS`); returns the path."""
    path = Path(path)
    with path.open("w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(COLUMNS)
        for r in rows:
            w.writerow(r.row())
    return path


def wanted(layout: Layout, owned: dict[str, int] | None = None, props=()) -> dict[str, int]:
    """Design number -> count still to get: the layout's LEGO bricks and the parts of its
    ``props`` (:func:`prop_counts`) minus ``owned``.

    Raises InputError for an owned count that is not a whole number >= 0.
    """
    need = lego_counts(layout)
    for number, count in prop_counts(props).items():
        need[number] = need.get(number, 0) + count
    for number, have in (owned or {}).items():
        if not (isinstance(have, int) and have >= 0):
            raise InputError(f"owned count of part {number} must be a whole number >= 0, got {have!r}")
        if number in need:
            need[number] = max(0, need[number] - have)
    return {n: c for n, c in need.items() if c > 0}


def write_wanted_list(layout: Layout, path: str | os.PathLike, owned: dict[str, int] | None = None,
                      remarks: str = "", props=()) -> Path:
    """Write the BrickLink wanted list of the missing LEGO bricks (and the parts of the
    ``props``) at ``path``; returns it.

    ``remarks`` (e.g. the model name) goes into each item's ``REMARKS``.
    """
    color = colours.bricklink_id(colours.BOM_COLOR)
    order = {n: i for i, n in enumerate(BY_NUMBER)}
    items = sorted(wanted(layout, owned, props).items(), key=lambda kv: (order.get(kv[0], 1e9), kv[0]))
    parts = ["<INVENTORY>"]
    for number, count in items:
        parts.append("  <ITEM>")
        parts.append("    <ITEMTYPE>P</ITEMTYPE>")
        parts.append(f"    <ITEMID>{escape(number)}</ITEMID>")
        parts.append(f"    <COLOR>{color}</COLOR>")
        parts.append(f"    <MINQTY>{count}</MINQTY>")
        if remarks:
            parts.append(f"    <REMARKS>{escape(remarks)}</REMARKS>")
        parts.append("    <NOTIFY>N</NOTIFY>")
        parts.append("  </ITEM>")
    parts.append("</INVENTORY>")
    path = Path(path)
    path.write_text("\n".join(parts) + "\n", encoding="utf-8")
    return path
