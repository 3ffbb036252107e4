"""Row offset between the sensors from the 2-D overlay of accumulated signed frames: :func:`row_offsets`."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import scipy.fft as sfft

from cvstereo.rigcheck.peaks import contrast, fft_len, subsample_peak, support
from cvstereo.rigcheck.windows import window_frames

__all__ = ["RowOffsets", "row_offsets"]


class RowOffsets(NamedTuple):
    """What :func:`row_offsets` found (in the camera order given)."""

    offset: float
    """Rows to add to the right camera's y (``y_left ~ y_right + offset``), sub-row."""
    confidence: float
    band_offsets: tuple[float, ...]
    """The same per horizontal band."""
    band_confidences: tuple[float, ...]
    band_rows: tuple[tuple[int, int], ...]
    """``[start, stop)`` left-camera rows of each band."""
    disparity: int
    """Horizontal shift ``x_left - x_right`` of the strongest overlay (the dominant disparity), px."""


def row_offsets(left, right, *, resolution, max_row_offset, max_disparity, window_us, max_windows,
                n_bands, min_events, blur_px) -> RowOffsets:
    """Row offset from the 2-D cross-correlation of accumulated signed frames over (dx, dy), also per band.

    For every row shift the best horizontal shift counts (whatever the disparity); the row shift where that
    is largest wins. Windows long against any time offset make this nearly independent of it.
    """
    width, height = resolution
    bands = _bands(left["y"], height, n_bands)
    masks = np.zeros((n_bands, height, 1), np.float32)
    for b in range(n_bands):
        masks[b, bands[b]:bands[b + 1]] = 1
    shape = (fft_len(height + max_row_offset + 1), fft_len(width + max_disparity + 1))
    acc = np.zeros((n_bands, shape[0], shape[1] // 2 + 1), np.complex128)
    for fl, fr, _ in window_frames(left, right, resolution=resolution, window_us=window_us,
                                   max_windows=max_windows, min_events=min_events, blur_px=blur_px):
        norm = np.sqrt(float((fl * fl).sum()) * float((fr * fr).sum()))
        if norm > 0:
            # c[a, b] = sum L(y + a, x + b) R(y, x): a = y_left - y_right, b = x_left - x_right. A band's 2-D
            # spectrum is rfft2's (along x, then along y) of the frame with the other rows zeroed: the
            # transform along x is the same for every band, taken once (the same numbers as rfft2 per band).
            along_x = sfft.rfft(fl, shape[1], axis=1)
            bands_2d = sfft.fft(along_x[None] * masks, shape[0], axis=1)
            acc += bands_2d * np.conj(sfft.rfft2(fr, shape))[None] / norm
    c = sfft.irfft2(acc, shape)
    rows = np.arange(-max_row_offset, max_row_offset + 1)
    cols = np.arange(-max_disparity, max_disparity + 1)
    surface = c[:, rows[:, None] % shape[0], cols[None, :] % shape[1]]                # (n_bands, rows, cols)
    prof = surface.max(axis=2)
    total = prof.sum(axis=0)
    i = int(np.argmax(total))
    dx = int(cols[np.argmax(surface.sum(axis=0)[i])])
    row = float(rows[0] + subsample_peak(total, i))
    conf = contrast(total, i, exclude=1) * support(left.size, right.size)
    band_offsets, band_conf = [], []
    for b in range(n_bands):
        j = int(np.argmax(prof[b]))
        band_offsets.append(float(rows[0] + subsample_peak(prof[b], j)))
        n_l, n_r = (int(((ev["y"] >= bands[b]) & (ev["y"] < bands[b + 1])).sum()) for ev in (left, right))
        band_conf.append(contrast(prof[b], j, exclude=1) * support(n_l, n_r))
    band_rows = tuple((int(bands[b]), int(bands[b + 1])) for b in range(n_bands))
    return RowOffsets(row, conf, tuple(band_offsets), tuple(band_conf), band_rows, dx)


def _bands(y, height, n_bands):
    """Row edges of ``n_bands`` horizontal bands holding about equal shares of the events (at least 4 rows)."""
    edges = np.quantile(y, np.linspace(0, 1, n_bands + 1)).round().astype(int)
    edges[0], edges[-1] = 0, height
    for i in range(1, n_bands):
        edges[i] = min(max(edges[i], edges[i - 1] + 4), height - 4 * (n_bands - i))
    return edges
