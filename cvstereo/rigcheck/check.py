"""The rig check's pipeline: :func:`check_rig` runs the estimators in order and assembles the report."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np

from cvstereo.geometry.rigcorrect import RigCorrection
from cvstereo.model.recording import Recording
from cvstereo.rigcheck.disparity import disparity_overlays, side_and_disparity
from cvstereo.rigcheck.params import RigCheckParams
from cvstereo.rigcheck.report import RigReport
from cvstereo.rigcheck.rows import row_offsets
from cvstereo.rigcheck.stats import count_statistics
from cvstereo.rigcheck.time_offset import time_offset

__all__ = ["STAGES", "check_rig"]

#: The stages :func:`check_rig` reports to its ``progress`` callback, in order (the two repeats may be skipped).
STAGES = ("row offset", "time offset", "row offset again", "time offset again", "side and disparity", "counts")


def check_rig(recording: Recording, params: RigCheckParams | None = None, *,
              progress: Callable[[str], None] | None = None, **overrides) -> RigReport:
    """Estimate the rig's imperfections from the events of a recording.

    Parameters
    ----------
    recording : Recording
        Both cameras, in the order believed (left first).
    params : RigCheckParams, optional
        Search ranges, windows and tuned constants (default: ``RigCheckParams()``).
    progress : callable, optional, keyword-only
        Called with the name of each stage of :data:`STAGES` as it starts (a stage that is not needed is
        not called), e.g. to move a progress bar.
    **overrides
        Fields of :class:`RigCheckParams` to replace, e.g. ``max_disparity=32, max_seconds=6``.

    Returns
    -------
    RigReport

    Raises
    ------
    ValueError
        Too few events in a camera, a recording shorter than ``min_window_us``, or options out of range.
    TypeError
        An override that is no field of :class:`RigCheckParams`.
    """
    params = RigCheckParams.with_overrides(params, overrides)
    if params.max_seconds is not None:
        recording = recording.slice_time(recording.t_start, recording.t_start + int(params.max_seconds * 1e6))
    for name, ev in (("left", recording.left), ("right", recording.right)):
        if ev.size < params.min_events:
            raise ValueError(
                f"check_rig: the {name} camera has {ev.size} events; at least {params.min_events} per camera are "
                "needed (give a longer recording, or check that both cameras were read)."
            )
    span_us = recording.t_end - recording.t_start
    if span_us < params.min_window_us:
        raise ValueError(
            f"check_rig: the recording's events span {span_us} us (from t = {recording.t_start} us); the rig check "
            f"needs a duration of at least {params.min_window_us / 1000:g} ms to tell event rates, noise and time "
            "offsets (give a longer recording)."
        )
    width, height = res = recording.resolution
    left, right = recording.left, recording.right
    window_us = params.window_us
    if window_us is None:
        rate = min(left.size, right.size) / recording.duration_s
        window_us = int(np.clip(params.window_events / rate * 1e6, params.min_window_us, params.max_window_us))
    settings = dataclasses.asdict(dataclasses.replace(params, window_us=window_us))

    # 1. Row offset from the 2-D overlay of accumulated frames over (dx, dy): windows long against any time
    #    offset, so nearly independent of it. 2. Time offset at that row shift and dominant disparity:
    #    searching rows and lags jointly is ambiguous (an inclined edge moving sideways looks the same a few
    #    rows lower and a few ms later), at a fixed row shift it is not. 3. The rows once more with the time
    #    offset removed (when it is large enough to matter), and the time offset again if the rows or the
    #    disparity changed.
    frame_opts = {"resolution": res, "max_row_offset": min(params.max_row_offset, height - 1),
                  "max_disparity": min(params.max_disparity, width - 1), "window_us": window_us,
                  "max_windows": params.max_windows, "n_bands": params.n_bands,
                  "min_events": params.window_min_events, "blur_px": params.blur_px}
    stage = progress or (lambda name: None)
    stage(STAGES[0])
    rows = row_offsets(left, right, **frame_opts)
    stage(STAGES[1])
    tau = time_offset(left, right, row=round(rows.offset), disparity=rows.disparity, resolution=res, params=params)
    rows2 = rows
    if abs(tau.offset_us) >= params.rows_again_share * window_us:
        stage(STAGES[2])
        rows2 = row_offsets(left, _shifted(right, 0, tau.offset_us, res), **frame_opts)
    if round(rows2.offset) != round(rows.offset) or rows2.disparity != rows.disparity:
        stage(STAGES[3])
        tau = time_offset(left, right, row=round(rows2.offset), disparity=rows2.disparity, resolution=res,
                          params=params)
    settings["time_offset_method"] = tau.method
    row_offset, time_offset_us, band_offsets = rows2.offset, tau.offset_us, rows2.band_offsets
    alternatives = tuple(float(a) for a in tau.alternatives_us)

    # 4. Side and disparities on the streams with both offsets removed (whole rows; time to the microsecond).
    stage(STAGES[4])
    overlays = disparity_overlays(left, _shifted(right, row_offset, time_offset_us, res), resolution=res,
                                  max_disparity=params.max_disparity, window_us=window_us,
                                  max_windows=params.max_windows, block=params.block, min_ncc=params.min_ncc,
                                  min_events=params.window_min_events, blur_px=params.blur_px,
                                  max_points=params.local_max_points)
    disp = side_and_disparity(overlays, params.disparity_percentiles, max_peaks=params.profile_max_peaks,
                              peak_mads=params.profile_peak_mads, peak_share=params.profile_peak_share)

    # 5. Counts, in the orientation the report speaks of.
    if disp.swap:
        left, right = right, left
        row_offset, time_offset_us = -row_offset, -time_offset_us
        band_offsets = tuple(-b for b in band_offsets)
        alternatives = tuple(-a for a in alternatives)
    stage(STAGES[5])
    counts = count_statistics(left, right, duration_s=recording.duration_s, resolution=res,
                              noise_window_us=params.noise_window_us, burst_window_us=params.burst_window_us,
                              burst_min_events=params.burst_min_events)
    confident = [b for b, c in zip(band_offsets, rows2.band_confidences, strict=True)
                 if c >= params.band_min_confidence]
    varies = bool(len(confident) >= 2 and max(confident) - min(confident) > params.band_varies_rows)
    pct = disp.percentiles
    return RigReport(
        swap=disp.swap, swap_confidence=disp.swap_confidence,
        row_offset=float(row_offset), row_offset_confidence=rows2.confidence,
        row_offset_bands=tuple(float(b) for b in band_offsets), band_rows=rows2.band_rows,
        row_offset_band_confidence=tuple(rows2.band_confidences), row_offset_varies=varies,
        time_offset_us=float(time_offset_us), time_offset_confidence=tau.confidence,
        time_offset_ambiguous=bool(tau.alternatives_us), time_offset_alternatives_us=alternatives,
        time_offset_period_us=float(tau.period_us),
        disparity_peak=disp.peak, disparity_peaks=disp.peaks, disparity_percentiles=pct,
        disparity_range=(pct[5], pct[95]), disparity_confidence=disp.confidence,
        **counts, duration_s=float(recording.duration_s), settings=settings,
    )


def _shifted(right, rows, time_us, resolution):
    """Right-camera events with ``round(rows)`` added to y and ``round(time_us)`` subtracted from t."""
    return RigCorrection(rows, round(time_us), resolution).correct_right(right)[0]
