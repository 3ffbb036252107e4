"""Which camera is left, and the disparities present: :func:`disparity_overlays` and :func:`side_and_disparity`.

Both come from overlaying short accumulated signed frames of the two cameras (rows and time already lined
up): the global profile over horizontal shifts says on which side the cameras overlay (the left camera sees
a scene point at the larger x, :func:`cvstereo.geometry.overlay.side_of_profile`), and block-wise normalised
cross-correlation at the left camera's event pixels gives the local disparities.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from cvstereo.geometry.overlay import row_correlation, side_of_profile
from cvstereo.rigcheck.peaks import fft_len, subsample_peak
from cvstereo.rigcheck.windows import window_frames

__all__ = ["DisparityFindings", "Overlays", "disparity_overlays", "side_and_disparity"]


class Overlays(NamedTuple):
    """What :func:`disparity_overlays` measured."""

    profile: np.ndarray
    """(2D+1,) normalised sum over windows and rows of ``sum_x L(x, y) R(x - s, y)``, index ``s + D``."""
    local: np.ndarray
    """(M,) best shift ``s`` at left-camera event pixels whose block overlays well (NCC >= min_ncc)."""


class DisparityFindings(NamedTuple):
    """Side and disparities, oriented as the recording should be used (after the swap)."""

    swap: bool
    swap_confidence: float
    peak: float
    peaks: tuple[float, ...]
    percentiles: dict
    confidence: float


def disparity_overlays(left, right, *, resolution, max_disparity, window_us, max_windows, block,
                       min_ncc, min_events, blur_px, max_points) -> Overlays:
    """Global overlay profile over shifts -D..D (D = ``max_disparity`` within the sensor) and local best shifts."""
    d = int(min(max_disparity, resolution[0] - 1))
    profile = np.zeros(2 * d + 1)
    local = []
    bw, bh = block
    nfft = fft_len(2 * resolution[0])
    for gl, gr, mask in window_frames(left, right, resolution=resolution, window_us=window_us,
                                      max_windows=max_windows, min_events=min_events, blur_px=blur_px):
        c = row_correlation(gl, gr, max_shift=d, nfft=nfft)
        if c is not None:
            profile += c
        local.append(_local_best(gl, gr, mask, d, bw, bh, min_ncc, max_points=max_points))
    return Overlays(profile, np.concatenate(local) if local else np.zeros(0))


def side_and_disparity(overlays: Overlays, percentiles, *, max_peaks, peak_mads, peak_share) -> DisparityFindings:
    """Decide the side from the profile, then orient the disparities by it (the possible side is >= 0).

    ``percentiles`` of the local disparities on the possible side are reported (NaN without any); the
    confidence is the share of the local overlays on the possible side.
    """
    profile, local = overlays
    d = (profile.size - 1) // 2
    swap, swap_conf = side_of_profile(profile)
    sign = -1 if swap else 1
    peak = sign * subsample_peak(profile, int(np.argmax(profile))) - sign * d
    found = _profile_peaks(profile, max_peaks=max_peaks, mads=peak_mads, share=peak_share)
    peaks = tuple(sign * (s - d) for s in found)
    peaks = tuple(float(p) for p in peaks if p >= 0)
    oriented = sign * local
    possible = oriented[oriented >= 0]
    conf = float(possible.size / local.size) if local.size else 0.0
    if possible.size:
        pct = {q: float(v) for q, v in zip(percentiles, np.percentile(possible, percentiles), strict=True)}
    else:
        pct = {q: float("nan") for q in percentiles}
        conf = 0.0
    return DisparityFindings(bool(swap), swap_conf, float(peak), peaks, pct, conf)


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


def _profile_peaks(profile, *, max_peaks, mads, share):
    """Indices (sub-sample) of local maxima standing out from the profile's background (by more than ``mads``
    median absolute deviations and ``share`` of the highest's height), strongest first."""
    base = float(np.median(profile))
    spread = float(np.median(np.abs(profile - base))) + 1e-12
    top = float(profile.max())
    out = []
    for i in range(1, profile.size - 1):
        v = profile[i]
        if v >= profile[i - 1] and v > profile[i + 1] and v - base > max(mads * spread, share * (top - base)):
            out.append((v, subsample_peak(profile, i)))
    out.sort(reverse=True)
    return [p for _, p in out[:max_peaks]]
