"""Folders the tests read, found from this file so that a test module may sit in any subfolder of tests/."""

from __future__ import annotations

from pathlib import Path

#: The repository's root (the folder of pyproject.toml).
REPO = Path(__file__).resolve().parent.parent
#: Small recordings and tables the tests read (tests/data).
DATA = REPO / "tests" / "data"
