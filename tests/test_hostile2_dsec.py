"""Hostile DSEC sequence folders and DSEC outputs (issue 26 item 5): `evaluate SEQUENCE m.npz`, `export-dsec`,
`info SEQUENCE`, `match SEQUENCE` on folders whose ground truth is missing, damaged or out of step.

The sequence is written by tests/_dsec_scene.py as DSEC's public description lays one out (events/left,
events/right, calibration/cam_to_cam.yaml, disparity/event/NNNNNN.png, disparity/timestamps.txt); each case
copies it and damages one thing. A refusal is one line naming the file and what to do; nothing is written; a
run that succeeds prints no NaN.

Failures say their kind (``tests/_hostile.py``), so that ``bench/hostile_tally.py`` tallies old and new code.
"""

from __future__ import annotations

import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from tests._hostile import Case, case, check_case

pytest.importorskip("h5py")
pytest.importorskip("hdf5plugin")
cv2 = pytest.importorskip("cv2")

pytestmark = pytest.mark.timeout(120)

SEQ = "seq"
TRUTH = f"{SEQ}/disparity/event"
STAMPS = f"{SEQ}/disparity/timestamps.txt"
CAL = f"{SEQ}/calibration/cam_to_cam.yaml"


@pytest.fixture(scope="module")
def base(tmp_path_factory) -> Path:
    from cvstereo.cli import main
    from tests._dsec_scene import write_dsec_sequence

    d = tmp_path_factory.mktemp("dsec-hostile")
    write_dsec_sequence(d / SEQ, seconds=0.1, seed=5, truth=True)
    assert main(["match", str(d / SEQ / "events" / "left" / "events.h5"),
                 str(d / SEQ / "events" / "right" / "events.h5"), "-m", "event-time", "--calibration", str(d / CAL),
                 "-o", str(d / "m.npz"), "--no-progress"]) == 0
    return d


def _png(shape, dtype, value) -> Callable[[Path], None]:
    def damage(work: Path) -> None:
        encoded, data = cv2.imencode(".png", np.full(shape, value, dtype))
        assert encoded
        (work / TRUTH / "000002.png").write_bytes(data.tobytes())

    return damage


def _write(rel: str, content: bytes | str) -> Callable[[Path], None]:
    def damage(work: Path) -> None:
        (work / rel).write_bytes(content.encode() if isinstance(content, str) else content)

    return damage


def _remove(rel: str) -> Callable[[Path], None]:
    def damage(work: Path) -> None:
        p = work / rel
        shutil.rmtree(p) if p.is_dir() else p.unlink()

    return damage


def _nothing(work: Path) -> None:
    return None


def _stamps(*values: str) -> Callable[[Path], None]:
    return _write(STAMPS, "".join(f"{v}\n" for v in values))


T = 52_000_050_000  # the first map's time (tests/_dsec_scene.py: T_OFFSET + 50 ms)
EVAL = f"evaluate {SEQ} m.npz"
EXPORT = f"export-dsec {SEQ} m.npz -o sub"

# name -> (damage, case)
CASES: dict[str, tuple[Callable[[Path], None], Case]] = {
    # --- ground truth missing or out of step -----------------------------------------------------------------
    "evaluate-no-ground-truth-folder": (_remove(f"{SEQ}/disparity"),
                                        case(EVAL, 1, ("no ground-truth disparity maps", "export-dsec"))),
    "evaluate-pngs-without-timestamps": (_remove(STAMPS), case(EVAL, 1, ("timestamps.txt", "2 PNGs"))),
    "evaluate-timestamps-without-pngs": (_remove(TRUTH), case(EVAL, 1, ("disparity/event", "PNG"))),
    "evaluate-timestamps-one-too-many": (_stamps(T, T + 50_000, T + 100_000),
                                         case(EVAL, 1, ("timestamps.txt", "3 timestamps for 2 PNGs"))),
    "evaluate-timestamps-one-too-few": (_stamps(T), case(EVAL, 1, ("1 timestamps for 2 PNGs",))),
    "evaluate-timestamps-text": (_stamps(T, "soon"), case(EVAL, 1, ("timestamps.txt", "line 2", "'soon'"))),
    "evaluate-timestamps-float": (_stamps(T, "52000100000.5"), case(EVAL, 1, ("line 2", "integer microseconds"))),
    "evaluate-timestamps-backwards": (_stamps(T, T - 1), case(EVAL, 1, ("line 2", "not after"))),
    "evaluate-timestamps-binary": (_write(STAMPS, b"\x00\xff\x1b[2J\n"), case(EVAL, 1, ("line 1", "timestamp"))),
    # --- a damaged PNG -----------------------------------------------------------------------------------------
    "evaluate-png-garbage": (_write(f"{TRUTH}/000002.png", b"\x89PNG\r\n\x1a\nnot really"),
                             case(EVAL, 1, ("000002.png", "not a readable PNG"))),
    "evaluate-png-empty": (_write(f"{TRUTH}/000002.png", b""), case(EVAL, 1, ("000002.png", "PNG"))),
    "evaluate-png-8-bit": (_png((480, 640), np.uint8, 40), case(EVAL, 1, ("000002.png", "16-bit"))),
    "evaluate-png-colour": (_png((480, 640, 3), np.uint16, 4000), case(EVAL, 1, ("000002.png", "one-channel"))),
    "evaluate-png-wrong-size": (_png((240, 320), np.uint16, 4000), case(EVAL, 1, ("000002.png", "320x240",
                                                                                  "640x480"))),
    # --- the rest of the folder ----------------------------------------------------------------------------------
    "evaluate-no-calibration": (_remove(CAL), case(EVAL, 1, (SEQ, "--calibration"))),
    "evaluate-truth-option-for-dsec": (_nothing, case(f"{EVAL} --truth gt.hdf5", 1, ("--truth", "disparity/"))),
    "evaluate-right-events-missing": (_remove(f"{SEQ}/events/right/events.h5"),
                                      case(EVAL, 1, ("events/right/events.h5",))),
    "evaluate-empty-folder": (lambda w: (w / "empty").mkdir(),
                              case("evaluate empty m.npz", 1, ("empty", "is a directory", "DSEC sequence folder"))),
    "match-sequence-and-a-right-file": (_nothing, case(f"match {SEQ} {SEQ}/events/right/events.h5 -o m2.npz", 1,
                                                       ("DSEC sequence folder", "second file"), absent="m2.npz")),
    # --- export -----------------------------------------------------------------------------------------------------
    "export-works": (_nothing, case(EXPORT, 0, out="2 disparity maps", writes=("sub/seq/000002.png",
                                                                               "sub/seq/000004.png"))),
    "export-test-sequence-without-timestamps": (_remove(f"{SEQ}/disparity"),
                                                case(EXPORT, 1, ("--timestamps",), absent="sub")),
    "export-timestamps-one-column": (_write("t.csv", f"{T}\n"),
                                     case(f"{EXPORT} --timestamps t.csv", 1, ("t.csv", "file_index"), absent="sub")),
    "export-timestamps-missing": (_nothing, case(f"{EXPORT} --timestamps none.csv", 1, ("none.csv",),
                                                 absent="sub")),
    "export-output-is-a-file": (_write("sub", b"keep me"), case(EXPORT, 1, ("sub", "not a folder"))),
    "export-not-a-sequence": (_nothing, case("export-dsec m.npz m.npz -o sub", 1, ("m.npz", "DSEC sequence"),
                                             absent="sub")),
    "export-matches-missing": (_nothing, case(f"export-dsec {SEQ} none.npz -o sub", 1, ("none.npz",), absent="sub")),
}


@pytest.fixture
def work(base, tmp_path, monkeypatch) -> Path:
    shutil.copytree(base / SEQ, tmp_path / SEQ)
    shutil.copy2(base / "m.npz", tmp_path / "m.npz")
    monkeypatch.chdir(tmp_path)
    return tmp_path


@pytest.mark.parametrize("name", list(CASES))
def test_hostile_dsec(name: str, work: Path, capsys):
    damage, hostile = CASES[name]
    damage(work)
    check_case(hostile, work, capsys)
