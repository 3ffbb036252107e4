"""Rig self-check: learn from the events alone what a calibration would have told.

The thesis' matchers need no calibration, but they assume a rig that real recordings do not always give:
the camera called "left" may be the right one, the sensors' rows may be a few rows apart, and the two
streams may be offset in time. :func:`check_rig` estimates, from the events of a :class:`Recording`:

- **swap**: whether the camera given as left is really the right one (the left camera sees a scene point at
  the larger x), from the sign of the horizontal shift that best overlays short accumulated frames;
- **row offset** ``r``: rows to add to the right camera's ``y`` so that it lines up with the left
  (``y_left ~ y_right + r``), fractional, also per horizontal band of the image;
- **time offset** ``tau``: how much later the right camera stamps the same scene change
  (``t_right ~ t_left + tau``, microseconds), fractional;
- **disparity range**: percentiles of the disparities (``x_left - x_right``) that overlay best locally,
  the dominant disparity and the peaks of the global overlay profile;
- **imbalance**: event-rate ratio right/left (overall and in 5 ms bursts) and ON share per camera;
- **noise**: events with no event at any of the 8 neighbouring pixels within a few ms, per second.

Each estimate carries a confidence in [0, 1]. The row offset comes from the 2-D cross-correlation of
accumulated signed frames over (dx, dy) (windows long against any time offset). The time offset comes from
two estimators: the histogram of time differences between events at corresponding pixels (same polarity,
that row offset, the dominant disparity +-1 px), precise when the disparities are whole pixels or the scene
nearly static; and the regression of the cameras' apparent shift on the image velocity over 10 ms windows
and image tiles (``s = d + v * tau``: slope tau, one intercept d per tile), which on sideways sweeps is not
fooled by a disparity error ``e`` that the histogram takes for a time offset ``e / v``. The histogram's answer
stands when its peak is sharp, the regression's otherwise (:func:`_time_offset`). Then the rows once more with
the time offset removed, and the disparity stage on the corrected streams. Known limit: a disparity that
changes in step with the speed (an arm wobbling in depth while it sweeps, over a clip of only a few sweeps)
cannot be told from a time offset by any estimator; on 2 s of the simulated arm presets that leaves errors of
1-4 ms at confidences mostly below the 0.3 that ``--auto`` needs, and slow one-way drifts (1 arm at 100 cm)
are not determined at all (confidence below 0.2).

Reported offsets and disparities refer to the recording *as it should be used*: after exchanging the
cameras when ``swap`` is True (:meth:`RigReport.prepare` does that), so that ``row_offset`` and
``time_offset_us`` can go straight to :func:`calibration_free.match` (see :meth:`RigReport.match_kwargs`).

>>> import numpy as np
>>> from cvstereo.recording import Recording
>>> from cvstereo.events import make_events
>>> rng = np.random.default_rng(0)
>>> t = np.sort(rng.integers(0, 1_000_000, 4000)); x = rng.integers(20, 100, 4000); y = rng.integers(0, 128, 4000)
>>> ev = make_events(t, x, y, rng.integers(0, 2, 4000))
>>> report = check_rig(Recording(ev, ev))
>>> report.swap, round(report.row_offset), round(report.time_offset_us)
(False, 0, 0)
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass

import cv2
import numpy as np

from cvstereo.recording import Recording

#: Percentiles of the local disparities that are reported.
DISPARITY_PERCENTILES = (5, 25, 50, 75, 95)

#: Events per camera that an automatic disparity-stage window aims at: enough to overlay shapes, few enough
#: that moving things do not smear across many pixels.
WINDOW_EVENTS = 300

#: Rate changes slower than this are removed from the per-row signals before their lag is measured.
HIGHPASS_US = 10_000

#: Below this many events per camera no estimate is meaningful.
MIN_EVENTS = 50

# Time offset by shift-velocity regression (_time_offset_regression).
#: Window of the frames whose shift between the cameras is measured: short enough that the image speed is
#: about constant within it (an arm reverses within ~100 ms), long enough for a few hundred events.
REG_WINDOW_US = 10_000
#: The speed comes from the windows this many steps before and after: a longer baseline gives a larger shift,
#: measured with less relative error, at the cost of averaging the speed over 2 * REG_GAP windows.
REG_GAP = 1
#: Image tiles (columns, rows), each with its own disparity in the fit: depth and lens distortion make the
#: disparity vary over the image, and tiles keep things moving in opposite directions (two arms) apart.
REG_TILES = (4, 2)
#: Measured windows per chunk (bounds memory: 2 cameras x 3 x 100 x 128 x 128 float32 = 40 MB).
REG_CHUNK = 100
#: Gaussian smoothing of the frames, px (sigma).
REG_BLUR_PX = 1.0
#: The correlation is interpolated on a grid this many times finer than a pixel.
REG_UPSAMPLE = 16
#: Search range around the dominant disparity, px, on top of the shift the largest time offset can cause.
REG_SHIFT_PX = 6
#: Fastest image motion considered, px/us (0.5 px/ms: a DVS128 crossed in a quarter second).
REG_MAX_SPEED = 0.5e-3
#: A window (tile) enters the fit when both its cameras' overlay and its speed's overlay reach this
#: normalised correlation (sparse noise-only windows do not).
REG_MIN_NCC = 0.3
#: Residuals beyond this many robust standard deviations (1.4826 MAD) are outliers (another object, an
#: occlusion); the fit is repeated without them.
REG_TRIM_MAD = 3.0
#: Trimming rounds at most.
REG_ITERATIONS = 6
#: A window is measured only when each camera has this many events in it (and in its neighbours).
REG_MIN_WINDOW_EVENTS = 20
#: At most this many windows are measured, evenly spread over the recording.
REG_MAX_WINDOWS = 300
#: Fewer usable windows than this leave the regression undetermined.
REG_MIN_WINDOWS = 20
#: Standard error of the slope at which the confidence is 0.5 (half the 0.5 ms a matcher tolerates).
REG_SE_SCALE_US = 250.0
#: Below this confidence (slope standard error above ~750 us) the regression is not used at all.
REG_MIN_CONFIDENCE = 0.1

#: Confidence a time offset needs before ``match_kwargs`` (and so ``match --auto``) applies it. Higher than
#: for rows: on the simulated arms, whose depth wobbles, wrong time offsets of 1-4 ms came with confidences up
#: to 0.55, and applying an offset wrong by more than the event-time matcher's 300 us window ruins its matches,
#: while leaving a true offset of a few ms unapplied only costs some of them.
TIME_APPLY_CONFIDENCE = 0.6
#: The pixel-coincidence histogram is trusted over the regression when its peak's half width at half height
#: is at most this (sensor jitter and latency spread a true coincidence peak by a few hundred us; a disparity
#: off by a fraction of a pixel on a slow sweep spreads it by several ms).
PAIRS_SHARP_US = 1_000


@dataclass(frozen=True)
class RigReport:
    """What :func:`check_rig` found. Offsets and disparities refer to the recording after :meth:`prepare`.

    Attributes
    ----------
    swap : bool
        True when the camera given as left is the right one: exchange them (``Recording.swapped()``).
    swap_confidence : float
    row_offset : float
        Rows to add to the right camera's y to line it up with the left (``y_left ~ y_right + row_offset``).
    row_offset_confidence : float
    row_offset_bands : tuple of float
        The same per horizontal band of the image (``band_rows`` gives each band's left-camera rows).
    band_rows : tuple of (int, int)
        ``[start, stop)`` rows of each band.
    row_offset_band_confidence : tuple of float
    row_offset_varies : bool
        True when confident bands disagree by more than one row.
    time_offset_us : float
        How much later the right camera stamps the same change (``t_right ~ t_left + time_offset_us``).
    time_offset_confidence : float
    disparity_peak : float
        The disparity that overlays the most events (sub-pixel), px.
    disparity_peaks : tuple of float
        Local maxima of the global overlay profile that stand out from its background, strongest first.
    disparity_percentiles : dict
        Percentile (int) -> disparity (px) of the local best overlays (:data:`DISPARITY_PERCENTILES`).
    disparity_range : (float, float)
        5th and 95th percentile.
    disparity_confidence : float
        Share of the local overlays that agree in sign with the decision (1 = all on the possible side).
    events : (int, int)
        Events of the left and right camera.
    rate_ratio : float
        Right / left event count.
    rate_ratio_confidence : float
    burst_ratio_p95 : float
        95th percentile, over 5 ms windows with events in both cameras, of the larger camera's count over the
        smaller's (the thesis saw up to 3x).
    on_fraction : (float, float)
        Share of ON events, left and right.
    on_fraction_confidence : float
    noise_rate_hz : (float, float)
        Isolated events per second, left and right.
    noise_fraction : (float, float)
        Share of isolated events.
    noise_confidence : float
    duration_s : float
        Seconds analysed.
    settings : dict
        The options :func:`check_rig` ran with.
    """

    swap: bool
    swap_confidence: float
    row_offset: float
    row_offset_confidence: float
    row_offset_bands: tuple[float, ...]
    band_rows: tuple[tuple[int, int], ...]
    row_offset_band_confidence: tuple[float, ...]
    row_offset_varies: bool
    time_offset_us: float
    time_offset_confidence: float
    disparity_peak: float
    disparity_peaks: tuple[float, ...]
    disparity_percentiles: dict
    disparity_range: tuple[float, float]
    disparity_confidence: float
    events: tuple[int, int]
    rate_ratio: float
    rate_ratio_confidence: float
    burst_ratio_p95: float
    on_fraction: tuple[float, float]
    on_fraction_confidence: float
    noise_rate_hz: tuple[float, float]
    noise_fraction: tuple[float, float]
    noise_confidence: float
    duration_s: float
    settings: dict

    def prepare(self, recording: Recording, *, min_confidence: float = 0.3) -> Recording:
        """The recording with the cameras exchanged if :attr:`swap` (with at least ``min_confidence``)."""
        return recording.swapped() if self.swap and self.swap_confidence >= min_confidence else recording

    def match_kwargs(self, *, min_confidence: float = 0.3, min_time_confidence: float = TIME_APPLY_CONFIDENCE) -> dict:
        """``row_offset`` and ``time_offset_us`` for :func:`calibration_free.match`.

        An offset whose confidence is below ``min_confidence`` (rows) or ``min_time_confidence`` (time) is left
        at 0; the row offset is rounded (matchers work on whole rows), the time offset to whole microseconds.
        """
        row = round(self.row_offset) if self.row_offset_confidence >= min_confidence else 0
        dt = round(self.time_offset_us) if self.time_offset_confidence >= min_time_confidence else 0
        return {"row_offset": int(row), "time_offset_us": int(dt)}

    def to_dict(self) -> dict:
        """A JSON-serialisable dict of every field."""
        out = dataclasses.asdict(self)
        out["disparity_percentiles"] = {str(k): v for k, v in self.disparity_percentiles.items()}
        return json.loads(json.dumps(out, default=_json_default))

    def summary(self) -> str:
        """A short human report, one finding per line."""
        def c(v):
            return f"(confidence {v:.2f})"

        side = ("SWAP: the camera given as right is the left one" if self.swap
                else "cameras in the given order: left is left")
        bands = ", ".join(f"{a}-{b - 1}: {v:+.1f}" for (a, b), v in zip(self.band_rows, self.row_offset_bands,
                                                                        strict=True))
        pct = self.disparity_percentiles
        lines = [
            f"rig check of {self.duration_s:.1f} s, {self.events[0]} + {self.events[1]} events",
            f"  left/right:    {side} {c(self.swap_confidence)}",
            f"  row offset:    {self.row_offset:+.2f} rows (add to the right camera's y) "
            f"{c(self.row_offset_confidence)}",
            f"    per band:    {bands}" + ("  -> varies across the image" if self.row_offset_varies else ""),
            f"  time offset:   {self.time_offset_us / 1000:+.2f} ms (right camera later) "
            f"{c(self.time_offset_confidence)}",
            f"  disparity:     peak {self.disparity_peak:.1f} px, 5-95 % {pct[5]:.0f}..{pct[95]:.0f} px, "
            f"median {pct[50]:.0f} px, profile peaks "
            + (", ".join(f"{d:.1f}" for d in self.disparity_peaks) or "none")
            + f" {c(self.disparity_confidence)}",
            f"  event rate:    right/left {self.rate_ratio:.2f}, 5 ms bursts up to {self.burst_ratio_p95:.1f}x (p95) "
            f"{c(self.rate_ratio_confidence)}",
            f"  ON share:      left {self.on_fraction[0]:.0%}, right {self.on_fraction[1]:.0%} "
            f"{c(self.on_fraction_confidence)}",
            f"  noise:         left {self.noise_rate_hz[0]:.0f}/s ({self.noise_fraction[0]:.0%}), right "
            f"{self.noise_rate_hz[1]:.0f}/s ({self.noise_fraction[1]:.0%}) isolated {c(self.noise_confidence)}",
        ]
        return "\n".join(lines)


def check_rig(recording: Recording, *, max_disparity: int = 64, max_row_offset: int = 8,
              max_time_offset_us: int = 20_000, time_bin_us: int = 200, n_bands: int = 4,
              window_us: int | None = None, max_windows: int = 100, block: tuple[int, int] = (9, 5),
              min_ncc: float = 0.5, noise_window_us: int = 5_000, max_seconds: float | None = 60.0) -> RigReport:
    """Estimate the rig's imperfections from the events of a recording.

    Parameters
    ----------
    recording : Recording
        Both cameras, in the order believed (left first).
    max_disparity : int, keyword-only
        Largest |disparity| searched, px.
    max_row_offset : int, keyword-only
        Largest |row offset| searched.
    max_time_offset_us : int, keyword-only
        Largest |time offset| searched, us.
    time_bin_us : int, keyword-only
        Bin of the event-rate signals; the estimate is interpolated below it.
    n_bands : int, keyword-only
        Horizontal bands of the image for which the row offset is estimated separately.
    window_us : int or None, keyword-only
        Accumulation window of the frames for the disparity stage; None: long enough for about
        :data:`WINDOW_EVENTS` events per camera (between 10 ms and 1 s).
    max_windows : int, keyword-only
        At most this many windows (evenly spread over the recording) enter the disparity stage.
    block : (width, height), keyword-only
        Block over which local overlays are scored (normalised cross-correlation of signed frames).
    min_ncc : float, keyword-only
        A local overlay counts when its best normalised cross-correlation reaches this.
    noise_window_us : int, keyword-only
        An event is noise when no neighbouring pixel fired within this time either side.
    max_seconds : float or None, keyword-only
        Analyse at most this many seconds from the start (bounds time and memory); None: everything.

    Returns
    -------
    RigReport

    Raises
    ------
    ValueError
        Too few events in a camera, or options out of range.
    """
    settings = {k: v for k, v in locals().items() if k != "recording"}
    settings["block"] = list(block)
    for name in ("max_disparity", "max_row_offset", "max_time_offset_us", "time_bin_us", "n_bands", "max_windows",
                 "noise_window_us") + (("window_us",) if window_us is not None else ()):
        if int(settings[name]) < (0 if name == "max_row_offset" else 1):
            raise ValueError(f"check_rig: {name}={settings[name]} is out of range; give a positive value.")
    if max_seconds is not None:
        recording = recording.slice_time(recording.t_start, recording.t_start + int(max_seconds * 1e6))
    for name, ev in (("left", recording.left), ("right", recording.right)):
        if ev.size < MIN_EVENTS:
            raise ValueError(
                f"check_rig: the {name} camera has {ev.size} events; at least {MIN_EVENTS} per camera are needed "
                "(give a longer recording, or check that both cameras were read)."
            )
    width, height = recording.resolution
    left, right = recording.left, recording.right
    if window_us is None:
        rate = min(left.size, right.size) / max(recording.duration_s, 1e-3)
        window_us = int(np.clip(WINDOW_EVENTS / rate * 1e6, 10_000, 1_000_000))
        settings["window_us"] = window_us

    # 1. Row offset from the 2-D overlay of accumulated frames over (dx, dy): windows long against any time
    #    offset, so nearly independent of it. 2. Time offset from per-row event-rate signals at that row
    #    shift: searching rows and lags jointly there is ambiguous (an inclined edge moving sideways looks the
    #    same a few rows lower and a few ms later), at a fixed row shift it is not. 3. The rows once more
    #    with the time offset removed, and the lag again if the rows changed.
    res = (width, height)
    frame_opts = {"resolution": res, "max_row_offset": min(max_row_offset, height - 1),
                  "max_disparity": min(max_disparity, width - 1), "window_us": window_us,
                  "max_windows": max_windows, "n_bands": n_bands}
    lag_opts = {"resolution": res, "max_lag_us": max_time_offset_us, "bin_us": time_bin_us}
    rows = _frame_row_offsets(left, right, **frame_opts)
    time_offset, time_conf, time_method = _time_offset(left, right, row=round(rows[0]), disparity=rows[5],
                                                       **lag_opts)
    rows2 = _frame_row_offsets(left, _shifted(right, 0, time_offset, res), **frame_opts)
    if round(rows2[0]) != round(rows[0]) or rows2[5] != rows[5]:
        time_offset, time_conf, time_method = _time_offset(left, right, row=round(rows2[0]), disparity=rows2[5],
                                                           **lag_opts)
    settings["time_offset_method"] = time_method
    row_offset, row_conf, band_offsets, band_conf, band_rows, _ = rows2

    # 4. Disparity on the streams with both offsets removed (whole rows; the time offset to the microsecond).
    corrected = _shifted(right, row_offset, time_offset, res)
    profile, local = _disparity_overlays(left, corrected, resolution=(width, height), max_disparity=max_disparity,
                                         window_us=window_us, max_windows=max_windows, block=block, min_ncc=min_ncc)
    swap, swap_conf = _decide_side(profile, max_disparity)
    sign = -1 if swap else 1
    peak = sign * _subsample_peak(profile, int(np.argmax(profile))) - sign * max_disparity
    peaks = tuple(sign * (s - max_disparity) for s in _profile_peaks(profile))
    peaks = tuple(float(p) for p in peaks if p >= 0)
    oriented = sign * local
    possible = oriented[oriented >= 0]
    disp_conf = float(possible.size / local.size) if local.size else 0.0
    if possible.size:
        pct = {q: float(v) for q, v in zip(DISPARITY_PERCENTILES, np.percentile(possible, DISPARITY_PERCENTILES),
                                           strict=True)}
    else:
        pct = {q: float("nan") for q in DISPARITY_PERCENTILES}
        disp_conf = 0.0

    # 3. Counts, in the orientation the report speaks of.
    if swap:
        left, right = right, left
        row_offset, time_offset = -row_offset, -time_offset
        band_offsets = tuple(-b for b in band_offsets)
    n_l, n_r = int(left.size), int(right.size)
    duration_s = max(recording.duration_s, 1e-6)
    rate_ratio = n_r / n_l
    rate_conf = _clip01(1.0 - np.sqrt(1.0 / n_l + 1.0 / n_r) / 0.1)
    on = (float(left["p"].mean()), float(right["p"].mean()))
    on_conf = _clip01(1.0 - max(np.sqrt(f * (1 - f) / n) for f, n in zip(on, (n_l, n_r), strict=True)) / 0.05)
    burst = _burst_ratio(left, right, window_us=5_000)
    iso = [_isolated(ev, window_us=noise_window_us, resolution=(width, height)) for ev in (left, right)]
    noise_rate = (iso[0] / duration_s, iso[1] / duration_s)
    noise_frac = (iso[0] / n_l, iso[1] / n_r)
    noise_conf = _clip01(1.0 - 1.0 / np.sqrt(1.0 + min(iso)))
    confident = [b for b, c in zip(band_offsets, band_conf, strict=True) if c >= 0.3]
    varies = bool(len(confident) >= 2 and max(confident) - min(confident) > 1.0)
    return RigReport(
        swap=bool(swap), swap_confidence=swap_conf,
        row_offset=float(row_offset), row_offset_confidence=row_conf,
        row_offset_bands=tuple(float(b) for b in band_offsets), band_rows=band_rows,
        row_offset_band_confidence=tuple(band_conf), row_offset_varies=varies,
        time_offset_us=float(time_offset), time_offset_confidence=time_conf,
        disparity_peak=float(peak), disparity_peaks=peaks, disparity_percentiles=pct,
        disparity_range=(pct[5], pct[95]), disparity_confidence=disp_conf,
        events=(n_l, n_r), rate_ratio=float(rate_ratio), rate_ratio_confidence=rate_conf,
        burst_ratio_p95=burst, on_fraction=on, on_fraction_confidence=on_conf,
        noise_rate_hz=(float(noise_rate[0]), float(noise_rate[1])),
        noise_fraction=(float(noise_frac[0]), float(noise_frac[1])), noise_confidence=noise_conf,
        duration_s=float(duration_s), settings=settings,
    )


# --------------------------------------------------------------------------------------------------------------
# Row and time offset


def _shifted(right, rows, time_us, resolution):
    """Right-camera events with ``round(rows)`` added to y and ``round(time_us)`` subtracted from t."""
    from cvstereo.rigcorrect import RigCorrection

    return RigCorrection(rows, round(time_us), resolution).correct_right(right)[0]


def _time_offset(left, right, *, row, disparity, resolution, max_lag_us, bin_us):
    """How much later the right camera stamps the same change: ``(time_offset_us, confidence, method)``.

    The pixel-coincidence histogram (:func:`_time_offset_pairs`) answers when its peak is sharp (at most
    :data:`PAIRS_SHARP_US` half width) or the shift-velocity regression (:func:`_time_offset_regression`) is
    undetermined (nearly static scenes, too few busy windows) or below :data:`REG_MIN_CONFIDENCE`; the
    regression otherwise. ``method`` names the one used.
    """
    reg = _time_offset_regression(left, right, row=row, disparity=disparity, resolution=resolution,
                                  max_lag_us=max_lag_us)
    pairs = _time_offset_pairs(left, right, row=row, disparity=disparity, resolution=resolution,
                               max_lag_us=max_lag_us, bin_us=bin_us)
    # The histogram is biased by (disparity error) / speed on moving scenes, and then also broad: pairs at the
    # neighbouring disparities land (1 px) / speed away. A sharp peak means the disparities were right (or the
    # scene nearly static) and the histogram is the more precise; a broad one defers to the regression.
    if pairs[2] > PAIRS_SHARP_US and reg is not None and reg[1] >= REG_MIN_CONFIDENCE:
        return reg[0], reg[1], "shift-velocity regression"
    return pairs[0], pairs[1], "pixel coincidences"


def _time_offset_regression(left, right, *, row, disparity, resolution, max_lag_us):
    """Time offset as the slope of the cameras' apparent shift against the image velocity.

    In a short window the right camera's image is the left one shifted by ``s = d + v * tau``: it shows the
    scene ``tau`` earlier, when things stood ``v * tau`` px further back (``v`` the horizontal image velocity,
    px/us). Per window (:data:`REG_WINDOW_US`) and image tile (:data:`REG_TILES`), ``s`` is the sub-pixel peak
    of the horizontal cross-correlation of the two cameras' smoothed signed frames (rows lined up by ``row``)
    and ``v`` the shift between the windows before and after, in either camera, over their distance. A
    weighted least-squares fit of ``s`` on ``v`` with one intercept per tile (the disparity varies over the
    image: depth, lens distortion) then gives ``tau`` as the common slope; windows whose residual exceeds
    :data:`REG_TRIM_MAD` robust standard deviations are dropped and the fit repeated. A sweep to and fro gives
    ``v`` of both signs and many sizes, which pins ``tau`` independently of the disparity; a steady drift
    does not, and the slope's standard error (from the residuals, deflated for their correlation between
    neighbouring windows) then says so.

    Known limit: a disparity that changes in step with the speed (an arm wobbling in depth while it sweeps,
    over a clip of a few sweeps) is indistinguishable from a time offset; longer recordings average it out.

    Returns ``(time_offset_us, confidence)``, or None when too few windows move (e.g. a nearly static scene).
    """
    width, height = resolution
    y = right["y"].astype(np.int64) + row
    keep = (y >= 0) & (y < height)
    right = right[keep].copy()
    right["y"] = y[keep]
    if right.size < MIN_EVENTS:
        return None
    t0 = min(int(left["t"][0]), int(right["t"][0]))
    t1 = max(int(left["t"][-1]), int(right["t"][-1])) + 1
    starts = np.arange(t0, t1, REG_WINDOW_US)
    counts = [np.diff(np.searchsorted(ev["t"], np.append(starts, starts[-1] + REG_WINDOW_US))) for ev in (left, right)]
    busy = (counts[0] >= REG_MIN_WINDOW_EVENTS) & (counts[1] >= REG_MIN_WINDOW_EVENTS)
    # A window is measured when it and its neighbours at +-REG_GAP are busy; at most REG_MAX_WINDOWS of them,
    # evenly spread (enough for the fit; bounds the time on long recordings).
    centre = np.flatnonzero(busy[REG_GAP:-REG_GAP] & busy[:-2 * REG_GAP] & busy[2 * REG_GAP:]) + REG_GAP
    if centre.size < REG_MIN_WINDOWS:
        return None
    if centre.size > REG_MAX_WINDOWS:
        centre = centre[np.linspace(0, centre.size - 1, REG_MAX_WINDOWS).round().astype(int)]
    search = REG_SHIFT_PX + int(np.ceil(REG_MAX_SPEED * max_lag_us))
    col_edges = np.linspace(0, width, REG_TILES[0] + 1).round().astype(int)
    row_edges = np.linspace(0, height, REG_TILES[1] + 1).round().astype(int)
    col_masks = np.zeros((REG_TILES[0], 1, 1, width), np.float32)
    col_masks_r = np.zeros_like(col_masks)
    for col in range(REG_TILES[0]):
        col_masks[col, ..., col_edges[col]:col_edges[col + 1]] = 1
        # The right camera sees a tile's content ``disparity`` columns further left.
        lo_r, hi_r = col_edges[col] - int(disparity), col_edges[col + 1] - int(disparity)
        col_masks_r[col, ..., max(lo_r, 0):max(hi_r, 0)] = 1
    n_cols, n_rows = REG_TILES
    lag_v = int(np.ceil(REG_MAX_SPEED * 2 * REG_GAP * REG_WINDOW_US))
    nfft = _fft_len(width + search + abs(int(disparity)) + 1)
    tiles, shifts, s_weight, speeds, v_weight = [], [], [], [], []
    # Chunks of measured windows bound the memory on long recordings.
    for lo in range(0, centre.size, REG_CHUNK):
        chunk = centre[lo:lo + REG_CHUNK]
        needed, where = np.unique(np.concatenate([chunk - REG_GAP, chunk, chunk + REG_GAP]), return_inverse=True)
        before, inner, after = where.reshape(3, chunk.size)
        fl = _window_stack(left, starts[needed], width, height)
        fr = _window_stack(right, starts[needed], width, height)
        # Spectra along x, once per camera and once per column tile; a row tile is a sum over its rows.
        spec_l, spec_r = np.fft.rfft(fl, nfft, axis=2), np.fft.rfft(fr, nfft, axis=2)
        energy_l, energy_r = (fl * fl).sum(axis=2), (fr * fr).sum(axis=2)
        for col in range(n_cols):
            tl = np.fft.rfft(fl * col_masks[col], nfft, axis=2)
            tr = np.fft.rfft(fr * col_masks_r[col], nfft, axis=2)
            el, er = (fl * fl * col_masks[col]).sum(axis=2), (fr * fr * col_masks_r[col]).sum(axis=2)
            for band in range(n_rows):
                rs = slice(row_edges[band], row_edges[band + 1])
                s, hs = _fine_shift(tl[inner, rs], spec_r[inner, rs], el[inner, rs], energy_r[inner, rs],
                                    disparity - search, disparity + search, nfft)
                ul, hl = _fine_shift(tl[after, rs], spec_l[before, rs],
                                     el[after, rs], energy_l[before, rs], -lag_v, lag_v, nfft)
                ur, hr = _fine_shift(tr[after, rs], spec_r[before, rs],
                                     er[after, rs], energy_r[before, rs], -lag_v, lag_v, nfft)
                tiles.append(np.full(inner.size, band * n_cols + col))
                shifts.append(s)
                s_weight.append(hs)
                speeds.append((ul + ur) / (2 * 2 * REG_GAP * REG_WINDOW_US))
                v_weight.append(np.minimum(hl, hr))
    n_tiles = n_cols * n_rows
    tile, s, v = np.concatenate(tiles), np.concatenate(shifts), np.concatenate(speeds)
    w = np.concatenate(s_weight) * np.concatenate(v_weight)
    w[(np.concatenate(s_weight) < REG_MIN_NCC) | (np.concatenate(v_weight) < REG_MIN_NCC)] = 0.0
    fit = _fixed_effects_slope(tile, s, v, w, n_tiles)
    if fit is None:
        return None
    tau, se = fit
    if not abs(tau) <= max_lag_us:
        return None
    conf = 1.0 / (1.0 + (se / REG_SE_SCALE_US) ** 2) * _support(left.size, right.size)
    return float(tau), float(conf)


def _window_stack(ev, starts, width, height):
    """(K, H, W) float32 signed event frames of the windows ``[starts[k], starts[k] + REG_WINDOW_US)`` (sorted,
    not overlapping), Gaussian-smoothed."""
    k = np.searchsorted(starts, ev["t"], side="right") - 1
    ok = (k >= 0) & (ev["t"] < starts[np.maximum(k, 0)] + REG_WINDOW_US)
    n = starts.size
    flat = (k[ok] * height + ev["y"][ok].astype(np.int64)) * width + ev["x"][ok]
    f = np.bincount(flat, weights=2.0 * ev["p"][ok] - 1.0, minlength=n * height * width)
    f = f.astype(np.float32).reshape(n, height, width)
    for i in range(n):
        # Smoothing makes the correlation peak broad enough to interpolate without locking to whole pixels.
        f[i] = cv2.GaussianBlur(f[i], (0, 0), REG_BLUR_PX, borderType=cv2.BORDER_CONSTANT)
    return f


def _fine_shift(spec_a, spec_b, energy_a, energy_b, lo, hi, nfft):
    """Per window, the sub-pixel ``s`` in ``[lo, hi]`` maximising ``sum_y sum_x a(x, y) b(x - s, y)``, and that
    maximum normalised like a correlation coefficient (0 when the peak sits at the end of the search range).

    ``spec_a``, ``spec_b``: (K, rows, nfft // 2 + 1) spectra along x of the frames (zero-padded to ``nfft``);
    ``energy_a``, ``energy_b``: (K, rows) sums of their squares per row. The rows' cross-spectra are summed
    and transformed back on a grid :data:`REG_UPSAMPLE` times finer than a pixel (exact interpolation of the
    band-limited correlation); a parabola through the finest samples then places the peak. A parabola on
    whole pixels alone biases sub-pixel shifts towards integers, which would leak into the slope.
    """
    spec = (spec_a * np.conj(spec_b)).sum(axis=1)
    n = nfft * REG_UPSAMPLE
    lags = np.arange(lo * REG_UPSAMPLE, hi * REG_UPSAMPLE + 1)
    c = (np.fft.irfft(spec, n, axis=-1) * REG_UPSAMPLE)[:, lags % n]
    i = c.argmax(axis=1)
    at_end = (i == 0) | (i == lags.size - 1)
    i = np.clip(i, 1, lags.size - 2)
    k = np.arange(c.shape[0])
    p, q, r = c[k, i - 1], c[k, i], c[k, i + 1]
    den = p - 2 * q + r
    off = np.where(den < 0, 0.5 * (p - r) / np.where(den < 0, den, -1.0), 0.0)
    norm = np.sqrt(energy_a.sum(axis=1) * energy_b.sum(axis=1))
    height = np.where(at_end | (norm <= 0), 0.0, q / np.maximum(norm, 1e-12))
    return (lags[i] + np.clip(off, -0.5, 0.5)) / REG_UPSAMPLE, height


def _fixed_effects_slope(tile, s, v, w, n_tiles):
    """Weighted, iteratively trimmed least squares of ``s = d[tile] + tau * v``: ``(tau, standard error)``.

    None when fewer than :data:`REG_MIN_WINDOWS` windows remain or the speeds do not vary within tiles.
    """
    good = np.isfinite(s) & np.isfinite(v) & (w > 0)
    design = np.concatenate([np.eye(n_tiles)[tile], v[:, None]], axis=1)
    for _ in range(REG_ITERATIONS):
        if good.sum() < REG_MIN_WINDOWS:
            return None
        sw = np.sqrt(w[good])
        # Scale v to px/ms so that the columns are of similar size (conditioning).
        a = design[good] * np.append(np.ones(n_tiles), 1e3)
        coef, *_ = np.linalg.lstsq(a * sw[:, None], s[good] * sw, rcond=None)
        res = s - design @ (coef * np.append(np.ones(n_tiles), 1e3))
        spread = 1.4826 * float(np.median(np.abs(res[good])))
        new = np.isfinite(s) & np.isfinite(v) & (w > 0) & (np.abs(res) <= REG_TRIM_MAD * max(spread, 1e-3))
        if np.array_equal(new, good):
            break
        good = new
    if good.sum() < REG_MIN_WINDOWS:
        return None
    # Standard error of the slope: weighted residual variance over the weighted within-tile spread of v.
    wg, vg, rg, tg = w[good], v[good], res[good], tile[good]
    v_mean = np.bincount(tg, wg * vg, n_tiles) / np.maximum(np.bincount(tg, wg, n_tiles), 1e-12)
    sxx = float((wg * (vg - v_mean[tg]) ** 2).sum())
    used = np.unique(tg).size
    dof = good.sum() - used - 1
    if sxx <= 0 or dof < 1:
        return None
    sigma2 = float((wg * rg * rg).sum()) / dof
    # Neighbouring windows of one tile share slow errors (a wobble in depth): fewer independent samples.
    same = tg[1:] == tg[:-1]
    rho = 0.0
    if same.sum() > 2:
        rho = float(np.clip(np.corrcoef(rg[1:][same], rg[:-1][same])[0, 1], 0.0, 0.95))
    se = np.sqrt(sigma2 / sxx * (1 + rho) / (1 - rho))
    return float(coef[-1] * 1e3), float(se)


def _time_offset_pairs(left, right, *, row, disparity, resolution, max_lag_us, bin_us, max_events=200_000):
    """How much later the right camera fires than the left at corresponding pixels.

    For every left event at (x, y), the right events of the same polarity at (x - d, y - row) for d within one
    pixel of the dominant ``disparity`` and within ``max_lag_us`` form pairs; their time differences pile up
    at the time offset (the same edge crosses both pixels), pairs of unrelated events spread evenly. The
    histogram's peak, interpolated below ``bin_us``, is the estimate. (Per-row event rates with x summed out
    would not need the disparity, but things entering the view and slow motion blur them beyond use.)

    Returns ``(time_offset_us, confidence, half_width_us)``, the last the peak's half width at half height.
    """
    width, height = resolution
    if left.size > max_events:
        left = left[np.linspace(0, left.size - 1, max_events).round().astype(np.int64)]
    key_r = (right["y"].astype(np.int64) * width + right["x"]) * 2 + right["p"]
    order = np.lexsort((right["t"], key_r))
    keys, times = key_r[order], right["t"][order]
    lag = int(np.ceil(max_lag_us / bin_us))
    hist = np.zeros(2 * lag + 1)
    for d in (disparity - 1, disparity, disparity + 1):
        x, y = left["x"].astype(np.int64) - d, left["y"].astype(np.int64) - row
        ok = (x >= 0) & (x < width) & (y >= 0) & (y < height)
        k = ((y * width + x) * 2 + left["p"])[ok]
        lo = np.searchsorted(keys, k, side="left")
        hi = np.searchsorted(keys, k, side="right")
        n = hi - lo
        if not n.sum():
            continue
        # All pairs (left event, right event at its corresponding pixel), then keep those within the lag range.
        first = np.repeat(lo - np.concatenate([[0], np.cumsum(n)[:-1]]), n) + np.arange(n.sum())
        dt = times[first] - np.repeat(left["t"][ok], n)
        dt = dt[np.abs(dt) <= lag * bin_us]
        hist += np.bincount(np.round(dt / bin_us).astype(np.int64) + lag, minlength=2 * lag + 1)[:2 * lag + 1]
    if hist.sum() == 0:
        return 0.0, 0.0, float("inf")
    corr = _smooth_lags(hist - np.median(hist), sigma=1.5)
    k = int(np.argmax(corr))
    time = float((_subsample_peak(corr, k) - lag) * bin_us)
    # The lags where the peak stays above half its height belong to the peak itself (the sensors' latencies
    # jitter by a few ms on real rigs and widen it); the confidence compares it with the lags beyond.
    width_bins = _half_width(corr, k)
    conf = _contrast(corr, k, exclude=width_bins) * _support(left.size, right.size)
    return time, conf, float(width_bins * bin_us)


def _frame_row_offsets(left, right, *, resolution, max_row_offset, max_disparity, window_us, max_windows, n_bands):
    """Row offset from the 2-D cross-correlation of accumulated signed frames over (dx, dy), also per band.

    For every row shift the best horizontal shift counts (whatever the disparity); the row shift where that
    is largest wins. Returns ``(row_offset, confidence, band_offsets, band_confidences, band_rows, dx)``, dx
    the horizontal shift of the strongest overlay (the dominant disparity, in the given camera order).
    """
    width, height = resolution
    bands = _bands(left["y"], height, n_bands)
    masks = np.zeros((n_bands, height, 1), np.float32)
    for b in range(n_bands):
        masks[b, bands[b]:bands[b + 1]] = 1
    shape = (_fft_len(height + max_row_offset + 1), _fft_len(width + max_disparity + 1))
    acc = np.zeros((n_bands, shape[0], shape[1] // 2 + 1), np.complex128)
    for fl, fr, _ in _window_frames(left, right, resolution=resolution, window_us=window_us,
                                    max_windows=max_windows):
        norm = np.sqrt(float((fl * fl).sum()) * float((fr * fr).sum()))
        if norm > 0:
            # c[a, b] = sum L(y + a, x + b) R(y, x): a = y_left - y_right, b = x_left - x_right.
            acc += np.fft.rfft2(fl[None] * masks, shape) * np.conj(np.fft.rfft2(fr, shape))[None] / norm
    c = np.fft.irfft2(acc, shape)
    rows = np.arange(-max_row_offset, max_row_offset + 1)
    cols = np.arange(-max_disparity, max_disparity + 1)
    surface = c[:, rows[:, None] % shape[0], cols[None, :] % shape[1]]                # (n_bands, rows, cols)
    prof = surface.max(axis=2)
    total = prof.sum(axis=0)
    i = int(np.argmax(total))
    dx = int(cols[np.argmax(surface.sum(axis=0)[i])])
    row = float(rows[0] + _subsample_peak(total, i))
    conf = _contrast(total, i, exclude=1) * _support(left.size, right.size)
    band_offsets, band_conf = [], []
    for b in range(n_bands):
        j = int(np.argmax(prof[b]))
        band_offsets.append(float(rows[0] + _subsample_peak(prof[b], j)))
        n_l, n_r = (int(((ev["y"] >= bands[b]) & (ev["y"] < bands[b + 1])).sum()) for ev in (left, right))
        band_conf.append(_contrast(prof[b], j, exclude=1) * _support(n_l, n_r))
    band_rows = tuple((int(bands[b]), int(bands[b + 1])) for b in range(n_bands))
    return row, conf, tuple(band_offsets), tuple(band_conf), band_rows, dx


def _window_frames(left, right, *, resolution, window_us, max_windows):
    """Yield ``(left, right, left_events)`` for windows busy in both cameras: Gaussian-smoothed signed frames,
    (H, W) float32, and the (H, W) bool mask of the pixels where the left camera had events.

    At most ``max_windows`` windows, evenly spread over the recording.
    """
    width, height = resolution
    t0 = min(int(left["t"][0]), int(right["t"][0]))
    t1 = max(int(left["t"][-1]), int(right["t"][-1])) + 1
    starts = np.arange(t0 - t0 % window_us, t1, window_us)
    edges = np.append(starts, starts[-1] + window_us)
    idx = [np.searchsorted(ev["t"], edges) for ev in (left, right)]
    busy = np.flatnonzero((np.diff(idx[0]) >= 10) & (np.diff(idx[1]) >= 10))
    if busy.size > max_windows:
        busy = busy[np.linspace(0, busy.size - 1, max_windows).round().astype(int)]
    for k in busy:
        frames = [_frame(ev[i[k]:i[k + 1]], width, height) for ev, i in ((left, idx[0]), (right, idx[1]))]
        # A little smoothing so that events one pixel apart still overlay (jitter, distortion).
        gl, gr = (cv2.GaussianBlur(f, (3, 3), 0.8, borderType=cv2.BORDER_CONSTANT) for f in frames)
        yield gl, gr, frames[0] != 0


def _bands(y, height, n_bands):
    """Row edges of ``n_bands`` horizontal bands holding about equal shares of the events (at least 4 rows)."""
    edges = np.quantile(y, np.linspace(0, 1, n_bands + 1)).round().astype(int)
    edges[0], edges[-1] = 0, height
    for i in range(1, n_bands):
        edges[i] = min(max(edges[i], edges[i - 1] + 4), height - 4 * (n_bands - i))
    return edges


def _support(n_left, n_right, scale=500.0):
    """How far an estimate from ``n_left`` and ``n_right`` events can be trusted on count alone, in [0, 1)."""
    return float(1.0 - np.exp(-min(n_left, n_right) / scale))


def _half_width(v, i):
    """Samples from the peak at ``i`` to where ``v`` first falls below half the peak's height above the median."""
    base = float(np.median(v))
    half = base + 0.5 * (float(v[i]) - base)
    below = np.flatnonzero(v < half)
    left = below[below < i]
    right = below[below > i]
    reach = [i - int(left[-1]) if left.size else i, int(right[0]) - i if right.size else len(v) - 1 - i]
    return max(1, max(reach))


def _row_time_histogram(ev, t0, n_bins, bin_us, height):
    """(height, n_bins) float32 counts of events per row and time bin."""
    k = (ev["t"] - t0) // bin_us
    flat = ev["y"].astype(np.int64) * n_bins + k
    return np.bincount(flat, minlength=height * n_bins).astype(np.float32).reshape(height, n_bins)


def _highpass(h, width):
    """Subtract a centred moving average of ``width`` bins along the last axis (zero beyond the ends)."""
    mean = cv2.blur(h, (max(1, int(width)), 1), borderType=cv2.BORDER_CONSTANT)
    return h - mean


def _smooth_lags(c, sigma):
    """Gaussian smoothing along the last axis (lags)."""
    radius = int(np.ceil(3 * sigma))
    k = np.exp(-0.5 * (np.arange(-radius, radius + 1) / sigma) ** 2)
    k /= k.sum()
    return np.apply_along_axis(lambda v: np.convolve(v, k, mode="same"), -1, c)


def _fft_len(n):
    """The next power of two >= n (pocketfft is fastest there)."""
    return 1 << int(np.ceil(np.log2(max(2, n))))


# --------------------------------------------------------------------------------------------------------------
# Disparity


def _disparity_overlays(left, right, *, resolution, max_disparity, window_us, max_windows, block, min_ncc):
    """Global overlay profile over shifts -D..D and the local best shifts.

    Returns
    -------
    profile : (2D+1,) float ndarray
        Normalised sum over windows and rows of ``sum_x L(x, y) R(x - s, y)``, index ``s + D``.
    local : (M,) float ndarray
        Best shift ``s`` at each left-camera event pixel whose block overlays well (NCC >= min_ncc).
    """
    d = int(min(max_disparity, resolution[0] - 1))
    profile = np.zeros(2 * d + 1)
    local = []
    bw, bh = block
    nfft = _fft_len(2 * resolution[0])
    for gl, gr, mask in _window_frames(left, right, resolution=resolution, window_us=window_us,
                                       max_windows=max_windows):
        # sum_x L(x) R(x - s) for every row, via FFT along x; index s (negative wraps around).
        c = np.fft.irfft(np.fft.rfft(gl, nfft, axis=1) * np.conj(np.fft.rfft(gr, nfft, axis=1)), nfft, axis=1)
        c = c.sum(axis=0)
        norm = np.sqrt((gl ** 2).sum() * (gr ** 2).sum())
        if norm > 0:
            profile += np.concatenate([c[-d:], c[:d + 1]]) / norm
        local.append(_local_best(gl, gr, mask, d, bw, bh, min_ncc, max_points=200))
    return profile, (np.concatenate(local) if local else np.zeros(0))


def _local_best(gl, gr, mask, d, bw, bh, min_ncc, max_points):
    """Best shift per left event pixel by block NCC of the signed frames, where it reaches ``min_ncc``.

    At most ``max_points`` pixels (evenly spread over the event pixels) are scored: the blocks overlap, so
    more would cost time without telling more.
    """
    ys, xs = np.nonzero(mask)
    if ys.size > max_points:
        pick = np.linspace(0, ys.size - 1, max_points).round().astype(int)
        ys, xs = ys[pick], xs[pick]
    ph, pw = bh // 2, bw // 2
    lp = np.pad(gl, ((ph, ph), (pw, pw)))
    rp = np.pad(gr, ((ph, ph), (pw + d, pw + d)))
    rows = ys[:, None, None] + np.arange(bh)[None, :, None]
    patch = lp[rows, xs[:, None, None] + np.arange(bw)[None, None, :]]           # (M, bh, bw)
    # The right strip covers columns x - pw - d .. x + pw + d; its window k is the block at shift s = d - k.
    strip = rp[rows, xs[:, None, None] + np.arange(bw + 2 * d)[None, None, :]]   # (M, bh, bw + 2d)
    wins = np.lib.stride_tricks.sliding_window_view(strip, bw, axis=2)            # (M, bh, 2d+1, bw)
    num = np.einsum("mhu,mhku->mk", patch, wins)
    sq = np.cumsum(np.pad((strip * strip).sum(axis=1), ((0, 0), (1, 0))), axis=1)
    den = np.sqrt(np.maximum((patch * patch).sum(axis=(1, 2))[:, None] * (sq[:, bw:] - sq[:, :-bw]), 0.0))
    ncc = np.where(den > 1e-6, num / np.maximum(den, 1e-6), -1.0)
    k = ncc.argmax(axis=1)
    ok = ncc[np.arange(k.size), k] >= min_ncc
    return (d - k[ok]).astype(float)


def _frame(ev, width, height):
    """(height, width) float32 sum of event signs."""
    f = np.zeros(height * width, np.float32)
    np.add.at(f, ev["y"].astype(np.int64) * width + ev["x"], 2.0 * ev["p"] - 1.0)
    return f.reshape(height, width)


def _decide_side(profile, d):
    """(swap, confidence) from the overlay profile's strongest positive vs negative shift."""
    base = float(np.median(profile))
    pos, neg = float(profile[d + 1:].max()), float(profile[:d].max())
    top = max(pos, neg) - base
    if top <= 0:
        return False, 0.0
    return bool(neg > pos), _clip01(abs(pos - neg) / top)


def _profile_peaks(profile, *, max_peaks=5):
    """Indices (sub-sample) of local maxima standing out from the profile's background, strongest first."""
    base = float(np.median(profile))
    spread = float(np.median(np.abs(profile - base))) + 1e-12
    top = float(profile.max())
    out = []
    for i in range(1, profile.size - 1):
        v = profile[i]
        if v >= profile[i - 1] and v > profile[i + 1] and v - base > max(6 * spread, 0.25 * (top - base)):
            out.append((v, _subsample_peak(profile, i)))
    out.sort(reverse=True)
    return [p for _, p in out[:max_peaks]]


# --------------------------------------------------------------------------------------------------------------
# Counts and noise


def _burst_ratio(left, right, *, window_us):
    t0 = min(int(left["t"][0]), int(right["t"][0]))
    n = (max(int(left["t"][-1]), int(right["t"][-1])) - t0) // window_us + 1
    a = np.bincount((left["t"] - t0) // window_us, minlength=n)
    b = np.bincount((right["t"] - t0) // window_us, minlength=n)
    both = (a >= 5) & (b >= 5)
    if not both.any():
        return float("nan")
    r = np.maximum(a[both] / b[both], b[both] / a[both])
    return float(np.percentile(r, 95))


def _isolated(ev, *, window_us, resolution):
    """Number of events with no event at any of the 8 neighbouring pixels within ``window_us`` either side.

    Events are sorted by (pixel, t); for each neighbour offset, a binary search finds the neighbour pixel's
    events nearest in time. The own pixel does not count: a hot pixel firing alone is noise too.
    """
    width, height = resolution
    pix = ev["y"].astype(np.int64) * width + ev["x"]
    t = ev["t"] - int(ev["t"][0])
    span = int(t[-1]) + 2 * window_us + 2
    key = np.sort(pix * span + t)
    # Queries in key order are (nearly) sorted too, which keeps the binary searches cache-friendly.
    pix, t = key // span, key % span
    x, y = pix % width, pix // width
    has = np.zeros(ev.size, bool)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            if dx == 0 and dy == 0:
                continue
            inside = (x + dx >= 0) & (x + dx < width) & (y + dy >= 0) & (y + dy < height)
            q = (pix + dy * width + dx) * span + t
            lo = np.searchsorted(key, q - window_us, side="left")
            hi = np.searchsorted(key, q + window_us, side="right")
            has |= inside & (hi > lo)
    return int((~has).sum())


# --------------------------------------------------------------------------------------------------------------
# Small helpers


def _subsample_peak(v, i):
    """Sub-sample position of the peak at index ``i`` by a parabola through its neighbours."""
    if i <= 0 or i >= len(v) - 1:
        return float(i)
    a, b, c = float(v[i - 1]), float(v[i]), float(v[i + 1])
    den = a - 2 * b + c
    return float(i) if den >= 0 else float(i + 0.5 * (a - c) / den)


def _contrast(v, i, *, exclude):
    """How much the peak at ``i`` stands out: 1 - (best value beyond ``exclude`` samples of it) / (peak value),
    both measured above the median of ``v``; clipped to [0, 1]."""
    base = float(np.median(v))
    peak = float(v[i]) - base
    if peak <= 0:
        return 0.0
    out = np.ones(len(v), bool)
    out[max(0, i - exclude):i + exclude + 1] = False
    if not out.any():
        return 1.0
    return _clip01(1.0 - max(float(v[out].max()) - base, 0.0) / peak)


def _clip01(v):
    return float(min(1.0, max(0.0, v)))


def _json_default(o):
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, float):
        return o
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")
