"""Hostile sweeps (issue 27): recordings that are no regular files, grid files of the wrong shape, values no
matcher takes, output folders that are files, cell files that lie, cells that fail.

Every case runs ``cvstereo sweep`` in-process (``--workers 0``: no Dask, the checks are the same) on files made
under ``tmp_path`` and asserts what ``tests/_hostile.py`` checks: exit code, the one-line error naming the
file, key and value, no traceback, inputs unchanged, no output folder left by a refused run. A refusal must
come before any work: a FIFO or ``/dev/zero`` as recording used to block or be hashed for ever, a value the
matcher refuses used to fail every cell without a word on screen.
"""

from __future__ import annotations

import contextlib
import json
import os
import socket
import time
from pathlib import Path

import pytest

pytest.importorskip("pyarrow")

from cvstereo.io import write_matches, write_recording
from cvstereo.sweep import TIMING_COLUMNS
from tests._hostile import case, check_case, null_device, run_cli
from tests._io_helpers import textured_blobs

pytestmark = pytest.mark.timeout(60)

#: A refusal (or a failing cell) must end the command within this many seconds: no hang.
PROMPT_S = 10

RUN = "--workers 0 -o out"

GRIDS = {
    "g_ok": '[[grid]]\nmethods = ["frame"]\nparams = { width_tolerance = [0.2, 0.3] }\n',
    "g_grid5": "grid = [5]\n",
    "g_grid_number": "grid = 5\n",
    "g_methods_str": '[[grid]]\nmethods = "frame"\n',
    "g_methods_num": "[[grid]]\nmethods = [5]\n",
    "g_methods_empty": "[[grid]]\nmethods = []\n",
    "g_method_unknown": '[[grid]]\nmethods = ["frame", "telepathy"]\n',
    "g_variants_str": '[[grid]]\nmethods = ["frame"]\nvariants = "all"\n',
    "g_variant_unknown": '[[grid]]\nmethods = ["frame"]\nvariants = ["gaussian"]\n',
    "g_params_number": '[[grid]]\nmethods = ["frame"]\nparams = 5\n',
    "g_value_nan": '[[grid]]\nmethods = ["frame"]\nparams = { threshold = [1.2, nan] }\n',
    "g_value_str": '[[grid]]\nmethods = ["event-time"]\nparams = { threshold = ["high"] }\n',
    "g_value_fraction": '[[grid]]\nmethods = ["frame"]\nparams = { window_us = [40000, 1.5] }\n',
    "g_value_negative": '[[grid]]\nmethods = ["frame"]\nparams = { max_disparity = [-5] }\n',
    "g_value_bool": '[[grid]]\nmethods = ["frame"]\nparams = { threshold = [true] }\n',
    "g_value_choice": '[[grid]]\nmethods = ["frame"]\nparams = { polarity = ["sideways"] }\n',
    "g_value_table": '[[grid]]\nmethods = ["frame"]\nparams = { threshold = [{ a = 1 }] }\n',
    "g_values_empty": '[[grid]]\nmethods = ["frame"]\nparams = { threshold = [] }\n',
    "g_param_unknown": '[[grid]]\nmethods = ["frame"]\nparams = { telepathy = [1] }\n',
    "g_param_sets_bad": '[[grid]]\nmethods = ["frame"]\nparam_sets = ["fast"]\n',
    "g_block_key_typo": '[[grid]]\nmethods = ["frame"]\nparam = { threshold = [1.0] }\n',
    "g_top_key_typo": 'figures = "mae"\n[[grid]]\nmethods = ["frame"]\n',
    "g_figure_unknown": 'figure = "accuracy"\n[[grid]]\nmethods = ["frame"]\n',
    "g_recordings_str": 'recordings = "rec.npz"\n[[grid]]\nmethods = ["frame"]\n',
    "g_recordings_fifo": 'recordings = ["fifo.npz"]\n[[grid]]\nmethods = ["frame"]\n',
}


@pytest.fixture(scope="module")
def base(tmp_path_factory) -> Path:
    """Every file the cases read, made once; each case works on its own copy."""
    from calibration_free import match

    d = tmp_path_factory.mktemp("hostile2-sweep")
    rec = textured_blobs(0, 4)
    write_recording(d / "rec.npz", rec)
    result = match(d / "rec.npz", method="frame")
    write_matches(d / "m.npz", result.matches, result.meta)  # a matches file, not a recording
    for i in range(5):
        (d / f"corrupt{i}.npz").write_bytes(b"PK\x03\x04 not a zip file " + bytes([i]))
    for name, text in GRIDS.items():
        (d / f"{name}.toml").write_text(text)
    (d / "g_binary.toml").write_bytes(b"\xff\xfe\x00grid\x80\x81")
    (d / "file.txt").write_text("not a folder\n")
    return d


@pytest.fixture
def work(base, tmp_path, monkeypatch) -> Path:
    """A copy of the base files plus the hostile ones (a folder, FIFOs, a device), as the working folder."""
    for p in base.iterdir():
        (tmp_path / p.name).write_bytes(p.read_bytes())
    (tmp_path / "dir.npz").mkdir()
    (tmp_path / "dir.toml").mkdir()
    (tmp_path / "outcells").mkdir()
    (tmp_path / "outcells" / "cells").write_text("a file where the cells folder goes\n")
    os.mkfifo(tmp_path / "fifo.npz")
    os.mkfifo(tmp_path / "fifo.toml")
    null_device(tmp_path / "null.dev")
    monkeypatch.chdir(tmp_path)
    return tmp_path


def grid_case(name: str, *err: str, code: int = 1):
    return case(f"sweep rec.npz --grid {name}.toml {RUN}", code, (f"{name}.toml", *err), absent="out")


NOT_REGULAR = "not a regular file"
CASES = {
    # --- recordings that are no regular files: refused before any hashing, no output folder -----------------
    "recording-fifo": case(f"sweep fifo.npz -m frame {RUN}", 1, ("fifo.npz", NOT_REGULAR), absent="out"),
    "recording-dev-zero": case(f"sweep /dev/zero -m frame {RUN}", 1, ("/dev/zero", NOT_REGULAR), absent="out"),
    "recording-device": case(f"sweep null.dev -m frame {RUN}", 1, ("null.dev", NOT_REGULAR), absent="out"),
    "recording-folder": case(f"sweep dir.npz -m frame {RUN}", 1, ("dir.npz", "is a directory"), absent="out"),
    "recording-glob-finds-fifo": case(f"sweep f*.npz -m frame {RUN}", 1, ("fifo.npz", NOT_REGULAR), absent="out"),
    "recording-fifo-after-good": case(f"sweep rec.npz fifo.npz -m frame {RUN}", 1, ("fifo.npz", NOT_REGULAR),
                                      absent="out"),
    "recording-from-grid-fifo": case(f"sweep --grid g_recordings_fifo.toml {RUN}", 1, ("fifo.npz", NOT_REGULAR),
                                     absent="out"),
    "recording-missing": case(f"sweep nothere.npz -m frame {RUN}", 1, ("nothere.npz", "does not exist"),
                              absent="out"),
    # --- preset specs -------------------------------------------------------------------------------------
    "preset-seconds-text": case(f"sweep preset:1arm-50cm:abc -m frame {RUN}", 1, ("preset:1arm-50cm:abc", "seconds"),
                                absent="out"),
    "preset-seconds-inf": case(f"sweep preset:1arm-50cm:inf -m frame {RUN}", 1, ("preset:1arm-50cm:inf", "seconds"),
                               absent="out"),
    "preset-seconds-negative": case(f"sweep preset:1arm-50cm:-1 -m frame {RUN}", 1,
                                    ("preset:1arm-50cm:-1", "seconds"), absent="out"),
    "preset-unknown": case(f"sweep preset:telepathy -m frame {RUN}", 1, ("preset:telepathy", "1arm-50cm"),
                           absent="out"),
    "preset-too-many-parts": case(f"sweep preset:1arm-50cm:1:2 -m frame {RUN}", 1, "preset:1arm-50cm:1:2",
                                  absent="out"),
    "suite-unknown": case(f"sweep suite:telepathy -m frame {RUN}", 1, ("suite:telepathy", "robustness"),
                          absent="out"),
    "suite-half-unknown": case(f"sweep suite:robustness:half -m frame {RUN}", 1, "suite:robustness:half",
                               absent="out"),
    # --- grid files: shape and types -------------------------------------------------------------------
    "grid-list-of-numbers": grid_case("g_grid5", "[[grid]]"),
    "grid-a-number": grid_case("g_grid_number", "[[grid]]"),
    "grid-methods-string": grid_case("g_methods_str", "methods", '["frame"]'),
    "grid-methods-numbers": grid_case("g_methods_num", "methods", "5"),
    "grid-methods-empty": grid_case("g_methods_empty", "methods"),
    "grid-method-unknown": grid_case("g_method_unknown", "telepathy"),
    "grid-variants-string": grid_case("g_variants_str", "variants", '["all"]'),
    "grid-variant-unknown": grid_case("g_variant_unknown", "gaussian"),
    "grid-params-number": grid_case("g_params_number", "params"),
    "grid-param-unknown": grid_case("g_param_unknown", "telepathy"),
    "grid-param-sets-unknown": grid_case("g_param_sets_bad", "param_sets", "fast"),
    "grid-block-key-typo": grid_case("g_block_key_typo", "param"),
    "grid-top-key-typo": grid_case("g_top_key_typo", "figures"),
    "grid-figure-unknown": grid_case("g_figure_unknown", "figure", "accuracy"),
    "grid-recordings-string": grid_case("g_recordings_str", "recordings", '["rec.npz"]'),
    "grid-file-fifo": case(f"sweep rec.npz --grid fifo.toml {RUN}", 1, ("fifo.toml", NOT_REGULAR), absent="out"),
    "grid-file-folder": case(f"sweep rec.npz --grid dir.toml {RUN}", 1, ("dir.toml", "is a directory"),
                             absent="out"),
    "grid-file-binary": case(f"sweep rec.npz --grid g_binary.toml {RUN}", 1, "g_binary.toml", absent="out"),
    # --- grid values the matcher refuses: every cell's parameters built up front, the first bad one named --
    "grid-value-nan": grid_case("g_value_nan", "threshold", "nan"),
    "grid-value-string": grid_case("g_value_str", "threshold", "high"),
    "grid-value-fraction-for-int": grid_case("g_value_fraction", "window_us", "1.5"),
    "grid-value-negative": grid_case("g_value_negative", "max_disparity", "-5"),
    "grid-value-bool-for-number": grid_case("g_value_bool", "threshold", "true"),
    "grid-value-not-a-choice": grid_case("g_value_choice", "polarity", "sideways"),
    "grid-value-table": grid_case("g_value_table", "threshold"),
    "grid-values-empty": grid_case("g_values_empty", "threshold"),
    # --- the same from the command line ------------------------------------------------------------------
    "param-negative": case(f"sweep rec.npz -m frame -p max_disparity=-5 {RUN}", 1, ("max_disparity", "-5"),
                           absent="out"),
    "param-zero-window": case(f"sweep rec.npz -m frame -p window_us=0 {RUN}", 1, "window_us", absent="out"),
    "param-empty-value": case(f"sweep rec.npz -m frame -p threshold=1.2, {RUN}", 1, "threshold", absent="out"),
    "param-set-unknown": case(f"sweep rec.npz -m frame --param-set fast {RUN}", 1, ("--param-set", "fast"),
                              absent="out"),
    "figure-unknown": case(f"sweep rec.npz -m frame --figure accuracy {RUN}", 1, ("--figure", "accuracy"),
                           absent="out"),
    # --- the output folder ----------------------------------------------------------------------------------
    "output-is-a-file": case("sweep rec.npz -m frame --workers 0 -o file.txt", 1, ("-o file.txt", "not a folder")),
    "output-is-a-device": case("sweep rec.npz -m frame --workers 0 -o null.dev", 1, ("-o null.dev", "not a folder")),
    "output-is-a-fifo": case("sweep rec.npz -m frame --workers 0 -o fifo.npz", 1, ("-o fifo.npz", "not a folder")),
    "output-cells-is-a-file": case("sweep rec.npz -m frame --workers 0 -o outcells", 1, ("cells", "not a folder")),
    # --- failing cells: recorded, and their reasons on screen --------------------------------------------
    "failing-cell-reason-shown": case(f"sweep rec.npz m.npz -m frame {RUN}", 0,
                                      ("m.npz", "failed", "matches file"), out="1 failed"),
    "many-failing-cells-counted": case(f"sweep corrupt0.npz corrupt1.npz corrupt2.npz corrupt3.npz corrupt4.npz "
                                       f"-m frame {RUN}", 0, ("corrupt0.npz", "corrupt2.npz", "2 more"),
                                       out="5 failed"),
}


@pytest.mark.parametrize("hostile", list(CASES.values()), ids=list(CASES))
def test_hostile_sweep(hostile, work, capsys):
    start = time.monotonic()
    _, err = check_case(hostile, work, capsys)
    if hostile.code != 0:  # a refusal does no work
        assert time.monotonic() - start < PROMPT_S, f"HANG: took {time.monotonic() - start:.0f} s"
    else:
        # Each shown reason is one line; they are few however many cells failed.
        shown = [line for line in err.splitlines() if "failed" in line]
        assert 1 <= len(shown) <= 4, f"MESSAGE: {len(shown)} lines for failing cells: {err!r}"


def _free_port() -> int:
    with contextlib.closing(socket.socket()) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.parametrize("address", ["nonsense", "tcp://127.0.0.1:{port}"], ids=["malformed", "nobody-listens"])
def test_scheduler_that_does_not_answer_is_refused_promptly(work, capsys, address):
    pytest.importorskip("dask.distributed")  # imported before the clock starts: the wait is what is timed
    address = address.format(port=_free_port())
    start = time.monotonic()
    check_case(case(["sweep", "rec.npz", "-m", "frame", "--scheduler", address, "-o", "out"], 1,
                    ("--scheduler", address), absent="out"), work, capsys)
    assert time.monotonic() - start < PROMPT_S, f"HANG: took {time.monotonic() - start:.0f} s"


# --------------------------------------------------------------------------------------------- cell files

def _table(out: Path) -> list[dict]:
    import pyarrow.parquet as pq

    return [{k: v for k, v in row.items() if k not in TIMING_COLUMNS}
            for row in pq.read_table(out / "results.parquet").to_pylist()]


CELL_CONTENTS = {
    "empty-list": b"[]",
    "empty-object": b"{}",
    "null": b"null",
    "empty-file": b"",
    "garbage": b"\x00\xff garbage \x80",
    "truncated": b'{"matches": 12, "cover',
    "no-figures": b'{"error": null}',
    "figures-wrong-type": b'{"matches": "many", "error": null}',
    "figure-nan": None,  # the real cell with bad2 = NaN (json.dumps writes NaN)
    "another-cells-file": None,  # the other cell's file under this cell's name
}


@pytest.mark.parametrize("content", list(CELL_CONTENTS), ids=list(CELL_CONTENTS))
def test_cell_file_that_is_not_a_whole_cell_is_recomputed(work, capsys, content):
    """A finished sweep, one cell file damaged, the same sweep again: that cell is recomputed (said on
    stderr), the other reused, and the table is the first run's."""
    argv = f"sweep rec.npz --grid g_ok.toml {RUN}".split()
    assert run_cli(argv) == (0, "")
    capsys.readouterr()
    first = _table(work / "out")
    files = sorted((work / "out" / "cells").glob("*.json"))
    assert len(files) == 2
    damaged, other = files
    if content == "figure-nan":
        row = json.loads(damaged.read_text())
        row["bad2"] = float("nan")
        damaged.write_text(json.dumps(row))
    elif content == "another-cells-file":
        damaged.write_bytes(other.read_bytes())
    else:
        damaged.write_bytes(CELL_CONTENTS[content])
    code, escaped = run_cli(argv)
    out, err = capsys.readouterr()
    assert not escaped, escaped
    assert code == 0, f"MESSAGE: exit {code}: {err}"
    assert "1 run now, 1 from an earlier run" in out, f"SILENT: the damaged cell was trusted: {out!r}"
    assert "1 cell file" in err and "recomputed" in err, f"MESSAGE: no note of the recomputed cell: {err!r}"
    assert _table(work / "out") == first, "SILENT: the table differs from the first run's"


def test_cell_file_that_is_a_fifo_is_refused_promptly(work, capsys):
    argv = f"sweep rec.npz --grid g_ok.toml {RUN}".split()
    assert run_cli(argv) == (0, "")
    capsys.readouterr()
    cell = sorted((work / "out" / "cells").glob("*.json"))[0]
    cell.unlink()
    os.mkfifo(cell)
    start = time.monotonic()
    check_case(case(argv, 1, (cell.name, NOT_REGULAR)), work, capsys)
    assert time.monotonic() - start < PROMPT_S, f"HANG: took {time.monotonic() - start:.0f} s"
