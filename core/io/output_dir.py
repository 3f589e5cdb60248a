"""Output folders and scratch folders: checked before a run, written aside, installed whole.

Every command that writes a folder of results (``fabricate``, ``watch``,
``calibration-strip``, the workbench's export) goes through :class:`OutputFolder`:

1. **Before the run** (:meth:`OutputFolder.open`) the place is checked by doing what the
   end of the run will do: the parent folder is made, a lock is taken (``.NAME.lock``
   beside the output: a second run into the same folder is refused in one line while the
   first holds it), and the temporary folder the run writes into (``.NAME.part-PID-XXXX``,
   beside the output, so that installing it is a rename) is created.  An output that exists
   must be an earlier output (``earlier``: only files a run of the same kind writes), must
   not hold an input of the run (the model, a region file), and must be movable (it is
   renamed aside and back).  Anything refused is one :class:`~core.errors.InputError` line;
   nothing of the user's is touched.
2. **Installing** (:meth:`OutputFolder.install`) renames the earlier output aside
   (``.NAME.old-PID-XXXX``), renames the new one into place and then removes the old one;
   if the new one cannot be put in place the old one is renamed back.  Signals are held
   back during the renames.
3. **On any failure** (:meth:`OutputFolder.close`) the temporary folder is removed; a full
   disk, a read-only or vanished place while writing becomes one InputError line saying so.
   Parent folders the run made for nothing are removed again.

Leftovers of killed runs (``.NAME.part-*``, ``.NAME.old-*``) are cleaned up by the next run
into the same output, under its lock (an ``old`` folder is put back when the output itself
is missing).  Scratch folders in the system's temporary folder (:func:`scratch`) carry the
process id of their run; those of runs no longer alive are removed by the next
:func:`scratch` of the same kind.
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import json
import os
import re
import secrets
import shutil
import signal
import tempfile
import threading
from pathlib import Path
from typing import Callable, Iterable

from core.errors import InputError

#: Files that mark a folder as an output of the pipeline (and so safe to replace).
PIPELINE_MARKERS = ("report.json", "layout.json")
#: System folders whose files the kernel makes up: no place for an output.
SYSTEM_FOLDERS = ("/proc", "/sys", "/dev")
#: Tries at removing a scratch folder that files still appear in (a thread of the run
#: writing into it as the run ends).
SCRATCH_REMOVALS = 5
#: Longest output name used whole in the names of its temporary folders and lock.
TAG_CHARS = 64
#: Errors of the place written to (not of Fabrickator): reported in one line.
PLACE_ERRNOS = {errno.ENOSPC: "the disk is full", errno.EDQUOT: "the disk quota is used up",
                errno.EROFS: "the file system is read-only", errno.EACCES: "permission denied",
                errno.EPERM: "the operation is not permitted there", errno.EIO: "an input/output "
                "error of the disk", errno.EFBIG: "a file is too large for the file system",
                errno.ENAMETOOLONG: "a name is too long for the file system",
                errno.ENOENT: "the folder vanished while the run wrote into it",
                errno.ESTALE: "the network file system lost the folder"}

Earlier = Callable[[Path], "str | None"]


def pipeline_output(folder: Path) -> str | None:
    """None when ``folder`` is an earlier output of the pipeline (only the files its
    ``report.json`` lists under ``outputs``; an older output without that list: one
    with report.json or layout.json), else why not (one phrase)."""
    names = sorted(p.name for p in folder.iterdir())
    if not names:
        return None
    report = folder / "report.json"
    try:
        listed = (json.loads(report.read_text(encoding="utf-8")).get("outputs")
                  if report.is_file() else None)
    except (OSError, ValueError, AttributeError):
        listed = None
    if isinstance(listed, list):
        foreign = [n for n in names if n not in set(listed) | {"report.json"}]
    elif any(n in PIPELINE_MARKERS for n in names):
        foreign = []
    else:
        foreign = names
    return _foreign(foreign)


def files_output(*allowed: str) -> Earlier:
    """An ``earlier`` rule for an output of fixed file names: the folder holds only ``allowed``."""
    def rule(folder: Path) -> str | None:
        return _foreign([p.name for p in folder.iterdir() if p.name not in allowed])
    return rule


def _foreign(names: list[str]) -> str | None:
    if not names:
        return None
    shown = ", ".join(sorted(names)[:3]) + (f" and {len(names) - 3} more" if len(names) > 3 else "")
    return f"it holds other files that Fabrickator did not write ({shown})"


class OutputFolder:
    """The output folder ``out`` of one run (module docstring): use as a context manager.

    ``inputs`` are the files the run reads (they must not lie inside
    ``out``), ``earlier`` says whether an existing folder is an earlier
    output of this kind (:func:`pipeline_output`, :func:`files_output`),
    ``flag`` is how the messages name the option (``--out``).  Inside the
    ``with``, write into :attr:`temp`, then call :meth:`install`.
    """

    def __init__(self, out: str | os.PathLike, inputs: Iterable = (),
                 earlier: Earlier = pipeline_output, flag: str = "--out"):
        self.out = Path(os.path.abspath(os.fspath(out)))
        self.inputs = [Path(os.fspath(p)) for p in inputs if p]
        self.earlier = earlier
        self.flag = flag
        self.temp: Path | None = None
        self.installed = False
        self.notes: list[str] = []
        self._lock_fd: int | None = None
        self._made: list[Path] = []

    # --- before the run ---------------------------------------------------

    def __enter__(self) -> "OutputFolder":
        self.open()
        return self

    def __exit__(self, kind, exc, tb) -> None:
        ours = self._ours(exc)
        self.close()
        if ours:
            raise InputError(self._write_failure(exc)) from None

    def _ours(self, exc) -> bool:
        """Whether ``exc`` is a failure of the place written to: a full disk or quota, a
        read-only file system, an input/output error anywhere, or an error of a file in
        the output's folder."""
        if not isinstance(exc, OSError) or exc.errno not in PLACE_ERRNOS:
            return False
        if exc.errno in (errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EIO, errno.EFBIG):
            return True
        name = os.fspath(exc.filename) if isinstance(exc.filename, (str, os.PathLike)) else ""
        return bool(name) and os.path.abspath(name).startswith(str(self.out.parent) + os.sep)

    def open(self) -> "OutputFolder":
        """Check the place, take the lock, clean up after killed runs, make :attr:`temp`.

        Raises InputError (one line, nothing of the user's changed) for a
        place that cannot hold the output: a system folder, a name too long,
        a parent that is a file or cannot be made, an ``out`` that is a
        file, holds an input or other files, cannot be moved, or is being
        written by another run.
        """
        out, name = self.out, self.out.name
        try:
            self._check_place()
            self._make_parent()
            self._lock()
            self._clean_leftovers()
            if out.is_dir():
                why = self._inputs_inside() or self.earlier(out)
                if why:
                    raise InputError(f"{self.flag} {out} is a folder that is not an earlier output: "
                                     f"{why}; choose an empty or new folder")
                self._probe_move()
            self.temp = Path(tempfile.mkdtemp(prefix=f".{_tag(name)}.part-{os.getpid()}-",
                                              dir=out.parent))
            self.temp.chmod(0o755)
        except InputError:
            self.close()
            raise
        except OSError as err:
            self.close()
            raise InputError(f"{self.flag} {out}: cannot write into {out.parent}: "
                             f"{_reason(err)}") from None
        return self

    def _check_place(self) -> None:
        out = self.out
        real = os.path.realpath(out)
        for system in SYSTEM_FOLDERS:
            if real == system or real.startswith(system + "/"):
                raise InputError(f"{self.flag} {out} is inside {system}, a system folder the "
                                 f"operating system makes up: choose a folder of yours")
        if out.parent == out:
            raise InputError(f"{self.flag} {out} is the root folder: choose a folder inside it")
        longest = _name_max(out)
        if len(os.fsencode(out.name)) > longest:
            raise InputError(f"{self.flag} {out.name[:40]}...: the name is "
                             f"{len(os.fsencode(out.name))} bytes long, the file system allows "
                             f"{longest}")
        if out.is_symlink():
            raise InputError(f"{self.flag} {out} is a symbolic link: give the folder itself "
                             f"({os.path.realpath(out)})")
        if out.exists() and not out.is_dir():
            raise InputError(f"{self.flag} {out} exists and is not a folder")
        above = out.parent
        while not above.exists() and above.parent != above:
            above = above.parent
        if not above.is_dir():
            raise InputError(f"{self.flag} {out}: {above} is a file, not a folder")

    def _make_parent(self) -> None:
        missing = []
        above = self.out.parent
        while not above.exists():
            missing.append(above)
            above = above.parent
        for folder in reversed(missing):
            folder.mkdir()
            self._made.append(folder)

    def _lock(self) -> None:
        """Take ``.NAME.lock`` beside the output; InputError when another run holds it."""
        path = self.out.parent / f".{_tag(self.out.name)}.lock"
        while True:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
            if not _try_lock(fd):
                holder = os.read(fd, 32).decode("ascii", "replace").strip()
                os.close(fd)
                who = f" (process {holder})" if holder.isdigit() else ""
                raise InputError(f"{self.flag} {self.out} is being written by another run{who}: "
                                 f"wait until it ends or choose another folder")
            try:
                same = os.fstat(fd).st_ino == os.stat(path).st_ino
            except FileNotFoundError:
                same = False
            if same:
                break
            os.close(fd)          # the holder removed it as we opened it: take the new one
        os.ftruncate(fd, 0)
        os.write(fd, str(os.getpid()).encode())
        self._lock_fd, self._lock_path = fd, path

    def _clean_leftovers(self) -> None:
        """Under the lock: remove the temporary folders of killed runs into this output (their
        process is gone); an earlier output set aside by a run killed while installing is
        put back."""
        pattern = re.compile(rf"\.{re.escape(_tag(self.out.name))}\.(part|old)-(\d+)-[^/]*$")
        aside = []
        for entry in self.out.parent.iterdir():
            found = pattern.match(entry.name)
            if (not found or not entry.is_dir() or entry.is_symlink()
                    or (int(found[2]) != os.getpid() and _alive(int(found[2])))):
                continue
            if found[1] == "old":
                aside.append(entry)
            else:
                shutil.rmtree(entry, ignore_errors=True)
        if aside and not self.out.exists():
            newest = max(aside, key=lambda p: p.stat().st_mtime)
            os.rename(newest, self.out)
            aside.remove(newest)
            self.notes.append(f"put back the earlier output {self.out} that a killed run had "
                              f"set aside")
        for entry in aside:
            shutil.rmtree(entry, ignore_errors=True)

    def _inputs_inside(self) -> str | None:
        out = os.path.realpath(self.out)
        for path in self.inputs:
            real = os.path.realpath(path)
            if real.startswith(out + os.sep):
                return f"it holds {path}, an input of this run, which replacing it would delete"
        return None

    def _probe_move(self) -> None:
        """Rename the existing output aside and back: what installing will do."""
        aside = self.out.parent / f".{_tag(self.out.name)}.old-{os.getpid()}-probe"
        try:
            os.rename(self.out, aside)
        except OSError as err:
            raise InputError(f"{self.flag} {self.out}: the earlier output there cannot be "
                             f"replaced: {_reason(err)}") from None
        os.rename(aside, self.out)

    # --- the end of the run -----------------------------------------------

    def install(self) -> None:
        """Put :attr:`temp` in place of the output: the earlier output is renamed aside,
        the new one renamed in, the old one removed (when it cannot be, the next run
        into this output removes it).  When the new one cannot be put in place, the
        earlier output is renamed back and InputError says why."""
        if self.temp is None or self.installed:
            raise RuntimeError("install() needs an open OutputFolder that is not installed yet")
        aside = None
        with _signals_held():
            try:
                if self.out.exists():
                    aside = self.out.parent / (f".{_tag(self.out.name)}.old-{os.getpid()}-"
                                               f"{secrets.token_hex(4)}")
                    os.rename(self.out, aside)
                os.rename(self.temp, self.out)
            except OSError as err:
                if aside is not None and not self.out.exists():
                    with contextlib.suppress(OSError):
                        os.rename(aside, self.out)
                raise InputError(f"{self.flag} {self.out}: the new output cannot be put in place "
                                 f"({_reason(err)}); the earlier one is kept") from None
            self.temp, self.installed = None, True
        if aside is not None:
            shutil.rmtree(aside, ignore_errors=True)
            if aside.exists():
                self.notes.append(f"the earlier output, set aside in {aside}, could not be "
                                  f"removed entirely; the next run into {self.out} tries again")

    def close(self) -> None:
        """Remove :attr:`temp` unless installed, parent folders made for nothing, the lock."""
        if self.temp is not None:
            shutil.rmtree(self.temp, ignore_errors=True)
            self.temp = None
        if not self.installed:
            for folder in reversed(self._made):
                with contextlib.suppress(OSError):
                    folder.rmdir()
        self._made = []
        if self._lock_fd is not None:
            if os.name == "posix":
                with contextlib.suppress(OSError):
                    os.unlink(self._lock_path)
            os.close(self._lock_fd)
            self._lock_fd = None

    def _write_failure(self, err: OSError) -> str:
        where = f" ({err.filename})" if err.filename else ""
        return (f"{self.flag} {self.out}: the run could not finish, {PLACE_ERRNOS[err.errno]}"
                f"{where}; the unfinished output was removed and {self.out} is as it was")


def check_root(root: str | os.PathLike, flag: str = "--out",
               watched: str | os.PathLike | None = None) -> Path:
    """Check that the folder ``root`` (made when missing) can hold output folders, by making
    and removing a temporary folder in it; the root as an absolute Path.  InputError (one
    line) for a system folder, the root folder, the ``watched`` folder itself, a file, a
    folder holding anything but earlier outputs (:func:`pipeline_output`) and the locks and
    temporary folders of runs, a folder that cannot be made or written."""
    path = Path(os.path.abspath(os.fspath(root)))
    probe = OutputFolder(path / "probe", flag=flag)
    try:
        probe._check_place()
    except InputError as err:
        raise InputError(str(err).replace(str(path / "probe"), str(path))) from None
    if path.exists() and not path.is_dir():
        raise InputError(f"{flag} {path} exists and is not a folder")
    if path.parent == path:
        raise InputError(f"{flag} {path} is the root folder: choose a folder inside it")
    if watched is not None and os.path.realpath(path) == os.path.realpath(watched):
        raise InputError(f"{flag} {path} is the watched folder itself: choose another folder "
                         f"for the outputs")
    if path.is_dir():
        try:
            why = _foreign([p.name for p in path.iterdir() if not _root_entry(p)])
        except OSError as err:
            raise InputError(f"{flag} {path}: cannot read it: {_reason(err)}") from None
        if why:
            raise InputError(f"{flag} {path} is a folder that is not an earlier output root: "
                             f"{why}; choose an empty or new folder")
    try:
        path.mkdir(parents=True, exist_ok=True)
        os.rmdir(tempfile.mkdtemp(prefix=f".probe-{os.getpid()}-", dir=path))
    except OSError as err:
        raise InputError(f"{flag} {path}: cannot write into it: {_reason(err)}") from None
    return path


def _root_entry(entry: Path) -> bool:
    """Whether ``entry`` of an output root is ours: an earlier output folder, or the lock or
    a temporary folder of a run into one."""
    if re.fullmatch(r"\..+\.(lock|(part|old)-\d+-.*)|\.probe-\d+-.*", entry.name):
        return True
    try:
        return entry.is_dir() and not entry.is_symlink() and pipeline_output(entry) is None
    except OSError:
        return False


@contextlib.contextmanager
def scratch(kind: str):
    """A scratch folder ``<temporary folder>/fabrickator-<kind>-<pid>-XXXX`` for the ``with``
    block (removed after it, whatever happens; a file still held open is left to the next
    run).  Scratch folders of the same kind whose process is no longer alive (a killed run)
    are removed first."""
    prefix = f"fabrickator-{kind}-"
    clean_stale_scratch(prefix)
    folder = tempfile.mkdtemp(prefix=f"{prefix}{os.getpid()}-")
    try:
        yield folder
    finally:
        for _ in range(SCRATCH_REMOVALS):      # a thread still writing in it empties it late
            shutil.rmtree(folder, ignore_errors=True)
            if not os.path.lexists(folder):
                break


def clean_stale_scratch(prefix: str, where: str | os.PathLike | None = None) -> list[Path]:
    """Remove the folders ``<prefix><pid>-*`` in ``where`` (the temporary folder) that belong
    to this user and whose process ``pid`` is not alive; the ones removed."""
    if os.name != "posix":
        return []
    base = Path(where or tempfile.gettempdir())
    pattern = re.compile(rf"{re.escape(prefix)}(\d+)-")
    removed = []
    try:
        entries = list(base.iterdir())
    except OSError:
        return []
    for entry in entries:
        found = pattern.match(entry.name)
        try:
            if (not found or int(found[1]) == os.getpid() or entry.is_symlink() or not entry.is_dir()
                    or entry.stat().st_uid != os.getuid() or _alive(int(found[1]))):
                continue
        except OSError:
            continue
        shutil.rmtree(entry, ignore_errors=True)
        removed.append(entry)
    return removed


def _alive(pid: int) -> bool:
    """Whether a process ``pid`` exists (one of another user counts as alive).  False
    where it cannot be asked without harm (Windows' ``os.kill`` ends the process): the
    leftovers of an output are then cleaned on the lock alone."""
    if os.name != "posix":
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:
        return True
    return True


def _tag(name: str) -> str:
    """The output's name as its temporary folders and lock carry it: whole up to TAG_CHARS,
    else shortened with a hash (so that their names stay within the file system's limit)."""
    if len(name) <= TAG_CHARS:
        return name
    return name[:TAG_CHARS - 9] + "~" + hashlib.sha1(name.encode("utf-8", "surrogateescape")).hexdigest()[:8]


def _name_max(out: Path) -> int:
    """The longest file name (bytes) the file system of ``out``'s nearest folder allows."""
    above = out.parent
    while not above.exists() and above.parent != above:
        above = above.parent
    try:
        return int(os.pathconf(above, "PC_NAME_MAX"))
    except (OSError, ValueError, AttributeError):
        return 255


def _reason(err: OSError) -> str:
    return PLACE_ERRNOS.get(err.errno) or err.strerror or str(err)


def _try_lock(fd: int) -> bool:
    """Lock ``fd`` for this process without waiting; False when another holds it.  A file
    system without locks counts as locked by us."""
    try:
        if os.name == "posix":
            import fcntl
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        else:
            import msvcrt
            msvcrt.locking(fd, msvcrt.LK_NBLCK, 1)
    except (BlockingIOError, PermissionError):
        return False
    except OSError as err:
        if err.errno in (errno.EAGAIN, errno.EACCES, errno.EDEADLK):
            return False
    return True


@contextlib.contextmanager
def _signals_held():
    """Hold back SIGINT, SIGTERM and SIGHUP (delivered after the block) in the main thread."""
    held = {signal.SIGINT, signal.SIGTERM} | ({signal.SIGHUP} if hasattr(signal, "SIGHUP") else set())
    if not hasattr(signal, "pthread_sigmask") or threading.current_thread() is not threading.main_thread():
        yield
        return
    before = signal.pthread_sigmask(signal.SIG_BLOCK, held)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, before)
