"""Keep numba's LLVM apart from the LLVM that Mesa loads into FreeCAD.

The core's kernels are compiled by numba, through llvmlite's
``libllvmlite.so``, which carries its own copy of LLVM.  On Debian 13 (and
wherever Mesa's OpenGL drivers are built on a shared ``libLLVM``), FreeCAD's
3D view loads the system's ``libLLVM.so.19`` first; the dynamic linker then
binds llvmlite's own LLVM calls to that other LLVM, and the first kernel
compiled inside FreeCAD crashes it (SIGSEGV in ``llvm::ValueHandleBase``,
seen in the GUI of FreeCAD 1.0 on llvmpipe and softpipe alike).

:func:`isolate` loads ``libllvmlite.so`` before llvmlite does, with
``RTLD_DEEPBIND``, so that the library binds to its own symbols first;
llvmlite's later ``ctypes.CDLL`` of the same file gets this handle.  It
imports only the standard library and never raises.
"""

from __future__ import annotations

import ctypes
import importlib.util
import os
import sys


def library() -> str | None:
    """The path of llvmlite's ``libllvmlite.so`` on ``sys.path``, or None."""
    try:
        spec = importlib.util.find_spec("llvmlite")
    except (ImportError, ValueError):
        return None
    if spec is None or not spec.origin:
        return None
    path = os.path.join(os.path.dirname(spec.origin), "binding", "libllvmlite.so")
    return path if os.path.isfile(path) else None


def isolate() -> str | None:
    """Preload llvmlite's library with ``RTLD_DEEPBIND``; its path, or None when not done.

    Not done (None) where the platform has no ``RTLD_DEEPBIND`` (not glibc
    Linux), where llvmlite is absent, or where llvmlite already loaded its
    library (too late to choose how; in FreeCAD this runs from ``Init.py``,
    first).
    """
    deep = getattr(os, "RTLD_DEEPBIND", None)
    if deep is None or "llvmlite.binding.ffi" in sys.modules:
        return None
    path = library()
    if path is None:
        return None
    try:
        ctypes.CDLL(path, mode=os.RTLD_NOW | deep)
    except OSError:
        return None
    return path
