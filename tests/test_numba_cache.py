"""A read-only installation still compiles its kernels: numba is pointed at a temporary cache folder."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from cvstereo._numba_cache import can_write, fallback_cache_dir


def test_can_write(tmp_path):
    assert can_write(tmp_path / "new" / "folder")
    blocker = tmp_path / "a-file"
    blocker.write_text("not a folder")
    assert not can_write(blocker / "sub")


def test_fallback_only_when_install_and_user_cache_are_read_only(tmp_path):
    ro = {Path("/site/cvstereo/__pycache__"), Path("/site/calibration_free/__pycache__"), Path("/home/u/.cache")}

    def writable(folder):
        return Path(folder) not in ro

    pkgs = ["/site/cvstereo", "/site/calibration_free"]
    assert fallback_cache_dir(pkgs, "/home/u/.cache", tmp_path, writable=writable) == tmp_path / "cvstereo-numba-cache"
    # A writable user cache: numba's own choice works, nothing to change.
    assert fallback_cache_dir(pkgs, "/home/u/other", tmp_path, writable=writable) is None
    # A writable install: nothing to change.
    assert fallback_cache_dir(["/site/other"], "/home/u/.cache", tmp_path, writable=writable) is None
    # Nothing writable at all: leave it to numba's own error.
    assert fallback_cache_dir(pkgs, "/home/u/.cache", tmp_path, writable=lambda d: False) is None


def test_user_choice_wins(tmp_path):
    """NUMBA_CACHE_DIR given by the user is kept as it is."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}
    out = subprocess.run([sys.executable, "-c", "import cvstereo, numba; print(numba.config.CACHE_DIR)"],
                         env=env, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == str(tmp_path)


def test_user_cache_dir_is_numbas_own():
    from numba.misc.appdirs import AppDirs

    from cvstereo._numba_cache import numba_user_cache_dir

    assert numba_user_cache_dir() == Path(AppDirs(appname="numba", appauthor=False).user_cache_dir)


def test_kernel_folders_are_the_folders_of_the_modules_with_cached_kernels():
    from cvstereo import _numba_cache

    package = Path(_numba_cache.__file__).parent
    with_kernels = {path.parent.relative_to(package).as_posix() for path in package.rglob("*.py")
                    if path.name != "_numba_cache.py" and "cache=True" in path.read_text()}
    assert with_kernels == set(_numba_cache.KERNEL_FOLDERS) and "matchers/frame" in with_kernels
