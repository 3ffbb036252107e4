"""The README's code blocks run as written (on a short simulated recording saved as recording.npz), and it stays
a welcome, not a manual."""

from __future__ import annotations

import numpy as np
import pytest

from tests._docs_blocks import ROOT, RUN_LANGUAGES, blocks, run_page

README = ROOT / "README.md"
#: Issue 25: a README of about 100-150 lines; the rest lives in docs/.
MAX_LINES = 150


def test_readme_is_short_and_starts_with_the_two_make_commands():
    text = README.read_text()
    assert len(text.splitlines()) <= MAX_LINES
    first = blocks(README)[0]
    assert [line.split("#")[0].strip() for line in first.code.splitlines()] == ["make demo", "make test"]


def test_readme_blocks_are_python_or_commands():
    found = blocks(README)
    assert {b.lang for b in found} <= set(RUN_LANGUAGES)
    assert sum(b.lang == "python" for b in found) >= 2
    assert all(b.skip for b in found if b.skip is not None)


def test_readme_picture_exists():
    assert (ROOT / "docs" / "img" / "disparity-map.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "docs/img/disparity-map.png" in README.read_text()


@pytest.mark.slow
def test_readme_blocks_run(tmp_path, monkeypatch, capsys):
    import cvstereo as cvs
    from cvstereo.io import write_recording

    write_recording(tmp_path / "recording.npz", cvs.simulate_preset("1arm-100cm", seconds=0.6, seed=1))
    monkeypatch.chdir(tmp_path)
    namespace = run_page(README, capsys)
    # The streaming loop keeps every packet's matches: they equal match() over the whole recording.
    whole = cvs.match(namespace["rec"], method="event-time", variant="shared", threshold=0.8)
    np.testing.assert_array_equal(namespace["matches"], whole.matches)
    assert (tmp_path / "map.png").read_bytes()[:4] == b"\x89PNG"
