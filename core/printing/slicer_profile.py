"""The PrusaSlicer settings Fabrickator slices with, read from the installed vendor bundle.

PrusaSlicer ships its printer, print and filament presets as a *vendor
bundle*, ``PrusaResearch.ini``, beside the binary (Debian:
``/usr/share/PrusaSlicer/profiles``; AppImage, Windows and macOS: the
``resources/profiles`` folder of the installation).  The bundle holds
presets as sections ``[TYPE:NAME]`` (TYPE is ``printer``, ``print`` or
``filament``; a NAME in ``*stars*`` is abstract), and a preset's ``inherits
= A; B`` lists parents of the same TYPE: the keys of A, then B override
them, then the preset's own keys override all.  The command line takes
only flat configs, so :func:`bundle_profile` resolves PRESETS (an MK3S,
0.20 mm QUALITY, Prusament PLA) that way from whichever version's bundle
is installed: PrusaSlicer 2.5 (bundle 1.5.x) and 2.9 (bundle 2.2.x) name
these presets alike and differ in many keys, and each slicer is given the
settings of its own bundle.

Where no bundle is found (no slicer installed, or one whose files are laid
out differently), FALLBACK_PROFILE stands in: the same presets resolved
from PrusaSlicer 2.5's bundle by ``tools/make_prusa_profile.py`` and
committed, so the estimate knows the bed and the support angle.
"""

from __future__ import annotations

import functools
import os
import re
from pathlib import Path

#: The committed flat profile used when no vendor bundle is installed.
FALLBACK_PROFILE = Path(__file__).resolve().parents[1] / "data" / "prusa_mk3s_0.20mm_quality_pla.ini"

#: File name of Prusa Research's vendor bundle.
VENDOR_BUNDLE = "PrusaResearch.ini"

#: The presets sliced with, by type.
PRESETS = {
    "printer": "Original Prusa i3 MK3S & MK3S+",
    "print": "0.20mm QUALITY @MK3",
    "filament": "Prusament PLA",
}

#: Where the bundle lies relative to the folder of the (symlink-resolved)
#: slicer binary: Debian and other FHS installs, the AppImage and Windows
#: layouts, macOS's app bundle.
BUNDLE_PLACES = (
    Path("..") / "share" / "PrusaSlicer" / "profiles",
    Path("..") / "resources" / "profiles",
    Path("resources") / "profiles",
    Path("..") / "Resources" / "profiles",
)

#: Keys that only steer the bundle's preset browser; they mean nothing to a
#: flat config (and print and filament would disagree on them).
BUNDLE_ONLY = {
    "inherits", "renamed_from", "alias",
    "compatible_printers", "compatible_printers_condition",
    "compatible_prints", "compatible_prints_condition",
}

SECTION = re.compile(r"^\[(?P<type>[^:\]]+):(?P<name>[^\]]+)\]\s*$")
_CONFIG_VERSION = re.compile(r"^config_version\s*=\s*(\S+)", re.M)


class BundleError(ValueError):
    """A vendor bundle lacks a preset Fabrickator needs, or its inheritance is broken."""


def parse_bundle(text: str) -> dict[tuple[str, str], dict[str, str]]:
    """Sections ``(type, name) -> {key: raw value}`` of a vendor bundle.

    Lines starting with ``#`` or ``;`` are comments; values are kept
    verbatim (escaped ``\\n`` and quotes as PrusaSlicer wrote them); a key
    repeated in one section keeps its last value.  Sections without a
    ``type:name`` header (``[vendor]``) are skipped.
    """
    sections: dict[tuple[str, str], dict[str, str]] = {}
    current: dict[str, str] | None = None
    for line in text.splitlines():
        stripped = line.strip()
        if not stripped or stripped[0] in "#;":
            continue
        if stripped.startswith("["):
            match = SECTION.match(stripped)
            current = None
            if match:
                current = sections.setdefault((match["type"], match["name"]), {})
            continue
        if current is not None and "=" in stripped:
            key, value = stripped.split("=", 1)
            current[key.strip()] = value.strip()
    return sections


def resolve(sections: dict[tuple[str, str], dict[str, str]], kind: str, name: str,
            _seen: tuple[str, ...] = ()) -> dict[str, str]:
    """All keys of preset ``[kind:name]`` with its ``inherits`` chain applied.

    Parents are applied left to right, then the preset's own keys; raises
    BundleError naming the preset that is missing (and which preset
    inherits it) or the inheritance cycle.
    """
    if name in _seen:
        raise BundleError(f"inheritance cycle {' -> '.join(_seen + (name,))} in the {kind} presets")
    own = sections.get((kind, name))
    if own is None:
        via = f" (inherited by {kind}:{_seen[-1]})" if _seen else ""
        raise BundleError(f"no preset [{kind}:{name}]{via}")
    merged: dict[str, str] = {}
    for parent in (p.strip() for p in own.get("inherits", "").split(";")):
        if parent:
            merged.update(resolve(sections, kind, parent, _seen + (name,)))
    merged.update(own)
    return merged


def flat_profile(sections: dict[tuple[str, str], dict[str, str]],
                 presets: dict[str, str] = PRESETS) -> dict[str, str]:
    """The union of the resolved presets, minus bundle-only keys.

    Also sets ``print_settings_id``, ``filament_settings_id`` and
    ``printer_settings_id`` to the preset names, as the GUI does (the MK3
    start and end G-code test them).  Raises BundleError when a preset is
    missing or two presets give one key different values.
    """
    flat: dict[str, str] = {}
    for kind, name in presets.items():
        values = {k: v for k, v in resolve(sections, kind, name).items() if k not in BUNDLE_ONLY}
        values[f"{kind}_settings_id"] = name
        for key, value in values.items():
            if key in flat and flat[key] != value:
                raise BundleError(f"{kind}:{name} sets {key} = {value!r}, another preset {flat[key]!r}")
            flat[key] = value
    return flat


def config_version(text: str) -> str:
    """The bundle's ``config_version`` ("1.5.1", "2.2.7"), or "?" when it names none."""
    match = _CONFIG_VERSION.search(text)
    return match[1] if match else "?"


def find_bundle(slicer: str | os.PathLike | None) -> Path | None:
    """The vendor bundle installed with the slicer binary ``slicer``, or None.

    Looks in BUNDLE_PLACES relative to the folder of the binary with its
    symlinks resolved (``/usr/bin/prusa-slicer`` finds
    ``/usr/share/PrusaSlicer/profiles/PrusaResearch.ini``).  The copies
    PrusaSlicer's configuration wizard keeps in the user's data folder are
    not used: the bundle shipped with a binary is the one it is known to read.
    """
    if not slicer:
        return None
    folder = Path(os.path.realpath(slicer)).parent
    for place in BUNDLE_PLACES:
        bundle = folder / place / VENDOR_BUNDLE
        if bundle.is_file():
            return bundle.resolve()
    return None


def bundle_profile(bundle: str | os.PathLike, presets: dict[str, str] = PRESETS) -> dict[str, str]:
    """The flat config of ``presets`` resolved from the vendor bundle file ``bundle``.

    Raises OSError when the file cannot be read and BundleError (naming the
    file) when it lacks a preset or an inherited one.  A bundle is parsed
    once per content (path, size and modification time) and process.
    """
    stat = os.stat(bundle)
    return dict(_bundle_profile(os.fspath(bundle), stat.st_size, stat.st_mtime_ns,
                                tuple(presets.items())))


@functools.lru_cache(maxsize=8)
def _bundle_profile(path: str, _size: int, _mtime_ns: int, presets: tuple) -> dict[str, str]:
    text = Path(path).read_text(encoding="utf-8")
    try:
        flat = flat_profile(parse_bundle(text), dict(presets))
    except BundleError as exc:
        raise BundleError(f"{path} (config_version {config_version(text)}): {exc}") from None
    return flat


def render(flat: dict[str, str], bundle: str | os.PathLike, version: str,
           presets: dict[str, str] = PRESETS) -> str:
    """The flat ini text: a header naming its origin, then ``key = value`` sorted by key."""
    header = [
        f"# generated by tools/make_prusa_profile.py from {bundle} (config_version {version})",
        *(f"# {kind}: {name}" for kind, name in presets.items()),
    ]
    return "\n".join(header + [f"{key} = {flat[key]}" for key in sorted(flat)]) + "\n"
