"""Every option and tuned constant of the rig self-check, in one frozen class: :class:`RigCheckParams`."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

__all__ = ["RigCheckParams"]


@dataclass(frozen=True)
class RigCheckParams:
    """Options of :func:`cvstereo.rigcheck.check_rig` and the constants its estimators were tuned with.

    The first group are the search ranges and windows a user may want to change for a recording; the
    ``reg_*`` group tunes the shift-velocity regression (:mod:`cvstereo.rigcheck.time_offset`); the rest
    decide between estimators and when a finding is applied.

    Attributes
    ----------
    max_disparity : int
        Largest |disparity| searched, px.
    max_row_offset : int
        Largest |row offset| searched.
    max_time_offset_us : int
        Largest |time offset| searched, us.
    time_bin_us : int
        Bin of the pixel-coincidence histogram of time differences; the estimate is interpolated below it.
    n_bands : int
        Horizontal bands of the image for which the row offset is estimated separately.
    window_us : int or None
        Accumulation window of the frames for the row and disparity stages; None: long enough for about
        ``window_events`` events per camera (between ``min_window_us`` and ``max_window_us``).
    min_window_us, max_window_us : int
        Bounds of the automatic window, us. The shortest is also the shortest recording checked: rates, bursts
        and time offsets over less are not estimates but divisions by almost nothing.
    window_min_events : int
        A window enters the row and disparity stages only with at least this many events in each camera.
    blur_px : float
        Gaussian smoothing (sigma, px; a 3x3 kernel) of those windows' frames, so that events one pixel apart
        still overlay (jitter, distortion).
    max_windows : int
        At most this many windows (evenly spread over the recording) enter the row and disparity stages.
    block : (width, height)
        Block over which local overlays are scored (normalised cross-correlation of signed frames).
    min_ncc : float
        A local overlay counts when its best normalised cross-correlation reaches this.
    local_max_points : int
        Local overlays scored per window at most (evenly picked among its event pixels): bounds the cost.
    profile_max_peaks : int
        At most this many peaks of the global overlay profile are reported, the strongest first.
    profile_peak_mads, profile_peak_share : float
        A local maximum of the profile is a peak when it stands above the profile's median by more than this many
        median absolute deviations and by more than this share of the highest maximum's height.
    band_min_confidence : float
        A band's row offset counts for ``row_offset_varies`` when its confidence reaches this.
    band_varies_rows : float
        The row offset varies when the counted bands' offsets spread over more than this many rows.
    noise_window_us : int
        An event is noise when no neighbouring pixel fired within this time either side.
    burst_window_us : int
        Window of the burst ratio (the thesis saw the cameras' counts differ up to 3x within a few ms).
    burst_min_events : int
        A window enters the burst ratio only with at least this many events in each camera: the ratio of fewer
        is mostly counting noise.
    max_seconds : float or None
        Analyse at most this many seconds from the start (bounds time and memory); None: everything.
    disparity_percentiles : tuple of int
        Percentiles of the local disparities that are reported.
    window_events : int
        Events per camera that an automatic disparity-stage window aims at: enough to overlay shapes, few
        enough that moving things do not smear across many pixels.
    min_events : int
        Below this many events per camera no estimate is meaningful.
    reg_window_us : int
        Window of the frames whose shift between the cameras is measured: short enough that the image speed
        is about constant within it (an arm reverses within ~100 ms), long enough for a few hundred events.
    reg_gap : int
        The speed comes from the windows this many steps before and after: a longer baseline gives a larger
        shift, measured with less relative error, at the cost of averaging the speed over ``2 * reg_gap``
        windows.
    reg_tiles : (columns, rows)
        Image tiles, each with its own disparity in the fit: depth and lens distortion make the disparity
        vary over the image, and tiles keep things moving in opposite directions (two arms) apart.
    reg_chunk : int
        Measured windows per chunk (bounds memory: 2 cameras x 3 x 100 x 128 x 128 float32 = 40 MB).
    reg_blur_px : float
        Gaussian smoothing of the frames, px (sigma): makes the correlation peak broad enough to interpolate
        without locking to whole pixels.
    reg_upsample : int
        The correlation is interpolated on a grid this many times finer than a pixel.
    reg_shift_px : int
        Search range around the dominant disparity, px, on top of the shift the largest time offset can cause.
    reg_max_speed : float
        Fastest image motion considered, px/us (0.5 px/ms: a DVS128 crossed in a quarter second).
    reg_min_ncc : float
        A window (tile) enters the fit when both its cameras' overlay and its speed's overlay reach this
        normalised correlation (sparse noise-only windows do not).
    reg_trim_mad : float
        Residuals beyond this many robust standard deviations (1.4826 MAD) are outliers (another object, an
        occlusion); the fit is repeated without them.
    reg_iterations : int
        Trimming rounds at most.
    reg_min_window_events : int
        A window is measured only when each camera has this many events in it (and in its neighbours).
    reg_max_windows : int
        At most this many windows are measured, spread over the recording (in runs, ``reg_run_windows``): the
        regression's cost grows with them, and 150 keep the slope within the tests' 0.5 ms on the simulated
        arms while a 10 s fan recording is checked in a few percent of its duration.
    reg_run_windows : int
        When windows must be picked, they come in runs of this many consecutive ones (evenly spread over the
        recording): a window's speed needs its neighbours' frames, which consecutive windows share, so a run
        costs about ``(reg_run_windows + 2 * reg_gap) / reg_run_windows`` frames per window instead of 3;
        runs of 100 ms still sample a sweep's speeds in both directions over a recording.
    reg_min_windows : int
        Fewer usable windows than this leave the regression undetermined.
    reg_se_scale_us : float
        Standard error of the slope at which the confidence is 0.5 (half the 0.5 ms a matcher tolerates).
    reg_min_confidence : float
        Below this confidence (slope standard error above ~750 us) the regression is not used at all.
    rows_again_share : float
        The rows are estimated once more with the time offset removed only when the offset is at least this
        share of the frames' window: a smaller one moves too few events across window edges to change them.
    pairs_max_events : int
        The pixel-coincidence histogram pairs at most this many left events (evenly picked): bounds its memory
        and time, and a few hundred thousand pairs pin the peak.
    pairs_smooth_bins : float
        Gaussian smoothing (sigma, bins) of that histogram before its peak is found.
    pairs_sharp_us : int
        The pixel-coincidence histogram is trusted over the regression when its peak's half width at half
        height is at most this (sensor jitter and latency spread a true coincidence peak by a few hundred us;
        a disparity off by a fraction of a pixel on a slow sweep spreads it by several ms).
    time_equal_share : float
        Peaks of the pixel-coincidence histogram that fall short of the highest by at most this share of its
        height (or by two standard deviations of their Poisson counts) are taken as equal: a periodic scene
        (a fan's blades) gives one per period, the search prefers the one nearest zero offset, and the time
        offset is then ambiguous (reported, and not applied by ``match --auto``).
    time_equal_sigmas : float
        The "two standard deviations" of ``time_equal_share``.
    time_apply_confidence : float
        Confidence a time offset needs before :meth:`RigReport.match_kwargs` (and so ``match --auto``)
        applies it. Higher than for rows: on the simulated arms, whose depth wobbles, wrong time offsets of
        1-4 ms came with confidences up to 0.55, and applying an offset wrong by more than the event-time
        matcher's 300 us window ruins its matches, while leaving a true offset of a few ms unapplied only
        costs some of them.
    """

    max_disparity: int = 64
    max_row_offset: int = 8
    max_time_offset_us: int = 20_000
    time_bin_us: int = 200
    n_bands: int = 4
    window_us: int | None = None
    min_window_us: int = 10_000
    max_window_us: int = 1_000_000
    window_min_events: int = 10
    blur_px: float = 0.8
    max_windows: int = 100
    block: tuple[int, int] = (9, 5)
    min_ncc: float = 0.5
    local_max_points: int = 200
    profile_max_peaks: int = 5
    profile_peak_mads: float = 6.0
    profile_peak_share: float = 0.25
    band_min_confidence: float = 0.3
    band_varies_rows: float = 1.0
    noise_window_us: int = 5_000
    burst_window_us: int = 5_000
    burst_min_events: int = 5
    max_seconds: float | None = 60.0
    disparity_percentiles: tuple[int, ...] = (5, 25, 50, 75, 95)
    window_events: int = 300
    min_events: int = 50
    reg_window_us: int = 10_000
    reg_gap: int = 1
    reg_tiles: tuple[int, int] = (4, 2)
    reg_chunk: int = 100
    reg_blur_px: float = 1.0
    reg_upsample: int = 16
    reg_shift_px: int = 6
    reg_max_speed: float = 0.5e-3
    reg_min_ncc: float = 0.3
    reg_trim_mad: float = 3.0
    reg_iterations: int = 6
    reg_min_window_events: int = 20
    reg_max_windows: int = 150
    reg_run_windows: int = 10
    reg_min_windows: int = 20
    reg_se_scale_us: float = 250.0
    reg_min_confidence: float = 0.1
    rows_again_share: float = 0.05
    pairs_max_events: int = 200_000
    pairs_smooth_bins: float = 1.5
    pairs_sharp_us: int = 1_000
    time_equal_share: float = 0.1
    time_equal_sigmas: float = 2.0
    time_apply_confidence: float = 0.6

    def __post_init__(self) -> None:
        positive = ("max_disparity", "max_time_offset_us", "time_bin_us", "n_bands", "max_windows",
                    "noise_window_us", "burst_window_us", "window_events", "min_events", "reg_window_us",
                    "reg_gap", "reg_chunk", "reg_upsample", "reg_iterations", "reg_min_windows", "reg_max_windows",
                    "reg_run_windows", "min_window_us", "max_window_us", "window_min_events", "local_max_points",
                    "profile_max_peaks", "burst_min_events", "pairs_max_events")
        for name in positive + (("window_us",) if self.window_us is not None else ()):
            if int(getattr(self, name)) < 1:
                raise ValueError(f"check_rig: {name}={getattr(self, name)} is out of range; give a positive value.")
        if self.max_window_us < self.min_window_us:
            raise ValueError(f"check_rig: max_window_us={self.max_window_us} is below min_window_us="
                             f"{self.min_window_us}; give max_window_us >= min_window_us.")
        if int(self.max_row_offset) < 0:
            raise ValueError(f"check_rig: max_row_offset={self.max_row_offset} is out of range; give 0 or more.")
        if self.max_seconds is not None and not self.max_seconds > 0:
            raise ValueError(f"check_rig: max_seconds={self.max_seconds} is out of range; give a positive value "
                             "or None (everything).")

    @classmethod
    def with_overrides(cls, params: RigCheckParams | None, overrides: dict) -> RigCheckParams:
        """``params`` (default: the defaults) with the fields named in ``overrides`` replaced.

        Raises
        ------
        TypeError
            A name that is no field (the message lists the fields).
        """
        base = params if params is not None else cls()
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(overrides) - names)
        if unknown:
            raise TypeError(f"check_rig: unknown option(s) {', '.join(unknown)}; RigCheckParams has "
                            f"{', '.join(sorted(names))}.")
        return dataclasses.replace(base, **overrides) if overrides else base
