"""Watch folder: model files that appear or change, once completely written.

A modeller (Blender with ``tools/blender/fabrickator_blender.py``, or any tool the user
exports from) writes a new version of the part into a folder; Fabrickator picks it up as
the next iteration.  The watcher polls (no platform file-notification API, so it behaves
the same on every system and inside FreeCAD's Qt timer):

* a file is *new or changed* when its (size, modification time) differs from what was last
  reported for that name;
* it is reported only once it is *complete*: the signature has stayed the same for
  :data:`SETTLE_S` seconds and the file parses as far as its format tells its end
  (:func:`is_complete`); an OBJ, whose end is not marked, must also stay the same for
  :data:`UNMARKED_SETTLE_S` seconds (a tool writing it in parts with longer pauses is
  picked up too early: write it aside and rename it);
* a file that stays the same for :data:`GIVE_UP_S` seconds more yet does not look complete
  is skipped until it changes, once, saying why (:func:`skip_reason`);
* hidden files (``.name``) and other suffixes (``.part``, ``.tmp``) are ignored, so a
  writer that writes aside and renames is picked up at the rename.

Which file is a version of which is one rule, :func:`model_name` and :func:`same_model`,
which the workbench's Watch folder command and :class:`Versions` (which earlier output the
CLI's ``watch`` iterates a new file on) follow: a file is a version of a model when it lies
in the same folder and its name, without the format suffix and without a version suffix
(:data:`VERSION_SUFFIX`), is the model's name, letter case aside.  So ``bracket.stl``,
``bracket_v1.stl``, ``Bracket_V2.stl``, ``bracket (1).stl`` and ``bracket.step`` are
versions of "bracket"; ``bracket2.stl`` is a model of its own.

:class:`FolderWatcher` does one scan per :meth:`~FolderWatcher.poll` (for a Qt timer);
:func:`watch` is the blocking generator the CLI ``watch`` command loops over.
"""

from __future__ import annotations

import os
import re
import struct
import time
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterator

from core.errors import InputError, check_path

#: Suffixes of the model files that are watched.
WATCHED_SUFFIXES = (".stl", ".obj", ".ply", ".3mf", ".step", ".stp")
#: Seconds a file's size and time must stay the same before it counts as written.
SETTLE_S = 1.0
#: Seconds a file of a format without an end marker (OBJ) must stay the same.
UNMARKED_SETTLE_S = 5.0
#: Formats whose end :func:`is_complete` cannot see.
UNMARKED_SUFFIXES = (".obj",)
#: Seconds between two scans of :func:`watch`.
POLL_S = 0.5
#: Seconds beyond its settle time a file must stay the same yet not look complete
#: (:func:`is_complete`) before it is skipped until it changes (said through ``on_skip``,
#: :func:`skip_reason`).
GIVE_UP_S = 5.0
#: What makes a file that reads as a model look incomplete, by suffix (:func:`is_complete`'s
#: tests).
INCOMPLETE_WHY = {
    ".stl": "neither a binary STL whose size matches its triangle count nor an ASCII STL "
            "ending with endsolid",
    ".step": "a STEP file must end with END-ISO-10303-21;",
    ".stp": "a STEP file must end with END-ISO-10303-21;",
    ".3mf": "a 3MF file must be a readable zip archive",
    ".ply": "not a PLY file holding the header and the vertices and faces it counts",
    ".obj": "an OBJ file must end with a line break and its faces refer to vertices it has",
}
#: A version suffix at the end of a file's stem, as modellers, exporters and file managers
#: append it: a separator (space, ``_``, ``-`` or ``.``), an optional ``v`` or ``rev`` and a
#: number, possibly dotted (``bracket_v2``, ``bracket.001``, ``bracket rev4``,
#: ``bracket_v1.2``); a copy number in parentheses (``bracket (1)``); or both.  Digits
#: without a separator belong to the name: ``gear2`` next to ``gear`` usually means a
#: second gear, and a renamed file is one rename away.
VERSION_SUFFIX = re.compile(r"(?:[ _.-](?:v|rev)?\d+(?:\.\d+)*)?(?: ?\(\d+\))?$", re.IGNORECASE)


def model_name(path: str | os.PathLike) -> str:
    """The name of the model the file at ``path`` is a version of: its stem without a
    version suffix (:data:`VERSION_SUFFIX`), letter case kept.

    ``bracket_v2.stl``, ``bracket-3.stl``, ``bracket (1).stl`` and ``bracket.stl``
    are all "bracket"; ``bracket2.stl`` is "bracket2".  A stem that is nothing but
    a version suffix (``_2.stl``) is its own name.
    """
    stem = Path(path).stem
    return VERSION_SUFFIX.sub("", stem, count=1) or stem


def model_key(path: str | os.PathLike) -> tuple[str, str]:
    """What the versions of one model share: (the file's folder, its :func:`model_name`
    case-folded).  A watcher keeps its last result per key (the CLI's ``watch``
    iterates a file on the output of the last file with the same key)."""
    p = Path(path)
    return os.path.normcase(os.path.abspath(p.parent)), model_name(p).casefold()


def same_model(a: str | os.PathLike, b: str | os.PathLike) -> bool:
    """Whether the files ``a`` and ``b`` are versions of one model: the same folder
    and the same :func:`model_name`, letter case aside (a file is a version of itself)."""
    return model_key(a) == model_key(b)


@dataclass
class Versions:
    """Which earlier result each new file of a watch iterates on: the result last
    :meth:`record`-ed for a version of the same model (:func:`model_key`).

    ``first`` (the CLI's ``--previous``) is what the first file of the watch iterates
    on; after that a file of a model not seen yet starts afresh.
    """

    first: str | os.PathLike | None = None
    _last: dict[tuple[str, str], str | os.PathLike] = field(default_factory=dict, init=False,
                                                           repr=False)

    def previous(self, path: str | os.PathLike) -> str | os.PathLike | None:
        """The result the file at ``path`` iterates on, or None for a fresh run."""
        if not self._last:
            return self.first
        return self._last.get(model_key(path))

    def record(self, path: str | os.PathLike, result: str | os.PathLike) -> None:
        """``result`` (an output folder) is the newest result of the model of ``path``."""
        self._last[model_key(path)] = result


def is_complete(path: str | os.PathLike) -> bool:
    """Whether the file at ``path`` looks completely written for its format.

    Binary STL: the size is 84 + 50 x the triangle count in its header.
    ASCII STL: it ends with an ``endsolid`` line.  STEP: it ends with
    ``END-ISO-10303-21;``.  3MF: a readable zip archive.  PLY: a whole
    header, and after it at least the vertices and faces it counts (ASCII:
    lines; binary: bytes, faces taken as triangles).  OBJ: ends with a line
    break, and every face refers to a vertex the file has (its end is not
    marked; the settle time decides the rest).  A file that cannot be read
    is not complete.
    """
    p = Path(path)
    try:
        size = p.stat().st_size
        if size == 0:
            return False
        suffix = p.suffix.lower()
        if suffix == ".stl":
            with p.open("rb") as f:
                head = f.read(84)
                if len(head) == 84 and size == 84 + 50 * struct.unpack("<I", head[80:84])[0]:
                    return True
                f.seek(max(0, size - 256))
                tail = f.read().rstrip().lower()
            return head[:5].lower() == b"solid" and b"endsolid" in tail.rsplit(b"\n", 1)[-1]
        if suffix in (".step", ".stp"):
            with p.open("rb") as f:
                f.seek(max(0, size - 256))
                return f.read().rstrip().endswith(b"END-ISO-10303-21;")
        if suffix == ".3mf":
            with zipfile.ZipFile(p) as archive:
                return archive.testzip() is None
        if suffix == ".ply":
            return _ply_complete(p.read_bytes())
        if suffix == ".obj":
            return _obj_complete(p.read_bytes())
        return True
    except (OSError, zipfile.BadZipFile, struct.error, ValueError, KeyError, IndexError):
        return False


_PLY_SIZES = {"char": 1, "uchar": 1, "int8": 1, "uint8": 1, "short": 2, "ushort": 2, "int16": 2,
              "uint16": 2, "int": 4, "uint": 4, "int32": 4, "uint32": 4, "float": 4,
              "float32": 4, "double": 8, "float64": 8}


def _ply_complete(data: bytes) -> bool:
    """Whether PLY ``data`` holds the whole header and at least what it counts."""
    end = data.find(b"end_header")
    if not data.startswith(b"ply") or end < 0:
        return False
    body = data[data.index(b"\n", end) + 1:] if b"\n" in data[end:] else b""
    header = data[:end].decode("ascii", "replace").split("\n")
    ascii_format, elements = False, []
    for line in (h.split() for h in header):
        if line[:1] == ["format"]:
            ascii_format = line[1] == "ascii"
        elif line[:1] == ["element"]:
            elements.append([int(line[2]), 0])
        elif line[:2] == ["property", "list"] and elements:
            elements[-1][1] += _PLY_SIZES[line[2]] + 3 * _PLY_SIZES[line[3]]
        elif line[:1] == ["property"] and elements:
            elements[-1][1] += _PLY_SIZES[line[1]]
    if ascii_format:
        return body.endswith(b"\n") and len(body.split(b"\n")) - 1 >= sum(n for n, _ in elements)
    return len(body) >= sum(n * size for n, size in elements)


def _obj_complete(data: bytes) -> bool:
    """Whether OBJ ``data`` ends with a line break and its faces refer to vertices it has."""
    if not data.endswith(b"\n"):
        return False
    vertices = len(re.findall(rb"(?m)^[ \t]*v[ \t]", data))
    for line in re.findall(rb"(?m)^[ \t]*f[ \t]([^\r\n#]*)", data):
        for corner in line.split():
            index = int(corner.split(b"/")[0])
            if index == 0 or abs(index) > vertices:
                return False
    return True


def skip_reason(path: str | os.PathLike, unchanged_s: float) -> str:
    """Why the file at ``path``, unchanged for ``unchanged_s`` seconds yet not complete
    (:func:`is_complete`), is skipped: the one line :func:`core.io.meshes.load_model` refuses
    it with, as ``fabricate`` prints it (``x.stl: not a valid STL file (...)``), or, when it
    reads as a model, what makes it look incomplete (:data:`INCOMPLETE_WHY`)."""
    from core.io import meshes as mesh_io

    p = Path(path)
    try:
        mesh_io.load_model(p)
    except InputError as err:
        return str(err)
    why = INCOMPLETE_WHY.get(p.suffix.lower(), "its end is missing")
    return f"{p.name}: unchanged for {unchanged_s:g} s but not a complete file: {why}"


@dataclass
class FolderWatcher:
    """Scans ``folder`` for new or changed model files (module docstring).

    Files present when the watcher is made count as already seen unless
    ``include_existing``.  Raises :class:`InputError` when ``folder`` is
    not a folder or cannot be read.
    """

    folder: Path
    suffixes: tuple[str, ...] = WATCHED_SUFFIXES
    settle_s: float = SETTLE_S
    include_existing: bool = False
    clock: Callable[[], float] = time.monotonic
    unmarked_settle_s: float = UNMARKED_SETTLE_S
    #: Called once with (path, why: :func:`skip_reason`, a line that names the file) for a
    #: file that stays the same yet never looks complete (:data:`GIVE_UP_S`): it is skipped
    #: until it changes.
    on_skip: Callable[[Path, str], None] | None = None
    _reported: dict[str, tuple[int, int]] = field(default_factory=dict, init=False, repr=False)
    _pending: dict[str, tuple[tuple[int, int], float]] = field(default_factory=dict, init=False,
                                                               repr=False)

    def __post_init__(self):
        self.folder = Path(self.folder)
        check_path(self.folder, "watch folder")     # a name too long, a loop of links: one line
        if not self.folder.is_dir():
            raise InputError(f"watch folder {self.folder} does not exist or is not a folder")
        self.suffixes = tuple(s.lower() for s in self.suffixes)
        present = dict(self._scan())            # InputError now when it cannot be read
        if not self.include_existing:
            self._reported = present

    def _scan(self) -> Iterator[tuple[str, tuple[int, int]]]:
        """(name, (size, mtime_ns)) of every watched file in the folder now."""
        try:
            entries = list(os.scandir(self.folder))
        except OSError as err:
            raise InputError(f"watch folder {self.folder} cannot be read: {err.strerror}") from None
        for entry in entries:
            if entry.name.startswith(".") or not entry.name.lower().endswith(self.suffixes):
                continue
            try:
                st = entry.stat()
            except OSError:
                continue
            if entry.is_file():
                yield entry.name, (st.st_size, st.st_mtime_ns)

    def poll(self) -> list[Path]:
        """One scan: the files that became complete since the last report, by name.

        A file is returned once per version: again only after it changes.
        """
        now = self.clock()
        ready = []
        seen = set()
        for name, signature in self._scan():
            seen.add(name)
            if self._reported.get(name) == signature:
                self._pending.pop(name, None)
                continue
            pending = self._pending.get(name)
            if pending is None or pending[0] != signature:
                self._pending[name] = (signature, now)
                continue
            settle = (max(self.settle_s, self.unmarked_settle_s)
                      if name.lower().endswith(UNMARKED_SUFFIXES) else self.settle_s)
            if now - pending[1] >= settle and is_complete(self.folder / name):
                self._reported[name] = signature
                del self._pending[name]
                ready.append(self.folder / name)
            elif now - pending[1] >= settle + GIVE_UP_S:
                self._reported[name] = signature
                del self._pending[name]
                if self.on_skip is not None:
                    self.on_skip(self.folder / name,
                                 skip_reason(self.folder / name, settle + GIVE_UP_S))
        for name in set(self._pending) - seen:
            del self._pending[name]
        return sorted(ready)


def watch(folder: str | os.PathLike, suffixes: tuple[str, ...] = WATCHED_SUFFIXES,
          settle_s: float = SETTLE_S, poll_s: float = POLL_S, include_existing: bool = False,
          stop: Callable[[], bool] | None = None, timeout_s: float | None = None,
          sleep: Callable[[float], None] = time.sleep,
          clock: Callable[[], float] = time.monotonic,
          on_skip: Callable[[Path, str], None] | None = None) -> Iterator[Path]:
    """An iterator over each model file of ``folder`` that appears or changes, once it is
    complete.

    Polls every ``poll_s`` seconds until ``stop()`` returns True or
    ``timeout_s`` seconds have passed (forever by default; a CLI ends it
    with Ctrl-C).  Raises :class:`InputError` at once (before the first
    file) when ``folder`` is not a folder or ``timeout_s`` is not a finite
    number above 0.
    """
    from core.request import timeout_seconds

    timeout_s = timeout_seconds(timeout_s)
    watcher = FolderWatcher(Path(folder), suffixes, settle_s, include_existing, clock,
                            on_skip=on_skip)
    return _polled(watcher, poll_s, stop, timeout_s, sleep, clock)


def _polled(watcher: FolderWatcher, poll_s: float, stop, timeout_s: float | None, sleep,
            clock) -> Iterator[Path]:
    """The files of :func:`watch`, one poll of ``watcher`` at a time."""
    start = clock()
    while True:
        yield from watcher.poll()
        if (stop is not None and stop()) or (timeout_s is not None and clock() - start >= timeout_s):
            return
        sleep(poll_s)
