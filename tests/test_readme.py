"""The README's code blocks run as written (on a short simulated recording saved as recording.npz), and it stays
a welcome, not a manual."""

from __future__ import annotations

import re

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
    whole = cvs.match(namespace["rec"], method="event-time", variant="shared", threshold=0.8, rig_check=False)
    np.testing.assert_array_equal(namespace["matches"], whole.matches)
    assert (tmp_path / "map.png").read_bytes()[:4] == b"\x89PNG"


def _readme_ways_to_the_command() -> list[str]:
    """The shell lines the README gives for reaching the command after `make`: activating .venv, or its path."""
    text = " ".join(README.read_text().split())
    ways = re.findall(r"run `(\. \.venv/bin/activate)`|call `(\.venv/bin/cvstereo)`", text)
    return [a or b for a, b in ways]


def test_readme_says_how_to_reach_the_command_and_make_installs_it_there():
    assert _readme_ways_to_the_command() == [". .venv/bin/activate", ".venv/bin/cvstereo"]
    # make's install rules are what put the command there: an editable install into .venv (README: `make demo`).
    makefile = (ROOT / "Makefile").read_text()
    assert "VENV := .venv" in makefile and makefile.count("-m pip install --quiet -e") == 2


@pytest.mark.skipif(not (ROOT / ".venv" / "bin" / "activate").is_file(), reason="no .venv in this checkout (run make)")
@pytest.mark.parametrize("way", ["activate", "path"])
def test_readme_way_to_the_command_works_in_a_fresh_shell(tmp_path, way):
    """A login shell with nothing of this session's environment (no PATH to .venv, no VIRTUAL_ENV), in the
    checkout: the README's line reaches this checkout's command."""
    import subprocess

    import cvstereo

    activate, path = _readme_ways_to_the_command()
    line = f"{activate} && cvstereo --version" if way == "activate" else f"{path} --version"
    env = {"HOME": str(tmp_path), "PATH": "/usr/local/bin:/usr/bin:/bin", "LANG": "C.UTF-8"}
    # Before: the clean shell has no cvstereo of this checkout on its PATH (else the test would prove nothing).
    before = subprocess.run(["bash", "-lc", "command -v cvstereo || true"], cwd=ROOT, env=env,
                            capture_output=True, text=True, timeout=60)
    assert not before.stdout.strip().startswith(str(ROOT))
    done = subprocess.run(["bash", "-lc", line], cwd=ROOT, env=env, capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == f"cvstereo {cvstereo.__version__}"
    where = subprocess.run(["bash", "-lc", f"{activate} && command -v cvstereo"], cwd=ROOT, env=env,
                           capture_output=True, text=True, timeout=60)
    assert where.stdout.strip() == str(ROOT / ".venv" / "bin" / "cvstereo")
