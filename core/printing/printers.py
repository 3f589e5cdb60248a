"""The maker's printer: any printer preset of PrusaSlicer's vendor bundles, or a config it exported.

PrusaSlicer installs one vendor bundle per printer maker
(``/usr/share/PrusaSlicer/profiles/*.ini``, :mod:`core.printing.slicer_profile`
reads their format).  :func:`choose` finds a printer preset by name in any
of them and the print and filament presets the same bundle declares
compatible with it: a preset's ``compatible_printers`` list names the
printers it is for; where that list is empty, its
``compatible_printers_condition`` (a small expression language,
:func:`condition`) decides, and a filament's ``compatible_prints_condition``
is tested against the chosen print too.  By default the print is one of
0.20 mm layers and the filament a PLA.  :func:`from_file` takes a flat
config that PrusaSlicer itself exported, as it is.

:func:`chosen` is the printer of a request (None without ``printer`` and
``slicer_config``: the default MK3S profile of :mod:`core.printing.print_time`
stays as it is), and :func:`profile` the settings to slice with.
"""

from __future__ import annotations

import difflib
import functools
import os
import re
import shutil
from dataclasses import dataclass, field, replace
from pathlib import Path
from types import MappingProxyType

import numpy as np
import trimesh

from core.errors import InputError
from core.printing import print_time, slicer_profile
from core.printing.estimate import PrintEstimate
from core.printing.plate import ARRANGE_GAP_MM, build_volume
from core.printing.poses import candidate_poses

#: Where the vendor bundles lie when no slicer binary points to them (Debian's package).
DEFAULT_BUNDLES = Path("/usr/share/PrusaSlicer/profiles")

#: The layer height (mm) of the print preset chosen by default.
DEFAULT_LAYER_MM = 0.2

#: Words of a print preset's name preferred among the 0.20 mm ones, best first.
PRINT_WORDS = ("QUALITY", "NORMAL", "STANDARD", "OPTIMAL")

#: PrusaSlicer's own defaults of the keys conditions test, for presets that leave them out.
CONDITION_DEFAULTS = {"nozzle_diameter": "0.4", "printer_notes": "", "printer_model": "",
                      "single_extruder_multi_material": "0", "printer_technology": "FFF",
                      "nozzle_high_flow": "0"}

#: Keys a flat config must have to be one PrusaSlicer exported for an FFF printer.
FLAT_KEYS = ("layer_height", "bed_shape", "max_print_height", "nozzle_diameter")


class ConditionError(ValueError):
    """A compatibility condition that is not PrusaSlicer's expression language as parsed here."""


@dataclass(frozen=True)
class Printer:
    """A printer with its print and filament presets and the flat config they make.

    ``vendor`` and ``bundle_version`` name the bundle (``"Creality"``,
    ``"0.2.1"``); for a user's own config they are ``"user config"`` and
    None, and ``source`` is that file (else the bundle file).
    """

    printer: str
    print_preset: str
    filament: str
    vendor: str
    bundle_version: str | None
    source: str
    config: dict = field(compare=False, repr=False, default_factory=dict)

    @property
    def label(self) -> str:
        """``"printer, print preset, filament"`` for the instructions and the CLI."""
        return ", ".join(p for p in (self.printer, self.print_preset, self.filament) if p)

    def to_json(self) -> dict:
        return {"printer": self.printer, "print_preset": self.print_preset, "filament": self.filament,
                "vendor": self.vendor, "bundle_version": self.bundle_version, "source": self.source,
                "layer_height_mm": _float(self.config.get("layer_height")),
                "build_volume_mm": [round(float(v), 3) for v in build_volume(self.config)]}


# ----------------------------------------------------------------- conditions

_TOKEN = re.compile(r"""\s*(?:
    (?P<regex>/(?:[^/\\]|\\.)*/) |
    (?P<string>"(?:[^"\\]|\\.)*") |
    (?P<number>-?\d+(?:\.\d*)?|-?\.\d+) |
    (?P<name>[A-Za-z_]\w*(?:\[\d+\])?) |
    (?P<op>=~|!~|==|!=|>=|<=|&&|\|\||>|<|!|\(|\))
    )""", re.X)
_COMPARE = ("=~", "!~", "==", "!=", ">=", "<=", ">", "<")


def _tokens(text: str) -> list[tuple[str, str]]:
    out, pos = [], 0
    text = text.strip()
    while pos < len(text):
        match = _TOKEN.match(text, pos)
        if not match or match.end() == pos:
            raise ConditionError(f"cannot read {text[pos:pos + 20]!r} in condition {text!r}")
        kind = match.lastgroup
        value = match[kind]
        if kind == "name" and value in ("and", "or", "not"):
            kind = "op"
        value = {"&&": "and", "||": "or"}.get(value, value)
        out.append((kind, value))
        pos = match.end()
        while pos < len(text) and text[pos].isspace():
            pos += 1
    return out


@functools.lru_cache(maxsize=4096)
def condition(text: str):
    """The parsed condition ``text`` as a tree of tuples: ``("or", a, b)``, ``("and", a, b)``,
    ``("not", a)``, ``(op, left, right)`` for a comparison, ``("value", kind, text)`` for an
    operand.  An empty text is ``("true",)``.  Raises ConditionError for anything else."""
    tokens = _tokens(text)
    if not tokens:
        return ("true",)
    pos = 0

    def peek():
        return tokens[pos] if pos < len(tokens) else (None, None)

    def take():
        nonlocal pos
        pos += 1
        return tokens[pos - 1] if pos <= len(tokens) else (None, None)

    def either():
        left = both()
        while peek() == ("op", "or"):
            take()
            left = ("or", left, both())
        return left

    def both():
        left = unary()
        while peek() == ("op", "and"):
            take()
            left = ("and", left, unary())
        return left

    def unary():
        if peek() in (("op", "not"), ("op", "!")):
            take()
            return ("not", unary())
        if peek() == ("op", "("):
            take()
            inner = either()
            if take() != ("op", ")"):
                raise ConditionError(f"unbalanced parentheses in condition {text!r}")
            return inner
        left = operand()
        if peek()[0] == "op" and peek()[1] in _COMPARE:
            op = take()[1]
            return (op, left, operand())
        return left

    def operand():
        kind, value = take()
        if kind not in ("regex", "string", "number", "name"):
            raise ConditionError(f"expected a value, got {value!r} in condition {text!r}")
        return ("value", kind, value)

    tree = either()
    if pos != len(tokens):
        raise ConditionError(f"unexpected {tokens[pos][1]!r} in condition {text!r}")
    return tree


def plain(value: str) -> str:
    """A config value as text: outer double quotes removed and ``\\n`` made a newline."""
    value = value.strip()
    if len(value) >= 2 and value[0] == value[-1] == '"':
        value = value[1:-1].replace('\\"', '"')
    return value.replace("\\n", "\n")


def _lookup(name: str, config: dict[str, str]) -> str:
    match = re.fullmatch(r"(\w+)(?:\[(\d+)\])?", name)
    key, index = match[1], match[2]
    if key == "num_extruders":
        return str(len(config.get("nozzle_diameter", "").split(",")))
    if key not in config and key in CONDITION_DEFAULTS:
        config = {key: CONDITION_DEFAULTS[key]}
    if key not in config:
        raise ConditionError(f"the condition asks for {key}, which the config lacks")
    value = plain(config[key])
    if index is not None:
        items = value.split(",")
        value = items[int(index)] if int(index) < len(items) else ""
    return value


def _value(node, config: dict[str, str]) -> str:
    _, kind, text = node
    if kind == "name":
        return _lookup(text, config)
    if kind == "string":
        return text[1:-1].replace('\\"', '"')
    return text


def _float(text) -> float | None:
    try:
        return float(text)
    except (TypeError, ValueError):
        return None


def holds(tree, config: dict[str, str]) -> bool:
    """Whether the parsed condition ``tree`` (:func:`condition`) holds for ``config`` (raw
    values, as a bundle or a flat config has them).  ``=~`` matches the whole value
    against the regex (``.`` also matching newlines, as PrusaSlicer's boost regex does);
    comparisons are numeric when both sides are numbers, else of the text.  Raises
    ConditionError when it names a key the config lacks."""
    head = tree[0]
    if head == "true":
        return True
    if head == "or":
        return holds(tree[1], config) or holds(tree[2], config)
    if head == "and":
        return holds(tree[1], config) and holds(tree[2], config)
    if head == "not":
        return not holds(tree[1], config)
    if head == "value":
        text = _value(tree, config)
        number = _float(text)
        return number != 0 if number is not None else text.strip().lower() in ("true", "1")
    left, right = _value(tree[1], config), tree[2]
    if head in ("=~", "!~"):
        pattern = right[2][1:-1] if right[1] == "regex" else _value(right, config)
        found = re.fullmatch(pattern, left, re.S) is not None
        return found if head == "=~" else not found
    right = _value(right, config)
    a, b = _float(left), _float(right)
    if a is None or b is None:
        a, b = left, right
    return {"==": a == b, "!=": a != b, ">=": a >= b, "<=": a <= b, ">": a > b, "<": a < b}[head]


def _names(value: str) -> list[str]:
    """The names of a ``compatible_printers``-style list (``"A";"B"`` or ``A;B``)."""
    return [plain(v) for v in re.findall(r'"(?:[^"\\]|\\.)*"|[^;"]+', value) if plain(v).strip()]


def compatible(preset: dict[str, str], printer_name: str, printer: dict[str, str],
               print_config: dict[str, str] | None = None) -> bool:
    """Whether the resolved ``preset`` (print or filament) is one PrusaSlicer offers for the
    printer ``printer_name`` (its resolved config ``printer``): listed in its
    ``compatible_printers``, or, with that list empty, its ``compatible_printers_condition``
    holds; and for a filament with ``print_config`` given, its ``compatible_prints_condition``
    holds for that print.  A condition that cannot be evaluated makes it incompatible."""
    try:
        listed = _names(preset.get("compatible_printers", ""))
        if listed:
            ok = printer_name in listed
        else:
            ok = holds(condition(preset.get("compatible_printers_condition", "")), printer)
        prints = preset.get("compatible_prints_condition", "")
        if ok and print_config is not None and prints.strip():
            ok = holds(condition(prints), {**printer, **print_config})
        return ok
    except ConditionError:
        return False


# ----------------------------------------------------------------- bundles

@dataclass(frozen=True)
class Bundle:
    """One vendor bundle: its vendor name, config_version, file and sections.  ``templates``
    marks PrusaSlicer's template bundle (``templates_profile = 1``, Templates.ini): filaments
    offered to every printer whose conditions allow them, beside its own bundle's."""

    vendor: str
    version: str
    path: str
    sections: dict = field(compare=False, repr=False)
    templates: bool = False

    #: :meth:`resolved`'s answers so far, (kind, name) -> preset (a cache: the sections never change)
    resolved_presets: dict = field(default_factory=dict, compare=False, repr=False)

    def presets(self, kind: str) -> list[str]:
        """The names of the bundle's concrete (not ``*abstract*``) presets of ``kind``, in order."""
        return [name for k, name in self.sections if k == kind and not name.startswith("*")]

    def resolved(self, kind: str, name: str) -> MappingProxyType:
        """Preset ``[kind:name]`` with its ``inherits`` chain applied
        (:func:`core.printing.slicer_profile.resolve`), read-only; resolved once per bundle."""
        key = (kind, name)
        if key not in self.resolved_presets:
            self.resolved_presets[key] = MappingProxyType(slicer_profile.resolve(self.sections, kind, name))
        return self.resolved_presets[key]


def bundle_folder(slicer: str | None = None) -> Path | None:
    """The folder of the vendor bundles installed with the slicer a request's choice
    ``slicer`` names (:func:`core.printing.print_time.slicer_path`; ``prusa-slicer`` on
    PATH where that names none, also for ``"none"``), else DEFAULT_BUNDLES when it exists,
    else None."""
    binary = print_time.slicer_path(slicer) or shutil.which("prusa-slicer")
    found = slicer_profile.find_bundle(binary)
    if found is not None:
        return found.parent
    return DEFAULT_BUNDLES if (DEFAULT_BUNDLES / slicer_profile.VENDOR_BUNDLE).is_file() else None


def bundles(folder: str | os.PathLike | None) -> list[Bundle]:
    """Every vendor bundle (``*.ini``) in ``folder``, by file name; none for None.  Each file is
    parsed once per content (size and modification time) and process."""
    if folder is None:
        return []
    out = []
    for path in sorted(Path(folder).glob("*.ini")):
        stat = path.stat()
        out.append(_bundle(os.fspath(path), stat.st_size, stat.st_mtime_ns))
    return out


@functools.lru_cache(maxsize=64)
def _bundle(path: str, _size: int, _mtime: int) -> Bundle:
    text = Path(path).read_text(encoding="utf-8", errors="replace")
    vendor = re.search(r"^\[vendor\]\s*$(?:(?!^\[).)*?^name\s*=\s*(.+?)\s*$", text, re.M | re.S)
    templates = re.search(r"^\[vendor\]\s*$(?:(?!^\[).)*?^templates_profile\s*=\s*1\s*$", text, re.M | re.S)
    return Bundle(vendor[1] if vendor else Path(path).stem, slicer_profile.config_version(text), path,
                  slicer_profile.parse_bundle(text), templates is not None)


def fff_printers(bundle: Bundle) -> list[str]:
    """The bundle's concrete printer presets for filament printers (not SLA)."""
    return [name for name in bundle.presets("printer")
            if bundle.resolved("printer", name).get("printer_technology", "FFF") != "SLA"]


def listing(folder: str | os.PathLike | None) -> dict[str, list[tuple[str, list[float]]]]:
    """``vendor -> [(printer name, [x, y, z] build volume mm)]`` of every bundle in ``folder``."""
    out: dict[str, list] = {}
    for bundle in bundles(folder):
        for name in fff_printers(bundle):
            config = bundle.resolved("printer", name)
            try:
                size = [float(v) for v in build_volume(config)]
            except InputError:
                continue
            out.setdefault(bundle.vendor, []).append((name, size))
    return out


def listing_lines(folder: str | os.PathLike | None) -> list[str]:
    """The ``printers`` command's text: per vendor a heading with its bundle's version and
    file, then each printer's name and its build volume, x by y by z mm."""
    found = {b.vendor: b for b in bundles(folder)}
    lines = []
    for vendor, entries in listing(folder).items():
        bundle = found[vendor]
        lines.append(f"{vendor} (bundle {bundle.version}, {bundle.path})")
        width = max(len(name) for name, _ in entries)
        lines += [f"  {name:<{width}}  {' x '.join(f'{round(v, 1):g}' for v in size)} mm" for name, size in entries]
    return lines


def _unknown(what: str, name: str, names: list[str], hint: str) -> InputError:
    near = difflib.get_close_matches(name, names, n=3, cutoff=0.0)
    return InputError(f"unknown {what} {name!r}; nearest: {'; '.join(repr(n) for n in near) or 'none'}"
                      f" ({hint})")


def _rank_print(name: str, preset: dict, default: str) -> tuple:
    layer = _float(preset.get("layer_height")) or 0.0
    words = [n for n, word in enumerate(PRINT_WORDS) if word in name.upper()]
    return (round(abs(layer - DEFAULT_LAYER_MM), 3), name != default,
            words[0] if words else len(PRINT_WORDS), name)


def _rank_filament(name: str, preset: dict, defaults: list[str], own: set[str]) -> tuple:
    pla = plain(preset.get("filament_type", "")).upper() == "PLA"
    return (not pla, name not in defaults, name not in own, not name.startswith("Generic PLA"),
            not name.startswith("Prusament PLA"), name)


def _filaments(sources: list[Bundle], printer: str, machine: dict, print_config: dict) -> dict[str, dict]:
    """``name -> resolved preset`` (its ``inherits`` dropped) of the filaments of ``sources``
    compatible with the printer and print, a name of an earlier bundle kept first.  A
    filament G-code left bare empty (``start_filament_gcode =``, as Templates.ini has it) is
    written ``""``, a list of one empty template as PrusaSlicer exports it: PrusaSlicer 2.9
    reads the bare form as a list of none and fails on the G-code macro."""
    out: dict[str, dict] = {}
    for source in sources:
        for name in source.presets("filament"):
            if name not in out and compatible(f := source.resolved("filament", name),
                                              printer, machine, print_config):
                out[name] = {k: '""' if k.endswith("_gcode") and not v.strip() else v
                             for k, v in f.items() if k != "inherits"}
    return out


def choose(printer: str, print_preset: str | None = None, filament: str | None = None,
           folder: str | os.PathLike | None = None) -> Printer:
    """The printer preset ``printer`` of the bundles in ``folder`` (default:
    :func:`bundle_folder`) with ``print_preset`` and ``filament`` (default: the compatible
    print closest to DEFAULT_LAYER_MM layers, preferring the printer's own default and
    PRINT_WORDS; the compatible PLA the printer names as its default, else one of its own
    bundle, else a generic one; the template bundle's filaments are offered too, as
    PrusaSlicer does).  Raises InputError with the three nearest names for an unknown or
    incompatible name, and when no bundle is installed."""
    folder = bundle_folder() if folder is None else folder
    found = [(b, n) for b in bundles(folder) for n in fff_printers(b)]
    if not found:
        raise InputError(f"--printer {printer!r}: no PrusaSlicer vendor bundles found (install "
                         f"PrusaSlicer, or give --slicer-config FILE.ini)")
    match = [(b, n) for b, n in found if n == printer]
    if not match:
        raise _unknown("printer", printer, [n for _, n in found], "python -m core printers lists them")
    bundle, _ = match[0]
    sections = bundle.sections
    machine = bundle.resolved("printer", printer)
    prints = {n: p for n in bundle.presets("print")
              if compatible(p := bundle.resolved("print", n), printer, machine)}
    if not prints:
        raise InputError(f"--printer {printer!r}: its bundle {bundle.path} has no print preset for it")
    if print_preset is None:
        default = plain(machine.get("default_print_profile", ""))
        print_preset = min(prints, key=lambda n: _rank_print(n, prints[n], default))
    elif print_preset not in prints:
        raise _unknown(f"print preset for {printer}", print_preset, list(prints),
                       "choose one of the printer's compatible print presets")
    filaments = _filaments([bundle] + [b for b in bundles(folder) if b.templates and b != bundle],
                           printer, machine, prints[print_preset])
    if not filaments:
        raise InputError(f"--printer {printer!r}: its bundle {bundle.path} has no filament for it")
    if filament is None:
        defaults = _names(machine.get("default_filament_profile", ""))
        own = set(bundle.presets("filament"))
        filament = min(filaments, key=lambda n: _rank_filament(n, filaments[n], defaults, own))
    elif filament not in filaments:
        raise _unknown(f"filament for {printer}", filament, list(filaments),
                       "choose one of the printer's compatible filaments")
    presets = {"printer": printer, "print": print_preset, "filament": filament}
    sections = {**sections, ("filament", filament): filaments[filament]}
    try:
        config = slicer_profile.flat_profile(sections, presets)
    except slicer_profile.BundleError as exc:
        raise InputError(f"--printer {printer!r}: {bundle.path}: {exc}") from None
    return Printer(printer, print_preset, filament, bundle.vendor, bundle.version, bundle.path, config)


def from_file(path: str | os.PathLike) -> Printer:
    """The flat config PrusaSlicer exported to ``path``, as it is.  Raises InputError when the
    file cannot be read or is not such a config (a vendor bundle's ``[sections]``, or
    none of FLAT_KEYS, or a bed that build_volume cannot read)."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeError) as exc:
        raise InputError(f"--slicer-config {path}: cannot read it "
                         f"({getattr(exc, 'strerror', None) or exc})") from None
    if re.search(r"^\s*\[[^\]]+\]\s*$", text, re.M):
        raise InputError(f"--slicer-config {path}: holds [sections], not one flat config "
                         f"(export it from PrusaSlicer with File > Export > Export Config)")
    config = {key.strip(): value.strip() for key, value in
              (line.split("=", 1) for line in text.splitlines()
               if "=" in line and not line.lstrip().startswith(("#", ";")))}
    missing = [k for k in FLAT_KEYS if k not in config]
    if missing:
        raise InputError(f"--slicer-config {path}: not a PrusaSlicer config, it lacks "
                         f"{', '.join(missing)} (export one with File > Export > Export Config)")
    try:
        build_volume(config)
    except InputError:
        raise InputError(f"--slicer-config {path}: its bed_shape / max_print_height "
                         f"cannot be read") from None
    name = plain(config.get("printer_settings_id", "")) or Path(path).stem
    return Printer(name, plain(config.get("print_settings_id", "")),
                   plain(config.get("filament_settings_id", "")).split(";")[0].strip('"'),
                   "user config", None, os.fspath(Path(path).resolve()), config)


def chosen(req) -> Printer | None:
    """The printer of the request ``req`` (its ``printer``, ``print_preset``, ``filament``
    and ``slicer_config``; a printer's presets from the bundles of its ``slicer``,
    :func:`bundle_folder`), or None when it names none.  Raises InputError for a bad
    choice (also ``print_preset`` or ``filament`` without ``printer``, or both a printer
    and a config file)."""
    printer, config = getattr(req, "printer", None), getattr(req, "slicer_config", None)
    print_preset, filament = getattr(req, "print_preset", None), getattr(req, "filament", None)
    if printer and config:
        raise InputError("give --printer or --slicer-config, not both")
    if (print_preset or filament) and not printer:
        raise InputError("--print-preset and --filament choose presets of a --printer: name one")
    if config:
        stat = os.stat(config) if os.path.exists(config) else None
        return _from_file(os.fspath(config), stat and (stat.st_size, stat.st_mtime_ns))
    if printer:
        return _choose(printer, print_preset, filament,
                       os.fspath(bundle_folder(getattr(req, "slicer", None)) or ""))
    return None


def described(req) -> Printer:
    """The printer a run of ``req`` slices on: the chosen one (:func:`chosen`), else the
    default profile's (:func:`core.printing.print_time.load_profile`): a ``profile`` file
    given, the presets :data:`core.printing.slicer_profile.PRESETS` of the vendor bundle
    installed with the request's ``slicer``, or the committed fallback profile where there is
    none (also when slicing is off)."""
    printer = chosen(req)
    if printer is not None:
        return printer
    binary = print_time.slicer_path(getattr(req, "slicer", None))
    config = print_time.load_profile(req.profile, binary)
    names = [plain(config.get(k, "")) for k in ("printer_settings_id", "print_settings_id",
                                                 "filament_settings_id")]
    if req.profile:
        vendor, version, source = "user profile", None, os.fspath(Path(req.profile).resolve())
    else:
        bundle, version = slicer_profile.find_bundle(binary), None
        if bundle is not None:
            try:
                slicer_profile.bundle_profile(bundle)   # where this fails, the fallback is used
                version = slicer_profile.config_version(bundle.read_text(encoding="utf-8"))
            except (OSError, UnicodeError, slicer_profile.BundleError):
                bundle = None
        vendor = "Prusa Research" if bundle is not None else "fallback profile"
        source = os.fspath(bundle if bundle is not None else slicer_profile.FALLBACK_PROFILE)
    return Printer(names[0], names[1], names[2].split(";")[0].strip('"'), vendor, version, source,
                   config)


@functools.lru_cache(maxsize=16)
def _from_file(path: str, _stamp) -> Printer:
    return from_file(path)


@functools.lru_cache(maxsize=16)
def _choose(printer: str, print_preset, filament, folder: str) -> Printer:
    return choose(printer, print_preset, filament, folder or None)


def profile(req):
    """What :mod:`core.printing.print_time` slices ``req`` with: the chosen printer's flat config (a
    dict), else the request's ``profile`` file (None: the default profile)."""
    printer = chosen(req)
    return dict(printer.config) if printer is not None else req.profile


def check_plates(printer: Printer | None, beds, ids) -> None:
    """Raise InputError naming the first printed part that, in its print pose on ``beds``
    (:func:`core.printing.export.plates`; ``ids`` the parts' names by index), fits the build volume
    of the chosen ``printer`` in no way; nothing for the default printer (None)."""
    if printer is None:
        return
    volume = build_volume(printer.config)
    for items in beds:
        for index, mesh, _ in items:
            if not fits(mesh.extents, volume):
                size = " x ".join(f"{v:.0f}" for v in mesh.extents)
                room = " x ".join(f"{v:g}" for v in volume)
                raise InputError(f"printed part {ids[index]} ({size} mm in its print pose, studs "
                                 f"never down) does not fit the {printer.printer}'s build volume "
                                 f"{room} mm: mark a smaller region or choose a larger printer")


def fits(extents, volume) -> bool:
    """Whether a part of ``extents`` (x, y, z mm, as it stands) fits the build ``volume``,
    as it stands or turned a quarter about z."""
    extents, volume = np.asarray(extents, float), np.asarray(volume, float) + 1e-6
    return bool(extents[2] <= volume[2] and (np.all(extents[:2] <= volume[:2])
                                             or np.all(extents[1::-1] <= volume[:2])))


def fits_some_pose(mesh: trimesh.Trimesh, volume) -> bool:
    """Whether ``mesh`` fits the build ``volume`` in one of its :func:`core.printing.poses.candidate_poses`."""
    return any(fits(np.ptp(trimesh.transform_points(mesh.convex_hull.vertices, rotation), axis=0), volume)
               for _, rotation in candidate_poses(mesh))


def enlarged(config: dict[str, str], extents) -> dict[str, str]:
    """``config`` with a rectangular bed and a height large enough for a part of
    ``extents`` in any pose (its longest side, ARRANGE_GAP_MM spare on each side)."""
    volume = build_volume(config)
    side = float(np.max(extents)) + 2 * ARRANGE_GAP_MM
    x, y = max(volume[0], side), max(volume[1], side)
    return {**config, "bed_shape": f"0x0,{x:g}x0,{x:g}x{y:g},0x{y:g}",
            "max_print_height": f"{max(volume[2], side):g}"}


def reference_time(mesh: trimesh.Trimesh, workdir: str | os.PathLike, profile=None,
                   slicer: str | None = "auto") -> PrintEstimate:
    """The whole model's print time on the printer of ``profile``
    (:func:`core.printing.print_time.print_time`, its fastest pose); when it fits that printer's build volume in no candidate pose, the
    time as if the bed were large enough (:func:`enlarged`), marked ``enlarged_bed`` and
    so named in ``method``."""
    binary, _ = print_time.resolve_slicer(slicer)
    config = print_time.load_profile(profile, binary)
    volume = build_volume(config)
    if fits_some_pose(mesh, volume):
        return print_time.print_time([mesh], workdir, profile=profile, slicer=slicer)
    result = print_time.print_time([mesh], workdir, profile=enlarged(config, mesh.extents), slicer=slicer)
    size = " x ".join(f"{v:g}" for v in np.round(volume, 1))
    return replace(result, enlarged_bed=True,
                   method=f"{result.method}; the model fits the printer's {size} mm in no pose: "
                          f"timed as if the bed were large enough")
