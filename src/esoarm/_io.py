"""Output files that appear only once complete, and one clear error when they cannot.

Every file esoarm writes (CSV tables and time series, figures, report pages)
goes through :func:`atomic_path`: the data is written to a temporary file
beside the target and renamed onto it only once complete.  Any failure -- a
directory that cannot be created or written, a full disk, a file-size limit,
Ctrl-C -- removes the temporary file, leaves the target as it was, and (for
operating-system errors) raises :class:`OutputError`, whose message is one
line naming the user's path, not the temporary one.

:func:`staged_dir` does the same for a directory of outputs (``esoarm
reproduce --out DIR``): the files are written into a temporary directory and
moved into DIR only once all of them are complete, so a failure halfway leaves
DIR as it was, not a directory that looks complete with files missing.

:func:`check_writable` tests a path before any work is done, so that a
command can reject an unwritable output path as bad input (exit status 2)
instead of failing after a long run.
"""

from __future__ import annotations

import errno
import os
import shutil
import stat
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

__all__ = ["OutputError", "atomic_path", "check_writable", "describe_os_error", "make_dir",
           "staged_dir", "target_file", "temp_name"]


class OutputError(OSError):
    """An output file or directory could not be written; the message is one line."""

    def __init__(self, path: str | Path, reason: str) -> None:
        super().__init__(f"cannot write '{path}': {reason}")
        self.path = Path(path)
        self.reason = reason

    def __str__(self) -> str:
        return str(self.args[0])


_REASONS = {
    errno.ENOSPC: "no space left on the device",
    errno.EDQUOT: "disk quota exceeded",
    errno.EFBIG: "file too large (the file-size limit, ulimit -f, was reached)",
    errno.EROFS: "the file system is read-only",
    errno.EACCES: "permission denied",
    errno.EPERM: "operation not permitted",
    errno.ENOTDIR: "a part of the path is a file, not a directory",
    errno.EISDIR: "is a directory",
    errno.ENOENT: "no file can be created there",
    errno.ENAMETOOLONG: "the file name is too long",
}


def describe_os_error(exc: OSError) -> str:
    """A short, user-facing reason for an operating-system error (no temporary paths)."""
    if exc.errno in _REASONS:
        return _REASONS[exc.errno]
    return exc.strerror or type(exc).__name__


#: Longest file name (one path component) in bytes on common file systems (ext4, xfs, tmpfs).
_NAME_MAX = 255


def temp_name(path: Path) -> Path:
    """The temporary file beside ``path`` (``.NAME.PID.tmp``; shorter when NAME is long)."""
    name = f".{path.name}.{os.getpid()}.tmp"
    if len(name.encode("utf-8", "surrogateescape")) > _NAME_MAX:
        name = f".esoarm.{os.getpid()}.tmp"
    return path.with_name(name)


def target_file(path: str | Path) -> Path:
    """The regular file that writing ``path`` replaces: a symbolic link is followed.

    An atomic write renames a new file onto its target; renamed onto a symbolic
    link it would replace the link, so the link's target is written instead
    (as a shell's ``>`` does).  A FIFO, a device or a socket cannot be replaced
    by a file without breaking what it is for: :class:`OutputError`.

    Raises
    ------
    OutputError
        ``path`` is a directory or a special file, or cannot be looked at.
    """
    path = Path(path)
    try:
        if path.is_symlink():
            path = Path(os.path.realpath(path))
        mode = path.stat().st_mode
    except (FileNotFoundError, NotADirectoryError):  # not there (yet): the caller says why
        return path
    except OSError as exc:
        raise OutputError(path, describe_os_error(exc)) from None
    if stat.S_ISDIR(mode):
        raise OutputError(path, "is a directory")
    if not stat.S_ISREG(mode):
        what = ("a FIFO (named pipe)" if stat.S_ISFIFO(mode) else
                "a socket" if stat.S_ISSOCK(mode) else "a device")
        raise OutputError(path, f"is {what}, not a regular file; give a file name")
    return path


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; rename it to ``path`` on success.

    The parent directory is created; a symbolic link is followed (its target
    is written, see :func:`target_file`).  On any exception (Ctrl-C included) the
    temporary file is removed and ``path`` is left as it was; an
    :class:`OSError` (full disk, no permission, file-size limit, …) is raised
    again as :class:`OutputError` naming ``path``.  The temporary file is
    created by the writer itself, so it gets the usual permissions.

    Raises
    ------
    OutputError
        The file could not be written; nothing was left behind.
    """
    user_path = Path(path)
    path = target_file(user_path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except (FileExistsError, NotADirectoryError):  # a file where a directory is needed
        raise OutputError(user_path, f"'{_file_in_the_way(path.parent)}' is a file, not a "
                          "directory") from None
    except OSError as exc:
        raise OutputError(user_path, describe_os_error(exc)) from None
    tmp = temp_name(path)
    try:
        yield tmp
        os.replace(tmp, path)
    except OSError as exc:
        _remove(tmp)
        if isinstance(exc, OutputError):
            raise
        raise OutputError(user_path, describe_os_error(exc)) from None
    except BaseException:
        _remove(tmp)
        raise


@contextmanager
def staged_dir(path: str | Path) -> Iterator[Path]:
    """Yield a new, empty temporary directory; move what was written there into ``path``.

    Write every output of a command into the yielded directory.  On success
    its contents are moved into ``path`` by renames only (no data is written
    then): when ``path`` does not exist the temporary directory itself is
    renamed to it; when it exists (results of an earlier run, other files),
    each new file replaces the one of the same name and other files are kept.
    On any exception (Ctrl-C included) the temporary directory is removed and
    ``path`` is left as it was; an :class:`OSError` is raised again as
    :class:`OutputError` naming the file under ``path`` (not the temporary one).

    The temporary directory is ``.NAME.PID.tmp`` beside a new ``path``, or
    ``.esoarm-partial.PID`` inside an existing one, so that the renames stay on
    one file system.

    Raises
    ------
    OutputError
        An output could not be written; ``path`` is as it was.
    """
    path = Path(path)
    existing = path.is_dir()
    if existing:
        tmp = path / f".esoarm-partial.{os.getpid()}"
    else:
        make_dir(path.absolute().parent)
        tmp = path.absolute().parent / f".{path.absolute().name}.{os.getpid()}.tmp"
    try:
        shutil.rmtree(tmp, ignore_errors=True)  # a leftover of a killed run with our pid
        tmp.mkdir()
    except OSError as exc:
        raise OutputError(path, describe_os_error(exc)) from None
    try:
        yield tmp
        if existing:
            _merge_into(tmp, path)
        else:
            try:
                os.rename(tmp, path)
            except OSError:  # something made path meanwhile: move the files into it
                make_dir(path)
                _merge_into(tmp, path)
    except OSError as exc:
        raise OutputError(_user_path(exc, tmp, path), _reason(exc)) from None
    finally:
        shutil.rmtree(tmp, ignore_errors=True)  # nothing left when all was moved


def _merge_into(src: Path, dst: Path) -> None:
    """Move the entries of ``src`` into the directory ``dst`` (renames), then remove ``src``."""
    for entry in sorted(src.iterdir()):
        target = dst / entry.name
        if entry.is_dir() and target.is_dir():
            _merge_into(entry, target)
        else:
            os.replace(entry, target)
    src.rmdir()


def _user_path(exc: OSError, tmp: Path, path: Path) -> Path:
    """The user's name of the file an error is about: under ``path`` rather than ``tmp``."""
    where = exc.path if isinstance(exc, OutputError) else Path(exc.filename or path)
    try:
        return path / Path(where).absolute().relative_to(tmp.absolute())
    except ValueError:  # not a file under tmp
        return path if not isinstance(exc, OutputError) else where


def _reason(exc: OSError) -> str:
    return exc.reason if isinstance(exc, OutputError) else describe_os_error(exc)


def _file_in_the_way(directory: Path) -> Path:
    """The nearest ancestor of ``directory`` (or itself) that exists: a file, when mkdir failed."""
    while not directory.exists() and directory.parent != directory:
        directory = directory.parent
    return directory


def make_dir(path: str | Path) -> Path:
    """Create a directory (and its parents); :class:`OutputError` naming it if that fails."""
    path = Path(path)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        raise OutputError(path, "exists and is not a directory") from None
    except OSError as exc:
        raise OutputError(path, describe_os_error(exc)) from None
    return path


def _remove(tmp: Path) -> None:
    try:
        tmp.unlink(missing_ok=True)
    except OSError:  # pragma: no cover - nothing more can be done
        pass


def check_writable(path: str | Path, *, directory: bool = False) -> None:
    """Check before any work that ``path`` (a file, or a directory) can be written.

    The nearest existing ancestor must be a directory in which a file (or, if
    directories are still to be made, a directory) can be created; the check
    creates and removes a probe there, so it also catches read-only and
    pseudo file systems such as ``/proc``.  An empty path, a name longer than
    the file system allows, and an existing FIFO, device or socket (which a
    new file would replace) are refused too.  Nothing is left behind.

    Raises
    ------
    OutputError
        The reason, naming ``path``.
    """
    if not str(path):
        raise OutputError(path, "an empty path; give a " + ("directory" if directory else "file")
                          + " name")
    path = Path(path)
    for name in path.parts:  # checked first: looking up a longer name fails
        size = len(name.encode("utf-8", "surrogateescape"))
        if size > _NAME_MAX:
            raise OutputError(path, f"a name in the path is too long ({size} bytes; file "
                              f"systems allow {_NAME_MAX})")
    try:
        _check_writable(path, directory)
    except OutputError as exc:
        if exc.path != path:  # a link's target, named by the user's path
            raise OutputError(path, exc.reason) from None
        raise
    except OSError as exc:  # a lookup that failed (e.g. a name too long for the system)
        raise OutputError(path, describe_os_error(exc)) from None


def _check_writable(path: Path, directory: bool) -> None:
    if directory:
        if path.exists() and not path.is_dir():
            raise OutputError(path, "exists and is not a directory")
    else:
        if path.is_dir():
            raise OutputError(path, "is a directory, expected a file name")
        target_file(path)  # a FIFO, a device: refused
        if path.is_symlink():
            path = Path(os.path.realpath(path))
    target_dir = path if directory else path.parent
    existing = target_dir
    while not existing.exists():
        if existing.parent == existing:
            break
        existing = existing.parent
    if existing.exists() and not existing.is_dir():
        raise OutputError(path, f"'{existing}' is a file, not a directory")
    try:
        if existing == target_dir:
            fd, probe = tempfile.mkstemp(prefix=".esoarm-probe-", dir=existing)
            os.close(fd)
            os.unlink(probe)
        else:
            os.rmdir(tempfile.mkdtemp(prefix=".esoarm-probe-", dir=existing))
    except OSError as exc:
        where = "" if existing == target_dir else f" (in '{existing}')"
        raise OutputError(path, describe_os_error(exc) + where) from None
