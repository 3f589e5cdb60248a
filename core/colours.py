"""The one place that decides a brick's colour, for every output that shows or orders it.

Two palettes (the ``palette`` setting of :class:`core.request.Request`, the
workbench's "Brick colours" preference):

* ``"bom"`` (the default): every LEGO brick is drawn in the colour the bill
  of materials orders, :data:`BOM_COLOR` (LDraw 71, Light Bluish Grey, the
  neutral colour of most LEGO construction sets).  The FreeCAD 3D view,
  ``layout.png``, ``instructions.html``, ``bom.csv``, ``bricklink.xml`` and
  ``assembly.mpd`` all show what the user orders.
* ``"random"``: a *display aid* to tell bricks apart.  The 3D view and
  ``layout.png`` draw each LEGO brick in a colour of :data:`RANDOM_CODES`
  (real LEGO colours), face-adjacent bricks different where possible.  What
  the user orders and builds does not change: the bill of materials, the
  BrickLink list, the LDraw model and the instructions stay in
  :data:`BOM_COLOR` (one colour is cheaper and easier to buy and sort than
  a dozen; nobody expects a display setting to change a shopping list).

Printed parts keep their own colour everywhere: :data:`PRINTED_COLOR`
(LDraw 25, Orange), which is also what LDraw and the instructions use.

A colour is an LDraw colour code; :data:`COLORS` gives its LDraw name, its
BrickLink colour id and name and its RGB, so that every output names and
draws the same colour.  :func:`delta_e` measures how far apart two colours
look (CIE76 on CIELAB), used to keep highlights away from the palette and
from FreeCAD's selection colours.
"""

from __future__ import annotations

import numpy as np

from core.errors import InputError

#: LDraw colour code -> (LDraw name, BrickLink colour id, BrickLink name, RGB hex,
#: Rebrickable colour id) (LDraw's LDConfig.ldr, BrickLink's colour guide and Rebrickable's
#: colour list; Rebrickable numbers its solid colours as LDraw does).
COLORS = {
    71: ("Light Bluish Grey", 86, "Light Bluish Gray", "#A0A5A9", 71),
    25: ("Orange", 4, "Orange", "#FE8A18", 25),
    4: ("Red", 5, "Red", "#C91A09", 4),
    1: ("Blue", 7, "Blue", "#0055BF", 1),
    14: ("Yellow", 3, "Yellow", "#F2CD37", 14),
    2: ("Green", 6, "Green", "#237841", 2),
    322: ("Medium Azure", 156, "Medium Azure", "#36AEBF", 322),
    27: ("Lime", 34, "Lime", "#BBE90B", 27),
    320: ("Dark Red", 59, "Dark Red", "#720E0F", 320),
    19: ("Tan", 2, "Tan", "#E4CD9E", 19),
    73: ("Medium Blue", 42, "Medium Blue", "#5A93DB", 73),
    29: ("Bright Pink", 104, "Bright Pink", "#E4ADC8", 29),
    151: ("Sand Green", 48, "Sand Green", "#A0BCAC", 151),
    0: ("Black", 11, "Black", "#05131D", 0),
    15: ("White", 1, "White", "#FFFFFF", 15),
    72: ("Dark Bluish Grey", 85, "Dark Bluish Gray", "#6C6E68", 72),
    70: ("Reddish Brown", 88, "Reddish Brown", "#582A12", 70),
    28: ("Dark Tan", 69, "Dark Tan", "#958A73", 28),
    272: ("Dark Blue", 63, "Dark Blue", "#0A3463", 272),
    288: ("Dark Green", 80, "Dark Green", "#184632", 288),
    10: ("Bright Green", 36, "Bright Green", "#4B9F4A", 10),
    484: ("Dark Orange", 68, "Dark Orange", "#A95500", 484),
    191: ("Bright Light Orange", 110, "Bright Light Orange", "#F8BB3D", 191),
    226: ("Bright Light Yellow", 103, "Bright Light Yellow", "#FFF03A", 226),
    308: ("Dark Brown", 120, "Dark Brown", "#352100", 308),
    379: ("Sand Blue", 55, "Sand Blue", "#6074A1", 379),
    212: ("Bright Light Blue", 105, "Bright Light Blue", "#9FC3E9", 212),
    7: ("Light Grey", 9, "Light Gray", "#9BA19D", 7),
    8: ("Dark Grey", 10, "Dark Gray", "#6D6E5C", 8),
    6: ("Brown", 8, "Brown", "#583927", 6),
}

#: The colour the bill of materials orders for every LEGO brick (Light Bluish Grey).
BOM_COLOR = 71
#: The colour of printed parts (Orange), in every palette.
PRINTED_COLOR = 25
#: Colours of the random palette: real LEGO colours, neither the BOM grey nor the
#: printed orange, so that printed parts still stand out.
RANDOM_CODES = (4, 1, 14, 2, 322, 27, 320, 19, 73, 29, 151)

#: Palette name -> what the preferences page calls it.
PALETTES = {"bom": "BOM colours", "random": "random colours"}


def check_palette(palette: str) -> str:
    """``palette`` if it is one of :data:`PALETTES`, else InputError naming the choices."""
    if palette not in PALETTES:
        raise InputError(f"--palette {palette!r} must be one of {', '.join(PALETTES)}")
    return palette


def rebrickable_id(code: int) -> int:
    """Rebrickable colour id of LDraw colour ``code`` (one of :data:`COLORS`)."""
    return COLORS[code][4]


def from_ldraw(number: int) -> int | None:
    """The colour of LDraw code ``number``, or None where :data:`COLORS` does not know it."""
    return number if number in COLORS else None


def from_rebrickable(number: int) -> int | None:
    """The LDraw code of Rebrickable colour id ``number``, or None where unknown."""
    return next((c for c, row in COLORS.items() if row[4] == number), None)


def from_bricklink(number: int) -> int | None:
    """The LDraw code of BrickLink colour id ``number``, or None where unknown."""
    return next((c for c, row in COLORS.items() if row[1] == number), None)


def _words(text: str) -> str:
    return "".join(ch for ch in str(text).lower().replace("gray", "grey") if ch.isalnum())


def by_name(text: str) -> int:
    """The LDraw code of the colour called ``text``: its LDraw or BrickLink name (case,
    spaces and grey/gray do not matter) or its LDraw code; InputError naming a few choices
    otherwise."""
    word = _words(text)
    for code, row in COLORS.items():
        if word in (_words(row[0]), _words(row[2]), str(code)):
            return code
    raise InputError(f"--colour {text!r} is not a colour Fabrickator knows: use an LDraw or "
                     f"BrickLink name such as Light Bluish Grey, Black, White, Red")


def rgb(code: int) -> tuple[float, float, float]:
    """RGB (0..1) of LDraw colour ``code`` (one of :data:`COLORS`)."""
    text = COLORS[code][3].lstrip("#")
    return tuple(int(text[i:i + 2], 16) / 255.0 for i in (0, 2, 4))


def name(code: int) -> str:
    """LDraw name of colour ``code`` (one of :data:`COLORS`)."""
    return COLORS[code][0]


def bricklink_id(code: int) -> int:
    """BrickLink colour id of LDraw colour ``code`` (one of :data:`COLORS`)."""
    return COLORS[code][1]


def ordered_code(brick) -> int:
    """The LDraw colour a brick is ordered and built in: :data:`PRINTED_COLOR` for a
    printed brick, :data:`BOM_COLOR` for a LEGO brick (in every palette)."""
    return PRINTED_COLOR if brick.kind == "printed" else BOM_COLOR


def palette_codes(palette: str) -> tuple[int, ...]:
    """The colours ``palette`` may draw a LEGO brick in: (:data:`BOM_COLOR`,) or
    :data:`RANDOM_CODES`.  InputError for an unknown palette."""
    return RANDOM_CODES if check_palette(palette) == "random" else (BOM_COLOR,)


def display_codes(layout, palette: str = "bom", labels: np.ndarray | None = None,
                  colouring: dict | None = None) -> np.ndarray:
    """LDraw colour code (n_bricks,) each brick of ``layout`` is drawn in with ``palette``.

    ``"bom"``: :func:`ordered_code`.  ``"random"``: LEGO bricks take a colour
    of :data:`RANDOM_CODES` that their id hashes to unless a face-adjacent
    brick already took it (then the next free one), so neighbours differ
    where the palette allows; the same layout always gets the same colours.
    Printed bricks are :data:`PRINTED_COLOR` in both.  ``labels`` is
    ``layout.labels()`` when the caller has it.  With ``colouring`` (brick id -> (LDraw
    colour, owned), the maker's own bricks of :func:`core.inventory.colour`) ``"bom"`` draws
    each LEGO brick in its colour there.  InputError for an unknown palette.
    """
    check_palette(palette)
    n = len(layout.bricks)
    codes = np.array([ordered_code(b) if colouring is None or b.id not in colouring
                      else colouring[b.id][0] for b in layout.bricks], dtype=np.int64).reshape(n)
    if palette == "bom" or n == 0:
        return codes
    labels = layout.labels() if labels is None else labels
    pairs = []
    for axis in range(3):
        a = np.moveaxis(labels, axis, 0)
        lo, hi = a[:-1].ravel(), a[1:].ravel()
        keep = (lo >= 0) & (hi >= 0) & (lo != hi)
        pairs.append(np.stack([lo[keep], hi[keep]], axis=1))
    pairs = np.unique(np.concatenate(pairs + [np.empty((0, 2), np.int64)]), axis=0)
    pairs = np.concatenate([pairs, pairs[:, ::-1]])
    pairs = pairs[np.argsort(pairs[:, 0], kind="stable")]
    start = np.searchsorted(pairs[:, 0], np.arange(n + 1))
    m = len(RANDOM_CODES)
    choice = np.full(n, -1, dtype=np.int64)
    for b, brick in enumerate(layout.bricks):
        if brick.kind == "printed":
            continue
        taken = set(choice[pairs[start[b]:start[b + 1], 1]].tolist())
        wish = (brick.id * 2654435761) % (2 ** 32) % m
        free = [c for c in ((wish + s) % m for s in range(m)) if c not in taken]
        choice[b] = free[0] if free else wish
    lego = choice >= 0
    codes[lego] = np.asarray(RANDOM_CODES)[choice[lego]]
    return codes


def brick_colours(layout, palette: str = "bom", labels: np.ndarray | None = None,
                  colouring: dict | None = None) -> np.ndarray:
    """RGB (n_bricks, 3), 0..1, each brick of ``layout`` is drawn in with ``palette``
    (the colours of :func:`display_codes`, with ``colouring``)."""
    codes = display_codes(layout, palette, labels, colouring)
    table = {c: rgb(c) for c in set(codes.tolist())}
    return np.array([table[c] for c in codes.tolist()], dtype=float).reshape(len(codes), 3)


def _lab(colour) -> np.ndarray:
    """CIELAB (D65) of an sRGB colour (0..1)."""
    c = np.asarray(colour, dtype=float)[:3]
    lin = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    m = np.array([[0.4124, 0.3576, 0.1805], [0.2126, 0.7152, 0.0722], [0.0193, 0.1192, 0.9505]])
    xyz = m @ lin / np.array([0.95047, 1.0, 1.08883])
    f = np.where(xyz > (6 / 29) ** 3, np.cbrt(xyz), xyz / (3 * (6 / 29) ** 2) + 4 / 29)
    return np.array([116 * f[1] - 16, 500 * (f[0] - f[1]), 200 * (f[1] - f[2])])


def delta_e(a, b) -> float:
    """How different two sRGB colours (0..1) look: the CIE76 colour difference (about
    2.3 is just noticeable; above about 40 they are different colours at a glance)."""
    return float(np.linalg.norm(_lab(a) - _lab(b)))


#: The stress scale of the force check: utilisation 0 (no pull on any stud) is dark,
#: 1 (the clutch fully used) is red, above 1 (fails) and unsupported is white.
STRESS_DARK = (0.16, 0.17, 0.20)
STRESS_RED = (0.86, 0.08, 0.06)
STRESS_WHITE = (1.0, 1.0, 1.0)


def stress_rgb(utilisation) -> np.ndarray:
    """RGB (n, 3) in 0..1 of utilisations (n,): dark at 0 through red at 1; white above 1
    and for inf or NaN.  Between 0 and 1 the square root spreads the small values."""
    u = np.asarray(utilisation, dtype=float)
    t = np.sqrt(np.clip(np.nan_to_num(u, nan=0.0, posinf=0.0), 0.0, 1.0))[:, None]
    out = (1 - t) * np.array(STRESS_DARK) + t * np.array(STRESS_RED)
    out[~np.isfinite(u) | (u > 1.0)] = STRESS_WHITE
    return out
