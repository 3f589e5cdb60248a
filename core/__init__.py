"""Fabrickator core: everything that does not need FreeCAD.

Stages (one module each), passing plain data from :mod:`core.model`:

``mesh_io`` (load and repair a model) → ``voxelize`` (legofy into a
:class:`~core.model.Grid`) → ``layout`` (merge 1x1 plates into catalog
parts, a :class:`~core.model.Layout`) → ``stability`` (connectivity graph,
components, weak points).  ``pipeline.fabricate`` runs them all; the CLI
(``python -m core``) wraps it.
"""

__version__ = "0.1.0"


def _writable_caches() -> None:
    """Point numba's cache (``cache=True`` kernels) and matplotlib's configuration and font
    cache at per-user folders in the temporary folder when their usual places cannot be
    written (a read-only install run by a user without a home): numba would fail with
    "cannot cache function ... no locator available", matplotlib print warnings.  Runs
    before any module of the package imports them; NUMBA_CACHE_DIR and MPLCONFIGDIR set
    by the user are kept."""
    import os
    import tempfile

    def writable(folder: str) -> bool:
        probe = folder
        while not os.path.isdir(probe) and os.path.dirname(probe) != probe:
            probe = os.path.dirname(probe)          # the nearest folder that exists
        return os.path.isabs(folder) and os.access(probe, os.W_OK | os.X_OK)

    home = os.path.expanduser("~")
    cache = os.environ.get("XDG_CACHE_HOME") or os.path.join(home, ".cache")
    config = os.environ.get("XDG_CONFIG_HOME") or os.path.join(home, ".config")
    wanted = (("NUMBA_CACHE_DIR", "numba", (os.path.join(os.path.dirname(os.path.abspath(__file__)),
                                                         "__pycache__"),
                                            os.path.join(cache, "numba"))),
              ("MPLCONFIGDIR", "matplotlib", (os.path.join(config, "matplotlib"),)))
    uid = os.getuid() if hasattr(os, "getuid") else 0
    for variable, name, usual in wanted:
        if os.environ.get(variable) or any(writable(folder) for folder in usual):
            continue
        fallback = os.path.join(tempfile.gettempdir(), f"fabrickator-{name}-cache-{uid}")
        try:
            os.makedirs(fallback, mode=0o700, exist_ok=True)
            st = os.lstat(fallback)
            if os.path.islink(fallback) or not os.path.isdir(fallback) or (
                    hasattr(os, "getuid") and (st.st_uid != uid or st.st_mode & 0o022)):
                fallback = tempfile.mkdtemp(prefix=f"fabrickator-{name}-cache-")  # not ours
        except OSError:
            continue
        os.environ[variable] = fallback


def _blas_threads() -> None:
    """One OpenBLAS thread, unless the user chose a number (OPENBLAS_NUM_THREADS,
    GOTO_NUM_THREADS or OMP_NUM_THREADS set): numpy's and scipy's OpenBLAS would each start
    a thread per core, each with a 32 MB buffer and a stack, address space that a limit
    (``ulimit -v``) counts (core.errors.ADDRESS_SPACE_NEEDED is measured with one), for
    linear algebra on 3 x 3 matrices that no thread speeds up.  Runs before numpy is
    imported; where numpy already is (FreeCAD), it changes nothing."""
    import os

    if not any(os.environ.get(variable) for variable in
               ("OPENBLAS_NUM_THREADS", "GOTO_NUM_THREADS", "OMP_NUM_THREADS")):
        os.environ["OPENBLAS_NUM_THREADS"] = "1"


_writable_caches()
_blas_threads()
