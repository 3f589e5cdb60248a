"""Errors a user can act on, and bugs reported as bugs.

:class:`InputError` is for the user's input only: a file, an option value,
a region, a brick set.  Its message is one line that names the problem;
the CLI prints it and exits with status 2.  A stage that finds a caller of
ours passing wrong data raises ValueError, TypeError or RuntimeError
instead: that is a bug in Fabrickator, not the user's fault.

Memory that runs out is neither: the system refused it.  The CLI checks the
address-space limit (``ulimit -v``) before it loads any library
(:func:`address_space_shortage`), and any exception that says the memory ran
out (:func:`memory_shortage`) ends in one line, ``not enough memory: ...``,
and exit status 2.

For any other exception that is not an InputError the CLI calls :func:`log_bug`
(the full traceback goes into a log file) and prints :func:`bug_message`
(one line naming that file), then exits with status 1.
"""

from __future__ import annotations

import errno
import os
import platform
import sys
import tempfile
import time
import traceback
from pathlib import Path

#: Folder name of the bug logs inside the state (or temporary) folder.
LOG_FOLDER = "fabrickator"


class InputError(Exception):
    """Bad input: the message is one line that names the problem."""

    def __init__(self, message: str):
        super().__init__(" ".join(str(message).split()))


def shown_path(path, limit: int = 80) -> str:
    """``path`` as a one-line message shows it: whole up to ``limit`` characters, else its
    start and end around ``...`` (a 5,000-character name must not fill the terminal)."""
    text = os.fspath(path) if isinstance(path, (str, os.PathLike)) else str(path)
    if len(text) <= limit:
        return text
    return f"{text[:limit // 2 - 2]}...{text[-(limit - limit // 2 - 1):]}"


def check_path(path, flag: str) -> None:
    """InputError (one line naming ``flag``, the path shortened and the system's reason) when
    looking up the user-given ``path`` fails for a reason other than its absence, a file
    where a folder is expected or a permission: a name too long (ENAMETOOLONG), a loop
    of symbolic links (ELOOP), an input/output error...  Those three are left to the
    checks of each option, whose messages say more."""
    import errno

    try:
        os.stat(path)
    except OSError as err:
        if err.errno in (errno.ENOENT, errno.ENOTDIR, errno.EACCES, errno.EPERM):
            return
        raise InputError(f"{flag} {shown_path(path)}: {err.strerror or err}") from None
    except ValueError as err:                       # a NUL byte in the name
        raise InputError(f"{flag} {shown_path(path)!r}: {err}") from None


#: Address space (bytes) a command of the CLI takes to load its libraries and run a small
#: model, by command (anything else: ``"*"``): each command's peak on examples/build/hmd.step
#: with one OpenBLAS thread (core/__init__.py; OpenCascade, LLVM for numba, two OpenBLAS),
#: with some headroom.  Below such a limit the libraries fail in ways no
#: Python code sees: OpenBLAS (before 0.3.30) retries its buffer for ever while it is
#: being loaded, LLVM aborts a thread ("cannot allocate memory for thread-local data").
ADDRESS_SPACE_NEEDED = {"fabricate": 3 << 29, "watch": 3 << 29, "calibration-strip": 3 << 29,
                        "stability": 3 << 28, "*": 3 << 28}


def address_space_limit() -> int | None:
    """The address space (bytes) this process may map (``ulimit -v``, RLIMIT_AS), or None
    when it is not limited (or the system has no such limit)."""
    try:
        import resource
    except ImportError:                              # not a POSIX system
        return None
    soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    return None if soft == resource.RLIM_INFINITY else soft


def _mb(size: int) -> str:
    return f"{size / 2**20:,.0f} MB"


def address_space_shortage(command: str) -> str | None:
    """The one line (``not enough memory: ...``) saying that the address-space limit is
    below what ``command`` of the CLI needs (:data:`ADDRESS_SPACE_NEEDED`), or None when it
    is not.  Imports nothing beyond the standard library: it is checked before the
    libraries that would hang below the limit are loaded."""
    limit = address_space_limit()
    need = ADDRESS_SPACE_NEEDED.get(command, ADDRESS_SPACE_NEEDED["*"])
    if limit is None or limit >= need:
        return None
    what = "python -m core" + (f" {command}" if command in ADDRESS_SPACE_NEEDED else "")
    return (f"not enough memory: the address space is limited to {_mb(limit)} (ulimit -v "
            f"{limit // 1024}); {what} needs at least {_mb(need)} to load its libraries "
            f"(ulimit -v {need // 1024})")


def memory_shortage(exc: BaseException) -> str | None:
    """The one line (``not enough memory: ...``) for an exception that says the memory ran
    out, or None for any other.  Memory ran out when ``exc``, or an exception it was raised
    from or while handling, is a MemoryError, a library that could not be mapped (an
    ImportError or OSError saying "failed to map segment" or "cannot allocate memory",
    ENOMEM) or a thread that could not be started.  The line names what failed and the
    address-space limit when there is one."""
    seen: set[int] = set()
    what = None
    while exc is not None and id(exc) not in seen and what is None:
        seen.add(id(exc))
        first = next((line.strip() for line in str(exc).splitlines() if line.strip()), "")
        if isinstance(exc, MemoryError):
            what = f"MemoryError: {first}" if first else "MemoryError"
        elif isinstance(exc, (ImportError, OSError)) and (
                getattr(exc, "errno", None) == errno.ENOMEM
                or "failed to map segment" in first or "cannot allocate memory" in first.lower()):
            what = f"a library could not be loaded: {shown_path(first, 160)}"
        elif isinstance(exc, RuntimeError) and "can't start new thread" in first:
            what = "a thread could not be started"
        exc = exc.__cause__ or exc.__context__
    if what is None:
        return None
    limit = address_space_limit()
    return f"not enough memory: {what}" + (
        f" (the address space is limited to {_mb(limit)}: ulimit -v {limit // 1024})"
        if limit is not None else "")


def log_folders() -> list[Path]:
    """Where :func:`log_bug` tries to write, in order: ``$XDG_STATE_HOME/fabrickator``
    (when XDG_STATE_HOME is set to an absolute path), ``~/.local/state/fabrickator``,
    then ``<temporary folder>/fabrickator``."""
    folders = []
    state = os.environ.get("XDG_STATE_HOME", "")
    if os.path.isabs(state):
        folders.append(Path(state) / LOG_FOLDER)
    home = Path(os.path.expanduser("~"))
    if home.is_absolute():
        folders.append(home / ".local" / "state" / LOG_FOLDER)
    folders.append(Path(tempfile.gettempdir()) / LOG_FOLDER)
    return folders


def log_bug(exc: BaseException, context: str) -> Path:
    """Write ``exc``'s full traceback into a new log file and return the file's path.

    The file, ``bug-<UTC time>-<pid>.log`` in the first of :func:`log_folders`
    that can be written, holds ``context`` (what was running, e.g. the
    command), Fabrickator's version, Python's version and executable, the
    platform, ``sys.argv`` and the traceback with its chained causes.  Each
    call makes its own file; nothing is overwritten.  Raises OSError only
    when no folder at all can be written.
    """
    from core import __version__

    lines = [
        f"context: {context}",
        f"time: {time.strftime('%Y-%m-%dT%H:%M:%SZ', time.gmtime())}",
        f"fabrickator: {__version__}",
        f"python: {sys.version.split()[0]} ({sys.executable})",
        f"platform: {platform.platform()}",
        f"argv: {sys.argv!r}",
        "",
        *traceback.format_exception(type(exc), exc, exc.__traceback__),
    ]
    text = "\n".join(line.rstrip("\n") for line in lines) + "\n"
    stamp = time.strftime("%Y%m%dT%H%M%SZ", time.gmtime())
    failure: OSError | None = None
    for folder in log_folders():
        try:
            folder.mkdir(parents=True, exist_ok=True)
            path = folder / f"bug-{stamp}-{os.getpid()}.log"
            n = 1
            while path.exists():
                n += 1
                path = folder / f"bug-{stamp}-{os.getpid()}-{n}.log"
            with open(path, "x", encoding="utf-8") as stream:
                stream.write(text)
            return path
        except OSError as err:
            failure = err
    raise OSError(f"cannot write a bug log into any of {[str(f) for f in log_folders()]}") from failure


def bug_message(exc: BaseException, log_path: str | os.PathLike) -> str:
    """The one line the CLI prints for a bug: ``bug: <ExcType>: <first line of
    the message> — this is a bug in Fabrickator, not your input; the traceback
    is in <log_path>; please report it``.  One line: of a message of several
    lines only the first (non-blank) one is used."""
    first = next((line.strip() for line in str(exc).splitlines() if line.strip()), "")
    what = f"{type(exc).__name__}: {first}" if first else type(exc).__name__
    return (f"bug: {what} — this is a bug in Fabrickator, not your input; "
            f"the traceback is in {os.fspath(log_path)}; please report it")


def bug_line(exc: BaseException, context: str) -> str:
    """The one line for a bug: :func:`bug_message` naming the log :func:`log_bug` wrote, or,
    when no log folder can be written (a full disk, a read-only home), the same line
    saying that instead.  Never raises."""
    try:
        return bug_message(exc, log_bug(exc, context))
    except OSError as err:
        first = next((line.strip() for line in str(exc).splitlines() if line.strip()), "")
        what = f"{type(exc).__name__}: {first}" if first else type(exc).__name__
        return (f"bug: {what} — this is a bug in Fabrickator, not your input; no log of it "
                f"could be written ({err.__cause__ or err}); please report it")
