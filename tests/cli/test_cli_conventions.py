"""One CLI convention (issue 15 item 8): ``RECORDING [RIGHT] [MATCHES]`` with ``--right`` as the same, one rule
for ``--method``, the short forms ``-m/-v/-p/-o``, and help texts without reStructuredText markup."""

from __future__ import annotations

import inspect
import json
import re

import numpy as np
import pytest

from calibration_free import match
from cvstereo.cli import COMMANDS, build_parser, main
from cvstereo.cli._text import plain_text
from cvstereo.io import read_matches, read_recording, write_recording
from cvstereo.model.events import make_events
from cvstereo.model.recording import Recording


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    """A bar seen 6 px apart (ground truth 6), as rec.npz and as an eDVS text pair l.txt + r.txt."""
    rng = np.random.default_rng(3)
    n = 6000
    t = np.sort(rng.integers(0, 240_000, n))
    x, y = rng.integers(40, 52, n), rng.integers(10, 110, n)
    p = rng.integers(0, 2, n)
    truth = np.full(n, 6.0)
    rec = Recording(make_events(t, x, y, p), make_events(t, x - 6, y, p), truth, truth)
    folder = tmp_path_factory.mktemp("pair")
    write_recording(folder / "rec.npz", rec)
    write_recording(folder / "l.txt", rec, format="edvs-text", right=folder / "r.txt")
    return folder


def _run(argv, capsys) -> str:
    assert main([str(a) for a in argv]) == 0
    return capsys.readouterr().out


def test_match_right_positional_or_option_gives_the_same_matches(pair, tmp_path, capsys):
    left, right = pair / "l.txt", pair / "r.txt"
    _run(["match", left, right, "-m", "frame", "-o", tmp_path / "a.npz"], capsys)
    _run(["match", left, "--right", right, "-m", "frame", "-o", tmp_path / "b.npz"], capsys)
    a, b = read_matches(tmp_path / "a.npz"), read_matches(tmp_path / "b.npz")
    # The independent expectation: the same events read from the .npz, matched through the Python API.
    expected = match(read_recording(pair / "rec.npz"), method="frame")
    assert expected.matches.size > 0
    np.testing.assert_array_equal(a.matches, expected.matches)
    np.testing.assert_array_equal(b.matches, expected.matches)
    assert a.meta["input"] == b.meta["input"] == [str(left), str(right)]
    assert abs(np.median(a.disparity) - 6) <= 1


def test_rigcheck_right_positional_or_option(pair, capsys):
    left, right = pair / "l.txt", pair / "r.txt"
    positional = json.loads(_run(["rigcheck", left, right, "--json"], capsys))
    option = json.loads(_run(["rigcheck", left, "--right", right, "--json"], capsys))
    stereo = json.loads(_run(["rigcheck", pair / "rec.npz", "--json"], capsys))
    assert positional == option == stereo


def test_evaluate_takes_right_before_matches_or_as_option(pair, tmp_path, capsys):
    left, right = pair / "l.txt", pair / "r.txt"
    _run(["match", pair / "rec.npz", "-o", tmp_path / "m.npz"], capsys)
    m = tmp_path / "m.npz"
    positional = json.loads(_run(["evaluate", left, right, m, "--json"], capsys))
    option = json.loads(_run(["evaluate", left, m, "--right", right, "--json"], capsys))
    assert positional["figures"] == option["figures"]
    assert positional["figures"]["matches"] == read_matches(m).matches.size > 0


def test_convert_right_positional_or_option(pair, tmp_path, capsys):
    left, right = pair / "l.txt", pair / "r.txt"
    _run(["convert", left, right, "-o", tmp_path / "a.npz"], capsys)
    _run(["convert", left, "--right", right, "-o", tmp_path / "b.npz"], capsys)
    original = read_recording(pair / "rec.npz")
    for name in ("a.npz", "b.npz"):
        back = read_recording(tmp_path / name)
        np.testing.assert_array_equal(back.left, original.left)
        np.testing.assert_array_equal(back.right, original.right)


def test_plot_tells_right_from_matches(pair, tmp_path, capsys):
    pytest.importorskip("matplotlib")
    import matplotlib

    matplotlib.use("Agg")
    left, right = pair / "l.txt", pair / "r.txt"
    _run(["match", left, right, "-o", tmp_path / "m.npz"], capsys)
    m = tmp_path / "m.npz"
    # (As with any optional positionals, argparse takes the positionals before the first option together: the
    # options follow them, here as in every command.)
    forms = {"positional.png": [left, right, m], "option.png": [left, m, "--right", right]}
    for name, inputs in forms.items():
        assert main(["plot", "disparity-map", *map(str, inputs), "-o", str(tmp_path / name), "--dpi", "40"]) == 0
    pictures = {name: (tmp_path / name).read_bytes() for name in forms}
    assert len(set(pictures.values())) == 1  # one picture, whichever spelling
    # Two files after RECORDING: the right camera's file (not .npz) is not taken for a matches file.
    assert main(["plot", "events", str(left), str(right), "-o", str(tmp_path / "ev.png"), "--dpi", "40"]) == 0
    capsys.readouterr()
    assert main(["plot", "disparity-map", str(left), str(right), "-o", str(tmp_path / "x.png")]) == 1
    assert "give the MATCHES file" in capsys.readouterr().err


def test_video_right_positional_or_option(pair, tmp_path, capsys):
    left, right = pair / "l.txt", pair / "r.txt"
    one = _run(["video", left, right, "-o", tmp_path / "a.mp4", "--scale", "1"], capsys)
    two = _run(["video", left, "--right", right, "-o", tmp_path / "b.mp4", "--scale", "1"], capsys)
    frames = [int(text.split()[0]) for text in (one, two)]
    assert frames[0] == frames[1] == 6  # 0.24 s in 40 ms frames


@pytest.mark.parametrize("argv", [
    ["match", "l.txt", "r.txt", "--right", "r.txt", "-o", "m2.npz"],
    ["rigcheck", "l.txt", "r.txt", "--right", "r.txt"],
    ["convert", "l.txt", "r.txt", "--right", "r.txt", "-o", "x.npz"],
    ["evaluate", "l.txt", "r.txt", "m.npz", "--right", "r.txt"],
    ["plot", "events", "l.txt", "r.txt", "m.npz", "--right", "r.txt", "-o", "x.png"],
    ["plot", "events", "l.txt", "r.txt", "--right", "r.txt", "-o", "x.png"],  # r.txt is no matches file
    ["video", "l.txt", "r.txt", "m.npz", "--right", "r.txt", "-o", "x.mp4"],
])
def test_right_given_twice_is_a_usage_error(argv, pair, monkeypatch, capsys):
    monkeypatch.chdir(pair)
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "the right camera's file is given twice" in err and "usage:" in err


# --- one rule for --method, short forms -------------------------------------------------------------------------


def test_match_and_live_default_to_the_registrys_method():
    from cvstereo.matchers.registry import DEFAULT_METHOD
    from cvstereo.run import match as pipeline_match

    assert DEFAULT_METHOD == inspect.signature(pipeline_match).parameters["method"].default
    parser = build_parser()
    assert parser.parse_args(["match", "rec.npz", "-o", "m.npz"]).method == DEFAULT_METHOD
    assert parser.parse_args(["live", "--simulate", "rec.npz"]).method == DEFAULT_METHOD
    for command in ("match", "live"):
        assert f"(default: {DEFAULT_METHOD};" in " ".join(_help(command).split())


@pytest.mark.parametrize(("short", "long"), [
    (["match", "r.npz", "-m", "event-area", "-v", "no-gaussian", "-p", "threshold=3", "-o", "m.npz"],
     ["match", "r.npz", "--method", "event-area", "--variant", "no-gaussian", "--param", "threshold=3",
      "--output", "m.npz"]),
    (["live", "--simulate", "r.npz", "-m", "event-time", "-v", "on", "-p", "threshold=0.5"],
     ["live", "--simulate", "r.npz", "--method", "event-time", "--variant", "on", "--param", "threshold=0.5"]),
    (["depth-fit", "a.npz:0.5", "b.npz:1", "-m", "frame", "-v", "all", "-p", "threshold=2", "-o", "d.json"],
     ["depth-fit", "a.npz:0.5", "b.npz:1", "--method", "frame", "--variant", "all", "--param", "threshold=2",
      "--output", "d.json"]),
    (["sweep", "r.npz", "-m", "frame", "-v", "all", "-p", "threshold=1,2", "-o", "s"],
     ["sweep", "r.npz", "--method", "frame", "--variant", "all", "--param", "threshold=1,2", "--output", "s"]),
    (["bench", "-m", "frame", "sgbm", "-o", "b"], ["bench", "--methods", "frame", "sgbm", "--output", "b"]),
    (["demo", "-m", "frame", "-o", "d"], ["demo", "--methods", "frame", "--output", "d"]),
])
def test_short_forms_mean_the_long_options(short, long):
    parser = build_parser()
    a, b = vars(parser.parse_args(short)), vars(parser.parse_args(long))
    assert a == b
    assert any(v not in (None, [], False) for k, v in a.items() if k in ("method", "methods", "param", "variant"))


def test_live_runs_without_method(pair, capsys):
    assert main(["live", "--simulate", str(pair / "rec.npz"), "--seconds", "0.5", "-p", "threshold=1.5"]) == 0
    assert '"matches"' in capsys.readouterr().err


# --- help without reStructuredText markup ------------------------------------------------------------------------

#: Markup patterns, written here independently of the cleaner: ``literal``, :role:`x`, *emphasis*/**strong**
#: after a space or bracket, and a "text::" literal-block marker.
MARKUP = {
    "double backticks": re.compile(r"``"),
    "role": re.compile(r":[a-z]+(:[a-z]+)?:`"),
    "emphasis": re.compile(r"(^|[\s(\[\"'])\*{1,2}[A-Za-z0-9][^*\n]*\*{1,2}(?=[\s.,;:)]|$)", re.M),
    "literal block": re.compile(r"::\s*$", re.M),
}


def _help(command: str | None = None) -> str:
    parser = build_parser()
    if command is None:
        return parser.format_help()
    sub = next(a for a in parser._actions if a.dest == "command")
    return sub.choices[command].format_help()


def _markup_in(text: str) -> list[str]:
    return [f"{name}: {m.group(0)!r}" for name, pattern in MARKUP.items() for m in pattern.finditer(text)]


@pytest.mark.parametrize("command", [None, *COMMANDS])
def test_help_has_no_rst_markup(command):
    text = _help(command)
    assert text.strip() and _markup_in(text) == []


def test_help_through_the_cli_has_no_rst_markup(capsys):
    for command in COMMANDS:
        with pytest.raises(SystemExit) as exc:
            main([command, "--help"])
        assert exc.value.code == 0
        out = capsys.readouterr().out
        assert out.startswith(f"usage: cvstereo {command}") and _markup_in(out) == [], command


def test_help_shows_the_modules_description_paragraph_only(capsys):
    # cli._subcommand: a command's description is its module docstring's second paragraph, lines joined;
    # the usage line before it and the paragraphs for code readers after it stay out of --help.
    with pytest.raises(SystemExit):
        main(["rigcheck", "--help"])
    out = " ".join(capsys.readouterr().out.split())
    assert "Estimate from the events alone which camera is left, the vertical (row) offset between the sensors," in out
    assert "once per blade period)." in out
    assert "what a calibration would have told" not in out and "reads n/a" not in out


def test_a_command_module_without_a_description_is_refused():
    import argparse

    from cvstereo.cli._subcommand import subcommand

    sub = argparse.ArgumentParser().add_subparsers()
    with pytest.raises(ValueError, match="cvstereo nodoc: the command module's docstring has no description"):
        subcommand(sub, "nodoc", "a summary", "``cvstereo nodoc``: only a usage line.")
    assert subcommand(sub, "given", "a summary", "``cvstereo given``.", description="Its own.").description == \
        "Its own."


def test_list_methods_has_no_rst_markup(capsys):
    _run(["match", "--list-methods"], capsys)  # warm: the registry's imports may print nothing, checked below
    out = _run(["match", "--list-methods"], capsys)
    assert "event-time:" in out and _markup_in(out) == []


def test_the_markup_checks_have_something_to_find():
    """The sources of these texts do carry markup (docstrings), so the tests above would fail without cleaning."""
    import cvstereo.cli.live as live
    import cvstereo.cli.record as record
    from cvstereo.matchers.registry import matcher_class

    assert _markup_in(record.__doc__) and _markup_in(live.__doc__)
    assert _markup_in(matcher_class("event-time").__doc__)


@pytest.mark.parametrize(("raw", "plain"), [
    ("``cvstereo record``: record", "cvstereo record: record"),
    ("see :func:`cvstereo.rigcheck.check_rig` and :class:`~cvstereo.io.stream.RecordingStream`",
     "see cvstereo.rigcheck.check_rig and RecordingStream"),
    ("a :ref:`nice title <some-target>` here", "a nice title here"),
    ("*not* this, **that**, (*x*)", "not this, that, (x)"),
    ("Examples::\n\n    cvstereo info a.npz", "Examples:\n\n    cvstereo info a.npz"),
    ("a literal block ::\n", "a literal block\n"),
    # Left as they are: globs, products, single-backtick quoting, argparse's %(default)s, layout.
    ('recordings = ["recordings/*.npz"], w_*.ply and c_*.ply',
     'recordings = ["recordings/*.npz"], w_*.ply and c_*.ply'),
    ("2 * 3 * 4, see `cvstereo match` (default: %(default)s)",
     "2 * 3 * 4, see `cvstereo match` (default: %(default)s)"),
    ("  events          both cameras\n  all   every", "  events          both cameras\n  all   every"),
])
def test_plain_text(raw, plain):
    assert plain_text(raw) == plain
    assert _markup_in(plain) == []
