"""``cvstereo match``'s default rig check on a prefix (issue 24 item 4): when it runs, what wins over it, what the
matches file records; a DSEC sequence's own calibration."""

from __future__ import annotations

from pathlib import Path

import pytest

from cvstereo.cli import main
from cvstereo.io import read_matches, write_recording
from tests.rigcheck.test_rigcheck import textured_patches, with_rig_errors

ROWS = 2


@pytest.fixture(scope="module")
def shifted(tmp_path_factory) -> Path:
    """Textured patches whose right camera sits ROWS rows low: the check must find -ROWS."""
    path = tmp_path_factory.mktemp("rig") / "shifted.npz"
    write_recording(path, with_rig_errors(textured_patches(seconds=0.4, seed=5), rows=ROWS))
    return path


def _match(path, tmp_path, *extra) -> tuple[dict, str]:
    out = tmp_path / "m.npz"
    assert main(["match", str(path), "-m", "frame-area", "-o", str(out), "--no-progress", *extra]) == 0
    return read_matches(out).meta, out


def test_default_checks_the_prefix_and_says_so(shifted, tmp_path, capsys):
    meta, _ = _match(shifted, tmp_path)
    said = capsys.readouterr().out
    assert meta["rigcheck"]["scope"] == "prefix"
    assert meta["rigcheck"]["applied"]["row_offset"] == -ROWS
    assert meta["geometry"]["rows"] == {"source": "rigcheck", "row_offset": -ROWS}
    assert meta["geometry"]["side"] == {"source": "rigcheck", "swap": False}
    assert "from the rig check of the first" in said
    assert "rig_correction" not in meta                       # the check's own correction, recorded under rigcheck


@pytest.mark.parametrize(("extra", "rows_source"), [(("--no-rig-check",), "none"), (("--param-set", "thesis"), "none"),
                                                     (("--row-offset", "0"), "options")])
def test_no_check_when_turned_off_thesis_or_offsets_given(shifted, tmp_path, extra, rows_source):
    meta, _ = _match(shifted, tmp_path, *extra)
    assert "rigcheck" not in meta
    assert meta["geometry"]["rows"]["source"] == rows_source
    assert meta["geometry"]["rows"]["row_offset"] == 0


def test_auto_keeps_its_meaning_the_whole_recording(shifted, tmp_path):
    meta, _ = _match(shifted, tmp_path, "--auto")
    assert "scope" not in meta["rigcheck"]                   # the full check's report, as before
    assert meta["rig_correction"]["row_offset"] == -ROWS


def test_a_swap_of_the_prefix_check_is_applied_again_for_scoring(tmp_path):
    import numpy as np

    from cvstereo.evaluation.metrics import check_same_recording
    from cvstereo.geometry.source import as_matched
    from cvstereo.io import read_recording

    rec = textured_patches(seconds=0.4, seed=6)
    path = tmp_path / "swapped.npz"
    write_recording(path, with_rig_errors(rec, swap=True))
    meta, _ = _match(path, tmp_path)
    assert meta["rigcheck"]["applied"]["swap"] is True and meta["geometry"]["side"]["swap"] is True
    as_read = read_recording(path)
    assert check_same_recording(as_read, meta) is None       # the fingerprint is the file's as read, not swapped
    assert np.array_equal(as_matched(as_read, meta).left, rec.left)


def test_dsec_sequence_takes_its_own_calibration(tmp_path, capsys):
    pytest.importorskip("h5py")
    pytest.importorskip("hdf5plugin")
    from tests._dsec_scene import write_dsec_sequence

    seq = write_dsec_sequence(tmp_path / "zurich_city_98_a", seconds=0.1, seed=2, truth=False)
    meta, _ = _match(seq, tmp_path)
    assert "rectification" in meta and "rigcheck" not in meta
    assert meta["geometry"]["rows"] == {"source": "calibration", "rectified": True}
    assert "cam_to_cam.yaml" in capsys.readouterr().out
    # An option that a calibration would conflict with means the raw events: no calibration taken then.
    meta, _ = _match(seq, tmp_path, "--row-offset", "0")
    assert "rectification" not in meta and meta["geometry"]["rows"]["source"] == "options"
