"""M3ED's HDF5 layout (issue 26 item 5), written with h5py as M3ED's public description and loaders lay it out:
both Prophesee cameras in one ``*_data.h5`` under ``/prophesee/{left,right}``: ``x``, ``y`` (uint16), ``t`` (int64
us), ``p`` (int8 0/1), ``ms_map_idx`` (the first event of each millisecond) and a ``calib`` group beside them."""

from __future__ import annotations

import numpy as np
import pytest

from cvstereo.cli import main
from cvstereo.io import detect_format, read_recording
from cvstereo.model.events import make_events

h5py = pytest.importorskip("h5py")


def _events(seed: int, n: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    t = np.sort(rng.integers(0, 250_000, n))
    return make_events(t, rng.integers(0, 1280, n), rng.integers(0, 720, n), rng.integers(0, 2, n))


def _write_m3ed(path, cameras: dict) -> None:
    with h5py.File(path, "w") as f:
        for name, ev in cameras.items():
            g = f.create_group(f"prophesee/{name}")
            g.create_dataset("x", data=ev["x"].astype(np.uint16))
            g.create_dataset("y", data=ev["y"].astype(np.uint16))
            g.create_dataset("t", data=ev["t"].astype(np.int64))
            g.create_dataset("p", data=ev["p"].astype(np.int8))
            ms = np.searchsorted(ev["t"], np.arange(int(ev["t"][-1]) // 1000 + 2) * 1000).astype(np.uint64)
            g.create_dataset("ms_map_idx", data=ms)
            g.create_dataset("calib/resolution", data=np.array([1280, 720]))
            g.create_dataset("calib/intrinsics", data=np.array([1030.0, 1030.0, 640.0, 360.0]))


def test_m3ed_file_reads_both_cameras_exactly(tmp_path, capsys):
    left, right = _events(1, 30_000), _events(2, 25_000)
    path = tmp_path / "car_urban_day_1_data.h5"
    _write_m3ed(path, {"left": left, "right": right})
    assert detect_format(path) == "m3ed"
    rec = read_recording(path)
    assert rec.resolution == (1280, 720)
    for got, want in ((rec.left, left), (rec.right, right)):
        np.testing.assert_array_equal(got[["t", "x", "y", "p"]], want[["t", "x", "y", "p"]])
    assert main(["info", str(path)]) == 0
    out = capsys.readouterr().out
    assert "m3ed, 1280x720" in out and "30,000" in out and "25,000" in out


def test_m3ed_values_are_checked_as_dsecs_are(tmp_path):
    ev = _events(3, 5000)
    ev["x"][1234] = 1280  # beyond the sensor
    path = tmp_path / "bad_data.h5"
    _write_m3ed(path, {"left": ev, "right": _events(4, 5000)})
    with pytest.raises(ValueError, match=r"/prophesee/left/x.*1234"):
        read_recording(path)
