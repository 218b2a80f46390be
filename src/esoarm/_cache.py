"""Where esoarm (and numba, for esoarm's kernels) keep compiled things: a writable place.

Compiled kernels are cached on disk: numba's (beside the sources, else in
``~/.cache/numba``), the fast engine's C kernel, the simavr harness and the
firmware builds (in esoarm's cache directory).  A service account or a
container often has a home directory it cannot write and the package installed
read-only; numba then stops with "cannot cache function …: no locator
available".  :func:`cache_dir` picks the first writable of

1. ``$ESOARM_CACHE_DIR`` (as given: an error later names it if it is not writable),
2. ``$XDG_CACHE_HOME/esoarm``, else ``~/.cache/esoarm``,
3. ``<temporary directory>/esoarm-<uid>`` (owned by the user, mode 700),

and :func:`configure_numba` points numba at ``<cache>/numba`` (through
``NUMBA_CACHE_DIR``) when neither of numba's own places can be written.  Light:
imported by ``import esoarm``, before numba is.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

__all__ = ["cache_dir", "configure_numba", "writable"]

_PACKAGE = Path(__file__).resolve().parent


def writable(path: Path) -> bool:
    """Whether files can be created in ``path``, or in the directory that would hold it.

    Parameters
    ----------
    path : Path
        A directory that may not exist yet.

    Returns
    -------
    bool
        True if ``path`` is a directory this process can write and enter, or
        if its nearest existing ancestor is one (``path`` can then be made).
    """
    import stat

    for cand in (path, *path.parents):
        try:
            mode = cand.stat().st_mode
        except FileNotFoundError:
            continue  # not there yet: could it be made in its parent?
        except OSError:  # a parent that cannot be entered, a loop, ...
            return False
        return stat.S_ISDIR(mode) and os.access(cand, os.W_OK | os.X_OK)
    return False  # pragma: no cover - the root always exists


def _user_cache_base() -> Path | None:
    xdg = os.environ.get("XDG_CACHE_HOME")
    if xdg:
        return Path(xdg)
    try:
        return Path.home() / ".cache"
    except RuntimeError:  # no HOME and no passwd entry
        return None


def _temp_cache() -> Path:
    import tempfile

    uid = os.getuid() if hasattr(os, "getuid") else 0
    path = Path(tempfile.gettempdir()) / f"esoarm-{uid}"
    try:
        path.mkdir(mode=0o700, exist_ok=True)
        st = path.stat()
        if (not hasattr(os, "getuid") or st.st_uid == uid) and writable(path):
            return path
    except OSError:
        pass
    # another user's directory of that name (or none possible): one of our own
    return Path(tempfile.mkdtemp(prefix=f"esoarm-{uid}-"))


def cache_dir() -> Path:
    """esoarm's cache directory (compiled kernels, the simavr harness, firmware builds).

    Returns
    -------
    Path
        ``$ESOARM_CACHE_DIR`` if set; else ``$XDG_CACHE_HOME/esoarm`` (or
        ``~/.cache/esoarm``) if it can be written; else a directory of this
        user's in the temporary directory.  Not created here.
    """
    env = os.environ.get("ESOARM_CACHE_DIR") or os.environ.get("ESOARM_CACHE")
    if env:
        return Path(env)
    base = _user_cache_base()
    if base is not None and writable(base / "esoarm"):
        return base / "esoarm"
    return _temp_cache()


def _numba_defaults_writable() -> bool:
    """Whether numba can cache esoarm's kernels without help.

    numba tries ``__pycache__`` beside each source file, then its user-wide
    directory (``$XDG_CACHE_HOME/numba`` or ``~/.cache/numba``); a kernel whose
    two places are both read-only cannot be compiled with ``cache=True``.
    """
    base = _user_cache_base()
    if base is not None and writable(base / "numba"):
        return True
    for folder, dirs, _files in os.walk(_PACKAGE):
        dirs[:] = [d for d in dirs if d != "__pycache__" and not d.startswith(".")]
        if not writable(Path(folder) / "__pycache__"):
            return False
    return True


def configure_numba() -> None:
    """Give numba a writable cache directory when its defaults are not writable.

    Sets ``NUMBA_CACHE_DIR`` to ``cache_dir()/numba`` unless the user set it,
    or numba can write beside esoarm's sources or in its user-wide directory.
    Call before numba is imported (``import esoarm`` does); if numba is already
    imported its configuration is updated too.
    """
    try:
        if os.environ.get("NUMBA_CACHE_DIR") or _numba_defaults_writable():
            return
        target = str(cache_dir() / "numba")
    except OSError:  # pragma: no cover - no temporary directory either: numba says so later
        return
    os.environ["NUMBA_CACHE_DIR"] = target
    config = sys.modules.get("numba.core.config")
    if config is not None:
        config.CACHE_DIR = target  # type: ignore[attr-defined]
