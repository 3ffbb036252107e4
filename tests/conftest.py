"""Shared fixtures: where the shared data lives, small synthetic streams."""

from __future__ import annotations

import os
import signal
from pathlib import Path

import numpy as np
import pytest
from hypothesis import settings

# The suite draws the same examples on every run (a CI run must not fail on a seed no run before it drew);
# ``--hypothesis-profile explore`` draws new ones, for hunting bugs locally.
settings.register_profile("deterministic", derandomize=True)
settings.register_profile("explore", derandomize=False)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "deterministic"))

REPO = Path(__file__).resolve().parent.parent

# One thread per matcher in the test workers (pytest-xdist runs one per core already): the library reads its
# default of ``threads`` from this variable once, at the first matcher (docs/guide/threads.md). Tests of the
# parallel paths give ``threads=`` themselves. Set before any test imports cvstereo; a value set outside wins.
os.environ.setdefault("CVSTEREO_THREADS", "1")

# The signal cases stand for a user pressing Ctrl-C in a terminal. A shell that starts a job in the background
# (`make test &`, a CI runner's non-interactive job) ignores SIGINT for it, every process it starts inherits
# the ignored disposition, and the commands under test would then rightly go on running. The suite restores
# Python's own handler so that its child processes start with SIGINT as a terminal gives it.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)


def shared_dir() -> Path:
    """The shared folder: $CVSTEREO_SHARED, else ../shared beside the repository (design.md)."""
    return Path(os.environ.get("CVSTEREO_SHARED", REPO.parent / "shared"))


@pytest.fixture(scope="session")
def tum_dir() -> Path:
    """The real TUM stereo recordings; skips the test when the shared data is absent."""
    path = shared_dir() / "data" / "tum-stereo"
    if not (path / "Fan_disp8.dat").exists():
        pytest.skip(f"shared data not found at {path} (set CVSTEREO_SHARED to the shared folder)")
    return path


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(0)
