"""Where numba keeps compiled kernels, so that a read-only installation still runs.

numba caches a ``cache=True`` function beside its module (``__pycache__``), else in the user's cache folder
(``~/.cache/numba``); where neither is writable (a system-wide install run by a user without a writable
HOME, a container with a read-only root) it refuses to compile at import: "cannot cache function ...: no
locator available". :func:`configure` runs before any kernel module is imported and, in that case only,
points numba at a folder under the system's temporary directory and says so once on the ``cvstereo``
logger. Everywhere else nothing changes.
"""

from __future__ import annotations

import logging
import os
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path

LOG = logging.getLogger("cvstereo")

#: The folders of the package (relative to it) that hold modules with cached numba kernels: numba writes a
#: kernel's cache into ``__pycache__`` beside its module, and matcher-only kernels live beside their matcher.
#: (test_numba_cache checks this list against the source.)
KERNEL_FOLDERS = ("frames", "matchers", "matchers/_shared", "matchers/event_area", "matchers/event_time",
                  "matchers/event_vector", "matchers/frame", "matchers/frame_area", "matchers/fused", "rigcheck",
                  "sensors", "simulate")


def can_write(folder: str | os.PathLike) -> bool:
    """True if a file can be created in ``folder`` (made if missing), as numba itself checks it."""
    try:
        os.makedirs(folder, exist_ok=True)
        tempfile.TemporaryFile(dir=folder).close()
    except OSError:
        return False
    return True


def fallback_cache_dir(package_dirs, user_cache_dir, temp_dir, *,
                       writable: Callable[[str | os.PathLike], bool] = can_write) -> Path | None:
    """The cache folder to give numba, or None when its own choices work.

    Parameters
    ----------
    package_dirs : iterable of path-like
        The folders of the packages with kernels (numba writes ``__pycache__`` inside them).
    user_cache_dir : path-like
        numba's user-wide cache folder.
    temp_dir : path-like
        The system's temporary folder.
    writable : callable, keyword-only
        The test for a writable folder.

    Returns
    -------
    pathlib.Path or None
        None if numba can write beside every package or in the user cache; else a per-user folder under
        ``temp_dir`` if it is writable; else None (numba then reports the problem itself).

    Examples
    --------
    >>> fallback_cache_dir(["/pkg"], "/home/u/.cache/numba", "/tmp", writable=lambda d: str(d).startswith("/tmp"))
    PosixPath('/tmp/cvstereo-numba-cache')
    """
    if all(writable(Path(d) / "__pycache__") for d in package_dirs) or writable(user_cache_dir):
        return None
    folder = Path(temp_dir) / "cvstereo-numba-cache"
    return folder if writable(folder) else None


def numba_user_cache_dir() -> Path:
    """numba's user-wide cache folder (its ``appdirs.user_cache_dir``), found without importing numba."""
    if sys.platform == "darwin":
        return Path.home() / "Library" / "Caches" / "numba"
    if sys.platform == "win32":
        return Path(os.environ.get("LOCALAPPDATA", Path.home() / "AppData" / "Local")) / "numba" / "Cache"
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "numba"


def configure() -> None:
    """Point numba at a temporary cache folder when neither the install nor the user cache is writable."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return  # the user chose
    here = Path(__file__).resolve().parent
    packages = [here / folder for folder in KERNEL_FOLDERS]
    try:
        user_cache = numba_user_cache_dir()
    except RuntimeError:  # no home folder at all
        user_cache = Path("/nonexistent")
    folder = fallback_cache_dir([p for p in packages if p.is_dir()], user_cache, tempfile.gettempdir())
    if folder is not None:
        # numba reads the variable when it is first imported; if it already was, set its config too.
        os.environ["NUMBA_CACHE_DIR"] = str(folder)
        if "numba" in sys.modules:
            sys.modules["numba"].config.CACHE_DIR = str(folder)
        LOG.info("cvstereo: the installation and the user cache are read-only; numba caches compiled kernels in "
                 "%s (set NUMBA_CACHE_DIR to choose another folder).", folder)
