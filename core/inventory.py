"""Inventory stage: the LEGO parts a maker owns, read from the files their tools export.

:func:`read` sums ``--inventory`` files in three formats into one :class:`Inventory` of
(design number, LDraw colour) -> count:

* a **Rebrickable** parts CSV (columns ``Part``, ``Color``, ``Quantity``, Rebrickable
  colour ids; a set-inventory CSV with more columns, or ``part_num``, ``color_id``,
  ``quantity`` headers, too);
* a **BrickLink** XML inventory or wanted list (``ITEM`` s with ``ITEMTYPE``, ``ITEMID``,
  ``COLOR`` as a BrickLink colour id, and ``MINQTY`` or ``QTY``);
* an **LDraw** ``.ldr``/``.mpd`` model: every type-1 line counts one part in its colour; a
  line that refers to a subfile of the same ``.mpd`` places that submodel (its parts, in the
  referring line's colour where theirs is 16, as often as it is placed), not a part.

Colour ids go through the one table of :mod:`core.colours`.  A row naming a part that is not
one of the catalog's plates and bricks (slopes, Technic, minifigures), or a colour that table
does not know, is kept in :attr:`Inventory.ignored`, never an error; a file that is not of its
format is an :class:`InputError` naming the file and line.
"""

from __future__ import annotations

import csv
import io
import os
from dataclasses import dataclass, field
from pathlib import Path
from xml.parsers import expat

import numpy as np
from scipy import ndimage

from core import colours
from core.catalog import BY_NUMBER, Part
from core.errors import InputError, shown_path

#: Header names (lower case) a parts CSV may give its three columns.
CSV_COLUMNS = {"part": ("part", "part_num", "part num", "partnum", "part number"),
               "color": ("color", "colour", "color_id", "color id", "colorid"),
               "quantity": ("quantity", "qty", "count", "quantity owned")}

#: File suffixes of each format (others are told apart by their first characters).
SUFFIXES = {".csv": "rebrickable", ".xml": "bricklink", ".ldr": "ldraw", ".mpd": "ldraw",
            ".dat": "ldraw", ".l3b": "ldraw"}

#: Submodels may nest this deep in an .mpd (deeper is a loop).
MAX_DEPTH = 64


@dataclass(frozen=True)
class Inventory:
    """Owned parts: ``counts`` (design number, LDraw colour) -> count of catalog parts;
    ``ignored`` the rows the layout cannot use, each ``{"file", "part", "colour", "count",
    "why"}``."""

    counts: dict = field(default_factory=dict)
    ignored: tuple = ()

    def designs(self) -> dict[str, int]:
        """Design number -> owned count, all colours together."""
        out: dict[str, int] = {}
        for (number, _), count in self.counts.items():
            out[number] = out.get(number, 0) + count
        return out

    def owned(self, parts: tuple[Part, ...]) -> dict[str, int]:
        """Design number -> owned count of each of ``parts`` (0 where none is owned)."""
        have = self.designs()
        return {p.number: have.get(p.number, 0) for p in parts}

    def to_json(self) -> dict:
        """The inventory as report.json lists it."""
        rows = [{"part": n, "ldraw_color": c, "color": colours.name(c), "count": k}
                for (n, c), k in sorted(self.counts.items())]
        return {"owned": rows, "owned_bricks": sum(self.counts.values()),
                "ignored": list(self.ignored),
                "ignored_parts": sum(r["count"] for r in self.ignored)}


def read(paths) -> Inventory:
    """The sum of the inventory files ``paths`` (each format told by its suffix or first
    characters).  InputError for a missing or malformed file, naming it and the line."""
    counts: dict[tuple[str, int], int] = {}
    ignored: dict[tuple, int] = {}
    for path in paths:
        for number, colour, count, why in _rows(Path(os.fspath(path))):
            if count <= 0:
                continue
            if why is None and number not in BY_NUMBER:
                why = "not one of the plates and bricks Fabrickator lays out with"
            if why is None:
                counts[(number, colour)] = counts.get((number, colour), 0) + count
            else:
                key = (Path(path).name, number, str(colour), why)
                ignored[key] = ignored.get(key, 0) + count
    rows = tuple({"file": f, "part": n, "colour": c, "count": k, "why": w}
                 for (f, n, c, w), k in sorted(ignored.items()))
    return Inventory(dict(sorted(counts.items())), rows)


def _rows(path: Path):
    """(design number, LDraw colour or a label, count, why ignored or None) of one file."""
    shown = shown_path(path)
    try:
        text = path.read_bytes().decode("utf-8-sig", errors="replace")
    except FileNotFoundError:
        raise InputError(f"--inventory {shown}: no such file") from None
    except IsADirectoryError:
        raise InputError(f"--inventory {shown} is a folder, not an inventory file") from None
    except OSError as e:
        raise InputError(f"--inventory {shown}: {e.strerror or e}") from None
    kind = SUFFIXES.get(path.suffix.lower()) or _sniff(text)
    reader = {"rebrickable": _rebrickable, "bricklink": _bricklink, "ldraw": _ldraw}[kind]
    return reader(text, shown)


def _sniff(text: str) -> str:
    """The format of a file without a known suffix, from its first characters."""
    start = text.lstrip()[:1]
    return "bricklink" if start == "<" else "ldraw" if start in ("0", "1") else "rebrickable"


def _number(text: str) -> str:
    """A design number as the catalog writes it: lower case, without folder and ``.dat``."""
    name = str(text).strip().replace("\\", "/").rsplit("/", 1)[-1].lower()
    return name[:-4] if name.endswith(".dat") else name


def _whole(text, shown: str, line: int, what: str) -> int:
    try:
        return int(str(text).strip())
    except ValueError:
        raise InputError(f"{shown} line {line}: {what} {str(text).strip()!r} is not a whole "
                         f"number") from None


def _coloured(number: str, code, label: str, count: int):
    """The row of a part in LDraw colour ``code`` (None: unknown, shown as ``label``)."""
    if code is None:
        return number, label, count, "colour not known to Fabrickator"
    return number, code, count, None


def _rebrickable(text: str, shown: str):
    """Rows of a Rebrickable parts (or set-inventory) CSV."""
    reader = csv.reader(io.StringIO(text))
    header = next(reader, None)
    names = [h.strip().lower() for h in header or ()]
    where = {}
    for key, aliases in CSV_COLUMNS.items():
        where[key] = next((i for i, h in enumerate(names) if h in aliases), None)
    if None in where.values():
        raise InputError(f"{shown} line 1: a parts CSV needs the columns Part, Color and "
                         f"Quantity (Rebrickable's export), got {','.join(names) or 'nothing'}")
    out = []
    for row in reader:
        if not any(cell.strip() for cell in row):
            continue
        line = reader.line_num
        if len(row) <= max(where.values()):
            raise InputError(f"{shown} line {line}: {len(row)} column(s), the header has "
                             f"{len(names)}")
        colour = _whole(row[where["color"]], shown, line, "colour")
        count = _whole(row[where["quantity"]], shown, line, "quantity")
        out.append(_coloured(_number(row[where["part"]]), colours.from_rebrickable(colour),
                             f"Rebrickable {colour}", count))
    return out


def _bricklink(text: str, shown: str):
    """Rows of a BrickLink XML inventory or wanted list."""
    items: list[tuple[int, dict]] = []
    state = {"item": None, "tag": None}
    parser = expat.ParserCreate()

    def start(tag, attrs):
        tag = tag.upper()
        if tag == "ITEM":
            state["item"] = {}
            items.append((parser.CurrentLineNumber, state["item"]))
        state["tag"] = tag

    def end(tag):
        if tag.upper() == "ITEM":
            state["item"] = None
        state["tag"] = None

    def data(chunk):
        if state["item"] is not None and state["tag"]:
            state["item"][state["tag"]] = state["item"].get(state["tag"], "") + chunk

    parser.StartElementHandler, parser.EndElementHandler = start, end
    parser.CharacterDataHandler = data
    try:
        parser.Parse(text, True)
    except expat.ExpatError as e:
        raise InputError(f"{shown} line {e.lineno}: not BrickLink XML "
                         f"({expat.ErrorString(e.code)})") from None
    out = []
    for line, item in items:
        number = _number(item.get("ITEMID", ""))
        if not number:
            raise InputError(f"{shown} line {line}: an ITEM without an ITEMID")
        qty = item.get("MINQTY", item.get("QTY", "1")).strip() or "1"
        count = _whole(qty, shown, line, "quantity")
        kind = item.get("ITEMTYPE", "P").strip().upper()
        if kind != "P":
            out.append((number, "", count, f"item type {kind}, not a part"))
            continue
        if not item.get("COLOR", "").strip():
            out.append((number, "", count, "no colour given"))
            continue
        colour = _whole(item["COLOR"], shown, line, "colour")
        out.append(_coloured(number, colours.from_bricklink(colour), f"BrickLink {colour}", count))
    return out


def _ldraw(text: str, shown: str):
    """Rows of an LDraw model: its parts, the submodels of an .mpd expanded."""
    files: dict[str, list] = {}
    current = None
    order: list[str] = []
    for line, raw in enumerate(text.splitlines(), start=1):
        words = raw.split()
        if not words:
            continue
        if words[0] == "0":
            if len(words) >= 3 and words[1].upper() == "FILE":
                current = " ".join(words[2:]).lower()
                files.setdefault(current, [])
                order.append(current)
            continue
        if words[0] in ("2", "3", "4", "5"):
            continue
        if words[0] != "1":
            raise InputError(f"{shown} line {line}: an LDraw line starts with 0 to 5, not "
                             f"{words[0][:20]!r}")
        if len(words) < 15:
            raise InputError(f"{shown} line {line}: a type-1 line needs a colour, 12 numbers "
                             f"and a file name")
        try:
            [float(w) for w in words[2:14]]
        except ValueError:
            raise InputError(f"{shown} line {line}: the position and matrix of a type-1 line "
                             f"must be numbers") from None
        colour = _whole(words[1], shown, line, "colour") if not words[1].lower().startswith("0x") \
            else words[1]
        files.setdefault(current, []).append((line, colour, " ".join(words[14:])))
    main = order[0] if order else None
    counts: dict[tuple, int] = {}
    _expand(files, main, 16, (main,), counts, shown)
    out = []
    for (number, colour), count in counts.items():
        if colour == 16:
            out.append((number, "16", count, "main colour 16 at the top of the model"))
        elif isinstance(colour, str):
            out.append((number, colour, count, "colour not known to Fabrickator"))
        else:
            out.append(_coloured(number, colours.from_ldraw(colour), f"LDraw {colour}", count))
    return out


def _expand(files, name, colour, stack, counts, shown) -> None:
    """Add the parts of (sub)model ``name``, placed once in ``colour``, to ``counts``
    (``stack``: the submodels it is placed in, itself included)."""
    for line, own, ref in files.get(name, ()):
        shade = colour if own == 16 else own
        sub = ref.lower()
        if sub in files:
            if sub in stack or len(stack) > MAX_DEPTH:
                raise InputError(f"{shown} line {line}: submodel {ref!r} contains itself")
            _expand(files, sub, shade, stack + (sub,), counts, shown)
        else:
            key = (_number(ref), shade)
            counts[key] = counts.get(key, 0) + 1


#: What one bought brick costs more than an owned one, in bricks: the layout splits a brick
#: it would have to buy into owned ones where that takes at most 1 + this many of them, and
#: the improvement's windows price a bought brick 1 + this.
BUY_COST = 1.5


@dataclass(frozen=True)
class Stock:
    """What the layout may use: ``owned`` design number -> owned count (a design not in it is
    not owned); ``buy`` whether more may be bought (at :data:`BUY_COST` each) or not
    (``--inventory-only``)."""

    owned: dict
    buy: bool = True

    def bought(self, used: dict) -> int:
        """How many of ``used`` (design number -> count) are beyond what is owned."""
        return sum(max(0, n - self.owned.get(d, 0)) for d, n in used.items())

    def cost(self, used: dict) -> float:
        """The bricks of ``used`` plus :data:`BUY_COST` per bought one."""
        return sum(used.values()) + BUY_COST * self.bought(used)


def used(layout) -> dict[str, int]:
    """Design number -> LEGO (not printed) bricks of it in ``layout``."""
    out: dict[str, int] = {}
    for b in layout.bricks:
        if b.kind == "lego":
            out[b.part] = out.get(b.part, 0) + 1
    return out


def usable(parts: tuple[Part, ...], stock: Stock) -> tuple[Part, ...]:
    """The parts of ``parts`` that ``stock`` owns, and the 1x1 plate 3024, which every layout
    needs to start from (:func:`core.layout.greedy.fit_stock` then keeps it to what is owned)."""
    return tuple(p for p in parts if stock.owned.get(p.number, 0) > 0 or p.number == "3024")


def fits(layout, stock: Stock) -> bool:
    """Whether ``layout`` uses no design more than ``stock`` owns, or buying is allowed."""
    return stock.buy or stock.bought(used(layout)) == 0


def colour(layout, inventory: Inventory, bought: int,
           kept: dict | None = None) -> dict[int, tuple[int, bool]]:
    """Brick id -> (LDraw colour, owned) for the LEGO bricks of ``layout``.

    Layer by layer from the bottom (then along x and y), each brick takes a colour of its
    design that is still owned: one the bricks around its printed part already have (where
    it touches one, :func:`_around_printed`), else one its layer already has, the most used
    there first, else its design's most plentiful; so a printed part's surroundings and a
    layer keep to few colours, and a colour fills whole layers before the next starts.
    Bricks beyond what is owned of their design are bought in ``bought``.  ``kept`` (brick id
    -> LDraw colour) are bricks an iteration keeps: already built, they keep their colour and
    count as owned, taking their design and colour from the inventory first where it has
    them.  The same layout, inventory and kept bricks give the same colours."""
    left = dict(inventory.counts)
    out: dict[int, tuple[int, bool]] = {}
    for b in layout.bricks:
        if b.kind == "lego" and kept and b.id in kept:
            key = (b.part, int(kept[b.id]))
            if left.get(key, 0) > 0:
                left[key] -= 1
            out[b.id] = (key[1], True)
    shades: dict[str, list[int]] = {}
    for (number, code), count in sorted(left.items(), key=lambda kv: (-kv[1], kv[0])):
        shades.setdefault(number, []).append(code)
    around = _around_printed(layout)
    near: dict[str, dict[int, int]] = {}
    layer, here = None, {}
    for b in sorted((b for b in layout.bricks if b.kind == "lego" and b.id not in out),
                    key=lambda b: (b.cell[2], b.cell[0], b.cell[1], b.id)):
        if b.cell[2] != layer:
            layer, here = b.cell[2], {}
        mine = [c for c in shades.get(b.part, ()) if left[(b.part, c)] > 0]
        if not mine:
            out[b.id] = (bought, False)
            continue
        group = near.setdefault(around[b.id], {}) if b.id in around else {}
        code = max(mine, key=lambda c: (group.get(c, 0), here.get(c, 0), left[(b.part, c)], -c))
        left[(b.part, code)] -= 1
        here[code] = here.get(code, 0) + 1
        if b.id in around:
            group[code] = group.get(code, 0) + 1
        out[b.id] = (code, True)
    return out


def _around_printed(layout) -> dict[int, str]:
    """LEGO brick id -> the printed part it touches face to face (the first by name)."""
    names = sorted({b.printed_part for b in layout.bricks if b.kind == "printed" and b.printed_part})
    if not names:
        return {}
    labels = layout.labels()
    index = np.array([b.kind == "printed" for b in layout.bricks] + [True])
    out: dict[int, str] = {}
    for name in names:
        mask = np.zeros(labels.shape, dtype=bool)
        for b in layout.bricks:
            if b.printed_part == name:
                mask[b.slices()] = True
        touched = np.unique(labels[ndimage.binary_dilation(mask) & ~mask])
        for n in touched[~index[touched]].tolist():
            out.setdefault(layout.bricks[n].id, name)
    return out


def summary(colouring: dict[int, tuple[int, bool]]) -> dict:
    """The report's counts of a colouring: ``bricks``, ``from_inventory``, ``to_buy``."""
    owned = sum(1 for _, mine in colouring.values() if mine)
    return {"bricks": len(colouring), "from_inventory": owned, "to_buy": len(colouring) - owned}


def summary_words(block: dict) -> str:
    """The summary line of an inventory run: "N of M bricks from your inventory, K to buy"."""
    return (f"{block['from_inventory']} of {block['bricks']} bricks from your inventory, "
            f"{block['to_buy']} to buy")


def colouring_of(document: dict) -> dict | None:
    """Brick id -> (LDraw colour, owned) of the bricks of a ``layout.json`` document that
    carry them (:func:`with_colours`), or None where none does."""
    found = {int(b["id"]): (int(b["colour"]), bool(b.get("owned", False)))
             for b in document.get("bricks", ()) if "colour" in b}
    return found or None


def with_colours(document: dict, colouring: dict | None) -> dict:
    """A ``layout.json`` document with each LEGO brick's ``colour`` (LDraw code) and ``owned``
    (from the maker's inventory) of ``colouring`` (brick id -> (code, owned); None: the
    document as it is)."""
    if colouring is None:
        return document
    bricks = []
    for b in document["bricks"]:
        b = dict(b)
        if b["id"] in colouring:
            b["colour"], b["owned"] = int(colouring[b["id"]][0]), bool(colouring[b["id"]][1])
        bricks.append(b)
    return {**document, "bricks": bricks}
