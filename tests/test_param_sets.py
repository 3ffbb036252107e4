"""The two parameter sets: ``thesis`` reproduces the matches of the thesis' constants bit for bit."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import pytest

from calibration_free import match
from cvstereo.io.npz import read_recording_npz

DATA = Path(__file__).resolve().parent / "data"
HASHES = json.loads((DATA / "thesis_hashes.json").read_text())["hashes"]


@pytest.fixture(scope="module")
def clip():
    return read_recording_npz(DATA / "thesis_clip.npz")


@pytest.mark.parametrize("key", sorted(HASHES))
def test_thesis_set_reproduces_the_committed_matches(clip, key):
    method, variant = key.split("/")
    result = match(clip, method=method, variant=variant, param_set="thesis")
    assert result.meta["param_set"] == "thesis"
    assert len(result) == HASHES[key]["matches"]
    assert hashlib.sha256(result.matches.tobytes()).hexdigest() == HASHES[key]["sha256"]
