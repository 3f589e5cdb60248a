"""The standard LEGO plates and bricks Fabrickator lays out with.

Each :class:`Part` has a footprint in studs (short side first), a height in
plate layers (1 for a plate, 3 for a brick) and its LEGO design number.
:func:`select` restricts the set to what a user wants or owns.
"""

from __future__ import annotations

from dataclasses import dataclass

from core.errors import InputError

#: (footprint, plate number, brick number), from the LEGO design numbers.
_TABLE = (
    ((1, 1), "3024", "3005"),
    ((1, 2), "3023", "3004"),
    ((1, 3), "3623", "3622"),
    ((1, 4), "3710", "3010"),
    ((1, 6), "3666", "3009"),
    ((1, 8), "3460", "3008"),
    ((2, 2), "3022", "3003"),
    ((2, 3), "3021", "3002"),
    ((2, 4), "3020", "3001"),
    ((2, 6), "3795", "2456"),
    ((2, 8), "3034", "3007"),
)

#: Mass in grams of each catalog part, from BrickLink's catalog weights (rounded to 0.01 g).
#: They agree within a few per cent with the parts StableLego weighed for its validated
#: builds (3005 0.43, 3004 0.81, 3010 1.57, 3009 2.28, 3008 3.03, 3003 1.15, 2456 3.23 g;
#: its 3001 weighed 2.16 g).  The 1x1 plate is 0.15 g (0.4 g is the 1x1 brick's weight).
MASS_G = {
    "3024": 0.15, "3023": 0.30, "3623": 0.44, "3710": 0.58, "3666": 0.84, "3460": 1.10,
    "3022": 0.52, "3021": 0.75, "3020": 0.98, "3795": 1.40, "3034": 1.85,
    "3005": 0.43, "3004": 0.81, "3622": 1.16, "3010": 1.57, "3009": 2.28, "3008": 3.03,
    "3003": 1.15, "3002": 1.64, "3001": 2.32, "2456": 3.23, "3007": 4.41,
}

PLATE_LAYERS = 1
BRICK_LAYERS = 3


@dataclass(frozen=True)
class Part:
    """A catalog part: ``footprint`` (w, d) with w <= d in studs, ``layers`` 1 or 3."""

    number: str
    footprint: tuple[int, int]
    layers: int

    @property
    def kind(self) -> str:
        return "plate" if self.layers == PLATE_LAYERS else "brick"

    @property
    def name(self) -> str:
        w, d = self.footprint
        return f"{self.kind.capitalize()} {w} x {d}"

    @property
    def cells(self) -> int:
        """Number of 1x1 plate cells the part fills."""
        return self.footprint[0] * self.footprint[1] * self.layers

    def orientations(self) -> tuple[tuple[int, int], ...]:
        """The distinct (size x, size y) footprints of the part turned 0° and 90°."""
        w, d = self.footprint
        return ((w, d),) if w == d else ((w, d), (d, w))


CATALOG: tuple[Part, ...] = tuple(
    Part(num, fp, layers)
    for fp, plate, brick in _TABLE
    for num, layers in ((plate, PLATE_LAYERS), (brick, BRICK_LAYERS))
)

BY_NUMBER = {p.number: p for p in CATALOG}


def select(spec: str | None = None) -> tuple[Part, ...]:
    """The parts named by ``spec``, a comma-separated list of words.

    A word is ``all``, ``plates``, ``bricks``, a design number (``3001``) or
    a footprint with a kind (``plate1x2``, ``brick2x4``).  None or ``""``
    means all parts.  The 1x1 plate (3024) is always needed, because a cell
    that nothing larger fits must still be covered; a set without it is an
    :class:`InputError`, as is an unknown word.
    """
    if not spec:
        return CATALOG
    chosen: dict[str, Part] = {}
    for word in (w.strip().lower() for w in spec.split(",")):
        if not word:
            continue
        if word == "all":
            found = list(CATALOG)
        elif word in ("plates", "bricks"):
            found = [p for p in CATALOG if p.kind + "s" == word]
        elif word in BY_NUMBER:
            found = [BY_NUMBER[word]]
        else:
            found = [p for p in CATALOG
                     if word in (f"{p.kind}{p.footprint[0]}x{p.footprint[1]}",
                                 f"{p.kind}{p.footprint[1]}x{p.footprint[0]}")]
        if not found:
            raise InputError(f"unknown part '{word}' in the brick set "
                             "(use all, plates, bricks, a design number like 3001, or plate2x4)")
        for p in found:
            chosen[p.number] = p
    if "3024" not in chosen:
        raise InputError("the brick set must contain the 1x1 plate 3024, "
                         "or some cells could not be covered")
    return tuple(p for p in CATALOG if p.number in chosen)
