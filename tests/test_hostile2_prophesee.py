"""Hostile Prophesee / Metavision files (issues 26 and 27): every damaged or mislabelled file ends in one line
naming the file and the format; good files of every kind read whole.

The files are packed byte by byte from the published format descriptions (tests/_prophesee_files.py): EVT 2.0,
2.1 and 3.0 ``.raw``, Prophesee CD ``.dat`` and Metavision CSV, 3,000 events each on a 128x128 sensor. Then they
are damaged as files are in practice: cut inside a word, random bytes after the header, a zeroed or erased
(0xFF) body, a header that names another encoding than the data's or one cvstereo does not read, a ``.dat``
event type that is not CD, a sensor no camera has, CSV lines that are not four numbers, a ``--columns`` that
does not name x, y, p and t. The TUM lab's eDVS text ``.dat`` keeps reading as eDVS text.

Failures say their kind (``tests/_hostile.py``), so that ``bench/hostile_tally.py`` tallies old and new code.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tests._hostile import case, check_case
from tests._hostile_calls import working_copy
from tests._prophesee_files import csv_file, dat_file, evt2_words, evt21_words, raw_file, raw_header, scene_events

pytest.importorskip("faery")
pytest.importorskip("evt3")

pytestmark = pytest.mark.timeout(60)

N = 3000
W = H = 128
EVENTS = scene_events(N, W, H, seed=5)


def _body(data: bytes) -> int:
    """Offset of the first event byte of a file written by tests/_prophesee_files.py."""
    return data.index(b"% end\n") + 6 if b"% end\n" in data else data.index(bytes([0x0C, 8])) + 2


@pytest.fixture(scope="module")
def base(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("prophesee")
    rng = np.random.default_rng(11)
    for enc in ("evt2", "evt21", "evt3"):
        raw_file(d / f"{enc}.raw", EVENTS, enc, W, H)
    raw_file(d / "right_evt3.raw", EVENTS, "evt3", W, H)
    dat_file(d / "cd.dat", EVENTS, W, H)
    dat_file(d / "cd.txt", EVENTS, W, H)
    csv_file(d / "mv.csv", EVENTS)
    (d / "edvs.dat").write_text("# resolution 128 128\n" + "".join(
        f"{int(e['t'])} {int(e['x'])} {int(e['y'])} {int(e['p'])} {k % 2}\n" for k, e in enumerate(EVENTS)))
    for name in ("evt2.raw", "evt21.raw", "evt3.raw", "cd.dat"):
        data = (d / name).read_bytes()
        start = _body(data)
        (d / f"cut_{name}").write_bytes(data[:-3])
        (d / f"garbage_{name}").write_bytes(data[:start] + rng.integers(0, 256, len(data) - start, np.uint8).tobytes())
        (d / f"zeroed_{name}").write_bytes(data[:start] + bytes(len(data) - start))
        (d / f"erased_{name}").write_bytes(data[:start] + b"\xff" * (len(data) - start))
    # A header that names one encoding over another's data.
    (d / "evt3_over_evt2.raw").write_bytes(raw_header("evt3", W, H) + evt2_words(EVENTS).tobytes())
    (d / "evt2_over_evt21.raw").write_bytes(raw_header("evt2", W, H) + evt21_words(EVENTS).tobytes())
    (d / "histo.raw").write_bytes(b"% format HISTO3D;height=128;width=128\n% end\n" + bytes(range(256)) * 8)
    (d / "noheader.raw").write_bytes(rng.integers(0, 256, 4096, np.uint8).tobytes())
    (d / "huge.raw").write_bytes(raw_header("evt3", W, H).replace(b"128x128", b"99999x128")
                                 .replace(b"width=128", b"width=99999") + b"\x00\x80" * 8)
    (d / "nosize.raw").write_bytes(b"% format EVT3\n% end\n" + (d / "evt3.raw").read_bytes()[_body(
        (d / "evt3.raw").read_bytes()):])
    raw_file(d / "small.raw", EVENTS[EVENTS["x"] < 64], "evt3", 64, 128)
    data = (d / "cd.dat").read_bytes()
    (d / "trigger.dat").write_bytes(data.replace(bytes([0x0C, 8]), bytes([0x0E, 8]), 1))
    text = (d / "mv.csv").read_text().splitlines()
    (d / "bad_line.csv").write_text("\n".join([*text[:100], "12,7,1,abc", *text[100:]]) + "\n")
    (d / "three.csv").write_text("\n".join(",".join(line.split(",")[:3]) for line in text) + "\n")
    (d / "outside.csv").write_text("\n".join([*text[:50], "200,3,1," + text[50].split(",")[3], *text[51:]]) + "\n")
    (d / "back.csv").write_text("\n".join([*text[:60], text[60].rsplit(",", 1)[0] + ",0", *text[61:]]) + "\n")
    return d


@pytest.fixture
def work(base, tmp_path, monkeypatch) -> Path:
    return working_copy(base, tmp_path, monkeypatch)


CASES = {
    # --- good files: every event read, told by content ------------------------------------------------------
    **{f"reads-{name.replace('.', '-')}": case(f"info {name}", 0, out=f"{N:,}")
       for name in ("evt2.raw", "evt21.raw", "evt3.raw", "cd.dat", "cd.txt")},
    "edvs-dat-stays-edvs": case("info edvs.dat", 0, out=("edvs-merged", f"{N // 2:,}")),
    "reads-csv": case("info mv.csv --resolution 128x128", 0, out=f"{N:,}"),
    "matches-evt3-pair": case("match evt3.raw right_evt3.raw -o m.npz", 0, writes="m.npz"),
    # --- cut inside a word ---------------------------------------------------------------------------------
    **{f"cut-{name.replace('.', '-')}": case(f"info cut_{name}", 1, (f"cut_{name}", what, "truncated"))
       for name, what in (("evt2.raw", "EVT 2.0"), ("evt21.raw", "EVT 2.1"), ("evt3.raw", "EVT 3.0"),
                          ("cd.dat", "Prophesee DAT"))},
    # --- damaged bodies ------------------------------------------------------------------------------------
    **{f"{kind}-{name.replace('.', '-')}": case(f"info {kind}_{name}", 1, (f"{kind}_{name}", what))
       for kind in ("garbage", "zeroed", "erased")
       for name, what in (("evt2.raw", "EVT 2.0"), ("evt21.raw", "EVT 2.1"), ("evt3.raw", "EVT 3.0"),
                          ("cd.dat", "Prophesee DAT"))},
    # --- headers that lie or that cvstereo does not read ---------------------------------------------------
    "evt3-header-over-evt2-data": case("info evt3_over_evt2.raw", 1, ("evt3_over_evt2.raw", "EVT 3.0")),
    "evt2-header-over-evt21-data": case("info evt2_over_evt21.raw", 1, ("evt2_over_evt21.raw", "EVT 2.0")),
    "histo3d-encoding": case("info histo.raw", 1, ("histo.raw", "HISTO3D")),
    "raw-without-header": case("info noheader.raw", 1, ("noheader.raw", "--format")),
    "sensor-too-large": case("info huge.raw", 1, ("huge.raw", "EVT 3.0", "99999")),
    "no-size-no-option": case("info nosize.raw", 1, ("nosize.raw", "EVT 3.0", "--resolution")),
    "dat-trigger-events": case("info trigger.dat", 1, ("trigger.dat", "Prophesee DAT", "0x0e")),
    # --- options that contradict the file ------------------------------------------------------------------
    "format-option-other-encoding": case("info evt2.raw --format evt3", 1, ("evt2.raw", "EVT 2.0", "EVT 3.0")),
    "format-option-on-edvs-text": case("info edvs.dat --format prophesee-dat", 1, ("edvs.dat", "Prophesee DAT")),
    "pair-of-two-encodings": case("info evt3.raw evt2.raw --format evt3", 1, ("evt2.raw", "EVT 2.0")),
    "pair-of-two-sizes": case("match evt3.raw small.raw -o m.npz", 1, ("evt3.raw", "sizes"), absent="m.npz"),
    "resolution-contradicts-header": case("info evt3.raw --resolution 640x480", 1, ("evt3.raw", "128x128")),
    "columns-on-evt3": case("info evt3.raw --columns t,x,y,p", 1, ("evt3.raw", "columns", "evt3")),
    # --- Metavision CSV ------------------------------------------------------------------------------------
    "csv-bad-line": case("info bad_line.csv --resolution 128x128", 1, ("bad_line.csv", "Metavision CSV", "line 101")),
    "csv-three-columns": case("info three.csv --format metavision-csv --resolution 128x128", 1,
                              ("three.csv", "Metavision CSV", "line 1")),
    "csv-outside-sensor": case("info outside.csv --resolution 128x128", 1, ("outside.csv", "Metavision CSV", "200")),
    "csv-time-back": case("info back.csv --resolution 128x128", 1, ("back.csv", "Metavision CSV", "earlier")),
    "csv-columns-not-xypt": case("info mv.csv --format metavision-csv --columns x,y,t --resolution 128x128", 1,
                                 ("mv.csv", "columns", "x, y, p and t")),
    "csv-no-resolution": case("info mv.csv", 1, ("mv.csv", "--resolution")),
}


@pytest.mark.parametrize("name", CASES)
def test_hostile_prophesee(name, work, capsys):
    check_case(CASES[name], work, capsys)
