"""Matches that know their recording (issue 27): a matches file carries a fingerprint of the events it was computed
on (counts, first and last time and a checksum per camera, as read), and ``evaluate``, ``video`` and ``plot``
refuse another recording in one line that says why: other events, or the same events on another clock (by how
much). Older files without a fingerprint still read, with a note; ``--force`` overrides.

The hostile recordings keep the event counts of the real one, which was all the old check compared: every
time equal, the clock shifted by 1 s or to the end of int64, the cameras exchanged, one event moved by a pixel.
Every failure message starts with its kind (TRACEBACK, DATALOSS, SILENT, MESSAGE, LEFTOVER).
"""

from __future__ import annotations

import itertools
import json
import shutil
from pathlib import Path

import pytest
from cvstereo.recording import Recording
from hypothesis import given, settings
from hypothesis import strategies as st

from cvstereo.io import read_matches, write_matches, write_recording
from tests._hostile import Case, case, check_case, run_cli
from tests._io_helpers import textured_blobs

pytestmark = pytest.mark.timeout(120)

W = 40_000
#: The shift that puts the last event at the end of int64: the clocks differ by this many microseconds.
END_OF_CLOCK = 2**63 - 1


def _shifted(rec: Recording, dt: int) -> Recording:
    left, right = rec.left.copy(), rec.right.copy()
    left["t"] += dt
    right["t"] += dt
    return Recording(left, right, rec.left_disparity, rec.right_disparity, rec.resolution)


@pytest.fixture(scope="module")
def base(tmp_path_factory) -> Path:
    from calibration_free import match

    d = tmp_path_factory.mktemp("fingerprint-base")
    rec = textured_blobs(0, 4, disparity=13, window_us=W)
    write_recording(d / "rec.npz", rec)
    write_recording(d / "l.txt", rec, right=d / "r.txt")
    for method, name in (("frame", "m.npz"), ("event-time", "m_evt.npz")):
        result = match(d / "rec.npz", method=method)
        assert len(result) > 20
        write_matches(d / name, result.matches, result.meta)
    frame = read_matches(d / "m.npz")  # as a matches file written before fingerprints
    write_matches(d / "m_old.npz", frame.matches, {k: v for k, v in frame.meta.items() if k != "fingerprint"})
    damaged = {"checksum": "sum64-le", "left": {"events": "many", "t_first": "\x1b[2J"}, "right": []}
    write_matches(d / "m_badfp.npz", frame.matches, {**frame.meta, "fingerprint": damaged})
    same_t = rec.left.copy(), rec.right.copy()
    for ev in same_t:
        ev["t"] = rec.left["t"][0]
    write_recording(d / "allt.npz", Recording(*same_t, rec.left_disparity, rec.right_disparity))
    write_recording(d / "shift1s.npz", _shifted(rec, 1_000_000))
    write_recording(d / "shiftend.npz", _shifted(rec, END_OF_CLOCK - int(rec.right["t"][-1])))
    write_recording(d / "swapped.npz", rec.swapped())  # its truth negated: x_left - x_right of the exchanged cameras
    moved = rec.left.copy()
    moved["x"][100] += 1
    write_recording(d / "moved.npz", Recording(moved, rec.right, rec.left_disparity, rec.right_disparity))
    write_recording(d / "empty.npz", Recording(rec.left[:0], rec.right[:0]))
    return d


@pytest.fixture
def work(base, tmp_path, monkeypatch) -> Path:
    for p in base.iterdir():
        shutil.copy2(p, tmp_path / p.name)
    shutil.copy2(base / "rec.npz", tmp_path / "copy.npz")
    monkeypatch.chdir(tmp_path)
    return tmp_path


OTHER = "another recording"
CLOCKS = "the clocks differ by"
CASES = {
    # --- evaluate --------------------------------------------------------------------------------------------
    "evaluate-renamed-copy": case("evaluate copy.npz m.npz", 0, out="| copy |"),
    "evaluate-text-pair-same-events": case("evaluate l.txt r.txt m.npz", 0, out="| l |"),
    "evaluate-every-t-equal": case("evaluate allt.npz m.npz", 1, ("m.npz", OTHER, "--force")),
    "evaluate-clock-shifted-1s": case("evaluate shift1s.npz m.npz", 1, ("m.npz", CLOCKS, "1 s", "--force")),
    "evaluate-clock-at-int64-end": case("evaluate shiftend.npz m.npz", 1, ("m.npz", CLOCKS)),
    "evaluate-cameras-exchanged": case("evaluate swapped.npz m.npz", 1, ("m.npz", OTHER)),
    "evaluate-one-event-moved": case("evaluate moved.npz m.npz", 1, ("m.npz", OTHER)),
    "evaluate-empty": case("evaluate empty.npz m.npz", 1, ("m.npz", OTHER)),
    "evaluate-event-anchors-shifted": case("evaluate shift1s.npz m_evt.npz", 1, ("m_evt.npz", CLOCKS, "1 s")),
    "evaluate-forced": case("evaluate shift1s.npz m.npz --force", 0, out="| shift1s |"),
    "evaluate-old-file": case("evaluate rec.npz m_old.npz", 0, ("m_old.npz", "not checked"), out="| rec |"),
    "evaluate-old-file-other-clock": case("evaluate shift1s.npz m_old.npz", 1, ("m_old.npz", "clock")),
    "evaluate-damaged-fingerprint": case("evaluate rec.npz m_badfp.npz", 0, ("m_badfp.npz", "malformed",
                                                                          "not checked"), out="| rec |"),
    "evaluate-damaged-fingerprint-other-clock": case("evaluate shift1s.npz m_badfp.npz", 1, ("m_badfp.npz",
                                                                                            "clock")),
    # --- video -----------------------------------------------------------------------------------------------
    "video-every-t-equal": case("video allt.npz m.npz -o v.mp4 --scale 1", 1, ("m.npz", OTHER), absent="v.mp4"),
    "video-clock-shifted": case("video shift1s.npz m.npz -o v.mp4 --scale 1", 1, (CLOCKS, "1 s"), absent="v.mp4"),
    "video-empty": case("video empty.npz m.npz -o v.mp4 --scale 1", 1, ("m.npz", OTHER), absent="v.mp4"),
    "video-cameras-exchanged": case("video swapped.npz m.npz -o v.mp4 --scale 1", 1, OTHER, absent="v.mp4"),
    "video-forced": case("video moved.npz m.npz -o v.mp4 --scale 1 --force", 0, out="-> v.mp4", writes="v.mp4"),
    "video-same": case("video copy.npz m.npz -o v.mp4 --scale 1", 0, out="-> v.mp4", writes="v.mp4"),
    # --- plot ------------------------------------------------------------------------------------------------
    "plot-time-every-t-equal": case("plot disparity-time allt.npz m.npz -o p.png", 1, ("m.npz", OTHER),
                                    absent="p.png"),
    "plot-map-clock-shifted": case("plot disparity-map shift1s.npz m.npz -o p.png", 1, CLOCKS, absent="p.png"),
    "plot-hist-one-event-moved": case("plot error-hist moved.npz m.npz -o p.png", 1, OTHER, absent="p.png"),
    "plot-all-cameras-exchanged": case("plot all swapped.npz m.npz -o figs", 1, OTHER, absent="figs"),
    "plot-forced": case("plot disparity-time moved.npz m.npz -o p.png --force", 0, out="-> p.png", writes="p.png"),
}


@pytest.mark.parametrize("hostile", list(CASES.values()), ids=list(CASES))
def test_hostile_fingerprint(hostile: Case, work: Path, capsys):
    if hostile.argv[0] == "plot":
        pytest.importorskip("matplotlib")
    check_case(hostile, work, capsys)


# ------------------------------------------------------------------------------------------------ effects

def test_the_clock_difference_is_said_in_seconds(work, capsys):
    code, _ = run_cli(["evaluate", "shiftend.npz", "m.npz"])
    err = capsys.readouterr().err
    shift_s = (END_OF_CLOCK - int(textured_blobs(0, 4, disparity=13, window_us=W).right["t"][-1])) / 1e6
    assert code == 1, "SILENT: exit 0"
    assert f"{shift_s:.6g} s" in err, f"MESSAGE: the shift {shift_s:.6g} s is not said: {err!r}"


def test_matches_of_swapped_cameras_are_scored_on_the_cameras_they_used(work, capsys):
    """``match --auto`` exchanges the cameras of swapped.npz; evaluating its matches against that file must score
    them on the exchanged cameras (the truth is 13 px everywhere), not on the file's order."""
    assert run_cli(["match", "swapped.npz", "--auto", "-o", "ms.npz"])[0] == 0
    capsys.readouterr()
    code, _ = run_cli(["evaluate", "swapped.npz", "ms.npz", "--json"])
    out, err = capsys.readouterr()
    assert code == 0, f"MESSAGE: exit {code}: {err}"
    figures = json.loads(out)["figures"]
    assert figures["mae"] is not None and figures["mae"] < 1.0, f"SILENT: MAE {figures['mae']} against 13 px"


def _fingerprint_of_cuts(rec: Recording, cuts: list[int]) -> dict:
    """The fingerprint of ``rec`` fed in packets cut at the event indices ``cuts`` (any, repeated, unordered)."""
    from cvstereo.fingerprint import EventFingerprint

    fp = EventFingerprint()
    bounds = [0, *sorted(cuts), None]
    for lo, hi in itertools.pairwise(bounds):
        fp.update(rec.left[lo:hi], rec.right[lo:hi])
    return fp.result()


@settings(max_examples=40, deadline=None)
@given(st.lists(st.integers(0, 2880), max_size=12))
def test_the_fingerprint_does_not_depend_on_packet_cuts(cuts):
    from cvstereo.fingerprint import fingerprint_of

    rec = textured_blobs(0, 4, disparity=13, window_us=W)
    assert _fingerprint_of_cuts(rec, cuts) == fingerprint_of(rec), f"SILENT: cuts {sorted(cuts)} change it"


@pytest.mark.parametrize("packet_us", [1, 999, 40_000, 10**9])
def test_match_stores_the_same_fingerprint_for_any_packet_length(packet_us):
    from cvstereo.fingerprint import fingerprint_of

    from calibration_free import match

    rec = textured_blobs(0, 4, disparity=13, window_us=W)
    got = match(rec, method="frame", packet_us=packet_us).meta.get("fingerprint")
    assert got == fingerprint_of(rec), f"SILENT: packets of {packet_us} us give {got}"


def test_the_fingerprint_tells_every_hostile_recording_apart(base):
    """Independent of the CLI: each hostile recording's fingerprint differs from the real one's."""
    from cvstereo.fingerprint import fingerprint_of

    from cvstereo.io import read_recording

    real = fingerprint_of(read_recording(base / "rec.npz"))
    for name in ("allt", "shift1s", "shiftend", "swapped", "moved", "empty"):
        assert fingerprint_of(read_recording(base / f"{name}.npz")) != real, f"SILENT: {name} looks the same"
    assert fingerprint_of(read_recording(base / "l.txt", base / "r.txt")) == real, \
        "SILENT: the same events read from text differ"
