"""Hostile input to the Python API (issue 13, "Crashes"): matchers, parameters, resolutions.

Packets the matcher cannot hold (coordinates outside its sensor, unsorted time, a wrong dtype) must be
refused before any compiled kernel sees them, with the camera, index and field named. The cases that
crashed the interpreter (SIGSEGV, "double free") run in a subprocess, so a crash fails the test instead
of killing pytest.
"""

from __future__ import annotations

import math
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from cvstereo.events import EVENT_DTYPE, MAX_RESOLUTION, make_events
from cvstereo.recording import Recording
from cvstereo.registry import available_methods, create_matcher, matcher_class, parse_param_strings

from cvstereo.cli import main
from cvstereo.errors import EventFormatError
from cvstereo.io.npz import write_recording_npz

pytestmark = pytest.mark.timeout(120)

#: The five thesis matchers and the two OpenCV baselines (dv-semidense needs an optional extra).
METHODS = [m for m in ("frame", "frame-area", "event-time", "event-area", "event-vector", "stereobm", "sgbm")
           if m in available_methods()]
REPO = Path(__file__).resolve().parent.parent


def _events(rng, n: int, width: int, height: int, t0: int = 0) -> np.ndarray:
    t = t0 + np.sort(rng.integers(0, 100_000, n))
    return make_events(t, rng.integers(0, width, n), rng.integers(0, height, n), rng.integers(0, 2, n))


def _first_outside(events: np.ndarray, resolution) -> tuple[int, str]:
    """Index and field of the first event outside ``resolution`` (the expectation, computed here)."""
    for i, (x, y) in enumerate(zip(events["x"].tolist(), events["y"].tolist(), strict=True)):
        if not 0 <= x < resolution[0]:
            return i, "x"
        if not 0 <= y < resolution[1]:
            return i, "y"
    raise AssertionError("no event outside")


# ------------------------------------------------------------------ coordinates outside (in a subprocess)

_FEED = textwrap.dedent("""
    import sys
    import numpy as np
    from cvstereo.registry import create_matcher
    left, right = np.load(sys.argv[1]), np.load(sys.argv[2])
    m = create_matcher(sys.argv[3], resolution=(int(sys.argv[4]), int(sys.argv[5])))
    try:
        m.feed(left, right)
        m.flush()
    except ValueError as exc:
        print("REFUSED", type(exc).__name__, exc)
    else:
        print("ACCEPTED")
""")


def _feed_isolated(tmp_path, method, resolution, left, right) -> str:
    np.save(tmp_path / "l.npy", left)
    np.save(tmp_path / "r.npy", right)
    proc = subprocess.run([sys.executable, "-c", _FEED, str(tmp_path / "l.npy"), str(tmp_path / "r.npy"), method,
                           str(resolution[0]), str(resolution[1])], capture_output=True, text=True, timeout=110,
                          cwd=REPO)
    assert proc.returncode == 0, f"the interpreter died (code {proc.returncode}): {proc.stderr[-500:]}"
    return proc.stdout.strip()


_OUTSIDE = {
    # name: (matcher resolution, events' sensor size, which camera carries the bad events)
    "dvs128-into-64": ((64, 64), (128, 128), "left"),
    "davis240-into-128": ((128, 128), (240, 180), "left"),
    "davis240-right-only": ((128, 128), (240, 180), "right"),
}


@pytest.mark.parametrize("case", list(_OUTSIDE))
@pytest.mark.parametrize("method", METHODS)
def test_feed_refuses_events_outside_the_sensor(tmp_path, method, case):
    res, size, bad_cam = _OUTSIDE[case]
    rng = np.random.default_rng(3)
    good = _events(rng, 3000, *res)
    bad = _events(rng, 3000, *size)
    left, right = (bad, good) if bad_cam == "left" else (good, bad)
    out = _feed_isolated(tmp_path, method, res, left, right)
    index, field = _first_outside(bad, res)
    assert out.startswith("REFUSED EventFormatError"), out
    assert f"{bad_cam} packet" in out and f"field '{field}' at index {index} " in out, out


@pytest.mark.parametrize("method", ["event-vector", "event-time", "event-area", "frame"])
@pytest.mark.parametrize("where", [("x", 200), ("x", -1), ("y", 128), ("y", -3)])
def test_feed_refuses_one_bad_coordinate(tmp_path, method, where):
    field, value = where
    rng = np.random.default_rng(4)
    left, right = _events(rng, 2000, 128, 128), _events(rng, 2000, 128, 128)
    right[field][777] = value
    out = _feed_isolated(tmp_path, method, (128, 128), left, right)
    assert out.startswith("REFUSED EventFormatError"), out
    assert f"right packet: field '{field}' at index 777 is {value}" in out, out


# ------------------------------------------------------------------------------------- order and dtype

@pytest.mark.parametrize("method", METHODS)
def test_feed_refuses_unsorted_packet(method):
    rng = np.random.default_rng(5)
    left, right = _events(rng, 500, 128, 128), _events(rng, 500, 128, 128)
    right["t"][300], right["t"][301] = right["t"][301] + 5, right["t"][300]  # index 301 goes backwards
    m = create_matcher(method)
    with pytest.raises(EventFormatError, match=r"right packet: field 't' at index 301 .* earlier than index 300"):
        m.feed(left, right)
    assert m.watermark is None and m.input_events == 0  # nothing of the refused packet was taken


@pytest.mark.parametrize("method", ["event-time", "frame"])
def test_feed_refuses_events_before_the_watermark(method):
    rng = np.random.default_rng(6)
    m = create_matcher(method)
    m.feed(_events(rng, 100, 128, 128), _events(rng, 100, 128, 128), until=200_000)
    with pytest.raises(EventFormatError, match=r"left packet starts at t=\d+, before events already fed"):
        m.feed(_events(rng, 100, 128, 128), _events(rng, 100, 128, 128, t0=200_000))


@pytest.mark.parametrize("method", ["event-area", "frame-area"])
def test_refused_packet_leaves_the_matcher_usable(method):
    rng = np.random.default_rng(7)
    left, right = _events(rng, 800, 128, 128), _events(rng, 800, 128, 128)
    bad = right.copy()
    bad["t"][10] = -5
    m, ref = create_matcher(method), create_matcher(method)
    with pytest.raises(EventFormatError, match=r"right packet: field 't' at index 10"):
        m.feed(left, bad)
    got = np.concatenate([m.feed(left, right), m.flush()])
    want = np.concatenate([ref.feed(left, right), ref.flush()])
    np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize("bad", ["float-t", "list", "2d", "wide-x"])
def test_feed_refuses_what_is_not_an_event_array(bad):
    good = make_events([0, 1], [1, 2], [1, 2], [1, 0])
    other = {
        "float-t": np.zeros(2, dtype=[("t", "f8"), ("x", "<i2"), ("y", "<i2"), ("p", "i1")]),
        "list": [(0, 1, 1, 1)],
        "2d": np.zeros((2, 2), EVENT_DTYPE),
        "wide-x": np.zeros(2, dtype=[("t", "<i8"), ("x", "<i8"), ("y", "<i2"), ("p", "i1")]),
    }[bad]
    m = create_matcher("event-time")
    with pytest.raises(EventFormatError, match=r"right packet"):
        m.feed(good, other)


# ----------------------------------------------------------------------------------------- parameters

_THRESHOLD_METHODS = [m for m in ("frame", "frame-area", "event-time", "event-area", "event-vector") if m in METHODS]


@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf])
@pytest.mark.parametrize("method", _THRESHOLD_METHODS)
def test_non_finite_threshold_refused(method, value):
    with pytest.raises(ValueError, match=r"'threshold' must be a finite number"):
        create_matcher(method, threshold=value)


@pytest.mark.parametrize("field", ["threshold", "gaussian_gain"])
def test_non_finite_refused_when_params_are_built_directly(field):
    cls = matcher_class("event-time")
    with pytest.raises(ValueError, match=rf"'{field}' must be a finite number"):
        cls(cls.Params(**{field: math.nan}))


@pytest.mark.parametrize("method,field", [
    ("frame", "window_us"), ("frame-area", "window_us"), ("stereobm", "window_us"),
    ("event-time", "decay_period_us"), ("event-time", "time_window_us"), ("event-vector", "max_disparity"),
])
@pytest.mark.parametrize("value", [99999999999999999999, 2**63, 2**40])
def test_huge_int_parameter_refused(method, field, value):
    if method not in METHODS:
        pytest.skip(f"{method} unavailable")
    with pytest.raises(ValueError, match=rf"'{field}' must be at most {2**31 - 1}"):
        create_matcher(method, **{field: value})


@pytest.mark.parametrize("method,field", [("event-time", "kernel_size"), ("event-area", "block"),
                                          ("frame", "kernel_size"), ("frame-area", "block")])
def test_filter_side_beyond_any_sensor_refused(method, field):
    # 99999 asked numpy for a 99999 x 99999 kernel (75 GB: MemoryError) before this bound.
    with pytest.raises(ValueError, match=rf"'{field}' must be at most {max(MAX_RESOLUTION) - 1} px"):
        create_matcher(method, **{field: 99999})


@pytest.mark.parametrize("value", [1e300, 40000.5, "40000", True])
def test_int_parameter_of_another_type_refused(value):
    with pytest.raises(ValueError, match=r"'window_us' must be an integer"):
        create_matcher("frame", window_us=value)


@pytest.mark.parametrize("value", [40000.0, np.int64(40000), np.float32(40000)])
def test_int_parameter_as_whole_number_is_accepted(value):
    # JSON meta and YAML configs write 40000.0, numpy code passes np.int64: the int they stand for is kept.
    got = create_matcher("frame", window_us=value).params.window_us
    assert got == 40000 and type(got) is int


@pytest.mark.parametrize("value", [10**400, "high", None])
def test_float_parameter_that_is_no_finite_number_refused(value):
    with pytest.raises(ValueError, match=r"'threshold' must be a (finite )?number"):
        create_matcher("event-time", threshold=value)


@pytest.mark.parametrize("item,fragment", [
    ("window_us=99999999999999999999", "at most"),
    ("window_us=1e300", "int"),
    ("threshold=nan", "finite"),
    ("threshold=inf", "finite"),
    ("sigma=-inf", "finite"),
])
def test_param_strings_refuse_out_of_range(item, fragment):
    cls = matcher_class("frame")
    with pytest.raises(ValueError, match=rf"'{item.split('=')[0]}'.*{fragment}"):
        parse_param_strings(cls.Params, [item])


@pytest.mark.parametrize("item", ["window_us=99999999999999999999", "threshold=nan", "window_us=1e300"])
def test_cli_match_param_out_of_range(tmp_path, capsys, item):
    rng = np.random.default_rng(8)
    rec = tmp_path / "rec.npz"
    write_recording_npz(rec, Recording(_events(rng, 200, 128, 128), _events(rng, 200, 128, 128)))
    before = rec.read_bytes()
    code = main(["match", str(rec), "-o", str(tmp_path / "m.npz"), "--param", item])
    err = capsys.readouterr().err
    assert code == 1, err
    assert len(err.strip().splitlines()) == 1 and item.split("=")[0] in err and "Traceback" not in err
    assert rec.read_bytes() == before and not (tmp_path / "m.npz").exists()


# --------------------------------------------------------------------------------------- resolutions

@pytest.mark.parametrize("res", [(0, 0), (-1, 128), (128, -1), (100000, 100000), (2049, 128), (12.5, 128)])
@pytest.mark.parametrize("method", ["event-time", "frame", "event-vector"])
def test_matcher_resolution_out_of_bounds(method, res):
    with pytest.raises(ValueError, match=r"resolution"):
        create_matcher(method, resolution=res)


def test_matcher_resolution_error_names_the_limit():
    with pytest.raises(ValueError, match=f"{MAX_RESOLUTION[0]}x{MAX_RESOLUTION[1]}"):
        create_matcher("event-time", resolution=(100000, 100000))
