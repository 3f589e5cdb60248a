"""Errors a user can act on, and bugs reported as bugs.

:class:`InputError` is for the user's input only: a file, an option value,
a region, a brick set.  Its message is one line that names the problem;
the CLI prints it and exits with status 2.  A stage that finds a caller of
ours passing wrong data raises ValueError, TypeError or RuntimeError
instead: that is a bug in Fabrickator, not the user's fault.

For any exception that is not an InputError the CLI calls :func:`log_bug`
(the full traceback goes into a log file) and prints :func:`bug_message`
(one line naming that file), then exits with status 1.
"""

from __future__ import annotations

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
