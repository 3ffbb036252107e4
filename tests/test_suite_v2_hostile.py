"""Hostile and careless uses of the generalization suite (issue 27's corpus for suite v2): the tuning guard, broken
suite files, halves that do not exist, rig and sensor values out of their domain, a scene on the wrong rig, and
the command lines that reach them (``simulate --suite``, ``sweep suite:NAME:HALF``), a stop mid-generation.

Every failure message starts with its kind (``tests/_hostile.py``): a check the code does not make at all is
SILENT (the wrong recording, value or file goes through), a refusal that does not name the place is MESSAGE.
Names are imported inside the cases, so that ``bench/hostile_tally.py --against`` an older commit counts each
case instead of failing the file at import.
"""

from __future__ import annotations

import copy
import os
import shutil
import signal
import subprocess
import sys
import time
import tomllib
from collections.abc import Callable
from importlib import resources
from pathlib import Path

import pytest

from tests._hostile import Case, case, check_case, leftovers

pytestmark = pytest.mark.timeout(120)


def refused(call: Callable, *fragments: str, error: type = ValueError) -> str:
    """Run ``call``; it must raise ``error`` (a ValueError unless told) in one line holding every fragment."""
    try:
        call()
    except (ImportError, AttributeError) as exc:
        pytest.fail(f"SILENT: this code has no such check ({type(exc).__name__}: {exc})")
    except error as exc:
        text = str(exc)
        missing = [f for f in fragments if f not in text]
        assert not missing, f"MESSAGE: {missing} not in {text!r}"
        assert "\n" not in text, f"MESSAGE: not one line: {text!r}"
        return text
    except Exception as exc:  # the point is to see what escapes
        pytest.fail(f"TRACEBACK: {type(exc).__name__}: {exc}")
    pytest.fail(f"SILENT: accepted, expected a {error.__name__}")


def _suite_data() -> dict:
    text = resources.files("cvstereo.simulate").joinpath("suites", "generalization_v2.toml")
    if not text.is_file():
        pytest.fail("SILENT: no generalization suite file on this code")
    return tomllib.loads(text.read_text(encoding="utf-8"))


def _parse(change: Callable[[dict], object]):
    def call():
        from cvstereo.simulate.generalization import parse_family_suite

        data = copy.deepcopy(_suite_data())
        change(data)
        parse_family_suite(data, where="g.toml")
    return call


def _first(data: dict, half: str) -> dict:
    return next(e for e in data["recording"] if e["half"] == half)


# --- the API ---------------------------------------------------------------------------------------------------

def _sim():
    """``cvstereo.simulate``, imported when a case runs (an older commit lacks some of its names)."""
    import cvstereo.simulate

    return cvstereo.simulate


def _eval_entry():
    return next(r for r in _sim().load_suite("generalization").recordings if r.half == "eval")


API = {  # case -> (call, fragments its one-line ValueError must hold)
    "guard-refuses-an-eval-entry": (lambda: _sim().require_tuning(_eval_entry()),
                                    ("objects-eval-128x128", "eval half", "tuning_recordings")),
    "tuning-half-has-no-eval-recording": (lambda: _sim().tuning_recordings(only=["objects-eval-128x128"]),
                                          ("tune half", "objects-eval-128x128")),
    "photo-in-both-halves": (_parse(lambda d: d["photos"]["eval"].append(d["photos"]["tune"][0])),
                             ("g.toml", "[photos]", "both halves")),
    "eval-recording-shows-a-tuning-photo": (_parse(lambda d: _first(d, "eval").update(photos=d["photos"]["tune"][:1])),
                                            ("g.toml", "recording 4", "eval half's list")),
    "seed-shared-by-the-halves": (_parse(lambda d: _first(d, "eval").update(seed=_first(d, "tune")["seed"])),
                                  ("g.toml", "seed", "objects-tune-128x128")),
    "half-misspelt-in-the-file": (_parse(lambda d: _first(d, "eval").update(half="evaluation")),
                                  ("g.toml", "half must be one of tune, eval")),
    "draw-range-upside-down": (_parse(lambda d: d["draw"].update(jitter_us=[300.0, 0.0])),
                               ("g.toml", "jitter_us", "low <= high")),
    "draw-range-missing": (_parse(lambda d: d["draw"].pop("hot_pixel_rate_hz")), ("g.toml", "hot_pixel_rate_hz")),
    "draw-range-a-string": (_parse(lambda d: d["draw"].update(roll_deg="1 degree")), ("g.toml", "roll_deg")),
    "recording-not-a-table": (_parse(lambda d: d["recording"].append("thin-eval-9")), ("g.toml", "recording 48")),
    "unknown-half-asked": (lambda: _sim().suite_recordings("generalization", half="evaluation"),
                           ("half must be one of tune, eval", "'evaluation'")),
    "half-of-a-suite-without-halves": (lambda: _sim().suite_recordings("robustness", half="tune"),
                                       ("robustness", "no tuning and evaluation halves", "generalization")),
    "roll-not-a-number": (lambda: _sim().Rig(roll_deg=float("nan")), ("roll_deg", "finite")),
    "roll-of-a-rig-upside-down": (lambda: _sim().Rig(roll_deg=180.0), ("roll_deg", "10")),
    "focal-ratio-zero": (lambda: _sim().Rig(focal_ratio=0.0), ("focal_ratio", "[0.5, 2]")),
    "right-lens-distortion-wild": (lambda: _sim().Rig(right_distortion_k1=-5.0), ("right_distortion_k1", "20 %")),
    "hot-pixel-share-above-one": (lambda: _sim().SensorModel(hot_pixel_fraction=1.5),
                                  ("hot_pixel_fraction", "[0, 1]")),
    "hot-pixel-rate-negative": (lambda: _sim().SensorModel(hot_pixel_rate_hz=-1.0), ("hot_pixel_rate_hz", ">= 0")),
    "family-unknown": (lambda: _sim().FamilyScene("sky", 1, (128, 128), 165.0, 1.0),
                       ("unknown scene family 'sky'", "objects")),
    "photo-unknown": (lambda: _sim().FamilyScene("objects", 1, (128, 128), 165.0, 1.0, ("motorcycle_left",)),
                      ("unknown photo", "motorcycle_left")),
    "scene-on-another-rig": (lambda: _sim().FamilyScene("objects", 1, (128, 128), 165.0, 1.0).render(
                                 _sim().Rig(resolution=(346, 260), focal_px=446.0), 0, [0.0]),
                             ("128x128", "346x260", "draw the scene for the rig")),
}


@pytest.mark.parametrize("name", list(API))
def test_hostile_use_of_the_suite_is_refused(name):
    call, fragments = API[name]
    refused(call, *fragments)


def test_guard_refuses_an_eval_recording_file_under_any_name(tmp_path):
    try:
        from cvstereo.simulate import suite_recordings
        from cvstereo.simulate.suite import require_tuning
    except ImportError as exc:
        pytest.fail(f"SILENT: this code has no tuning guard ({exc})")
    (_, path), = suite_recordings("generalization", seconds=0.03, cache_dir=tmp_path / "cache",
                                  only=["thin-eval-128x128"])
    renamed = tmp_path / "my_tuning_clip.npz"
    shutil.copyfile(path, renamed)
    refused(lambda: require_tuning(renamed), "thin-eval-128x128", "eval half", str(renamed))


# --- the command line ------------------------------------------------------------------------------------------

@pytest.fixture
def work(tmp_path, monkeypatch):
    (tmp_path / "file.npz").write_bytes(b"keep me")
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("CVSTEREO_CACHE", str(tmp_path / "cache"))
    return tmp_path


CLI = {
    "list-names-both-suites": case("simulate --list-suites", 0,
                                   out=("robustness (v1): 29", "generalization (v2): 48 recordings",
                                        "thin-eval-640x480", "ON ")),
    "suite-output-is-a-file": case("simulate --suite generalization -o file.npz", 1, ("-o file.npz", "folder")),
    "suite-seconds-zero": case("simulate --suite generalization --seconds 0", 1, "--seconds"),
    "suite-with-scene-options": case("simulate --suite generalization --arms 2", 2),
    "suite-half-in-simulate": case("simulate --suite generalization:tune", 1,
                                   ("no suite 'generalization:tune'", "robustness, generalization")),
    "sweep-half-misspelt": case("sweep suite:generalization:evaluation -m stereobm -o out", 1,
                                ("half must be one of tune, eval", "'evaluation'"), absent=("out",)),
    "sweep-half-of-suite-v1": case("sweep suite:robustness:tune -m stereobm -o out", 1,
                                   ("robustness", "no tuning and evaluation halves"), absent=("out",)),
    "sweep-half-with-a-tail": case("sweep suite:generalization:tune:2 -m stereobm -o out", 1,
                                   ("half must be one of tune, eval", "'tune:2'"), absent=("out",)),
}


@pytest.mark.parametrize("hostile", list(CLI.values()), ids=list(CLI))
def test_hostile_command_line(hostile: Case, work: Path, capsys):
    check_case(hostile, work, capsys)


def test_stop_mid_generation_leaves_no_partial_recording(work):
    """SIGTERM while the suite is being generated: exit 143, one line, and the cache holds whole recordings only
    (a half-written file would be taken for a finished one by the next run)."""
    cache = work / "cache"
    proc = subprocess.Popen([sys.executable, "-m", "cvstereo", "simulate", "--suite", "generalization", "--seconds",
                             "0.4", "--no-progress"], stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True,
                            env={**os.environ, "CVSTEREO_CACHE": str(cache)})
    first = proc.stderr.readline()  # "generated objects-tune-128x128 in ...": the second one is under way
    assert first.startswith("generated "), f"MESSAGE: {first!r}"
    time.sleep(0.1)
    proc.send_signal(signal.SIGTERM)
    try:
        _, err = proc.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        proc.kill()
        pytest.fail("HANG: simulate --suite did not stop within 60 s of SIGTERM")
    assert "Traceback" not in err, f"TRACEBACK: {err}"
    assert proc.returncode == 128 + signal.SIGTERM, f"MESSAGE: exit {proc.returncode}: {err!r}"
    # Recordings that finished before the signal landed are announced as usual (a fast machine finishes the
    # second one first); the stop is the one line after them.
    *done, last = err.strip().splitlines()
    assert last == "cvstereo simulate: stopped by SIGTERM", f"MESSAGE: {err!r}"
    assert all(line.startswith("generated ") for line in done), f"MESSAGE: {err!r}"
    assert not leftovers(cache), f"LEFTOVER: {leftovers(cache)}"
    from cvstereo.io.npz import read_recording_npz

    for path in cache.glob("*.npz"):  # every file there reads back whole
        try:
            read_recording_npz(path)
        except (OSError, ValueError) as exc:
            pytest.fail(f"DATALOSS: {path.name} is not a whole recording: {exc}")
