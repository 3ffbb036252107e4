"""Hostile HDF5 event files (issue 27): DSEC and MVSEC layouts whose values a cast would silently change.

Each file is written with h5py itself (never with cvstereo), from one recording of 6,000 events over 300 ms
whose every value is known, then one dataset is made hostile: floats where integers are meant, values beyond
the sensor or beyond the dtype the reader casts to (int32 65541 would become x = 5), polarities that a cast
would make OFF, uint64 times that would become negative, an index table that decreases or points outside the
data, datasets of the wrong kind or shape. Every refusal must be one line naming the file, the dataset and the
first bad index (with the value as stored); every file that is merely unusual must read back exactly.

Failures say their kind (``tests/_hostile.py``), so that ``bench/hostile_tally.py`` tallies old and new code.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tests._hostile import case, check_case
from tests._hostile_calls import FILE_ERRORS, accepted, refused, same_events, working_copy

h5py = pytest.importorskip("h5py")
pytest.importorskip("hdf5plugin")

pytestmark = pytest.mark.timeout(60)

N = 6000
SPAN_US = 300_000
T_OFFSET = 49_599_300_523  # DSEC-like: microseconds of the day
K = 4321  # the index made hostile: in the fifth 50 ms slice, so that a message must name the file's index
INT64_MAX = 2**63 - 1


def _good() -> dict[str, np.ndarray]:
    rng = np.random.default_rng(7)
    return {"t": np.sort(rng.integers(0, SPAN_US, N)), "x": rng.integers(0, 640, N), "y": rng.integers(0, 480, N),
            "p": rng.integers(0, 2, N)}


GOOD = _good()
MS_TO_IDX = np.searchsorted(GOOD["t"], np.arange(SPAN_US // 1000 + 2) * 1000, side="left").astype(np.uint64)
GROUP = object()  # a group where a dataset is meant


def _dsec_columns(**changes) -> dict:
    """DSEC's datasets for the good recording, with ``changes`` (name -> values, GROUP, or None: left out)."""
    cols = {"events/x": GOOD["x"].astype(np.uint16), "events/y": GOOD["y"].astype(np.uint16),
            "events/t": GOOD["t"].astype(np.uint32), "events/p": GOOD["p"].astype(np.uint8),
            "t_offset": np.int64(T_OFFSET), "ms_to_idx": MS_TO_IDX}
    cols.update({k.replace("__", "/"): v for k, v in changes.items()})
    return cols


def _write(path: Path, datasets: dict, *, compress: bool = False) -> None:
    import hdf5plugin

    with h5py.File(path, "w") as f:
        for key, values in datasets.items():
            if values is None:
                continue
            if values is GROUP:
                f.create_group(key)
                continue
            values = np.asarray(values)
            kw = hdf5plugin.Blosc(cname="zstd") if compress and values.ndim else {}
            f.create_dataset(key, data=values, **kw)


def _with(values: np.ndarray, dtype, index: int, value) -> np.ndarray:
    out = np.asarray(values).astype(dtype)
    out[index] = value
    return out


def _mvsec_rows(**column_values) -> np.ndarray:
    """MVSEC's (N, 4) float64 rows x, y, t (s), p (-1/+1) of the good recording at 346x260, with changes."""
    rows = np.column_stack([GOOD["x"] % 346, GOOD["y"] % 260, (GOOD["t"] + 1_504_645_177_000_000) / 1e6,
                            np.where(GOOD["p"] == 1, 1.0, -1.0)]).astype(np.float64)
    for column, (index, value) in column_values.items():
        rows[index, "xytp".index(column)] = value
    return rows


def _first_at_least(t: np.ndarray, bound: int) -> int:
    return int(np.flatnonzero(t >= bound)[0])


# name -> datasets. Values are changed at index K unless said otherwise.
_T_BACK = GOOD["t"].astype(np.uint32)
_T_BACK[K] = _T_BACK[K - 1] - 5
_MS_DOWN = MS_TO_IDX.astype(np.int64)
_MS_DOWN[100] = _MS_DOWN[99] - 10
_T_BIG = GOOD["t"].astype(np.uint64)
_T_BIG[K:] += np.uint64(2**63)
_OFFSET_NEAR_MAX = INT64_MAX - 150_000  # relative times of 150 ms and more no longer fit

FILES = {
    "t_float_s.h5": _dsec_columns(events__t=GOOD["t"] / 1e6),
    "t_float_us.h5": _dsec_columns(events__t=GOOD["t"].astype(np.float64)),
    "t_float32.h5": _dsec_columns(events__t=GOOD["t"].astype(np.float32)),
    "x_half.h5": _dsec_columns(events__x=_with(GOOD["x"], np.float64, K, 82.5)),
    "x_nan.h5": _dsec_columns(events__x=_with(GOOD["x"], np.float64, K, np.nan)),
    "x_int32_wrap.h5": _dsec_columns(events__x=_with(GOOD["x"], np.int32, K, 65541)),
    "x_uint16_max.h5": _dsec_columns(events__x=_with(GOOD["x"], np.uint16, K, 65535)),
    "x_at_width.h5": _dsec_columns(events__x=_with(GOOD["x"], np.uint16, K, 640)),
    "y_negative.h5": _dsec_columns(events__y=_with(GOOD["y"], np.int16, K, -3)),
    "y_int64_huge.h5": _dsec_columns(events__y=_with(GOOD["y"], np.int64, K, 2**40 + 7)),
    "p_256.h5": _dsec_columns(events__p=_with(GOOD["p"], np.uint16, K, 256)),
    "p_half.h5": _dsec_columns(events__p=_with(GOOD["p"], np.float64, K, 0.5)),
    "p_two.h5": _dsec_columns(events__p=_with(GOOD["p"], np.uint8, K, 2)),
    "p_minus_two.h5": _dsec_columns(events__p=_with(np.where(GOOD["p"] == 1, 1, -1), np.int8, K, -2)),
    "t_uint64_huge.h5": _dsec_columns(events__t=_T_BIG, ms_to_idx=None),
    "t_offset_overflow.h5": _dsec_columns(t_offset=np.int64(_OFFSET_NEAR_MAX)),
    "t_backwards.h5": _dsec_columns(events__t=_T_BACK),
    "ms_decreasing.h5": _dsec_columns(ms_to_idx=_MS_DOWN),
    "ms_negative.h5": _dsec_columns(ms_to_idx=_with(MS_TO_IDX, np.int64, 150, -1)),
    "ms_past_end.h5": _dsec_columns(ms_to_idx=np.where(np.arange(MS_TO_IDX.size) >= 200, N + 1000,
                                                       MS_TO_IDX).astype(np.uint64)),
    "ms_all_past_end.h5": _dsec_columns(ms_to_idx=MS_TO_IDX + np.uint64(N)),
    "ms_float.h5": _dsec_columns(ms_to_idx=MS_TO_IDX.astype(np.float64)),
    "ms_strings.h5": _dsec_columns(ms_to_idx=np.array([b"0", b"17"])),
    "t_offset_pair.h5": _dsec_columns(t_offset=np.array([T_OFFSET, T_OFFSET + 1], np.int64)),
    "t_offset_float.h5": _dsec_columns(t_offset=np.float64(T_OFFSET / 1e6)),
    "t_offset_string.h5": _dsec_columns(t_offset=np.array(b"49599300523")),
    "t_offset_uint64_huge.h5": _dsec_columns(t_offset=np.uint64(2**64 - 5)),
    "x_strings.h5": _dsec_columns(events__x=GOOD["x"].astype("S4")),
    "t_group.h5": _dsec_columns(events__t=GROUP),
    "x_2d.h5": _dsec_columns(events__x=np.column_stack([GOOD["x"], GOOD["x"]]).astype(np.uint16)),
    "y_short.h5": _dsec_columns(events__y=GOOD["y"][:-10].astype(np.uint16)),
    # files that are unusual but whose events are all there: they must read back exactly
    "x_float_whole.h5": _dsec_columns(events__x=GOOD["x"].astype(np.float64)),
    "p_plus_minus.h5": _dsec_columns(events__p=np.where(GOOD["p"] == 1, 1, -1).astype(np.int8)),
    "p_bool.h5": _dsec_columns(events__p=GOOD["p"].astype(bool)),
    "p_float_whole.h5": _dsec_columns(events__p=GOOD["p"].astype(np.float32)),
    "t_uint64_small.h5": _dsec_columns(events__t=GOOD["t"].astype(np.uint64)),
    "ms_first_nonzero.h5": _dsec_columns(ms_to_idx=np.maximum(MS_TO_IDX, np.uint64(100))),
    "ms_short.h5": _dsec_columns(ms_to_idx=MS_TO_IDX[:10]),
    "ms_missing.h5": _dsec_columns(ms_to_idx=None),
    "ms_all_zero.h5": _dsec_columns(ms_to_idx=np.zeros(MS_TO_IDX.size, np.uint64)),
    "good.h5": _dsec_columns(),
}
MVSEC_FILES = {
    "mvsec_t_huge.hdf5": _mvsec_rows(t=(K, 1e300)),
    "mvsec_t_minus_huge.hdf5": _mvsec_rows(t=(K, -1e300)),
    "mvsec_t_beyond_int64.hdf5": _mvsec_rows(t=(K, 1e13)),
    "mvsec_t_nan.hdf5": _mvsec_rows(t=(K, np.nan)),
    "mvsec_t_back.hdf5": _mvsec_rows(t=(K, 1_504_645_176.0)),
    "mvsec_x_65541.hdf5": _mvsec_rows(x=(K, 65541.0)),
    "mvsec_x_half.hdf5": _mvsec_rows(x=(K, 82.5)),
    "mvsec_y_outside.hdf5": _mvsec_rows(y=(K, 260.0)),
    "mvsec_p_half.hdf5": _mvsec_rows(p=(K, 0.5)),
    "mvsec_p_three.hdf5": _mvsec_rows(p=(K, 3.0)),
    "mvsec_strings.hdf5": np.array([[b"1", b"2", b"3", b"4"]] * 4),
    "mvsec_3cols.hdf5": _mvsec_rows()[:, :3],
}


@pytest.fixture(scope="module")
def base(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("hostile2-hdf5")
    for name, datasets in FILES.items():
        _write(d / name, datasets)
    _write(d / "right.h5", _dsec_columns())
    _write(d / "compressed.h5", _dsec_columns(), compress=True)
    raw = (d / "compressed.h5").read_bytes()
    (d / "truncated.h5").write_bytes(raw[: int(len(raw) * 0.6)])
    for name, rows in MVSEC_FILES.items():
        _write(d / name, {"davis/left/events": rows, "davis/right/events": _mvsec_rows()})
    return d


@pytest.fixture
def work(base, tmp_path, monkeypatch) -> Path:
    return working_copy(base, tmp_path, monkeypatch)


def _at(dataset: str, index: int, value) -> tuple[str, ...]:
    return (dataset, f"index {index}", f"is {value}")


_TIME_OFFSET_BAD = _first_at_least(GOOD["t"], INT64_MAX - _OFFSET_NEAR_MAX + 1)
MV_T, MV_X, MV_Y, MV_P = (f"/davis/left/events column {c}" for c in "txyp")

CASES = {
    # --- floats where integers are meant --------------------------------------------------------------
    "t-float-seconds": case("info t_float_s.h5", 1, ("t_float_s.h5", "/events/t", "float64", "microseconds")),
    "t-float-whole-us": case("info t_float_us.h5", 1, ("/events/t", "float64", "microseconds")),
    "t-float32": case("info t_float32.h5", 1, ("/events/t", "float32", "microseconds")),
    "x-half-pixel": case("info x_half.h5", 1, _at("/events/x", K, 82.5)),
    "x-nan": case("info x_nan.h5", 1, _at("/events/x", K, "nan")),
    "p-half": case("info p_half.h5", 1, _at("/events/p", K, 0.5)),
    # --- values beyond the sensor or the dtype cast to -------------------------------------------------
    "x-int32-65541": case("info x_int32_wrap.h5", 1, _at("/events/x", K, 65541)),
    "x-uint16-65535": case("info x_uint16_max.h5", 1, _at("/events/x", K, 65535)),
    "x-at-width": case("info x_at_width.h5", 1, (*_at("/events/x", K, 640), "640x480")),
    "y-negative": case("info y_negative.h5", 1, _at("/events/y", K, -3)),
    "y-int64-huge": case("info y_int64_huge.h5", 1, _at("/events/y", K, 2**40 + 7)),
    "p-256": case("info p_256.h5", 1, _at("/events/p", K, 256)),
    "p-two": case("info p_two.h5", 1, _at("/events/p", K, 2)),
    "p-minus-two": case("info p_minus_two.h5", 1, _at("/events/p", K, -2)),
    "t-uint64-2pow63": case("info t_uint64_huge.h5", 1, _at("/events/t", K, int(_T_BIG[K]))),
    "t-offset-overflow": case("info t_offset_overflow.h5", 1,
                              (*_at("/events/t", _TIME_OFFSET_BAD, GOOD["t"][_TIME_OFFSET_BAD]), "time offset")),
    "t-backwards": case("info t_backwards.h5", 1, (*_at("/events/t", K, _T_BACK[K]), "earlier")),
    # --- the index table ----------------------------------------------------------------------------------
    "ms-decreasing": case("info ms_decreasing.h5", 1, (*_at("/ms_to_idx", 100, _MS_DOWN[100]), "decrease")),
    "ms-negative": case("info ms_negative.h5", 1, _at("/ms_to_idx", 150, -1)),
    "ms-past-end": case("info ms_past_end.h5", 1, (*_at("/ms_to_idx", 200, N + 1000), f"0..{N}")),
    "ms-all-past-end": case("info ms_all_past_end.h5", 1, _at("/ms_to_idx", _first_at_least(MS_TO_IDX, 1),
                                                               N + int(MS_TO_IDX[_first_at_least(MS_TO_IDX, 1)]))),
    "ms-float": case("info ms_float.h5", 1, ("/ms_to_idx", "float64")),
    "ms-strings": case("info ms_strings.h5", 1, ("/ms_to_idx", "strings")),
    # --- datasets of the wrong kind or shape ------------------------------------------------------------
    "t-offset-pair": case("info t_offset_pair.h5", 1, ("t_offset_pair.h5", "/t_offset", "(2,)")),
    "t-offset-float": case("info t_offset_float.h5", 1, ("/t_offset", "float64")),
    "t-offset-string": case("info t_offset_string.h5", 1, ("t_offset_string.h5", "/t_offset")),
    "t-offset-uint64-huge": case("info t_offset_uint64_huge.h5", 1, ("/t_offset", str(2**64 - 5))),
    "x-strings": case("info x_strings.h5", 1, ("x_strings.h5", "/events/x", "strings")),
    "t-group": case("info t_group.h5", 1, ("t_group.h5", "/events/t", "group")),
    "x-2d": case("info x_2d.h5", 1, ("/events/x", "shape")),
    "y-short": case("info y_short.h5", 1, ("y_short.h5", "different lengths")),
    "truncated": case("info truncated.h5", 1, "truncated.h5"),
    # --- unusual but whole: every event read, and the count printed -------------------------------------
    **{f"reads-{name[:-3].replace('_', '-')}": case(f"info {name}", 0, out=f"{N:,}")
       for name in ("x_float_whole.h5", "p_plus_minus.h5", "p_bool.h5", "p_float_whole.h5", "t_uint64_small.h5",
                    "ms_first_nonzero.h5", "ms_short.h5", "ms_missing.h5", "ms_all_zero.h5")},
    # --- MVSEC ---------------------------------------------------------------------------------------------
    "mvsec-t-1e300": case("info mvsec_t_huge.hdf5", 1, _at(MV_T, K, "1e+300")),
    "mvsec-t-minus-1e300": case("info mvsec_t_minus_huge.hdf5", 1, _at(MV_T, K, "-1e+300")),
    "mvsec-t-beyond-int64": case("info mvsec_t_beyond_int64.hdf5", 1, _at(MV_T, K, "1e+13")),
    "mvsec-t-nan": case("info mvsec_t_nan.hdf5", 1, _at(MV_T, K, "nan")),
    "mvsec-t-back": case("info mvsec_t_back.hdf5", 1, (MV_T, f"index {K}", "earlier")),
    "mvsec-x-65541": case("info mvsec_x_65541.hdf5", 1, _at(MV_X, K, 65541)),
    "mvsec-x-half": case("info mvsec_x_half.hdf5", 1, _at(MV_X, K, 82.5)),
    "mvsec-y-outside": case("info mvsec_y_outside.hdf5", 1, (*_at(MV_Y, K, 260), "346x260")),
    "mvsec-p-half": case("info mvsec_p_half.hdf5", 1, _at(MV_P, K, 0.5)),
    "mvsec-p-three": case("info mvsec_p_three.hdf5", 1, _at(MV_P, K, 3)),
    "mvsec-strings": case("info mvsec_strings.hdf5", 1, ("mvsec_strings.hdf5", "/davis/left/events", "strings")),
    "mvsec-three-columns": case("info mvsec_3cols.hdf5", 1, ("/davis/left/events", "(N, 4)")),
    # --- a refused input leaves no output ---------------------------------------------------------------
    "match-left-wraps": case("match x_int32_wrap.h5 right.h5 -m frame -o m.npz", 1, _at("/events/x", K, 65541),
                             absent="m.npz"),
    "match-right-index-down": case("match good.h5 ms_decreasing.h5 -m frame -o m.npz", 1,
                                   ("ms_decreasing.h5", "/ms_to_idx"), absent="m.npz"),
    "convert-p-256": case("convert p_256.h5 right.h5 -o out.npz", 1, _at("/events/p", K, 256), absent="out.npz"),
}


@pytest.mark.parametrize("hostile", list(CASES.values()), ids=list(CASES))
def test_hostile_hdf5_command_line(hostile, work: Path, capsys):
    check_case(hostile, work, capsys)


# ------------------------------------------------------------------------------------------------ Python API

def _read(path):
    from cvstereo.io import open_recording

    stream = open_recording(path)
    return stream.read_camera(stream.cameras[0])[0]


def _expected(p_from=None) -> dict[str, np.ndarray]:
    return {"t": GOOD["t"] + T_OFFSET, "x": GOOD["x"], "y": GOOD["y"], "p": GOOD["p"] if p_from is None else p_from}


@pytest.mark.parametrize("name", ["x_float_whole.h5", "p_plus_minus.h5", "p_bool.h5", "p_float_whole.h5",
                                  "t_uint64_small.h5", "ms_first_nonzero.h5", "ms_short.h5", "ms_missing.h5",
                                  "ms_all_zero.h5"])
def test_unusual_files_read_back_exactly(base, name):
    same_events(accepted(lambda: _read(base / name)), _expected(), name)


def test_uint16_65535_is_named_as_stored(base):
    refused(lambda: _read(base / "x_uint16_max.h5"), "/events/x", f"index {K}", "is 65535", absent=("is -1",))


def test_int32_65541_is_never_read_as_5(base):
    refused(lambda: _read(base / "x_int32_wrap.h5"), "is 65541", absent=("is 5,",))


def test_short_index_reads_in_bounded_chunks(base, monkeypatch):
    # An index that stops after 10 ms leaves the rest of the file to one slice: it must still come in blocks.
    import cvstereo.io.hdf5 as hdf5

    monkeypatch.setattr(hdf5, "CHUNK_ROWS", 1000)
    stream = hdf5.open_dsec(base / "ms_short.h5")
    sizes = [ev.size for ev, _ in stream.chunks(stream.cameras[0])]
    assert sum(sizes) == N, f"SILENT: {sum(sizes)} events read of {N}"
    assert max(sizes) <= 1000, f"SILENT: a chunk of {max(sizes)} events, beyond CHUNK_ROWS"


def test_time_slice_with_a_shifted_index_is_exact(base, tmp_path):
    # A monotone index that lies (every entry 500 events late) must not pick the wrong events.
    from cvstereo.io.hdf5 import read_time_slice

    path = tmp_path / "shifted.h5"
    _write(path, _dsec_columns(ms_to_idx=np.minimum(MS_TO_IDX + np.uint64(500), np.uint64(N))))
    t = GOOD["t"] + T_OFFSET
    for start_ms, stop_ms in ((12, 47), (100, 101), (0, 300), (250, 299)):
        t0, t1 = T_OFFSET + start_ms * 1000 + 123, T_OFFSET + stop_ms * 1000 + 7
        sel = (t >= t0) & (t < t1)
        got = accepted(lambda t0=t0, t1=t1: read_time_slice(path, t0, t1))
        same_events(got, {k: v[sel] for k, v in _expected().items()}, f"slice {start_ms}..{stop_ms} ms")


def test_time_slice_refuses_what_the_stream_refuses(base):
    from cvstereo.io.hdf5 import read_time_slice

    refused(lambda: read_time_slice(base / "x_int32_wrap.h5", T_OFFSET, T_OFFSET + SPAN_US), "/events/x",
            f"index {K}", "65541")


def test_time_range_of_a_two_element_offset_is_refused(base):
    from cvstereo.io.hdf5 import dsec_time_range

    refused(lambda: dsec_time_range(base / "t_offset_pair.h5"), "/t_offset", "(2,)")


def test_time_range_of_huge_uint64_times_is_refused(base):
    from cvstereo.io.hdf5 import dsec_time_range

    refused(lambda: dsec_time_range(base / "t_uint64_huge.h5"), "/events/t", str(int(_T_BIG[-1])))


def test_mvsec_huge_time_is_never_int64_min(base):
    refused(lambda: _read(base / "mvsec_t_huge.hdf5"), MV_T, f"index {K}", absent=(str(-(2**63)),))


def test_layout_of_a_dataset_named_events_is_not_a_traceback(tmp_path):
    from cvstereo.io.hdf5 import hdf5_layout

    path = tmp_path / "odd.h5"
    _write(path, {"events": np.zeros(3), "davis": np.zeros(2)})
    refused(lambda: hdf5_layout(path), "odd.h5", "neither the DSEC layout")


@pytest.mark.parametrize("name", ["t_offset_pair.h5", "t_group.h5", "x_strings.h5", "ms_float.h5", "x_2d.h5"])
def test_errors_are_the_ones_the_cli_reports(base, name):
    # The CLI turns ValueError and OSError into one line; a TypeError or AttributeError would be a traceback.
    refused(lambda: _read(base / name), name, errors=FILE_ERRORS)
