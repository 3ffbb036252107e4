"""Rows that differ across the image (cvstereo.rigcheck.row_field): the fit, the tiles, the stage, and the whole.

The fit and the tiles are checked on hand-made profiles whose answer is known; the stage on a field whose moved
events are worked out by hand; the whole on a simulated rig with a roll, focal lengths and lenses that differ,
against the rig's own row field (``Rig.right_row_shift``, itself tested against OpenCV's camera model) and the
simulator's per-event truth.
"""

from __future__ import annotations

import numpy as np
import pytest

from cvstereo.cli import main as cli_main
from cvstereo.evaluation.metrics import evaluate
from cvstereo.io.npz import write_recording_npz
from cvstereo.model.events import StereoPacket, make_events
from cvstereo.model.matches import make_matches
from cvstereo.rigcheck.row_field import (
    MIN_ANSWERS,
    MIN_TILES,
    RowField,
    TileRows,
    fit_row_field,
    row_field_stage,
    tile_rows,
)
from cvstereo.run import match
from cvstereo.simulate import Rig, simulate
from tests.simulate.test_suite_v2_truth import QUIET, _plane

RES = (128, 96)


def _grid_tiles(coefficients, *, outliers=()) -> TileRows:
    """A 4 x 3 grid of tiles on RES whose peaks lie on ``a + b u + c v``, some replaced by ``outliers``
    (index, peak)."""
    w, h = RES
    x, y = np.meshgrid((np.arange(4) + 0.5) * w / 4, (np.arange(3) + 0.5) * h / 3 - (h - 1) / 2)
    x, y = x.ravel(), y.ravel()
    peaks = coefficients[0] + coefficients[1] * (x - (w - 1) / 2) / (w / 2) + coefficients[2] * y / (w / 2)
    for index, peak in outliers:
        peaks[index] = peak
    return TileRows(x, y, peaks, np.full(x.size, 10.0))


def test_fit_finds_an_affine_field_past_outlying_tiles():
    truth = np.array([2.0, -1.5, 3.0])
    field = fit_row_field(_grid_tiles(truth, outliers=[(0, 11.0), (7, -9.0), (9, 6.5)]), RES)
    assert field is not None and field.tiles_used == 9 and field.tiles == 12
    np.testing.assert_allclose(field.coefficients, truth, atol=1e-9)
    # Clipped to the agreeing tiles' peaks +-1 row: the corners beyond the tiles' centres do not run away.
    rows = field.rows()
    inliers = np.delete(_grid_tiles(truth).peaks, [0, 7, 9])
    assert rows.min() >= inliers.min() - 1 - 1e-9 and rows.max() <= inliers.max() + 1 + 1e-9


def test_fit_gives_no_field_where_too_few_tiles_agree():
    # Peaks growing as the square of the tile's index, signs alternating: no plane passes within 1.5 rows of more
    # than 4 of them (three fix a plane; checked over every trio when the test was written).
    scattered = _grid_tiles(np.zeros(3))
    index = np.arange(12)
    peaks = 3.0 * index**2 * (-1.0) ** index
    assert fit_row_field(TileRows(scattered.x, scattered.y, peaks, scattered.weights), RES) is None
    few = _grid_tiles(np.array([1.0, 0.0, 0.0]))
    keep = slice(0, MIN_TILES - 1)
    assert fit_row_field(TileRows(few.x[keep], few.y[keep], few.peaks[keep], few.weights[keep]), RES) is None


def test_tiles_tell_their_rows_only_from_a_clear_peak_inside_the_offsets_tried():
    offsets = np.arange(-4, 5, 2)                                   # -4 -2 0 2 4
    counts = np.zeros((5, 1, 4))
    counts[:, 0, 0] = [10, 40, 100, 70, 10]                         # clear peak at 0, leaning to +2
    counts[:, 0, 1] = [10, 20, 30, 60, 100]                         # peak at the end: beyond the offsets tried?
    counts[:, 0, 2] = [95, 97, 100, 96, 98]                         # flat: prominence 0.02
    counts[:, 0, 3] = [0, 5, MIN_ANSWERS - 1, 3, 0]                 # too few answers
    tiles = tile_rows(counts, offsets, RES)
    assert tiles.peaks.size == 1
    # Parabola through (-2, 40), (0, 100), (2, 70): vertex 0.5 * (40 - 70) / (40 - 200 + 70) = 1/6 of a step
    # of 2 rows past 0.
    assert tiles.peaks[0] == pytest.approx(1 / 3, abs=1e-9)
    assert tiles.x[0] == pytest.approx(16.0) and tiles.y[0] == pytest.approx(48 - 47.5)
    assert tiles.weights[0] == pytest.approx(100 * (1 - 40 / 100))


def _field(rows_left: float, rows_right: float) -> RowField:
    """A field rising from ``rows_left`` at the left edge to ``rows_right`` at the right (a roll), on RES."""
    w = RES[0]
    slope = (rows_right - rows_left) / 2 * w / (w - 1)
    return RowField(np.array([(rows_left + rows_right) / 2, slope, 0.0]), -50.0, 50.0, 5, 5, RES)


def test_stage_moves_right_events_by_the_fields_rows_and_restores_their_matches():
    field = _field(-2.0, 3.0)
    shift = np.rint(field.rows()).astype(int)
    assert shift[0, 0] == -2 and shift[0, -1] == 3
    left = make_events([10, 20], [5, 100], [40, 40], [1, 0])
    right = make_events([10, 20, 30, 40], [0, 127, 60, 120], [40, 40, 1, 95], [1, 1, 0, 1])   # the last moves off
    stage = row_field_stage(field)
    stream = stage.stream([StereoPacket(left, right, 50)])
    packet = next(stream)
    np.testing.assert_array_equal(packet.left, left)                # the left camera is the reference
    want_y = right["y"] + shift[right["y"], right["x"]]
    inside = (want_y >= 0) & (want_y < RES[1])
    np.testing.assert_array_equal(packet.right["y"], want_y[inside])
    assert inside.tolist() == [True, True, True, False] and stream.dropped == [0, 1]
    # Event-anchored matches go back to the very events; left-anchored ones stay.
    moved = packet.right
    found = make_matches(np.r_[moved["t"], 10], np.r_[moved["x"], 5], np.r_[moved["y"], 40], np.r_[moved["p"], 1],
                         np.r_[np.ones(moved.size), 0].astype(int), np.full(moved.size + 1, 4.0))
    back = stream.restore(found, anchor="event")
    np.testing.assert_array_equal(back["y"][:-1], right["y"][inside])
    assert back["y"][-1] == 40 and back["x"][-1] == 5


def test_stage_maps_window_anchored_matches_to_the_nearest_raw_row():
    field = RowField(np.array([0.0, 0.0, 3.0]), -50.0, 50.0, 5, 5, RES)   # a focal mismatch: rows spread apart
    stage = row_field_stage(field)
    shift = np.rint(field.rows()).astype(int)
    for x, y_moved in [(0, 0), (50, 20), (127, 47), (90, 95)]:
        raw_x, raw_y = stage.unrectify_pixels(np.array([x]), np.array([y_moved]), 1)
        forward = np.arange(RES[1]) + shift[:, x]
        assert raw_x[0] == x
        assert abs(forward[raw_y[0]] - y_moved) == np.abs(forward - y_moved).min()


@pytest.fixture(scope="module")
def crooked_plane():
    """A textured plane sliding past a rig whose rows differ by 12 across the image (roll 3 degrees, focal
    lengths 3 % apart, lenses apart, 3 rows offset)."""
    rig = Rig(resolution=(128, 128), vertical_offset_px=3.0, roll_deg=3.0, focal_ratio=1.03, distortion_k1=-0.05,
              right_distortion_k1=0.0, left=QUIET, right=QUIET)
    return rig, simulate(_plane(1.0), rig=rig, seconds=0.3, seed=0, render_hz=500)


def test_match_finds_the_rigs_row_field_and_matches_better_with_it(crooked_plane):
    rig, rec = crooked_plane
    truth = rig.right_row_shift()
    plain = match(rec, method="event-area")
    fielded = match(rec, method="event-area", row_field=True)
    check = fielded.meta["rigcheck"]
    assert check["applied"]["row_field"] is True and "row_field" not in plain.meta["rigcheck"]
    found = check["row_field"]
    field = RowField.from_description(found, rec.resolution)
    rms_field = np.sqrt(np.mean((field.rows() - truth) ** 2))
    rms_offset = np.sqrt(np.mean((check["applied"]["row_offset"] - truth) ** 2))
    assert rms_offset > 2.0 and rms_field < 0.6
    before, after = (evaluate(rec, r.matches, r.meta) for r in (plain, fielded))
    assert after["bad2"] < 0.05 < before["bad2"] and after["coverage"] > before["coverage"]
    # The matches point at the recording's own events: right-anchored ones at right events, as recorded.
    right = fielded.matches[fielded.matches["camera"] == 1]
    recorded = set(zip(rec.right["t"].tolist(), rec.right["x"].tolist(), rec.right["y"].tolist(), strict=True))
    assert right.size > 1000
    assert all(k in recorded for k in zip(right["t"].tolist(), right["x"].tolist(), right["y"].tolist(), strict=True))


def test_row_field_needs_the_rig_check(crooked_plane, tmp_path, capsys):
    _, rec = crooked_plane
    for kwargs in ({"rig_check": False}, {"param_set": "thesis"}, {"row_offset": 0}):
        with pytest.raises(ValueError, match="row_field needs the rig check"):
            match(rec, method="event-area", row_field=True, **kwargs)
    path = tmp_path / "rec.npz"
    write_recording_npz(path, rec)
    assert cli_main(["match", str(path), "--row-field", "--no-rig-check", "-o", str(tmp_path / "m")]) != 0
    assert "--row-field needs the default rig check" in capsys.readouterr().err
    assert not (tmp_path / "m.npz").exists()


def test_a_fit_that_answers_no_more_than_one_offset_is_not_applied(crooked_plane, monkeypatch):
    import cvstereo.rigcheck.row_field as row_field

    _, rec = crooked_plane
    found = row_field.estimate_row_field(rec.left, rec.right, resolution=rec.resolution, centre=-3)
    assert found.field is found.fitted is not None
    assert found.answers >= row_field.MIN_GAIN * found.best_offset_answers
    assert found.best_offset_answers == found.counts.sum(axis=(1, 2)).max()
    # Asked for more answers than the field gives, the search keeps the fit apart and applies nothing.
    monkeypatch.setattr(row_field, "MIN_GAIN", found.answers / found.best_offset_answers + 0.01)
    refused = row_field.estimate_row_field(rec.left, rec.right, resolution=rec.resolution, centre=-3)
    assert refused.field is None and refused.fitted is not None and refused.answers == found.answers
    assert "rows" not in refused.describe() and refused.describe()["answers"] == found.answers


def _keys(result) -> list:
    m = result.matches
    return sorted(zip(m["t"].tolist(), m["x"].tolist(), m["y"].tolist(), m["camera"].tolist(),
                      m["disparity"].tolist(), strict=True))


@pytest.mark.parametrize("method", ["event-area", "frame-area"])
def test_the_same_matches_however_the_stream_is_cut_and_on_any_number_of_threads(crooked_plane, method):
    _, rec = crooked_plane
    base = match(rec, method=method, row_field=True, threads=1)
    assert base.meta["rigcheck"]["applied"]["row_field"] is True
    for kwargs in ({"packet_us": 7_000, "threads": 1}, {"threads": 2}):
        other = match(rec, method=method, row_field=True, **kwargs)
        assert other.meta["rigcheck"]["row_field"]["coefficients"] == base.meta["rigcheck"]["row_field"]["coefficients"]
        assert _keys(other) == _keys(base)


def test_after_a_swap_the_field_is_sought_in_the_order_used(crooked_plane):
    from cvstereo.rigcheck.prefix import PrefixRigCheck
    from tests.rigcheck.test_rigcheck import with_rig_errors

    _, rec = crooked_plane
    # The check sees the exchange on this plane at a confidence below the default's 0.8: undone at any confidence.
    undone = PrefixRigCheck(rec.resolution, row_field=True, swap_min_confidence=0.0)
    list(undone.stream(with_rig_errors(rec, swap=True).packets(40_000)))
    assert undone.describe()["applied"]["swap"] is True
    as_recorded = PrefixRigCheck(rec.resolution, row_field=True)
    list(as_recorded.stream(rec.packets(40_000)))
    assert undone.describe()["row_field"]["coefficients"] == as_recorded.describe()["row_field"]["coefficients"]
