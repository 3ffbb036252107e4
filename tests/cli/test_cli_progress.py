"""Every long command takes --progress/--no-progress; by default bars appear only on a terminal."""

from __future__ import annotations

import io

import pytest

from cvstereo.cli import build_parser
from cvstereo.cli._common import progress_wanted

LONG = {"demo": [], "bench": [], "simulate": ["--preset", "1arm-50cm"], "match": ["r.npz", "-o", "m.npz"],
        "sweep": ["r.npz", "-m", "frame", "-o", "out"], "rigcheck": ["r.npz"]}


@pytest.mark.parametrize("command", LONG)
def test_long_commands_take_progress_options(command, monkeypatch):
    parser = build_parser()
    assert parser.parse_args([command, *LONG[command], "--no-progress"]).progress is False
    assert parser.parse_args([command, *LONG[command], "--progress"]).progress is True
    args = parser.parse_args([command, *LONG[command]])
    monkeypatch.setattr("sys.stderr", io.StringIO())  # a log file, not a terminal
    assert progress_wanted(args) is False


def test_default_follows_the_terminal(monkeypatch):
    class Tty(io.StringIO):
        def isatty(self):
            return True

    monkeypatch.setattr("sys.stderr", Tty())
    assert progress_wanted(build_parser().parse_args(["demo"])) is True
