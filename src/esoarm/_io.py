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
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

__all__ = ["OutputError", "atomic_path", "check_writable", "describe_os_error", "make_dir",
           "staged_dir"]


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


def _tmp_name(path: Path) -> Path:
    return path.with_name(f".{path.name}.{os.getpid()}.tmp")


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; rename it to ``path`` on success.

    The parent directory is created.  On any exception (Ctrl-C included) the
    temporary file is removed and ``path`` is left as it was; an
    :class:`OSError` (full disk, no permission, file-size limit, …) is raised
    again as :class:`OutputError` naming ``path``.  The temporary file is
    created by the writer itself, so it gets the usual permissions.

    Raises
    ------
    OutputError
        The file could not be written; nothing was left behind.
    """
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(path, describe_os_error(exc)) from None
    if path.is_dir():
        raise OutputError(path, "is a directory")
    tmp = _tmp_name(path)
    try:
        yield tmp
        os.replace(tmp, path)
    except OSError as exc:
        _remove(tmp)
        if isinstance(exc, OutputError):
            raise
        raise OutputError(path, describe_os_error(exc)) from None
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
    pseudo file systems such as ``/proc``.  Nothing is left behind.

    Raises
    ------
    OutputError
        The reason, naming ``path``.
    """
    path = Path(path)
    if directory:
        if path.exists() and not path.is_dir():
            raise OutputError(path, "exists and is not a directory")
    elif path.is_dir():
        raise OutputError(path, "is a directory, expected a file name")
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
