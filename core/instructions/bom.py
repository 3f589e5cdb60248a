"""Bill of materials: what to get before building, as a CSV and a BrickLink wanted list.

``bom.csv`` has one row per LEGO design number and colour (kind ``lego``:
design number, name, colour, count; the colour each brick is ordered in is
:func:`core.colours.ordered_code`'s, the same in every display palette), one
row per part the build's props are stacked from (kind ``prop``: the most of it
standing at once, :func:`prop_counts`) and one row per printed part (kind
``printed``: its ID, bricks replaced, volume, print time and STL file).
A printed part's print time is the slicer's share when the pipeline sliced
(``PrintedPart.print_s``), else the calibrated estimate of
:func:`core.printing.estimate.estimate_seconds` for that part alone, and the
``print_method`` column says which.

``bricklink.xml`` is a BrickLink wanted list (Wanted > Upload, BrickLink
XML format: no XML declaration, ``INVENTORY`` of ``ITEM`` s with
``ITEMTYPE`` P, ``ITEMID`` the design number, ``COLOR`` the BrickLink colour
id and ``MINQTY``) of the LEGO bricks still missing after what the user
``owned`` (the props' parts included).

With an inventory (``colouring``: brick id -> (LDraw colour, owned), from
:func:`core.inventory.colour`) each brick is counted in its own colour, ``bom.csv`` gains the
columns :data:`INVENTORY_COLUMNS` (per design and colour: how many come from the inventory,
how many to buy) and ``bricklink.xml`` lists only what is to buy, in BrickLink colour ids; a
prop's parts come first from the owned parts the build leaves over.
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
#: The columns bom.csv gains with an inventory: of ``count`` (needed), owned and to buy.
INVENTORY_COLUMNS = ("owned", "to_buy")


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
    owned: int | None = None

    def row(self) -> list:
        extra = [] if self.owned is None else [self.owned, self.count - self.owned]
        return [self.kind, self.part, self.name, self.color, self.ldraw_color,
                "" if self.bricklink_color is None else self.bricklink_color, self.count,
                "" if self.bricks_replaced is None else self.bricks_replaced,
                "" if self.volume_mm3 is None else f"{self.volume_mm3:.1f}",
                "" if self.print_s is None else f"{self.print_s:.0f}",
                self.print_method, self.file] + extra


def lego_counts(layout: Layout) -> dict[str, int]:
    """LEGO design number -> number of LEGO (not printed) bricks of it in ``layout``."""
    counts: dict[str, int] = {}
    for b in layout.bricks:
        if b.kind != "printed":
            counts[b.part] = counts.get(b.part, 0) + 1
    return counts


def lego_colour_counts(layout: Layout, colouring: dict | None = None) -> dict[tuple[str, int], int]:
    """(design number, LDraw colour) -> number of LEGO bricks of it in ``layout``, in the
    colour each is ordered in (:func:`core.colours.ordered_code`, or ``colouring``'s)."""
    counts: dict[tuple[str, int], int] = {}
    for b in layout.bricks:
        if b.kind != "printed":
            code = colours.ordered_code(b) if colouring is None else colouring[b.id][0]
            key = (b.part, code)
            counts[key] = counts.get(key, 0) + 1
    return counts


def owned_colour_counts(layout: Layout, colouring: dict) -> dict[tuple[str, int], int]:
    """(design number, LDraw colour) -> LEGO bricks of it in ``layout`` from the inventory."""
    counts: dict[tuple[str, int], int] = {}
    for b in layout.bricks:
        if b.kind != "printed" and colouring[b.id][1]:
            key = (b.part, colouring[b.id][0])
            counts[key] = counts.get(key, 0) + 1
    return counts


def to_buy(layout: Layout, colouring: dict, inventory, bought: int, props=()) -> dict:
    """(design number, LDraw colour) -> count to buy: the bricks ``colouring`` does not take
    from the inventory, and the props' parts beyond what of each design the build leaves
    over in ``inventory`` (bought in ``bought``)."""
    need: dict[tuple[str, int], int] = {}
    for b in layout.bricks:
        if b.kind != "printed" and not colouring[b.id][1]:
            key = (b.part, colouring[b.id][0])
            need[key] = need.get(key, 0) + 1
    spare = inventory.designs()
    for (number, _), count in owned_colour_counts(layout, colouring).items():
        spare[number] = spare.get(number, 0) - count
    for number, count in prop_counts(props).items():
        more = max(0, count - max(spare.get(number, 0), 0))
        if more:
            need[(number, bought)] = need.get((number, bought), 0) + more
    return need


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


def lines(layout: Layout, printed_parts=(), props=(), colouring: dict | None = None) -> list[BomLine]:
    """The bill of materials of ``layout``, its props and its printed parts.

    LEGO rows come in catalog order (plates before bricks of each size), then
    the props' parts (:func:`prop_counts`); printed rows in part order.  Promises:
    the LEGO counts add up to the layout's LEGO bricks, and there is one printed
    row per printed part.  With ``colouring`` (see the module's text) LEGO rows are per
    design and each brick's colour, with the owned count.
    """
    from core.printing.estimate import ESTIMATE_METHOD, estimate_seconds

    counts = lego_colour_counts(layout, colouring)
    mine = None if colouring is None else owned_colour_counts(layout, colouring)
    order = {n: i for i, n in enumerate(BY_NUMBER)}
    out = [BomLine("lego", number, _part_name(number), colours.name(code), code,
                   colours.bricklink_id(code), count,
                   owned=None if mine is None else mine.get((number, code), 0))
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
    """Write ``rows`` as ``bom.csv`` (header :data:`COLUMNS`, and :data:`INVENTORY_COLUMNS`
    where a row has an owned count); returns the path."""
    path = Path(path)
    counted = any(r.owned is not None for r in rows)
    with path.open("w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(COLUMNS + (INVENTORY_COLUMNS if counted else ()))
        for r in rows:
            w.writerow(r.row() + (["", ""] if counted and r.owned is None else []))
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
                      remarks: str = "", props=(), buying: dict | None = None) -> Path:
    """Write the BrickLink wanted list of the missing LEGO bricks (and the parts of the
    ``props``) at ``path``; returns it.

    ``remarks`` (e.g. the model name) goes into each item's ``REMARKS``.  ``buying``
    ((design, LDraw colour) -> count, :func:`to_buy`) is the list instead, each in its colour.
    """
    order = {n: i for i, n in enumerate(BY_NUMBER)}
    if buying is None:
        code = colours.BOM_COLOR
        buying = {(n, code): k for n, k in wanted(layout, owned, props).items()}
    items = sorted(((n, c), k) for (n, c), k in buying.items() if k > 0)
    items.sort(key=lambda kv: (order.get(kv[0][0], 1e9), kv[0]))
    parts = ["<INVENTORY>"]
    for (number, code), count in items:
        color = colours.bricklink_id(code)
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
