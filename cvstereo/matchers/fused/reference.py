"""Reference fused matcher (:mod:`cvstereo.matchers.fused.matcher` gives the design): whole windows in numpy.

Readable twin of :mod:`cvstereo.matchers.fused._features` and :mod:`cvstereo.matchers.fused._kernels`: the time
surfaces as whole arrays, the support square as a sum of shifted copies, the cost as a dense ``(H, W, D)``
float32 volume, the semi-global paths one pixel at a time over float32 numpy vectors of disparities. Every
floating-point expression is evaluated in the kernel's order, so that the matches are bit-identical; it is
slow, for short inputs.
"""

from __future__ import annotations

import numpy as np

from cvstereo.matchers.fused._constants import (
    CONSISTENT_MAX_UNCERTAINTY,
    LR_PENALTY,
    NOISE_RADIUS,
    RATIO_UNCERTAINTY,
    RECENT_WINDOWS,
    SECOND_BEST_GAP_PX,
    SEGMENT_RADIUS,
    SEGMENT_STEP_PX,
    SEGMENT_TIER,
    SEGMENT_WIDTH_PX,
    SUBPIXEL_MAX_SHIFT_PX,
    TEMPORAL_CAP_PX,
)
from cvstereo.matchers.fused.params import BORDER_MIN_ANSWERS, PRIOR_MAX_UNCERTAINTY, FusedParams
from cvstereo.matchers.fused.signal import signal_level
from cvstereo.model.events import DEFAULT_RESOLUTION
from cvstereo.model.matches import concat_matches, make_matches

__all__ = ["aggregate", "choose", "cost_volume", "fused_reference", "path_step", "support_sum", "time_surfaces",
           "windows"]


def windows(left: np.ndarray, right: np.ndarray, window_us: int):
    """``(t_end, left events, right events)`` of every window in which either camera has events, in time order
    (a window with one camera silent still updates the time surfaces)."""
    for k in np.union1d(left["t"] // window_us, right["t"] // window_us).tolist():
        yield (k + 1) * window_us, left[left["t"] // window_us == k], right[right["t"] // window_us == k]


def time_surfaces(last: np.ndarray, t_end: int, tau: int) -> np.ndarray:
    """``max(0, 1 - (t_end - last) / tau)`` per polarity and pixel; 0 where the pixel never fired."""
    ts = np.zeros(last.shape)
    seen = last > np.iinfo(np.int64).min
    age = np.where(seen, t_end - np.where(seen, last, 0), tau)
    fresh = age < tau
    ts[fresh] = 1.0 - age[fresh].astype(np.float64) / float(tau)
    return ts


def support_sum(ts: np.ndarray, radius: int) -> np.ndarray:
    """Sum of each pixel's ``(2r+1)^2`` square (zero outside the sensor): along rows, then along columns."""
    if radius == 0:
        return ts
    _, h, w = ts.shape
    padded = np.zeros((2, h, w + 2 * radius))
    padded[:, :, radius:radius + w] = ts
    rows = np.zeros(ts.shape)
    for dx in range(2 * radius + 1):
        rows = rows + padded[:, :, dx:dx + w]
    padded = np.zeros((2, h + 2 * radius, w))
    padded[:, radius:radius + h] = rows
    out = np.zeros(ts.shape)
    for dy in range(2 * radius + 1):
        out = out + padded[:, dy:dy + h]
    return out


def cost_volume(fl, fr, prior, prm: FusedParams) -> np.ndarray:
    """(H, W, D) float32 cost of every pixel and disparity: the best L1 over the tolerated rows, plus the temporal
    term (rounded to float32 before it is added); the features are rounded to float32 first."""
    _, h, w = fl.shape
    nd = prm.max_disparity + 1
    fl, fr = fl.astype(np.float32), fr.astype(np.float32)
    cost = np.full((h, w, nd), np.inf, np.float32)
    for d in range(nd):
        shifted = np.zeros(fr.shape, np.float32)  # right features at x - d, zero beyond the left edge
        shifted[:, :, d:] = fr[:, :, :w - d] if d else fr
        for dy in range(-prm.row_tolerance, prm.row_tolerance + 1):
            rows = np.arange(h) + dy
            ok = (rows >= 0) & (rows < h)
            other = np.zeros(fr.shape, np.float32)
            other[:, ok] = shifted[:, rows[ok]]
            c = np.abs(fl[0] - other[0]) + np.abs(fl[1] - other[1])
            c = np.where(ok[:, None], c, np.float32(np.inf))
            cost[:, :, d] = np.minimum(cost[:, :, d], c)
        if prm.temporal_weight > 0:
            has = ~np.isnan(prior)
            distance = np.minimum(np.abs(d - np.where(has, prior, 0.0)), TEMPORAL_CAP_PX)
            term = (prm.temporal_weight * distance).astype(np.float32)
            cost[:, :, d] = np.where(has, cost[:, :, d] + term, cost[:, :, d])
    return cost


def path_step(cost: np.ndarray, prev: np.ndarray, p1: float, p2: float) -> np.ndarray:
    """One semi-global step along a path (Hirschmüller 2008, eq. 13), in float32."""
    p1, p2 = np.float32(p1), np.float32(p2)
    mn = prev.min()
    m = prev.copy()
    m[1:] = np.minimum(m[1:], prev[:-1] + p1)
    m[:-1] = np.minimum(m[:-1], prev[1:] + p1)
    m = np.minimum(m, mn + p2)
    return cost + (m - mn)


def aggregate(cost: np.ndarray, active: np.ndarray, prm: FusedParams) -> np.ndarray:
    """Sum of the semi-global paths (rows; and columns with 4 paths) over runs of active pixels."""
    if prm.sgm_paths == 0:
        return cost
    h, w, _ = cost.shape
    directions = [(0, 1), (0, -1)] + ([(1, 0), (-1, 0)] if prm.sgm_paths == 4 else [])
    paths = {}
    for dy, dx in directions:
        out = np.zeros(cost.shape, np.float32)
        ys = range(h) if (dy, dx) >= (0, 0) else range(h - 1, -1, -1)
        for y in ys:
            xs = range(w) if (dy, dx) >= (0, 0) else range(w - 1, -1, -1)
            for x in xs:
                if not active[y, x]:
                    continue
                py, px = y - dy, x - dx
                if 0 <= py < h and 0 <= px < w and active[py, px]:
                    out[y, x] = path_step(cost[y, x], out[py, px], prm.p1, prm.p2)
                else:
                    out[y, x] = cost[y, x]
        paths[(dy, dx)] = out
    if prm.sgm_paths == 2:
        return paths[(0, 1)] + paths[(0, -1)]
    # (left + above) + (right + below): the kernel's order (its forward pass sums the first two, its backward pass
    # the others).
    return (paths[(0, 1)] + paths[(1, 0)]) + (paths[(0, -1)] + paths[(-1, 0)])


def choose(total, active, counts, recent, prm: FusedParams):
    """Winner, uncertainty, noise filter, left-right check, sub-pixel, partner, occlusion and segment tests at every
    left event pixel: the answers kept, and the answers before the occlusion test (the next window's prior)."""
    h, w, nd = total.shape
    out = []
    for y, x in zip(*np.nonzero(counts.sum(axis=0)), strict=True):
        if not active[y, x]:
            continue
        r = NOISE_RADIUS
        isolated = recent[max(y - r, 0):y + r + 1, max(x - r, 0):x + r + 1].sum() < prm.min_neighbours
        s = total[y, x]
        best = int(np.argmin(s))
        far = np.abs(np.arange(nd) - best) > SECOND_BEST_GAP_PX
        second = s[far].min() if far.any() else np.inf
        ratio = 1.0 if second == 0.0 else float(s[best]) / float(second)
        consistent = True
        if prm.lr_tolerance >= 0:
            xr = x - best
            best_r = -1
            if xr >= 0:
                ds = np.arange(nd)
                ds = ds[xr + ds < w]
                cand = np.where(active[y, xr + ds], total[y, xr + ds, ds], np.inf)
                best_r = int(np.argmin(cand)) if np.isfinite(cand).any() else -1
            consistent = best_r >= 0 and abs(best_r - best) <= prm.lr_tolerance
        # Inconsistent winners rank behind every consistent one (design part 7).
        u = RATIO_UNCERTAINTY * ratio if consistent else RATIO_UNCERTAINTY * ratio + LR_PENALTY
        if isolated and not u < prm.isolated_max_uncertainty:
            continue  # the noise filter (design part 13): an isolated pixel answers only with a clear match
        disp = float(best)
        if prm.subpixel and 0 < best < nd - 1:
            a, b, c = float(s[best - 1]), float(s[best]), float(s[best + 1])
            den = (a - 2.0 * b) + c
            if den > 0.0:
                disp = disp + min(max((a - c) / (2.0 * den), -SUBPIXEL_MAX_SHIFT_PX), SUBPIXEL_MAX_SHIFT_PX)
        out.append([x, y, 1 if counts[1, y, x] >= counts[0, y, x] else 0, disp, u, consistent])
    # Inconsistent winners: the median of the consistent answers within fill_radius, where there are any; a
    # winner that agrees with it is confirmed instead.
    consistent_d = np.full((h, w), np.nan)
    for x, y, _, disp, _, ok in out:
        if ok:
            consistent_d[y, x] = disp
    r = prm.fill_radius
    for row in out:
        x, y, ok = row[0], row[1], row[5]
        if ok or r == 0:
            continue
        near = consistent_d[max(y - r, 0):y + r + 1, max(x - r, 0):x + r + 1]
        vals = np.sort(near[~np.isnan(near)])
        c = vals.size
        if c:
            med = float(vals[c // 2]) if c % 2 else (float(vals[c // 2 - 1]) + float(vals[c // 2])) / 2.0
            if prm.fill_confirms and abs(row[3] - med) <= prm.lr_tolerance:
                row[4] = row[4] - LR_PENALTY  # confirmed by the consistent answers around it: no left-right penalty
            else:
                row[3] = med
    # Partner test: an answer left of the median disparity of the consistent answers in its band of rows has its
    # true partner outside the right image (design part 10).
    outside = [False] * len(out)
    if prm.border_rows >= 0:
        for i, row in enumerate(out):
            band = np.sort([r[3] for r in out
                            if abs(r[1] - row[1]) <= prm.border_rows and r[4] <= CONSISTENT_MAX_UNCERTAINTY])
            c = band.size
            if c >= BORDER_MIN_ANSWERS:
                d = band[c // 2] if c % 2 else (band[c // 2 - 1] + band[c // 2]) / 2.0
                outside[i] = row[0] < d
    # Occlusion test: an answer that nearer answers further right in its row hide from the right camera gets the
    # left-right penalty; both sides of the test are the answers of uncertainty at most 0.5 before it.
    # The next window's prior is the answers before the test (design part 9) that have a partner.
    prior = [tuple(row[:5]) for row, off in zip(out, outside, strict=True)
             if row[4] <= min(prm.max_uncertainty, PRIOR_MAX_UNCERTAINTY) and not off]
    hides = [(row[1], row[0], row[0] - row[3]) for row in out if row[4] <= CONSISTENT_MAX_UNCERTAINTY]
    for row, off in zip(out, outside, strict=True):
        x, y, r = row[0], row[1], row[0] - row[3]
        crossing = sum(y2 == y and x2 > x and r2 <= r - prm.occlusion_margin for y2, x2, r2 in hides)
        hidden = prm.occlusion_margin >= 0 and crossing >= prm.occlusion_support
        if row[4] <= CONSISTENT_MAX_UNCERTAINTY and (off or hidden):
            row[4] = row[4] + LR_PENALTY
    # Segment test (design part 11): the answers still consistent, grouped by flood fill over neighbours within
    # SEGMENT_RADIUS px of like disparity; a group smaller than the width's least count ranks between the others and
    # the inconsistent answers, but for its clear answers (below isolated_max_uncertainty, the noise filter's rule).
    least = round(prm.segment_min_answers * total.shape[1] / SEGMENT_WIDTH_PX)
    if least > 0:  # three tiers: consistent, consistent of a small segment, inconsistent
        at = {(row[0], row[1]): row for row in out if row[4] <= CONSISTENT_MAX_UNCERTAINTY}
        group_of: dict = {}
        for start in at:
            if start in group_of:
                continue
            group, todo = [start], [start]
            group_of[start] = group
            while todo:
                x, y = todo.pop()
                for dy in range(-SEGMENT_RADIUS, SEGMENT_RADIUS + 1):
                    for dx in range(-SEGMENT_RADIUS, SEGMENT_RADIUS + 1):
                        near = (x + dx, y + dy)
                        if (near in at and near not in group_of
                                and abs(at[near][3] - at[(x, y)][3]) <= SEGMENT_STEP_PX):
                            group_of[near] = group
                            group.append(near)
                            todo.append(near)
        small = {pixel for pixel, row in at.items()
                 if len(group_of[pixel]) < least and not row[4] < prm.isolated_max_uncertainty}
        for row in out:
            if (row[0], row[1]) in small:
                row[4] = CONSISTENT_MAX_UNCERTAINTY + row[4] / 2.0
            elif row[4] > CONSISTENT_MAX_UNCERTAINTY:
                row[4] = SEGMENT_TIER + (row[4] - CONSISTENT_MAX_UNCERTAINTY) / 2.0
    return [tuple(row[:5]) for row in out if row[4] <= prm.max_uncertainty], prior


def fused_reference(left: np.ndarray, right: np.ndarray, params: FusedParams | None = None, *,
                    resolution=DEFAULT_RESOLUTION, with_uncertainty: bool = False):
    """The fused matcher over a whole stream.

    Parameters
    ----------
    left, right : (N,) ndarray of EVENT_DTYPE
    params : FusedParams, optional
    resolution : (width, height), keyword-only
    with_uncertainty : bool, keyword-only
        Also return each match's uncertainty.

    Returns
    -------
    (M,) ndarray of MATCH_DTYPE, time-ordered; and (M,) float32 ndarray if ``with_uncertainty``
    """
    prm = params or FusedParams()
    w, h = resolution
    last = np.full((2, 2, h, w), np.iinfo(np.int64).min, dtype=np.int64)
    prior, prior_end = np.full((h, w), np.nan), None
    parts, uncertainty = [], []
    for t_end, wl, wr in windows(left, right, prm.window_us):
        feats = []
        for cam, ev in enumerate((wl, wr)):
            np.maximum.at(last[cam], (ev["p"].astype(np.intp), ev["y"].astype(np.intp), ev["x"].astype(np.intp)),
                          ev["t"])
            feats.append(signal_level(support_sum(time_surfaces(last[cam], t_end, prm.tau_us), prm.support_radius)))
        counts = np.zeros((2, h, w), dtype=np.int64)
        np.add.at(counts, (wl["p"].astype(np.intp), wl["y"].astype(np.intp), wl["x"].astype(np.intp)), 1)
        recent = (last[0] >= t_end - RECENT_WINDOWS * prm.window_us).any(axis=0)
        # Active: within path_radius (Chebyshev) of a left event of the window.
        anchors = counts.sum(axis=0) > 0
        r = prm.path_radius
        padded = np.zeros((h + 2 * r, w + 2 * r), bool)
        padded[r:r + h, r:r + w] = anchors
        active = np.zeros((h, w), bool)
        for dy in range(2 * r + 1):
            for dx in range(2 * r + 1):
                active |= padded[dy:dy + h, dx:dx + w]
        use_prior = prior if prior_end == t_end - prm.window_us else np.full((h, w), np.nan)
        total = aggregate(cost_volume(feats[0], feats[1], use_prior, prm), active, prm)
        found, answers = choose(total, active, counts, recent, prm)
        prior, prior_end = np.full((h, w), np.nan), t_end
        for x, y, _, disp, _ in answers:
            prior[y, x] = disp
        if found:
            x, y, p, disp, u = (np.array(c) for c in zip(*found, strict=True))
            parts.append(make_matches(t_end, x, y, p, 0, disp.astype(np.float32)))
            uncertainty.append(u)
    matches = concat_matches(parts)
    if with_uncertainty:
        return matches, (np.concatenate(uncertainty) if uncertainty else np.zeros(0)).astype(np.float32)
    return matches
