"""Hostile arrays and arguments into the Python API (issue 27): ``events_from``, ``match(left, right, ...)``,
``as_events`` and recording files holding the same values.

Events are handed in as users have them: MVSEC-like ``(N, 4)`` rows in seconds, uint64 and float times,
coordinates in wide or unsigned integers, tonic's ``sensor_size``, lists of rows, a Recording with options that
would not apply. Every value a cast would change silently must be refused with the value as given and its
index; every argument that would be ignored must be refused; every shape users have must give the events it
holds (checked against the rows themselves).

Failures say their kind (``tests/_hostile.py``), so that ``bench/hostile_tally.py`` tallies old and new code.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from cvstereo.arrays import events_from
from cvstereo.events import EVENT_DTYPE, as_events, make_events
from cvstereo.pipeline import match
from cvstereo.recording import Recording

from cvstereo.io import write_recording
from tests._hostile import case, check_case
from tests._hostile_calls import accepted, refused, same_events, working_copy

pytestmark = pytest.mark.timeout(120)

N = 400
K = 321  # the index made hostile


def _rows(seed: int = 0) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    return {"t": np.sort(rng.integers(0, 80_000, N)), "x": rng.integers(0, 128, N), "y": rng.integers(0, 128, N),
            "p": rng.integers(0, 2, N)}


ROWS = _rows()


def _mvsec(rows=ROWS) -> np.ndarray:
    """x, y, t (s), p (-1/+1) as float64 rows, as MVSEC stores them."""
    return np.column_stack([rows["x"], rows["y"], rows["t"] / 1e6, np.where(rows["p"] == 1, 1.0, -1.0)])


def _structured(dtype, **changes) -> np.ndarray:
    out = np.empty(N, dtype)
    for name in out.dtype.names:
        out[name] = ROWS[{"timestamp": "t", "polarity": "p"}.get(name, name)]
    for name, (index, value) in changes.items():
        out[name][index] = value
    return out


WIDE = [("t", "<u8"), ("x", "<i4"), ("y", "<i4"), ("p", "<i4")]


# ------------------------------------------------------------------------------------------------ times

def test_float_seconds_without_a_unit_are_refused():
    refused(lambda: events_from(_mvsec(), columns="xytp"), "time_unit='s'", "float")


def test_match_on_float_seconds_without_a_unit_is_refused():
    refused(lambda: match(_mvsec(), _mvsec(_rows(1)), columns="xytp", method="frame"), "time_unit", "left events")


def test_float_whole_microseconds_without_a_unit_are_refused():
    rows = np.column_stack([ROWS["t"], ROWS["x"], ROWS["y"], ROWS["p"]]).astype(np.float64)
    refused(lambda: events_from(rows, columns="txyp"), "time_unit")


def test_missing_columns_message_suggests_only_calls_that_read_right():
    message = refused(lambda: events_from(_mvsec()), "columns=")
    assert "columns='xytp'" not in message or "time_unit='s'" in message, \
        f"MESSAGE: suggests columns='xytp' without the unit of MVSEC's seconds: {message!r}"


def test_the_suggested_mvsec_call_reads_right():
    got = accepted(lambda: events_from(_mvsec(), columns="xytp", time_unit="s"))
    same_events(got, ROWS, "MVSEC rows in seconds")


def test_float_seconds_in_a_structured_array_are_refused():
    data = _structured([("t", "<f8"), ("x", "<i2"), ("y", "<i2"), ("p", "i1")])
    data["t"] = ROWS["t"] / 1e6
    refused(lambda: events_from(data), "time_unit")


def test_uint64_time_of_2pow63_is_refused():
    data = _structured(WIDE)
    data["t"][K:] += np.uint64(2**63)
    refused(lambda: events_from(data), f"index {K}", str(int(data["t"][K])))


def test_as_events_refuses_uint64_time_of_2pow63():
    data = _structured(WIDE)
    data["t"][K:] += np.uint64(2**63)
    refused(lambda: as_events(data), "field 't'", f"index {K}", str(int(data["t"][K])))


def test_uint64_rows_of_2pow63_are_refused():
    rows = np.column_stack([ROWS["t"], ROWS["x"], ROWS["y"], ROWS["p"]]).astype(np.uint64)
    rows[K:, 0] += np.uint64(2**63)
    refused(lambda: events_from(rows, columns="txyp"), f"index {K}", str(int(rows[K, 0])))


@pytest.mark.parametrize("value", [1e300, 1e13, -1e13, np.inf])
def test_float_seconds_beyond_int64_microseconds_are_refused(value):
    rows = _mvsec()
    rows[K:, 2] = value
    refused(lambda: events_from(rows, columns="xytp", time_unit="s"), f"index {K}", "field 't'",
            absent=(str(-(2**63)),))


def test_integer_seconds_beyond_int64_microseconds_are_refused():
    data = _structured([("t", "<i8"), ("x", "<i2"), ("y", "<i2"), ("p", "i1")])
    data["t"][K:] = 2**62
    refused(lambda: events_from(data, time_unit="s"), f"index {K}", str(2**62))


def test_epoch_nanoseconds_convert_exactly():
    data = _structured([("t", "<i8"), ("x", "<i2"), ("y", "<i2"), ("p", "i1")])
    data["t"] = 1_700_000_000_000_000_000 + ROWS["t"] * 1000 + 499  # rounds down to whole microseconds
    got = accepted(lambda: events_from(data, time_unit="ns"))
    same_events(got, {**ROWS, "t": 1_700_000_000_000_000 + ROWS["t"]}, "epoch nanoseconds")


def test_uint64_times_that_fit_are_read():
    same_events(accepted(lambda: events_from(_structured(WIDE))), ROWS, "uint64 times")


# ------------------------------------------------------------------------------------------------ coordinates

@pytest.mark.parametrize(("field", "dtype", "value"), [
    ("x", "<u2", 65535), ("x", "<i4", 65541), ("x", "<u4", 4294967295), ("y", "<i8", -5), ("y", "<i8", 2**40),
    ("x", "<i2", 128),
])
def test_coordinate_beyond_the_sensor_is_named_as_given(field, dtype, value):
    types = {"t": "<i8", "x": "<i2", "y": "<i2", "p": "i1", field: dtype}
    data = _structured([(k, types[k]) for k in "txyp"], **{field: (K, value)})
    refused(lambda: events_from(data), f"field '{field}'", f"index {K}", f"is {value}", absent=("is -1,", "is 5,"))


def test_recording_with_uint16_65535_is_named_as_given():
    data = _structured([("t", "<i8"), ("x", "<u2"), ("y", "<u2"), ("p", "u1")], x=(K, 65535))
    refused(lambda: Recording(data, data), "left camera", f"index {K}", "is 65535")


@pytest.mark.parametrize("value", [2, 256, -2])
def test_polarity_other_than_on_off_is_refused(value):
    data = _structured([("t", "<i8"), ("x", "<i2"), ("y", "<i2"), ("p", "<i4")], p=(K, value))
    refused(lambda: events_from(data), "field 'p'", f"index {K}", f"is {value}")


def test_fractional_polarity_in_rows_is_refused():
    rows = _mvsec()
    rows[K, 3] = 0.5
    refused(lambda: events_from(rows, columns="xytp", time_unit="s"), "field 'p'", f"index {K}", "0.5")


# ------------------------------------------------------------------------------------------------ sizes

def test_tonic_sensor_size_is_accepted_as_resolution():
    rows = {**ROWS, "x": ROWS["x"] + 200}
    data = np.column_stack([rows["t"], rows["x"], rows["y"], rows["p"]])
    same_events(accepted(lambda: events_from(data, columns="txyp", resolution=(346, 260, 2))), rows,
                "tonic sensor_size")


def test_match_takes_tonic_sensor_size():
    left = make_events(ROWS["t"], ROWS["x"] + 200, ROWS["y"], ROWS["p"])
    result = accepted(lambda: match(left, left, method="frame-area", resolution=(346, 260, 2)))
    assert result.meta["resolution"] == [346, 260], f"SILENT: resolution {result.meta['resolution']}"


@pytest.mark.parametrize("size", [(346, 260, 3), (0, 0), (-5, 10), (1.5, 2), ("a", "b"), (10**9, 5), (128,)])
def test_nonsense_sizes_get_one_clear_line(size):
    refused(lambda: events_from(np.zeros(0, EVENT_DTYPE), resolution=size), "width and height",
            absent=("0..-1", "valid 0.."))


@pytest.mark.parametrize("size", [(0, 0), (346, 260, 3)])
def test_match_with_nonsense_size_gets_one_clear_line(size):
    left = make_events(ROWS["t"], ROWS["x"], ROWS["y"], ROWS["p"])
    refused(lambda: match(left, left, method="frame", resolution=size), "resolution", absent=("0..-1",))


# ------------------------------------------------------------------------------------------------ arguments

@pytest.fixture(scope="module")
def recording() -> Recording:
    ev = make_events(ROWS["t"], ROWS["x"], ROWS["y"], ROWS["p"])
    return Recording(ev, ev, resolution=(128, 128))


def test_other_resolution_with_a_recording_is_refused(recording):
    refused(lambda: match(recording, method="frame", resolution=(346, 260)), "346", "128x128")


def test_same_resolution_with_a_recording_is_accepted(recording):
    result = accepted(lambda: match(recording, method="frame", resolution=(128, 128)))
    assert result.meta["resolution"] == [128, 128], f"SILENT: {result.meta['resolution']}"


@pytest.mark.parametrize("options", [{"columns": "txyp"}, {"time_unit": "s"}], ids=["columns", "time_unit"])
def test_array_options_with_a_recording_are_refused(recording, options):
    refused(lambda: match(recording, method="frame", **options), next(iter(options)))


def test_list_of_rows_is_event_data():
    rows = np.column_stack([ROWS["t"], ROWS["x"], ROWS["y"], ROWS["p"]])
    want = match(rows, rows, method="frame-area", columns="txyp")
    got = accepted(lambda: match(rows.tolist(), rows.tolist(), method="frame-area", columns="txyp"))
    assert np.array_equal(got.matches, want.matches), "SILENT: a list of rows gives other matches than its array"


def test_list_of_tuples_is_read_as_rows():
    rows = [tuple(r) for r in np.column_stack([ROWS["t"], ROWS["x"], ROWS["y"], ROWS["p"]]).tolist()]
    same_events(accepted(lambda: events_from(rows, columns="txyp")), ROWS, "list of tuples")


def test_list_of_rows_without_right_camera_says_so():
    rows = np.column_stack([ROWS["t"], ROWS["x"], ROWS["y"], ROWS["p"]]).tolist()
    refused(lambda: match(rows, method="frame", columns="txyp"), "right camera")


def test_ragged_rows_are_refused_in_one_line():
    refused(lambda: events_from([[1, 2, 3, 1], [4, 5, 6]], columns="txyp"), "rows")


# ------------------------------------------------------------------------------------------------ files

def _recording_file(path: Path, **fields) -> None:
    """An npz recording whose left camera has the given dtypes (right: the plain events)."""
    types = {"t": "<i8", "x": "<i2", "y": "<i2", "p": "i1"}
    changes = {}
    for name, (dtype, index, value) in fields.items():
        types[name] = dtype
        changes[name] = (index, value)
    left = _structured([(k, types[k]) for k in "txyp"], **changes)
    if types["t"] == "<u8" and "t" in changes:
        left["t"][K:] = left["t"][K] + np.arange(N - K).astype(np.uint64)
    np.savez_compressed(path, left=left, right=make_events(ROWS["t"], ROWS["x"], ROWS["y"], ROWS["p"]),
                        resolution=np.array([128, 128]))


@pytest.fixture(scope="module")
def base(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("hostile2-arrays")
    _recording_file(d / "t_uint64.npz", t=("<u8", K, 2**63 + 5))
    _recording_file(d / "x_uint16.npz", x=("<u2", K, 65535))
    _recording_file(d / "x_int32.npz", x=("<i4", K, 65541))
    _recording_file(d / "p_int16.npz", p=("<i2", K, 256))
    _recording_file(d / "wide_ok.npz", t=("<u8", 0, 0), x=("<i4", 0, 0), y=("<u2", 0, 0), p=("?", 0, False))
    write_recording(d / "good.npz", Recording(make_events(ROWS["t"], ROWS["x"], ROWS["y"], ROWS["p"]),
                                              make_events(ROWS["t"], ROWS["x"], ROWS["y"], ROWS["p"])))
    return d


@pytest.fixture
def work(base, tmp_path, monkeypatch) -> Path:
    return working_copy(base, tmp_path, monkeypatch)


CASES = {
    "npz-t-uint64": case("info t_uint64.npz", 1, ("t_uint64.npz", f"index {K}", str(2**63 + 5))),
    "npz-x-uint16-65535": case("info x_uint16.npz", 1, ("x_uint16.npz", f"index {K}", "is 65535")),
    "npz-x-int32-65541": case("info x_int32.npz", 1, ("x_int32.npz", f"index {K}", "is 65541")),
    "npz-p-256": case("info p_int16.npz", 1, ("p_int16.npz", f"index {K}", "is 256")),
    "convert-x-uint16": case("convert x_uint16.npz -o out.npz", 1, ("x_uint16.npz", "65535"), absent="out.npz"),
    "match-t-uint64": case("match t_uint64.npz -m frame -o m.npz", 1, ("t_uint64.npz", str(2**63 + 5)),
                           absent="m.npz"),
    "npz-wide-dtypes-read": case("info wide_ok.npz", 0, out=f"{N:,}"),
}


@pytest.mark.parametrize("hostile", list(CASES.values()), ids=list(CASES))
def test_hostile_arrays_command_line(hostile, work: Path, capsys):
    check_case(hostile, work, capsys)
