"""The numba kernels of the fused matcher (:mod:`calibration_free.fused` describes the method).

Two kernels per window, with the signal-level normalisation (plain numpy, shared with the reference) between
them: :func:`surface_features` (time surfaces of one camera, summed over the support square) and
:func:`match_features` (cost, semi-global aggregation, winner, left-right check, sub-pixel, uncertainty).
Every floating-point expression is written in the same order as in :mod:`calibration_free.reference.fused`,
so that both give bit-identical matches (tests/test_fused.py).
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: "Never saw an event" in the last-event-time arrays.
NEVER = np.int64(-(2**62))


@njit(cache=True, nogil=True)
def surface_features(t, x, y, p, last, t_end, tau, radius):
    """Update a camera's last-event times with a window's events; return its support-summed time surfaces.

    Parameters
    ----------
    t, x, y, p : (N,) arrays
        The camera's events of the window.
    last : (2, H, W) int64 ndarray
        Last event time per polarity and pixel (:data:`NEVER` if none), updated in place.
    t_end, tau, radius : int
        Window end, decay time (us) and support half side (px).

    Returns
    -------
    (2, H, W) float64 ndarray
        ``sum over the (2r+1)^2 square of max(0, 1 - (t_end - last) / tau)``, per polarity.
    """
    for i in range(t.size):
        pi, yi, xi = p[i], y[i], x[i]
        if t[i] > last[pi, yi, xi]:
            last[pi, yi, xi] = t[i]
    _, h, w = last.shape
    ts = np.zeros((2, h, w))
    for c in range(2):
        for yy in range(h):
            for xx in range(w):
                age = t_end - last[c, yy, xx]
                if age < tau:
                    ts[c, yy, xx] = 1.0 - float(age) / float(tau)
    if radius == 0:
        return ts
    # Separable: sums along the row first, then of those along the column (the reference's order).
    rows = np.zeros((2, h, w))
    for c in range(2):
        for yy in range(h):
            for xx in range(w):
                acc = 0.0
                for x2 in range(max(xx - radius, 0), min(xx + radius + 1, w)):
                    acc += ts[c, yy, x2]
                rows[c, yy, xx] = acc
    out = np.zeros((2, h, w))
    for c in range(2):
        for yy in range(h):
            for xx in range(w):
                acc = 0.0
                for y2 in range(max(yy - radius, 0), min(yy + radius + 1, h)):
                    acc += rows[c, y2, xx]
                out[c, yy, xx] = acc
    return out


@njit(cache=True, nogil=True, inline="always")
def _path_step(cost, k, prev, q, out, p1, p2):
    """One semi-global step from pixel q to pixel k along a path (rows of the compact arrays):
    ``out[k, d] = cost[k, d] + min(prev[q, d], prev[q, d+-1] + p1, min(prev[q]) + p2) - min(prev[q])``.

    Branch-free in the inner loop (the minima are exact in any order, so this equals the reference)."""
    nd = cost.shape[1]
    mn = prev[q, 0]
    for d in range(1, nd):
        mn = min(mn, prev[q, d])
    jump = mn + p2
    if nd == 1:
        out[k, 0] = cost[k, 0] + (min(prev[q, 0], jump) - mn)
        return
    out[k, 0] = cost[k, 0] + (min(min(prev[q, 0], prev[q, 1] + p1), jump) - mn)
    for d in range(1, nd - 1):
        m = min(min(prev[q, d], jump), min(prev[q, d - 1], prev[q, d + 1]) + p1)
        out[k, d] = cost[k, d] + (m - mn)
    last = nd - 1
    out[k, last] = cost[k, last] + (min(min(prev[q, last], prev[q, last - 1] + p1), jump) - mn)


@njit(cache=True, nogil=True)
def match_features(fl, fr, counts, active, recent, prior, max_d, row_tol, p1, p2, paths, temporal_weight, lr_tol,
                   subpixel, min_neighbours, max_uncertainty, fill_radius, work):
    """Match one window's normalised features; return the answers at the left camera's event pixels.

    Parameters
    ----------
    fl, fr : (2, H, W) float64 ndarray
        Normalised features of the left and right camera.
    counts : (2, H, W) int ndarray
        The left camera's event counts of the window per polarity (anchors: pixels with events).
    active : (H, W) bool ndarray
        The left pixels the semi-global paths run through (anchors must be among them).
    recent : (H, W) bool ndarray
        Left pixels with an event in the last two windows (the noise filter's neighbours).
    prior : (H, W) float64 ndarray
        Disparity of the previous window per pixel, NaN where none (temporal coherence).
    max_d, row_tol, p1, p2, paths, temporal_weight, lr_tol, subpixel, min_neighbours, max_uncertainty, fill_radius
        :class:`~calibration_free.fused_params.FusedParams` fields.
    work : (5, n, max_d + 1) float64 ndarray
        Scratch space for at least the n active pixels (kept by the caller: fresh pages cost more than the
        arithmetic).

    Returns
    -------
    x, y, pol : (M,) int ndarrays; disparity, uncertainty : (M,) float64 ndarrays
        In raster order (row, then column).
    """
    _, h, w = fl.shape
    nd = max_d + 1
    # Compact storage of the active pixels, raster order.
    index = np.full((h, w), -1, np.int64)
    n = 0
    for yy in range(h):
        for xx in range(w):
            if active[yy, xx]:
                index[yy, xx] = n
                n += 1
    ay = np.empty(n, np.int64)
    ax = np.empty(n, np.int64)
    cost = work[0, :n]
    for yy in range(h):
        for xx in range(w):
            k = index[yy, xx]
            if k < 0:
                continue
            ay[k] = yy
            ax[k] = xx
            pr = prior[yy, xx]
            for d in range(nd):
                xr = xx - d
                c = np.inf
                for y2 in range(max(yy - row_tol, 0), min(yy + row_tol + 1, h)):
                    r0 = fr[0, y2, xr] if xr >= 0 else 0.0
                    r1 = fr[1, y2, xr] if xr >= 0 else 0.0
                    c2 = abs(fl[0, yy, xx] - r0) + abs(fl[1, yy, xx] - r1)
                    if c2 < c:
                        c = c2
                if temporal_weight > 0.0 and not np.isnan(pr):
                    c = c + temporal_weight * min(abs(d - pr), 2.0)
                cost[k, d] = c
    if paths == 0:
        total = cost
    else:
        # Forward raster pass: paths from the left (and from above); backward pass: from the right (and below).
        l_a = work[1, :n]
        l_b = work[2, :n]
        tmp_v = work[3, :n]
        tmp_w = work[4, :n]
        for k in range(n):
            yy, xx = ay[k], ax[k]
            q = index[yy, xx - 1] if xx > 0 else -1
            if q >= 0:
                _path_step(cost, k, l_a, q, l_a, p1, p2)
            else:
                l_a[k, :] = cost[k]
            if paths == 4:
                q = index[yy - 1, xx] if yy > 0 else -1
                if q >= 0:
                    _path_step(cost, k, tmp_v, q, tmp_v, p1, p2)
                else:
                    tmp_v[k, :] = cost[k]
        for k in range(n - 1, -1, -1):
            yy, xx = ay[k], ax[k]
            q = index[yy, xx + 1] if xx < w - 1 else -1
            if q >= 0:
                _path_step(cost, k, l_b, q, l_b, p1, p2)
            else:
                l_b[k, :] = cost[k]
            if paths == 4:
                q = index[yy + 1, xx] if yy < h - 1 else -1
                if q >= 0:
                    _path_step(cost, k, tmp_w, q, tmp_w, p1, p2)
                else:
                    tmp_w[k, :] = cost[k]
        total = l_a  # summed in place: the forward paths are no longer needed
        for k in range(n):
            for d in range(nd):
                s = l_a[k, d] + l_b[k, d]
                if paths == 4:
                    s = s + tmp_v[k, d]
                    s = s + tmp_w[k, d]
                total[k, d] = s
    out_x = np.empty(n, np.int64)
    out_y = np.empty(n, np.int64)
    out_p = np.empty(n, np.int64)
    out_d = np.empty(n)
    out_u = np.empty(n)
    out_ok = np.empty(n, np.bool_)
    consistent_d = np.full((h, w), np.nan)
    m = 0
    for yy in range(h):
        for xx in range(w):
            if counts[0, yy, xx] + counts[1, yy, xx] == 0:
                continue
            k = index[yy, xx]
            if k < 0:
                continue
            neighbours = 0
            for y2 in range(max(yy - 1, 0), min(yy + 2, h)):
                for x2 in range(max(xx - 1, 0), min(xx + 2, w)):
                    if recent[y2, x2]:
                        neighbours += 1
            if neighbours < min_neighbours:
                continue
            s = total[k]
            best = 0
            for d in range(1, nd):
                if s[d] < s[best]:
                    best = d
            second = np.inf
            for d in range(nd):
                if abs(d - best) > 1 and s[d] < second:
                    second = s[d]
            ratio = 1.0 if second == 0.0 else s[best] / second
            consistent = True
            if lr_tol >= 0:
                xr = xx - best
                best_r = -1
                if xr >= 0:
                    best_rv = np.inf
                    for d in range(nd):
                        xl = xr + d
                        if xl >= w:
                            break
                        q = index[yy, xl]
                        if q >= 0 and total[q, d] < best_rv:
                            best_rv = total[q, d]
                            best_r = d
                consistent = best_r >= 0 and abs(best_r - best) <= lr_tol
            u = 0.5 * ratio if consistent else 0.5 * ratio + 0.5
            disp = float(best)
            if subpixel and 0 < best < nd - 1:
                a, b, c = s[best - 1], s[best], s[best + 1]
                den = (a - 2.0 * b) + c
                if den > 0.0:
                    delta = (a - c) / (2.0 * den)
                    disp = disp + min(max(delta, -0.5), 0.5)
            out_x[m] = xx
            out_y[m] = yy
            out_p[m] = 1 if counts[1, yy, xx] >= counts[0, yy, xx] else 0
            out_d[m] = disp
            out_u[m] = u
            out_ok[m] = consistent
            if consistent:
                consistent_d[yy, xx] = disp
            m += 1
    # Inconsistent winners take the median of the consistent answers around them (when there are any).
    keep = np.zeros(m, np.bool_)
    vals = np.empty((2 * fill_radius + 1) ** 2)
    for i in range(m):
        if not out_ok[i] and fill_radius > 0:
            c = 0
            for y2 in range(max(out_y[i] - fill_radius, 0), min(out_y[i] + fill_radius + 1, h)):
                for x2 in range(max(out_x[i] - fill_radius, 0), min(out_x[i] + fill_radius + 1, w)):
                    v = consistent_d[y2, x2]
                    if not np.isnan(v):
                        vals[c] = v
                        c += 1
            if c > 0:
                srt = np.sort(vals[:c])
                out_d[i] = srt[c // 2] if c % 2 else (srt[c // 2 - 1] + srt[c // 2]) / 2.0
        keep[i] = out_u[i] <= max_uncertainty
    return out_x[:m][keep], out_y[:m][keep], out_p[:m][keep], out_d[:m][keep], out_u[:m][keep]
