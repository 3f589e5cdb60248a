"""PrusaSlicer's answers kept by content, so an unchanged plate is never sliced twice.

A slice is fully decided by the meshes as they lie on the bed, the settings
they are sliced with and the slicer binary itself; :func:`key` hashes exactly
those (the vertices and faces in bed coordinates, the config text, the retry
settings, the binary's path, size and modification time).  :func:`get` and
:func:`put` read and write one small JSON file per key under :func:`folder`:
``$FABRICKATOR_CACHE`` when set (``none`` or an empty value: no cache), else
``$XDG_CACHE_HOME/fabrickator/slices``, else ``~/.cache/fabrickator/slices``.
The same folder serves the command line, ``watch`` and FreeCAD's recomputes.
A cache that cannot be read or written is passed over, never an error: it
only saves time.
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
from pathlib import Path

import numpy as np

#: Environment variable naming the cache folder, or ``none`` to switch the cache off.
CACHE_ENV = "FABRICKATOR_CACHE"

#: Bumped whenever what a cached answer holds, or what decides it, changes.
FORMAT = 1


def folder() -> Path | None:
    """The slice cache's folder (not necessarily existing yet), or None when it is off."""
    chosen = os.environ.get(CACHE_ENV)
    if chosen is not None:
        return None if chosen.strip().lower() in ("", "none") else Path(chosen).expanduser() / "slices"
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "fabrickator" / "slices"


def key(meshes, config_text: str, attempts, slicer: str) -> str:
    """The content hash of one slice: ``meshes`` as they lie on the bed, the config text
    they are sliced with, the retry ``attempts`` ((label, settings) pairs) and the binary."""
    digest = hashlib.sha256(f"fabrickator-slice {FORMAT}\n".encode())
    for mesh in meshes:
        vertices = np.ascontiguousarray(mesh.vertices, dtype=np.float64)
        faces = np.ascontiguousarray(mesh.faces, dtype=np.int64)
        digest.update(f"mesh {vertices.shape} {faces.shape}\n".encode())
        digest.update(vertices.tobytes())
        digest.update(faces.tobytes())
    digest.update(config_text.encode())
    digest.update(json.dumps([[label, settings] for label, settings in attempts],
                             sort_keys=True).encode())
    try:
        stat = os.stat(slicer)
        digest.update(f"{os.path.realpath(slicer)} {stat.st_size} {stat.st_mtime_ns}".encode())
    except OSError:
        digest.update(str(slicer).encode())
    return digest.hexdigest()


def get(slice_key: str) -> dict | None:
    """The answer stored under ``slice_key``, or None (no cache, not stored, unreadable)."""
    where = folder()
    if where is None:
        return None
    try:
        value = json.loads((where / f"{slice_key}.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return value if isinstance(value, dict) and value.get("format") == FORMAT else None


def put(slice_key: str, answer: dict) -> None:
    """Store ``answer`` (plain JSON data) under ``slice_key``, atomically; silently
    nothing when the cache is off or cannot be written."""
    where = folder()
    if where is None:
        return
    try:
        where.mkdir(parents=True, exist_ok=True)
        handle, name = tempfile.mkstemp(prefix=".put-", dir=where)
        with os.fdopen(handle, "w", encoding="utf-8") as out:
            json.dump({**answer, "format": FORMAT}, out)
        os.replace(name, where / f"{slice_key}.json")
    except OSError:
        return
