"""A job: the model to build and every setting of the run, with the one table of defaults.

:class:`Request` is what the command line, the watch command and the
FreeCAD workbench hand to the driver (:func:`core.pipeline.run`).  Its
fields' defaults are *the* defaults of Fabrickator: the CLI's options
(:func:`add_options`), the workbench's preferences and the Fabrication's
properties all read them from :data:`DEFAULTS`, so a default changes in
one place.  The stud and socket fit default to :class:`core.parts.interfaces.Fit`,
the table of the printed interfaces.
"""

from __future__ import annotations

import dataclasses
import math
import os
import re
from dataclasses import dataclass, field

from core.colours import by_name, check_palette
from core.errors import InputError
from core.model import UNITS, UP_AXES, Load
from core.parts.interfaces import Fit

#: How hard the layout is improved after the greedy pass (:mod:`core.layout.search`), cheapest first.
EFFORTS = ("fast", "normal", "best")

#: The --scale factors accepted: beyond them a model is nanometres or light years across.
SCALE_RANGE = (1e-6, 1e6)
#: A --load box is clipped to this reach (mm) on every side: a box of 1e308 mm means the
#: whole part, and its cell numbers must stay within 64-bit integers.
LOAD_REACH_MM = 1e12

def _setting(default, help: str, flag: str | None = None, metavar: str | None = None,
             off: str | None = None):
    """A Request field with its CLI help (``flag`` None: not a command-line option of its own;
    ``off``: the help of the ``--no-...`` switch of a setting that is on by default)."""
    return field(default=default, metadata={"help": help, "flag": flag, "metavar": metavar,
                                            "off": off})


@dataclass(frozen=True)
class Request:
    """Everything one run needs: the model file and the settings (all plain values).

    ``high_res`` are boxes ("X0,Y0,Z0,X1,Y1,Z1" strings, six numbers or
    (2, 3) arrays, model mm), ``high_res_solids`` region solid files (in
    ``units``/``scale``), ``high_res_bricks`` brick ids of the layout,
    ``part_edits`` merge/split edits ({"op", "boxes", "bricks"}).
    ``previous`` is an earlier output folder (or an unpacked snapshot) of
    the same object: the run is then an iteration on it.  With
    ``previous_regions`` the previous run's high-res regions stay marked and
    this request's regions add to them (the command line); without, only
    this request's regions count (the workbench, which sends all of its
    regions every time).  ``iterate_moved`` False lays the new version out
    anew where it stands when it was moved or turned against the previous
    one (the workbench, whose bricks stand at the Source); True iterates in
    the previous frame.  ``slicer`` None leaves the slicer to ``$FABRICKATOR_SLICER``,
    else ``prusa-slicer`` on PATH; ``"none"`` times prints by the calibrated estimate
    alone.  Build a Request, then :meth:`checked` it.
    """

    model: str = _setting("", "the model file")
    units: str = _setting("mm", "unit of the file's coordinates", "--units")
    scale: float = _setting(1.0, "extra scale factor applied after --units", "--scale", "S")
    up: str = _setting("z", "the model's axis that points up (z, y, x, -z, -y, -x): the model is "
                            "turned so that it points along +z before anything else; --high-res and "
                            "--load boxes are in the turned model's coordinates, as layout.json is",
                       "--up", "AXIS")
    seed: int = _setting(0, "seed of the layout (same seed, same layout)", "--seed", "N")
    parts: str | None = _setting(None, "brick set: all, plates, bricks, design numbers (3001,3024) "
                                       "or plate2x4-style names, comma-separated; must contain 3024",
                                 "--parts", "SET")
    high_res: tuple = _setting((), "box in model mm whose bricks become printed parts (repeatable; "
                                   "write --high-res=-5,... when it starts with a minus)",
                               "--high-res", "X0,Y0,Z0,X1,Y1,Z1")
    high_res_solids: tuple = _setting((), "region solid (STL/STEP/...) whose bricks become printed "
                                          "(repeatable)", "--high-res-solid", "FILE")
    high_res_bricks: tuple = _setting((), "brick ids of the layout that become printed")
    suggest: bool = _setting(False, "also mark the regions the suggest command finds (holes and "
                                    "pins under 20 mm, walls thinner than a cell), on top of "
                                    "--high-res", "--suggest")
    suggest_tolerance: float = _setting(0.5, "with --suggest: a feature whose loss under "
                                             "legofication (a hole's or pin's radius, a wall's "
                                             "thickness) is at most MM is not suggested",
                                        "--tolerance", "MM")
    suggest_speedup: float = _setting(1.5, "with --suggest: drop suggested regions, walls first, "
                                           "then the slowest to print, until printing the rest is "
                                           "estimated X times faster than printing the model whole "
                                           "(0 keeps them all)", "--min-speedup", "X")
    part_edits: tuple = _setting((), "merge/split edits of the printed parts")
    stud_fit: float = _setting(Fit.stud_fit, "printed studs are 4.8 + MM across (signed); find "
                                             "your printer's value with calibration-strip",
                               "--stud-fit", "MM")
    socket_fit: float = _setting(Fit.socket_fit, "printed sockets are 4.8 + MM between the walls a "
                                                 "real stud touches (signed, negative is tighter)",
                                 "--socket-fit", "MM")
    seconds_per_brick: float = _setting(10.0, "assembly estimate per LEGO brick placed",
                                        "--seconds-per-brick", "S")
    seconds_per_part: float = _setting(30.0, "assembly estimate per printed part inserted",
                                       "--seconds-per-part", "S")
    slice_parts: bool = _setting(True, "print-time the whole model and the printed parts with "
                                       "PrusaSlicer")
    connectors: bool = _setting(True, "give printed parts the studs and sockets they clamp with",
                                "--no-connectors", off="cut printed parts exactly, even where "
                                                       "that cuts the studs and sockets they "
                                                       "clamp with")
    fit_grid: bool = _setting(True, "shift the grid so that the high-res regions print the least",
                              "--no-grid-fit", off="keep the grid centred on the part instead of "
                                                   "shifting it so that the high-res regions "
                                                   "print the least")
    profile: str | None = _setting(None, "a PrusaSlicer ini to slice with instead of the installed slicer's presets")
    printer: str | None = _setting(None, "a printer preset of PrusaSlicer's installed vendor bundles "
                                         "to slice for, with its bed and height (python -m core "
                                         "printers lists them); default: Original Prusa i3 MK3S",
                                   "--printer", "NAME")
    print_preset: str | None = _setting(None, "a print preset compatible with --printer (default: "
                                              "one of 0.20 mm layers)", "--print-preset", "NAME")
    filament: str | None = _setting(None, "a filament preset compatible with --printer (default: "
                                          "a PLA)", "--filament", "NAME")
    fit_source: str = _setting("default", "where the stud and socket fit come from (the report "
                                          "says): default, given, or the fit saved for the printer")
    slicer: str | None = _setting(None, "the PrusaSlicer binary to time prints with (a name on PATH "
                                        "or a path), or none for the calibrated estimate only; "
                                        "default: $FABRICKATOR_SLICER, else prusa-slicer on PATH",
                                  "--slicer", "PATH|none")
    slicer_config: str | None = _setting(None, "a config PrusaSlicer exported (File > Export > "
                                               "Export Config), sliced with as it is, instead of "
                                               "--printer", "--slicer-config", "FILE.ini")
    previous: str | None = _setting(None, "an earlier --out of the same object: align, diff, keep "
                                          "its layout where nothing changed, reprint only changed "
                                          "parts (changes.html)", "--previous", "DIR")
    previous_regions: bool = _setting(True, "keep the previous run's high-res regions marked")
    iterate_moved: bool = _setting(True, "iterate on a moved or turned new version in the "
                                         "previous frame (else lay it out anew)")
    picture: bool = _setting(True, "render layout.png", "--no-picture",
                             off="do not render layout.png")
    hollow: int = _setting(-1, "keep a shell STUDS thick (--hollow alone: 2) and the pillars that "
                               "hold its roof; 0 builds solid; default: hollow parts of 50,000 "
                               "cells or more when that saves more than a third of the bricks",
                           "--hollow", "STUDS")
    effort: str = _setting("normal", "how hard the layout is optimised after the greedy pass: fast (the "
                                     "greedy layout only), normal (a few seconds for 2,000 cells) "
                                     "or best (up to a minute): fewer separate pieces, weak points "
                                     "and bricks", "--effort", "LEVEL")
    lower_bound: bool = _setting(False, "also solve the exact lower bound on the brick count (an "
                                        "integer program, up to 20 s), and the fewest bricks of a "
                                        "layout in one piece like this one (up to 20 s more), for "
                                        "report.json's layout_quality; without it the first bound "
                                        "is only computed when it costs no more than the layout",
                                 "--lower-bound")
    palette: str = _setting("bom", "brick colours of layout.png and the FreeCAD view: bom (the colour "
                                   "the parts list orders) or random (a LEGO colour per brick, to "
                                   "tell bricks apart; parts list, LDraw and instructions keep the "
                                   "parts list's colour)", "--palette", "NAME")
    ground: str = _setting("table", "what the build stands on for the force check: table (its "
                                    "bottom layer only presses down) or baseplate (its bottom "
                                    "layer is clamped to a LEGO baseplate)", "--ground", "table|baseplate")
    loads: tuple = _setting((), "a mass resting on the bricks a box touches (model mm), e.g. the "
                                "phone in a headset: X0,Y0,Z0,X1,Y1,Z1:GRAMS (repeatable)",
                            "--load", "X0,Y0,Z0,X1,Y1,Z1:GRAMS")
    inventory: tuple = _setting((), "the LEGO parts you own: a Rebrickable parts CSV, a BrickLink XML "
                                    "inventory or an LDraw .ldr/.mpd (repeatable, summed); the layout "
                                    "uses them first and buys only what they cannot do",
                                "--inventory", "FILE")
    inventory_only: bool = _setting(False, "build only from the --inventory parts, or stop naming "
                                           "the cells they cannot cover", "--inventory-only")
    colour: str = _setting("Light Bluish Grey", "colour of the bricks to buy (an LDraw or BrickLink "
                                                "name)", "--colour", "NAME")
    clutch_n: float = _setting(0.98, "tension one stud contact point holds, N (a LEGO stud is "
                                     "gripped at 3 points under 2-wide bricks, 4 under 1-wide)",
                               "--clutch", "N")

    @property
    def fit(self) -> Fit:
        """The stud and socket :class:`~core.parts.interfaces.Fit` of this request."""
        return Fit(stud_fit=float(self.stud_fit), socket_fit=float(self.socket_fit))

    def replace(self, **changes) -> "Request":
        """A copy with ``changes``; InputError naming an unknown setting."""
        unknown = sorted(set(changes) - set(DEFAULTS))
        if unknown:
            raise InputError(f"unknown setting(s): {', '.join(unknown)}")
        return dataclasses.replace(self, **changes)

    def checked(self) -> "Request":
        """This request with its values normalised (tuples, floats, str paths).

        Raises :class:`InputError` with one line naming the first setting
        out of range: units not in :data:`UNITS`, an up axis not in :data:`UP_AXES`, a hollow setting not in -1..64, scale not a positive finite
        number, a negative or non-integer seed, seconds not in [0, 1e6), a
        palette :func:`core.colours.check_palette` refuses, an effort not in
        :data:`EFFORTS`, ``inventory_only`` without an inventory, an empty
        ``slicer``, a ``colour``
        :func:`core.colours.by_name` does not know, a
        stud or socket fit :meth:`Fit.check` refuses (the units are checked
        where the model is loaded, :func:`core.io.meshes.load_model`).
        """
        if not self.model:
            raise InputError("no model file given")
        if self.units not in UNITS:
            raise InputError(f"--units {self.units!r} is not a unit: use one of {', '.join(UNITS)}")
        if self.up not in UP_AXES:
            raise InputError(f"--up {self.up!r} is not an axis: use one of {', '.join(UP_AXES)}")
        if not _number(self.scale) or not (math.isfinite(self.scale) and self.scale > 0):
            raise InputError(f"--scale {self.scale!r} must be a positive number")
        if not SCALE_RANGE[0] <= self.scale <= SCALE_RANGE[1]:
            raise InputError(f"--scale {self.scale!r} is out of range: use a factor from "
                             f"{SCALE_RANGE[0]:g} to {SCALE_RANGE[1]:g}")
        if self.parts is not None and not str(self.parts).replace(",", "").strip():
            raise InputError(f"--parts {self.parts!r} names no part: give a brick set (all, "
                             f"plates, bricks, 3001, plate2x4, ...) or leave the option out")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or not 0 <= self.seed < 2 ** 32:
            raise InputError(f"--seed {self.seed!r} must be a whole number from 0 to {2 ** 32 - 1}")
        for name in ("seconds_per_brick", "seconds_per_part"):
            value = getattr(self, name)
            if not _number(value) or not 0 <= value < 1e6:
                raise InputError(f"--{name.replace('_', '-')} {value!r} must be a number of "
                                 f"seconds >= 0")
        for name in ("stud_fit", "socket_fit"):
            if not _number(getattr(self, name)):
                raise InputError(f"--{name.replace('_', '-')} {getattr(self, name)!r} must be a "
                                 f"number of mm")
        self.fit.check()
        check_palette(self.palette)
        if self.ground not in ("table", "baseplate"):
            raise InputError(f"--ground {self.ground!r}: choose table or baseplate")
        if not _number(self.clutch_n) or not 0 < self.clutch_n < 1e3:
            raise InputError(f"--clutch {self.clutch_n!r} must be a force in N above 0")
        for load in self.loads:
            parse_load(load)
        if not _number(self.suggest_tolerance) or not 0 <= self.suggest_tolerance < 1e3:
            raise InputError(f"--tolerance {self.suggest_tolerance!r} must be a number of mm "
                             f"from 0 to 1000")
        if not _number(self.suggest_speedup) or not 0 <= self.suggest_speedup < 1e3:
            raise InputError(f"--min-speedup {self.suggest_speedup!r} must be a number from 0 "
                             f"to 1000")
        if isinstance(self.hollow, bool) or not isinstance(self.hollow, int) or not -1 <= self.hollow <= 64:
            raise InputError(f"--hollow {self.hollow!r} must be a whole number of studs from 0 "
                             "(solid) to 64, or -1 (automatic)")
        if self.effort not in EFFORTS:
            raise InputError(f"--effort {self.effort!r} must be one of {', '.join(EFFORTS)}")
        if self.slicer is not None and (not isinstance(self.slicer, (str, os.PathLike))
                                        or not os.fspath(self.slicer).strip()):
            raise InputError(f"--slicer {self.slicer!r} names no slicer: give a binary name or "
                             f"path, or none")
        if self.inventory_only and not self.inventory:
            raise InputError("--inventory-only needs the parts you own: give --inventory FILE")
        by_name(self.colour)
        return dataclasses.replace(
            self, model=os.fspath(self.model), scale=float(self.scale),
            high_res=tuple(self.high_res), high_res_solids=tuple(map(os.fspath, self.high_res_solids)),
            high_res_bricks=tuple(self.high_res_bricks), part_edits=tuple(self.part_edits),
            stud_fit=float(self.stud_fit), socket_fit=float(self.socket_fit),
            loads=tuple(str(x) for x in self.loads), clutch_n=float(self.clutch_n),
            suggest_tolerance=float(self.suggest_tolerance), suggest_speedup=float(self.suggest_speedup),
            inventory=tuple(map(os.fspath, self.inventory)),
            seconds_per_brick=float(self.seconds_per_brick),
            seconds_per_part=float(self.seconds_per_part),
            profile=None if self.profile is None else os.fspath(self.profile),
            printer=self.printer or None, print_preset=self.print_preset or None,
            filament=self.filament or None,
            slicer=None if self.slicer is None else _slicer_choice(self.slicer),
            slicer_config=os.fspath(self.slicer_config) if self.slicer_config else None,
            previous=None if self.previous is None else os.fspath(self.previous))


def parse_load(text) -> Load:
    """A :class:`Load` from ``"X0,Y0,Z0,X1,Y1,Z1:GRAMS"`` (a Load passes through).

    Raises :class:`InputError` naming the problem: not six numbers and a
    mass, a non-finite number, an empty box, a mass not > 0.
    """
    if isinstance(text, Load):
        return text
    match = re.fullmatch(r"\s*([^:]+):\s*([^:]+?)\s*", str(text))
    if not match:
        raise InputError(f"--load {text!r}: write X0,Y0,Z0,X1,Y1,Z1:GRAMS (a box in model mm and a mass)")
    try:
        box = [float(v) for v in match[1].split(",")]
        grams = float(match[2])
    except ValueError:
        raise InputError(f"--load {text!r}: the box and the mass must be numbers") from None
    if len(box) != 6:
        raise InputError(f"--load {text!r}: the box needs six numbers X0,Y0,Z0,X1,Y1,Z1, got {len(box)}")
    if not all(math.isfinite(v) for v in box + [grams]):
        raise InputError(f"--load {text!r}: numbers must be finite")
    if not grams > 0:
        raise InputError(f"--load {text!r}: the mass must be more than 0 g")
    lo, hi = [min(a, b) for a, b in zip(box[:3], box[3:])], [max(a, b) for a, b in zip(box[:3], box[3:])]
    if any(b - a <= 0 for a, b in zip(lo, hi)):
        raise InputError(f"--load {text!r}: the box is empty (each side must be longer than 0 mm)")
    lo, hi = ([min(max(v, -LOAD_REACH_MM), LOAD_REACH_MM) for v in side] for side in (lo, hi))
    if any(b - a <= 0 for a, b in zip(lo, hi)):
        raise InputError(f"--load {text!r}: the box lies farther than {LOAD_REACH_MM:g} mm away")
    return Load(tuple(float(v) for v in lo), tuple(float(v) for v in hi), grams)


def timeout_seconds(value, flag: str = "--timeout") -> float | None:
    """``value`` as a timeout in seconds: None stays None (no timeout); anything else must
    be a finite number above 0, else InputError naming ``flag``."""
    if value is None:
        return None
    if not _number(value) or value <= 0:
        raise InputError(f"{flag} {value!r} must be a number of seconds above 0 "
                         f"(leave it out to run until Ctrl-C)")
    return float(value)


def _slicer_choice(value) -> str:
    """A checked ``slicer`` setting: ``"none"`` in any case as ``"none"``, a binary as a str path."""
    text = os.fspath(value).strip()
    return "none" if text.lower() == "none" else text


def _number(value) -> bool:
    return not isinstance(value, bool) and isinstance(value, (int, float)) and math.isfinite(value)


#: The one table of defaults: setting name -> default value.
DEFAULTS = {f.name: f.default for f in dataclasses.fields(Request)}


def request(model, **settings) -> Request:
    """A checked :class:`Request` for ``model`` with ``settings`` (InputError for a bad one)."""
    return Request(model=model).replace(**settings).checked()


def add_options(parser, names, units=()) -> None:
    """Add the command-line options of the settings ``names`` to an argparse ``parser``.

    Each option's flag, help and default come from the Request field: a
    boolean setting whose default is True becomes a ``--no-...`` switch (one
    whose default is False a plain switch), ``effort`` a choice of :data:`EFFORTS`,
    a tuple setting a repeatable option; ``units`` are the unit names
    ``--units`` offers.
    """
    for f in dataclasses.fields(Request):
        if f.name not in names:
            continue
        flag, default, text = f.metadata["flag"], f.default, f.metadata["help"]
        if isinstance(default, bool):
            parser.add_argument(flag, dest=f.name, action="store_false" if default else "store_true",
                                help=f.metadata["off"] or text)
        elif isinstance(default, tuple):
            parser.add_argument(flag, dest=f.name, action="append", default=[],
                                metavar=f.metadata["metavar"], help=text)
        elif f.name == "hollow":
            parser.add_argument(flag, dest=f.name, type=int, nargs="?", const=2, default=default,
                                metavar=f.metadata["metavar"], help=text)
        elif f.name == "units":
            parser.add_argument(flag, dest=f.name, choices=sorted(units), default=default,
                                help=f"{text} (default {default})")
        elif f.name == "effort":
            parser.add_argument(flag, dest=f.name, choices=EFFORTS, default=default,
                                metavar=f.metadata["metavar"], help=f"{text} (default {default})")
        else:
            kind = {"seed": int}.get(f.name, float if isinstance(default, float) else str)
            shown = f"{default:+g}" if f.name.endswith("_fit") else f"{default:g}" if isinstance(default, float) else default
            parser.add_argument(flag, dest=f.name, type=kind, default=default,
                                metavar=f.metadata["metavar"],
                                help=text + ("" if default is None else f" (default {shown})"))


def from_options(args, model) -> Request:
    """The checked Request of parsed command-line ``args`` (from :func:`add_options`) for ``model``."""
    given = {f.name: getattr(args, f.name) for f in dataclasses.fields(Request)
             if f.name != "model" and hasattr(args, f.name)}
    return request(model, **given)
