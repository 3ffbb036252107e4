"""Live input from DV network streams and DV cameras (issue 26 item 3).

A simulated stereo recording is served by two of dv-processing's own NetworkWriters (``tests/_dv_serve.py``);
``live --dv`` must receive every event of each camera and match them exactly as the file is matched (the
matches' sha256 against ``cvstereo.match`` on the file), ``record --dv`` must write them back event for event.
The camera path (USB, ``openSync``) cannot be tested without cameras: it is tested through its seam, a fake of
dv-processing's camera module with its interface.
"""

from __future__ import annotations

import hashlib
import json
import time
import types

import numpy as np
import pytest

from cvstereo.cli import main
from cvstereo.io.npz import read_recording_npz, write_recording_npz
from cvstereo.matchers.registry import DEFAULT_METHOD
from cvstereo.simulate import simulate_preset
from tests._dv_serve import served

pytest.importorskip("dv_processing")

pytestmark = pytest.mark.timeout(120)


@pytest.fixture(scope="module")
def clip(tmp_path_factory):
    """A few hundred thousand events of a simulated stereo scene, in a file."""
    rec = simulate_preset("2arms-50cm", seconds=2.0, seed=0)
    path = tmp_path_factory.mktemp("dv") / "clip.npz"
    write_recording_npz(path, rec)
    return path, rec


def _summary(err: str) -> dict:
    return json.loads(err.strip().splitlines()[-1])


@pytest.mark.parametrize("method", [DEFAULT_METHOD, "fused"])
def test_live_dv_receives_every_event_and_matches_as_the_file(clip, method, capsys):
    import cvstereo as cvs

    path, rec = clip
    assert rec.left.size + rec.right.size > 200_000
    with served(path) as (left, right):
        assert main(["live", "--dv", left, right] + ([] if method == DEFAULT_METHOD else ["-m", method])) == 0
    report = _summary(capsys.readouterr().err)
    summary, status = report["summary"], report["status"]
    assert (summary["events_left"], summary["events_right"]) == (rec.left.size, rec.right.size)
    assert status["late_events"] == 0
    expected = cvs.match(rec, method=method, rig_check=False).matches  # live does not check the rig
    assert expected.size > 100
    assert summary["matches"] == expected.size
    assert summary["matches_sha256"] == hashlib.sha256(expected.tobytes()).hexdigest()
    assert status["left"]["protocol"].endswith(f"{rec.resolution[0]}x{rec.resolution[1]}")


def test_record_dv_reads_back_event_for_event(clip, tmp_path, capsys):
    path, rec = clip
    out = tmp_path / "rec.npz"
    with served(path) as (left, right):
        assert main(["record", "--dv", left, right, "-o", str(out)]) == 0
    got = read_recording_npz(out)
    np.testing.assert_array_equal(got.left, rec.left)
    np.testing.assert_array_equal(got.right, rec.right)
    assert got.resolution == rec.resolution
    assert not (tmp_path / "rec.npz.journal").exists()
    assert "corrupt bytes" not in capsys.readouterr().err  # a DV stream has decoded events, no bytes


def test_resolution_comes_from_the_stream(clip, tmp_path, capsys):
    # Both streams state 240x180 (a DAVIS240): the recording is written with it, not with the eDVS's 128x128.
    path, _ = clip
    out = tmp_path / "rec.npz"
    size = ("--resolution", "240", "180")
    with served(path, extra=(size, size)) as (left, right):
        assert main(["record", "--dv", left, right, "-o", str(out)]) == 0
    assert read_recording_npz(out).resolution == (240, 180)


# -- the camera path, through its seam ----------------------------------------------------------------------------
class FakeCamera:
    """What dv-processing's camera objects offer the source: batches of events, then the end."""

    def __init__(self, serial, events, resolution=(346, 260)):
        self.serial, self.resolution = serial, resolution
        self.batches = [events[i:i + 1000] for i in range(0, events.size, 1000)]
        self.synced_with = None

    def getCameraName(self):
        return f"DAVIS346_{self.serial}"

    def isEventStreamAvailable(self):
        return True

    def getEventResolution(self):
        return self.resolution

    def getNextEventBatch(self):
        if not self.batches:
            return None
        part = self.batches.pop(0)
        raw = np.zeros(part.size, [("timestamp", "<i8"), ("x", "<i2"), ("y", "<i2"), ("polarity", "i1")])
        for ours, theirs in (("t", "timestamp"), ("x", "x"), ("y", "y"), ("p", "polarity")):
            raw[theirs] = part[ours]
        return types.SimpleNamespace(numpy=lambda: raw)

    def isRunning(self):
        return bool(self.batches)


def fake_dv(cameras: dict[str, FakeCamera], *, syncable=True):
    """A stand-in for dv_processing with the camera module's discover/open/openSync/synchronizeAnyTwo."""
    opened = []

    def open_sync(desc):
        if not syncable:
            raise RuntimeError("device does not support synchronization")
        opened.append(("openSync", desc.serialNumber))
        return cameras[desc.serialNumber]

    def open_plain(desc):
        opened.append(("open", desc.serialNumber))
        return cameras[desc.serialNumber]

    def synchronize(a, b):
        a.synced_with, b.synced_with = b.serial, a.serial

    camera = types.SimpleNamespace(
        discover=lambda: [types.SimpleNamespace(serialNumber=s, cameraModel="DAVIS346") for s in cameras],
        open=open_plain, openSync=open_sync, synchronizeAnyTwo=synchronize)
    return types.SimpleNamespace(io=types.SimpleNamespace(camera=camera)), opened


@pytest.mark.parametrize("syncable", [True, False])
def test_two_cameras_are_opened_together_synchronised_where_they_can_be(monkeypatch, rng, syncable):
    from cvstereo.sensors import dvlive
    from cvstereo.sensors.stereo import StereoRig

    def events(n, shift):
        t = np.sort(rng.integers(0, 500_000, n)) + 1_700_000_000_000_000
        ev = np.zeros(n, dvlive.EVENT_DTYPE)
        ev["t"], ev["x"], ev["y"] = t, rng.integers(shift, 346, n), rng.integers(0, 260, n)
        ev["p"] = rng.integers(0, 2, n)
        return ev

    left, right = events(5000, 0), events(4000, 5)
    cams = {"00001": FakeCamera("00001", left), "00002": FakeCamera("00002", right)}
    fake, opened = fake_dv(cams, syncable=syncable)
    monkeypatch.setattr(dvlive, "_dv", lambda: fake)
    # One by serial number, one by MODEL_SERIAL name, as dv-list-devices shows them.
    rig = StereoRig(dvlive.dv_sources("00001", "DAVIS346_00002"))
    with rig:
        assert rig.resolution == (346, 260)
        rig.start()
        got = [[], []]
        deadline = time.monotonic() + 10
        while not all(c.ended for c in rig.cams) and time.monotonic() < deadline:
            for cam_i, chunk in rig.poll(0.01):
                got[cam_i].append(chunk.events)
        for cam_i, chunk in rig.poll(0):
            got[cam_i].append(chunk.events)
    np.testing.assert_array_equal(np.concatenate(got[0]), left)
    np.testing.assert_array_equal(np.concatenate(got[1]), right)
    if syncable:
        assert opened == [("openSync", "00001"), ("openSync", "00002")]
        assert (cams["00001"].synced_with, cams["00002"].synced_with) == ("00002", "00001")
    else:
        assert opened == [("open", "00001"), ("open", "00002")]


def test_a_camera_not_connected_is_one_error_listing_those_that_are(monkeypatch, capsys):
    from cvstereo.sensors import dvlive

    fake, _ = fake_dv({"00001": FakeCamera("00001", np.zeros(0, dvlive.EVENT_DTYPE))})
    monkeypatch.setattr(dvlive, "_dv", lambda: fake)
    assert main(["live", "--dv", "00001", "00009"]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("cvstereo live: error: ") and len(err.splitlines()) == 1
    assert "00009" in err and "DAVIS346_00001" in err
