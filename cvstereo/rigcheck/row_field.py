"""Rows that differ across the image: a row field found by matching, and the stage that applies it.

The rig check finds one row offset for the whole image. A real rig also has a roll between its cameras, focal
lengths a little apart and two lenses: the rows that line up then change across the image, by a row or two at
128x128 and by ten to twenty at 640x480. This module finds how, from the same evidence as the rows by matching
(:mod:`cvstereo.rigcheck.rows_by_matching`: a matcher answers most where the rows line up), counted per part of
the image:

1. ``frame-area`` (adaptive, one thread) matches the prefix's span with the right camera's rows moved by every
   second offset within :data:`REACH` rows of the offset the check applies; its answers are counted per tile of a
   :data:`TILES` grid, at the right camera's own pixel of each answer;
2. a tile tells its rows when its answers peak inside the offsets tried (not at either end), with
   :data:`MIN_ANSWERS` or more at the peak, and its profile rises :data:`MIN_PROMINENCE` or more above its median
   (thin structures and fine repeating texture give flat profiles or peaks at the ends); its peak offset is
   refined by a parabola;
3. an affine field ``rows = a + b u + c v`` (u, v: the pixel from the image centre over half the width: a row
   offset, a roll, a focal mismatch; a lens term was tried and extrapolated rows off) is fitted to those tiles
   robustly: of the fields through any three tiles the one that the most tile weight (answers at the peak times
   the prominence) agrees with within :data:`TOLERANCE` rows, refitted by weighted least squares on the tiles that
   agree; it needs :data:`MIN_TILES` of them, else there is no field (the constant offset stays);
4. the field is clipped to the agreeing tiles' peaks +-1 row (no extrapolation into parts without evidence) and
   rounded: the right camera's events move by whole rows (:func:`row_field_stage`, through
   :class:`cvstereo.geometry.rectify.Rectification`'s stream, which maps event-anchored matches back to the very
   events they were anchored on);
5. the matcher runs once more with the field applied, and the field is kept only where it answers at least
   :data:`MIN_GAIN` times as often as the best whole-image offset tried: wrong tiles can agree with each other
   (a repeating texture, a flat profile's chance peaks), but a field that lines up fewer rows than one offset
   does cannot give more answers (the principle of the rows by matching).

Every constant was chosen on suite v2's tuning half and on 48 more recordings drawn as it (its families, sensors
and photos, other seeds; ``bench/bench_row_field.py --extra``).

>>> tiles = TileRows(x=np.array([16., 48, 80, 112, 16, 48, 80, 112]), y=np.array([-32., -32, -32, -32, 32, 32, 32, 32]),
...                  peaks=np.array([1., 1, 1, 1, 3, 3, 3, 9]), weights=np.ones(8))
>>> field = fit_row_field(tiles, (128, 96))
>>> field.tiles_used, [round(float(c), 2) for c in field.coefficients]    # the outlier at +9 is left out
(7, [2.0, 0.0, 2.0])
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from cvstereo.geometry.rectify import NONE, Rectification
from cvstereo.rigcheck.peaks import subsample_peak
from cvstereo.rigcheck.rows_by_matching import moved_matches, over_offsets, span_matches, span_of

__all__ = ["MIN_ANSWERS", "MIN_GAIN", "MIN_PROMINENCE", "MIN_TILES", "REACH", "SPAN_EVENTS", "SPAN_MAX_US",
           "SPAN_MIN_US", "TILES", "TOLERANCE", "RowField", "RowFieldSearch", "TileRows", "estimate_row_field",
           "fit_row_field", "row_field_stage", "tile_rows"]

#: Tiles of the image (columns, rows) whose answers are counted apart.
TILES = (4, 3)
#: Rows tried either way of the offset the check applies, every second one.
REACH = 12
#: Least answers at a tile's peak for the tile to count.
MIN_ANSWERS = 20
#: Least prominence of a tile's profile (1 - median / peak): flat profiles tell no rows.
MIN_PROMINENCE = 0.1
#: Rows within which a tile agrees with a field.
TOLERANCE = 1.0
#: Least tiles that must agree with the field.
MIN_TILES = 5
#: The field must give this many times the answers of the best whole-image offset tried.
MIN_GAIN = 1.01
#: The span matched: from the first event until each camera has SPAN_EVENTS events (at least SPAN_MIN_US, at most
#: SPAN_MAX_US), as the rows by matching; the check's prefix is often shorter, and the stream is held for it.
SPAN_EVENTS, SPAN_MIN_US, SPAN_MAX_US = 100_000, 80_000, 10_000_000


@dataclass(frozen=True)
class TileRows:
    """The tiles that tell their rows: centres (x from the left edge, y from the image centre, pixels), peak row
    offsets and weights."""

    x: np.ndarray
    y: np.ndarray
    peaks: np.ndarray
    weights: np.ndarray


@dataclass(frozen=True)
class RowField:
    """A fitted row field.

    Attributes
    ----------
    coefficients : (3,) ndarray
        ``a, b, c`` of ``rows = a + b u + c v`` (u = (x - (W - 1) / 2) / (W / 2), v = (y - (H - 1) / 2) / (W / 2)).
    low, high : float
        The field is clipped to this range (the agreeing tiles' peaks +-1 row).
    tiles_used, tiles : int
        Tiles that agree with the field, of those that told their rows.
    resolution : (width, height)
    """

    coefficients: np.ndarray
    low: float
    high: float
    tiles_used: int
    tiles: int
    resolution: tuple[int, int]

    @classmethod
    def from_description(cls, entry: dict, resolution) -> RowField:
        """The field of a matches file's ``meta["rigcheck"]["row_field"]`` (:meth:`describe`) on a sensor of
        ``resolution``."""
        return cls(np.asarray(entry["coefficients"], np.float64), *map(float, entry["clip"]), int(entry["tiles_used"]),
                   int(entry["tiles"]), tuple(resolution))

    def rows(self) -> np.ndarray:
        """(H, W) float: the rows to add to each right pixel's y."""
        w, h = self.resolution
        yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
        return np.clip(_terms(xx, yy - (h - 1) / 2, w) @ self.coefficients, self.low, self.high)

    def describe(self) -> dict:
        """The meta entry ``row_field`` of the rig check: the fit, the whole rows it spans, its tiles."""
        rows = np.rint(self.rows())
        return {"coefficients": [float(c) for c in self.coefficients], "clip": [self.low, self.high],
                "rows": [int(rows.min()), int(rows.max())], "tiles_used": self.tiles_used, "tiles": self.tiles}


def _terms(x, y, width: int) -> np.ndarray:
    """The field's terms (1, u, v) at columns ``x`` and rows ``y`` counted from the image centre."""
    u, v = (np.asarray(x, np.float64) - (width - 1) / 2) / (width / 2), np.asarray(y, np.float64) / (width / 2)
    return np.stack([np.ones_like(u), u, v], axis=-1)


def tile_rows(counts: np.ndarray, offsets: np.ndarray, resolution) -> TileRows:
    """The tiles that tell their rows, from their answers per offset.

    Parameters
    ----------
    counts : (n_offsets, tile rows, tile columns) ndarray
        Answers per offset tried and tile.
    offsets : (n_offsets,) ndarray of int
        The offsets, evenly spaced, increasing.
    resolution : (width, height)
    """
    w, h = resolution
    n, ty, tx = counts.shape
    step = float(offsets[1] - offsets[0]) if n > 1 else 1.0
    found = []
    for j, k in itertools.product(range(ty), range(tx)):
        profile = counts[:, j, k]
        best = int(np.argmax(profile))
        top = float(profile[best])
        if top < MIN_ANSWERS or best in (0, n - 1):  # at either end the peak may lie beyond the offsets tried
            continue
        prominence = 1.0 - float(np.median(profile)) / top
        if prominence < MIN_PROMINENCE:
            continue
        found.append(((k + 0.5) * w / tx, (j + 0.5) * h / ty - (h - 1) / 2,
                      float(offsets[0]) + step * subsample_peak(profile, best), top * prominence))
    x, y, peaks, weights = np.array(found, np.float64).reshape(-1, 4).T
    return TileRows(x, y, peaks, weights)


def _weighted_fit(a: np.ndarray, peaks: np.ndarray, weights: np.ndarray) -> np.ndarray:
    sw = np.sqrt(weights)
    return np.linalg.lstsq(a * sw[:, None], peaks * sw, rcond=None)[0]


def fit_row_field(tiles: TileRows, resolution) -> RowField | None:
    """The affine field most tile weight agrees with (step 3 of the module's docstring), or None.

    Parameters
    ----------
    tiles : TileRows
    resolution : (width, height)

    Returns
    -------
    RowField or None
        None where fewer than :data:`MIN_TILES` tiles agree with any field.
    """
    n = tiles.peaks.size
    if n < max(3, MIN_TILES):
        return None
    a = _terms(tiles.x, tiles.y, resolution[0])
    best, best_weight = None, -1.0
    for trio in itertools.combinations(range(n), 3):  # at most 220 for 4 x 3 tiles
        sub = list(trio)
        try:
            coef = np.linalg.solve(a[sub], tiles.peaks[sub])
        except np.linalg.LinAlgError:  # three tiles on a line
            continue
        agree = np.abs(a @ coef - tiles.peaks) <= TOLERANCE
        weight = float(tiles.weights[agree].sum())
        if agree.sum() >= MIN_TILES and weight > best_weight:
            best, best_weight = agree, weight
    if best is None:
        return None
    for _ in range(2):  # refit on the agreeing tiles; the refit may change which agree
        coef = _weighted_fit(a[best], tiles.peaks[best], tiles.weights[best])
        best = np.abs(a @ coef - tiles.peaks) <= TOLERANCE
        if best.sum() < MIN_TILES:
            return None
    return RowField(coef, float(tiles.peaks[best].min()) - 1.0, float(tiles.peaks[best].max()) + 1.0,
                    int(best.sum()), n, tuple(resolution))


class RowFieldSearch(NamedTuple):
    """What :func:`estimate_row_field` found."""

    field: RowField | None
    """The field to apply: the fit where its answers pass the check of step 4, else None."""
    fitted: RowField | None
    """The fit of step 3, before that check (None: too few tiles agreed)."""
    tiles: TileRows
    """The tiles that told their rows."""
    counts: np.ndarray
    """Answers per offset tried and tile, (n_offsets, tile rows, tile columns)."""
    answers: int | None
    """Answers with the fitted field applied (None without a fit)."""
    best_offset_answers: int
    """Most answers with one row offset for the whole image, of those tried."""
    stage: Rectification | None = None
    """The stage that applies ``field`` (:func:`row_field_stage`, the one its answers were counted with), or None."""

    def describe(self) -> dict:
        """The meta entry's findings: tiles, answers, and the field applied (:meth:`RowField.describe`)."""
        out = {"tiles": int(self.tiles.peaks.size), "answers": self.answers,
               "best_offset_answers": self.best_offset_answers}
        return out if self.field is None else {**out, **self.field.describe()}


def estimate_row_field(left: np.ndarray, right: np.ndarray, *, resolution, centre: int, reach: int = REACH,
                       min_us: int = SPAN_MIN_US, max_us: int = SPAN_MAX_US, events: int = SPAN_EVENTS,
                       threads: int = 1) -> RowFieldSearch:
    """The module's steps 1-5 on a prefix of the stream.

    Parameters
    ----------
    left, right : ndarray of EVENT_DTYPE
        The events checked, time-ordered, in the cameras' order after any swap.
    resolution : (width, height)
    centre : int
        The row offset the check applies: the offsets tried lie within ``reach`` rows of it.
    reach : int
    min_us, max_us, events : int
        The span matched, as the rows by matching (:func:`~cvstereo.rigcheck.rows_by_matching.matching_span`).
    threads : int
        How many offsets are matched at once (the same counts on any number).

    Returns
    -------
    RowFieldSearch
    """
    w, h = resolution
    span = span_of(left, right, min_us=min_us, max_us=max_us, events=events)
    offsets = np.arange(centre - reach, centre + reach + 1, 2)

    def per_tile(off: int) -> np.ndarray:
        found = moved_matches(span, off, resolution=resolution)
        # Each answer at the right camera's own pixel: frame-area anchors on either camera.
        on_right = found["camera"] == 1
        ry = np.where(on_right, found["y"].astype(np.int64) - off, found["y"].astype(np.int64))
        rx = np.where(on_right, found["x"], found["x"] - np.rint(found["disparity"])).astype(np.int64)
        out = np.zeros((TILES[1], TILES[0]))
        np.add.at(out, (np.clip(ry * TILES[1] // h, 0, TILES[1] - 1), np.clip(rx * TILES[0] // w, 0, TILES[0] - 1)), 1)
        return out

    counts = np.stack(over_offsets(per_tile, offsets.tolist(), threads))
    tiles = tile_rows(counts, offsets, resolution)
    fitted = fit_row_field(tiles, resolution)
    best = int(counts.sum(axis=(1, 2)).max())  # every answer falls in a tile
    if fitted is None:
        return RowFieldSearch(None, None, tiles, counts, None, best)
    stage = row_field_stage(fitted)
    moved = stage.rectify(span.right, 1)[0]
    answers = int(span_matches(span.left, moved, resolution=resolution, end=span.end).size)
    if answers < MIN_GAIN * best:
        return RowFieldSearch(None, fitted, tiles, counts, answers, best)
    return RowFieldSearch(fitted, fitted, tiles, counts, answers, best, stage)


def row_field_stage(field: RowField) -> Rectification:
    """The stage that moves each right event by the field's whole rows at its pixel (events moved off the sensor
    dropped and counted) and maps right-anchored matches back: event-anchored ones to their events, window-anchored
    ones to the raw row whose moved row is nearest. The left camera passes as it is."""
    w, h = field.resolution
    shift = np.rint(field.rows()).astype(np.int64)
    yy, xx = np.mgrid[0:h, 0:w]
    moved = yy + shift
    forward = np.full((h, w, 2), NONE, np.int16)
    inside = (moved >= 0) & (moved < h)
    forward[inside, 0], forward[inside, 1] = xx[inside], moved[inside]
    # Per column the moved rows rise with the raw ones (the field changes by less than a row per row), so each
    # moved row's nearest raw row is found by a search.
    ordered = np.maximum.accumulate(moved, axis=0)
    inverse = np.empty((h, w, 2), np.int16)
    inverse[..., 0] = xx
    for col in range(w):
        pos = np.clip(np.searchsorted(ordered[:, col], np.arange(h)), 1, h - 1)
        below = np.abs(ordered[pos - 1, col] - np.arange(h)) <= np.abs(ordered[pos, col] - np.arange(h))
        inverse[:, col, 1] = np.where(below, pos - 1, pos)
    return Rectification.from_tables((None, forward), (None, inverse), field.resolution,
                                     {"row_field": field.describe()})
