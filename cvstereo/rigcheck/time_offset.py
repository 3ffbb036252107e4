"""Time offset between the streams: pixel coincidences and shift-velocity regression (:func:`time_offset`).

Two estimators of ``tau`` (``t_right ~ t_left + tau``): the histogram of time differences between events at
corresponding pixels (:func:`time_offset_pairs`), precise when the disparities are whole pixels or the scene
nearly static; and the regression of the cameras' apparent shift on the image velocity over short windows
and image tiles (:func:`time_offset_regression`), which on sideways sweeps is not fooled by a disparity error
``e`` that the histogram takes for a time offset ``e / v``. On a periodic scene the histogram peaks once per
period; :func:`equal_peaks` finds the peaks as high as the highest, the one nearest 0 is taken and the others
are reported (the offset is then ambiguous).
"""

from __future__ import annotations

from typing import NamedTuple

import cv2
import numba
import numpy as np
import scipy.fft as sfft

from cvstereo.frames.accumulate import signed_frame
from cvstereo.rigcheck.params import RigCheckParams
from cvstereo.rigcheck.peaks import contrast, fft_len, half_width, smooth_lags, subsample_peak, support

__all__ = ["PAIRS", "REGRESSION", "RowSpectra", "SlopeFit", "TimeOffset", "cross_spectra", "equal_peaks",
           "time_offset", "time_offset_pairs", "time_offset_regression"]

# The defaults of the pixel-coincidence options, for callers of time_offset_pairs without a RigCheckParams.
_DEFAULTS = RigCheckParams()
# The regression fits its speeds in px/ms rather than px/us (columns of similar size: conditioning).
_US_PER_MS = 1e3
# A median absolute deviation times this is the standard deviation of normally distributed residuals.
_MAD_TO_SIGMA = 1.4826

PAIRS = "pixel coincidences"
REGRESSION = "shift-velocity regression"


class TimeOffset(NamedTuple):
    """A time-offset estimate (of :func:`time_offset`, and of either estimator alone)."""

    offset_us: float
    """How much later the right camera stamps the same change, us."""
    confidence: float
    method: str
    """:data:`PAIRS` or :data:`REGRESSION`: the estimator that answered."""
    alternatives_us: tuple[float, ...] = ()
    """Other offsets the pixel coincidences support as well (a periodic scene), nearest first."""
    period_us: float = float("nan")
    """Spacing of those equal peaks (the scene's period), NaN without them."""
    half_width_us: float = float("nan")
    """Half width of the coincidence histogram's peak at half its height (inf without any pair); NaN from the
    regression."""


class SlopeFit(NamedTuple):
    """A fitted slope and its standard error."""

    slope: float
    standard_error: float


def time_offset(left, right, *, row, disparity, resolution, params: RigCheckParams) -> TimeOffset:
    """How much later the right camera stamps the same change.

    The pixel-coincidence histogram answers when its peak is sharp (at most ``params.pairs_sharp_us`` half
    width) or the shift-velocity regression is undetermined (nearly static scenes, too few busy windows) or
    below ``params.reg_min_confidence``; the regression otherwise.
    """
    pairs = time_offset_pairs(left, right, row=row, disparity=disparity, resolution=resolution,
                              max_lag_us=params.max_time_offset_us, bin_us=params.time_bin_us,
                              equal_share=params.time_equal_share, equal_sigmas=params.time_equal_sigmas,
                              max_events=params.pairs_max_events, smooth_bins=params.pairs_smooth_bins)
    # The histogram is biased by (disparity error) / speed on moving scenes, and then also broad: pairs at the
    # neighbouring disparities land (1 px) / speed away. A sharp peak means the disparities were right (or the
    # scene nearly static) and the histogram is the more precise; a broad one defers to the regression, which
    # (the costlier estimator) is only run then.
    if pairs.half_width_us > params.pairs_sharp_us:
        reg = time_offset_regression(left, right, row=row, disparity=disparity, resolution=resolution,
                                     params=params)
        if reg is not None and reg.confidence >= params.reg_min_confidence:
            # A periodic scene shows in the coincidences whichever estimator answers.
            return reg._replace(alternatives_us=pairs.alternatives_us, period_us=pairs.period_us)
    return pairs


def time_offset_regression(left, right, *, row, disparity, resolution,
                           params: RigCheckParams) -> TimeOffset | None:
    """Time offset as the slope of the cameras' apparent shift against the image velocity.

    In a short window the right camera's image is the left one shifted by ``s = d + v * tau``: it shows the
    scene ``tau`` earlier, when things stood ``v * tau`` px further back (``v`` the horizontal image velocity,
    px/us). Per window (``params.reg_window_us``) and image tile (``params.reg_tiles``), ``s`` is the sub-pixel
    peak of the horizontal cross-correlation of the two cameras' smoothed signed frames (rows lined up by
    ``row``) and ``v`` the shift between the windows before and after, in either camera, over their distance.
    A weighted least-squares fit of ``s`` on ``v`` with one intercept per tile (the disparity varies over the
    image: depth, lens distortion) then gives ``tau`` as the common slope; windows whose residual exceeds
    ``params.reg_trim_mad`` robust standard deviations are dropped and the fit repeated. A sweep to and fro
    gives ``v`` of both signs and many sizes, which pins ``tau`` independently of the disparity; a steady drift
    does not, and the slope's standard error (from the residuals, deflated for their correlation between
    neighbouring windows) then says so.

    Known limit: a disparity that changes in step with the speed (an arm wobbling in depth while it sweeps,
    over a clip of a few sweeps) is indistinguishable from a time offset; longer recordings average it out.

    Returns None when too few windows move (e.g. a nearly static scene).
    """
    width, height = resolution
    window_us, gap, max_lag_us = params.reg_window_us, params.reg_gap, params.max_time_offset_us
    y = right["y"].astype(np.int64) + row
    keep = (y >= 0) & (y < height)
    right = right[keep].copy()
    right["y"] = y[keep]
    if right.size < params.min_events:
        return None
    t0 = min(int(left["t"][0]), int(right["t"][0]))
    t1 = max(int(left["t"][-1]), int(right["t"][-1])) + 1
    starts = np.arange(t0, t1, window_us)
    counts = [np.diff(np.searchsorted(ev["t"], np.append(starts, starts[-1] + window_us))) for ev in (left, right)]
    busy = (counts[0] >= params.reg_min_window_events) & (counts[1] >= params.reg_min_window_events)
    # A window is measured when it and its neighbours at +-gap are busy; at most reg_max_windows of them,
    # evenly spread (enough for the fit; bounds the time on long recordings).
    centre = np.flatnonzero(busy[gap:-gap] & busy[:-2 * gap] & busy[2 * gap:]) + gap
    if centre.size < params.reg_min_windows:
        return None
    if centre.size > params.reg_max_windows:
        centre = _runs(centre, params.reg_max_windows, params.reg_run_windows)
    search = params.reg_shift_px + int(np.ceil(params.reg_max_speed * max_lag_us))
    n_cols, n_rows = params.reg_tiles
    col_edges = np.linspace(0, width, n_cols + 1).round().astype(int)
    row_edges = np.linspace(0, height, n_rows + 1).round().astype(int)
    # Columns of each tile in either camera: the right camera sees a tile's content ``disparity`` columns
    # further left.
    cols_l = [(col_edges[c], col_edges[c + 1]) for c in range(n_cols)]
    cols_r = [(min(max(a - int(disparity), 0), width), min(max(b - int(disparity), 0), width)) for a, b in cols_l]
    lag_v = int(np.ceil(params.reg_max_speed * 2 * gap * window_us))
    nfft = fft_len(width + search + abs(int(disparity)) + 1)
    fine = {"nfft": nfft, "upsample": params.reg_upsample}
    tiles, shifts, s_weight, speeds, v_weight = [], [], [], [], []
    # Chunks of measured windows bound the memory on long recordings.
    for lo in range(0, centre.size, params.reg_chunk):
        chunk = centre[lo:lo + params.reg_chunk]
        needed, where = np.unique(np.concatenate([chunk - gap, chunk, chunk + gap]), return_inverse=True)
        before, inner, after = where.reshape(3, chunk.size)
        fl, fr = (_window_stack(ev, starts[needed], width, height, window_us, params.reg_blur_px)
                  for ev in (left, right))
        # Spectra along x, once per camera and once per column tile, each only of the windows it is used at; a
        # row tile is a sum over its rows.
        use_before, use_inner, use_after = (np.isin(np.arange(needed.size), w) for w in (before, inner, after))
        spec_l = _row_spectra(fl, 0, width, nfft, use_before)
        spec_r = _row_spectra(fr, 0, width, nfft, use_inner | use_before)
        for col in range(n_cols):
            tl = _row_spectra(fl, *cols_l[col], nfft, use_inner | use_after)
            tr = _row_spectra(fr, *cols_r[col], nfft, use_after)
            for band in range(n_rows):
                rows = (row_edges[band], row_edges[band + 1])
                s, hs = _fine_shift(tl, inner, spec_r, inner, rows, disparity - search, disparity + search, **fine)
                ul, hl = _fine_shift(tl, after, spec_l, before, rows, -lag_v, lag_v, **fine)
                ur, hr = _fine_shift(tr, after, spec_r, before, rows, -lag_v, lag_v, **fine)
                tiles.append(np.full(inner.size, band * n_cols + col))
                shifts.append(s)
                s_weight.append(hs)
                speeds.append((ul + ur) / (2 * 2 * gap * window_us))
                v_weight.append(np.minimum(hl, hr))
    n_tiles = n_cols * n_rows
    tile, s, v = np.concatenate(tiles), np.concatenate(shifts), np.concatenate(speeds)
    s_weight, v_weight = np.concatenate(s_weight), np.concatenate(v_weight)
    w = s_weight * v_weight
    w[(s_weight < params.reg_min_ncc) | (v_weight < params.reg_min_ncc)] = 0.0
    fit = _fixed_effects_slope(tile, s, v, w, n_tiles, params)
    if fit is None:
        return None
    tau, se = fit
    if not abs(tau) <= max_lag_us:
        return None
    conf = 1.0 / (1.0 + (se / params.reg_se_scale_us) ** 2) * support(left.size, right.size)
    return TimeOffset(float(tau), float(conf), REGRESSION)


def _runs(centre, count, run):
    """About ``count`` of the sorted window indices ``centre``, in runs of ``run`` consecutive entries evenly
    spread over them: neighbouring windows share their frames (a window and its neighbours at +-gap are
    needed), so runs cost about ``(run + 2 * gap) / run`` frames per measured window instead of 3."""
    n_runs = max(1, int(np.ceil(count / run)))
    first = np.linspace(0, centre.size - run, n_runs).round().astype(int)
    return np.unique(centre[(first[:, None] + np.arange(run)[None, :]).ravel()])


class RowSpectra(NamedTuple):
    """Spectra along x of the rows of a stack of frames (:func:`_row_spectra`), kept only for nonzero rows."""

    spectra: np.ndarray
    """(N, F) complex: the spectra of the N nonzero rows."""
    index: np.ndarray
    """(K, H) int64: the row of ``spectra`` that holds frame k's row y, -1 where that row is zero."""
    energy: np.ndarray
    """(K, H) float32: each row's sum of squares."""


def _row_spectra(frames, lo, hi, nfft, windows) -> RowSpectra:
    """Spectra along x (zero-padded to ``nfft``) and energies of each row of the frames cut to the columns
    ``[lo, hi)`` (zero elsewhere), of the frames where ``windows`` (bool, per frame) is True (the others
    count as zero).

    Only the rows holding a nonzero value are transformed and kept: in a short window most rows hold no event
    within a blur's reach (on the fan four in five), and the transforms and the products of spectra are most
    of the regression's time. In single precision, as the frames are: the sums of the cross-spectra are double
    (:func:`cross_spectra`), and the check's figures agree with double-precision transforms to the third
    decimal (51 prefixes and files).
    """
    seg = frames[:, :, lo:hi]
    nonzero = seg.any(axis=2) & windows[:, None]
    index = np.full(frames.shape[:2], -1, np.int64)
    index[nonzero] = np.arange(int(nonzero.sum()))
    padded = np.zeros((int(nonzero.sum()), nfft), np.float32)
    padded[:, lo:hi] = seg[nonzero]
    energy = np.zeros(frames.shape[:2], np.float32)
    energy[nonzero] = (seg[nonzero] ** 2).sum(axis=1)
    return RowSpectra(sfft.rfft(padded, axis=1), index, energy)


def cross_spectra(a: RowSpectra, frames_a, b: RowSpectra, frames_b, y0, y1):
    """Per pair j, the sum over the rows y0 .. y1 - 1 of spectrum(a, frame frames_a[j], y) times the conjugate
    of spectrum(b, frame frames_b[j], y); rows that are zero in either frame add nothing and are left out."""
    out = np.zeros((frames_a.size, a.spectra.shape[1]), np.complex128)
    _add_cross(a.spectra, np.ascontiguousarray(a.index[frames_a, y0:y1]), b.spectra,
               np.ascontiguousarray(b.index[frames_b, y0:y1]), out)
    return out


@numba.njit(cache=True, nogil=True)
def _add_cross(spec_a, rows_a, spec_b, rows_b, out):
    """``out[j] += spec_a[rows_a[j, k]] * conj(spec_b[rows_b[j, k]])`` over k, where both rows exist (>= 0).

    A pair's products are summed in the order of the rows into its own line of ``out``, which stays in the cache;
    gathering each row's products for all pairs first (numpy's way) moved tens of megabytes at 640x480. Each
    product in the spectra's precision, the sum in double.
    """
    n_pairs, n_rows = rows_a.shape
    for j in range(n_pairs):
        for k in range(n_rows):
            p, q = rows_a[j, k], rows_b[j, k]
            if p >= 0 and q >= 0:
                for f in range(out.shape[1]):
                    out[j, f] += np.complex128(spec_a[p, f] * np.conj(spec_b[q, f]))


def _window_stack(ev, starts, width, height, window_us, blur_px):
    """(K, H, W) float32 signed event frames of the windows ``[starts[k], starts[k] + window_us)`` (sorted,
    not overlapping) of the time-ordered events ``ev``, Gaussian-smoothed."""
    # Each window's events by bisection of the time-ordered events (two searches per window, not one per event).
    lo, hi = np.searchsorted(ev["t"], starts), np.searchsorted(ev["t"], starts + window_us)
    n = starts.size
    f = np.empty((n, height, width), np.float32)
    for i in range(n):
        f[i] = signed_frame(ev[lo[i]:hi[i]], resolution=(width, height))
        # Smoothing makes the correlation peak broad enough to interpolate without locking to whole pixels.
        f[i] = cv2.GaussianBlur(f[i], (0, 0), blur_px, borderType=cv2.BORDER_CONSTANT)
    return f


def _fine_shift(a: RowSpectra, frames_a, b: RowSpectra, frames_b, rows, lo, hi, *, nfft, upsample):
    """Per pair of frames (``frames_a[j]`` of ``a``, ``frames_b[j]`` of ``b``), the sub-pixel ``s`` in
    ``[lo, hi]`` maximising ``sum_y sum_x a(x, y) b(x - s, y)`` over the rows ``rows`` = (first, stop), and that
    maximum normalised like a correlation coefficient (0 when the peak sits at the end of the search range).

    ``a``, ``b``: spectra along x of the frames' rows, zero-padded to ``nfft`` (:func:`_row_spectra`). The
    rows' cross-spectra are summed and transformed back on a grid ``upsample`` times finer than a pixel (exact
    interpolation of the band-limited correlation); a parabola through the finest samples then places the
    peak. A parabola on whole pixels alone biases sub-pixel shifts towards integers, which would leak into the
    slope.
    """
    y0, y1 = (int(r) for r in rows)
    spec = cross_spectra(a, frames_a, b, frames_b, y0, y1)
    n = nfft * upsample
    lags = np.arange(lo * upsample, hi * upsample + 1)
    c = (sfft.irfft(spec, n, axis=-1) * upsample)[:, lags % n]
    i = c.argmax(axis=1)
    at_end = (i == 0) | (i == lags.size - 1)
    i = np.clip(i, 1, lags.size - 2)
    k = np.arange(c.shape[0])
    p, q, r = c[k, i - 1], c[k, i], c[k, i + 1]
    den = p - 2 * q + r
    off = np.where(den < 0, 0.5 * (p - r) / np.where(den < 0, den, -1.0), 0.0)
    norm = np.sqrt(a.energy[frames_a, y0:y1].sum(axis=1) * b.energy[frames_b, y0:y1].sum(axis=1))
    height = np.where(at_end | (norm <= 0), 0.0, q / np.maximum(norm, 1e-12))
    return (lags[i] + np.clip(off, -0.5, 0.5)) / upsample, height


def _fixed_effects_slope(tile, s, v, w, n_tiles, params: RigCheckParams) -> SlopeFit | None:
    """Weighted, iteratively trimmed least squares of ``s = d[tile] + tau * v``.

    None when fewer than ``params.reg_min_windows`` windows remain or the speeds do not vary within tiles.
    """
    good = np.isfinite(s) & np.isfinite(v) & (w > 0)
    design = np.concatenate([np.eye(n_tiles)[tile], v[:, None]], axis=1)
    for _ in range(params.reg_iterations):
        if good.sum() < params.reg_min_windows:
            return None
        sw = np.sqrt(w[good])
        # Scale v to px/ms so that the columns are of similar size (conditioning).
        a = design[good] * np.append(np.ones(n_tiles), _US_PER_MS)
        coef, *_ = np.linalg.lstsq(a * sw[:, None], s[good] * sw, rcond=None)
        res = s - design @ (coef * np.append(np.ones(n_tiles), _US_PER_MS))
        spread = _MAD_TO_SIGMA * float(np.median(np.abs(res[good])))
        new = np.isfinite(s) & np.isfinite(v) & (w > 0) & (np.abs(res) <= params.reg_trim_mad * max(spread, 1e-3))
        if np.array_equal(new, good):
            break
        good = new
    if good.sum() < params.reg_min_windows:
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
    return SlopeFit(float(coef[-1] * _US_PER_MS), float(se))


def time_offset_pairs(left, right, *, row, disparity, resolution, max_lag_us, bin_us,
                      equal_share=_DEFAULTS.time_equal_share, equal_sigmas=_DEFAULTS.time_equal_sigmas,
                      max_events=_DEFAULTS.pairs_max_events,
                      smooth_bins=_DEFAULTS.pairs_smooth_bins) -> TimeOffset:
    """How much later the right camera fires than the left at corresponding pixels.

    For every left event at (x, y), the right events of the same polarity at (x - d, y - row) for d within one
    pixel of the dominant ``disparity`` and within ``max_lag_us`` form pairs; their time differences pile up
    at the time offset (the same edge crosses both pixels), pairs of unrelated events spread evenly. The
    histogram's peak, interpolated below ``bin_us``, is the estimate.

    A periodic scene (a fan's blades) piles pairs up once per period as well: of the peaks as high as the
    highest within their uncertainty (:func:`equal_peaks`, ``equal_share``) the one nearest zero lag is
    taken, and the others are returned as alternatives with their spacing.
    """
    width, height = resolution
    if left.size > max_events:
        left = left[np.linspace(0, left.size - 1, max_events).round().astype(np.int64)]
    lag = int(np.ceil(max_lag_us / bin_us))
    reach = lag * bin_us
    # Right events sorted by (pixel and polarity, time) in one int64 key whose time part leaves room for the
    # search range, so that one binary search each way finds exactly the right events at a left event's
    # corresponding pixel within +-reach of it (all pairs of a busy pixel over the whole recording would be
    # many times more).
    t0 = min(int(left["t"][0]), int(right["t"][0]))
    span = max(int(left["t"][-1]), int(right["t"][-1])) - t0 + 2 * reach + 2
    pix_r = (right["y"].astype(np.int64) * width + right["x"]) * 2 + right["p"]
    keys = np.sort(pix_r * span + (right["t"] - t0))
    times = keys % span
    hist = np.zeros(2 * lag + 1)
    for d in (disparity - 1, disparity, disparity + 1):
        x, y = left["x"].astype(np.int64) - d, left["y"].astype(np.int64) - row
        ok = (x >= 0) & (x < width) & (y >= 0) & (y < height)
        t_left = left["t"][ok].astype(np.int64) - t0
        k = ((y * width + x) * 2 + left["p"])[ok] * span + t_left
        lo = np.searchsorted(keys, k - reach, side="left")
        hi = np.searchsorted(keys, k + reach, side="right")
        n = hi - lo
        if not n.sum():
            continue
        # Every pair (left event, right event at its corresponding pixel within the lag range).
        first = np.repeat(lo - np.concatenate([[0], np.cumsum(n)[:-1]]), n) + np.arange(n.sum())
        dt = times[first] - np.repeat(t_left, n)
        hist += np.bincount(np.round(dt / bin_us).astype(np.int64) + lag, minlength=2 * lag + 1)[:2 * lag + 1]
    if hist.sum() == 0:
        return TimeOffset(0.0, 0.0, PAIRS, half_width_us=float("inf"))
    sigma = smooth_bins
    corr = smooth_lags(hist - np.median(hist), sigma=sigma)
    # Counts are Poisson: the smoothed histogram's variance is the counts smoothed by the squared kernel.
    var = smooth_lags(hist, sigma=sigma / np.sqrt(2)) / (2 * np.sqrt(np.pi) * sigma)
    equal = equal_peaks(corr, var, equal_share=equal_share, z=equal_sigmas)
    k = min(equal, key=lambda i: (abs(i - lag), i))
    time = float((subsample_peak(corr, k) - lag) * bin_us)
    # The lags where the peak stays above half its height belong to the peak itself (the sensors' latencies
    # jitter by a few ms on real rigs and widen it); the confidence compares it with the lags beyond.
    width_bins = half_width(corr, k)
    others = sorted((i for i in equal if abs(i - k) > width_bins), key=lambda i: (abs(i - k), i))
    period = float(np.median(np.diff(sorted([k, *others]))) * bin_us) if others else float("nan")
    conf = contrast(corr, k, exclude=width_bins) * support(left.size, right.size)
    return TimeOffset(time, conf, PAIRS, tuple(float((subsample_peak(corr, i) - lag) * bin_us) for i in others),
                      period, float(width_bins * bin_us))


def equal_peaks(v, var, *, equal_share, z=_DEFAULTS.time_equal_sigmas):
    """Indices of the local maxima of ``v`` as high as its highest within their uncertainty, the highest first.

    A peak is as high when it falls short of the highest by at most ``equal_share`` of the highest's height
    above the median, or by ``z`` standard deviations of the difference (``var``: each sample's variance).
    """
    best = int(np.argmax(v))
    base = float(np.median(v))
    top = float(v[best])
    inner = np.flatnonzero((v[1:-1] >= v[:-2]) & (v[1:-1] > v[2:])) + 1
    tol = np.maximum(equal_share * (top - base), z * np.sqrt(np.maximum(var[best] + var[inner], 0.0)))
    near = inner[(top - v[inner] <= tol) & (v[inner] > base) & (inner != best)]
    return [best, *near[np.argsort(-v[near], kind="stable")].tolist()]
