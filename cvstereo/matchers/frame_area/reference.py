"""Reference frame-area SAD matcher (docs/algorithms.md section 3, thesis Algorithm 2): a full cost volume.

The SAD of every reference pixel and disparity from OpenCV kernels at once (a cost volume from ``cv2.absdiff``
and an unnormalised ``cv2.boxFilter`` per disparity), then Algorithm 2's scan over it: row by row, x
ascending, searching unset pixels above the threshold and writing each winner into its block.
"""

from __future__ import annotations

import cv2
import numpy as np

from cvstereo.matchers._shared.frame_gains import FrameGains
from cvstereo.matchers._shared.reference_border import border_rule_of
from cvstereo.matchers._shared.reference_checks import lr_consistent
from cvstereo.matchers._shared.reference_windows import (
    filtered_unit,
    gaussian_filter,
    signed_frame,
    values_at_events,
    window_events,
)
from cvstereo.matchers._shared.signal_level import SignalLevel
from cvstereo.matchers.frame_area.params import FrameAreaParams
from cvstereo.model.events import DEFAULT_RESOLUTION
from cvstereo.model.matches import empty_matches, make_matches
from cvstereo.model.polarity import frame_signs

__all__ = ["frame_area_reference", "sad_volume", "scan_disparity_map"]


def sad_volume(reference: np.ndarray, other: np.ndarray, *, max_disparity: int, block: int = 5,
               reference_camera: int = 1) -> np.ndarray:
    """SAD of the block around every reference pixel against the other frame's block at each disparity.

    The candidate of reference pixel ``(y, x)`` at disparity ``d`` is ``(y, x + d)`` in the other (left) frame
    when the reference is the right camera, ``(y, x - d)`` in the right frame when it is the left camera; so
    ``d = x_left - x_right`` either way.

    Parameters
    ----------
    reference, other : (height, width) float ndarray
    max_disparity : int, keyword-only
    block : int, keyword-only
        Odd block side.
    reference_camera : {0, 1}, keyword-only

    Returns
    -------
    (max_disparity + 1, height, width) float64 ndarray
        ``inf`` where either block would leave the sensor.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> right = rng.normal(size=(12, 20))
    >>> left = np.roll(right, 3, axis=1)                       # x_left = x_right + 3
    >>> int(np.argmin(sad_volume(right, left, max_disparity=6)[:, 6, 6]))
    3
    """
    ref = np.asarray(reference, dtype=np.float64)
    oth = np.asarray(other, dtype=np.float64)
    h, w = ref.shape
    r = block // 2
    vol = np.full((max_disparity + 1, h, w), np.inf)
    for d in range(min(max_disparity, w - block) + 1):
        # Crop both frames to the columns where the candidate exists; column c of the crop is reference x
        # (= c for the right reference, c + d for the left one).
        a, b = (ref[:, : w - d], oth[:, d:]) if reference_camera == 1 else (ref[:, d:], oth[:, : w - d])
        sad = cv2.boxFilter(cv2.absdiff(a, b), -1, (block, block), normalize=False,
                            borderType=cv2.BORDER_CONSTANT)
        x0 = r if reference_camera == 1 else r + d  # first reference x whose both blocks are inside
        vol[d, r: h - r, x0: x0 + (w - d - 2 * r)] = sad[r: h - r, r: w - d - r]
    return vol


def scan_disparity_map(reference: np.ndarray, volume: np.ndarray, *, threshold: float,
                       block: int = 5, uniqueness: float = 0.0) -> np.ndarray:
    """Algorithm 2's scan: row by row, x ascending; search unset pixels above threshold; write the block.

    Parameters
    ----------
    reference : (height, width) float ndarray
        The reference frame (decides which pixels are searched).
    volume : (D + 1, height, width) float ndarray
        SAD per disparity (:func:`sad_volume`).
    threshold : float, keyword-only
    block : int, keyword-only
    uniqueness : float, keyword-only
        0: off. Otherwise a search whose winner has a candidate more than 1 px away with a SAD at most
        ``1 + uniqueness`` times its own writes NaN into its block.

    Returns
    -------
    (height, width) float32 ndarray
        Disparity, NaN where none was written (0 is a valid disparity).
    """
    h, w = reference.shape
    r = block // 2
    disp = np.full((h, w), np.nan, dtype=np.float32)
    inner = np.zeros((h, w), dtype=bool)
    inner[r: h - r, r: w - r] = True  # blocks must not leave the sensor
    ys, xs = np.nonzero((np.abs(reference) >= threshold) & inner)  # row-major: the scan order
    if ys.size == 0:
        return disp
    # argmin returns the first minimum: ties go to the smaller disparity, as a strict < scan does.
    costs = volume[:, ys, xs]
    best = np.argmin(costs, axis=0).astype(np.float32)
    if uniqueness > 0:
        least = costs[best.astype(int), np.arange(ys.size)]
        far = np.abs(np.arange(costs.shape[0])[:, None] - best[None, :]) > 1
        best[(far & (costs <= least * (1.0 + uniqueness))).any(axis=0)] = np.nan
    done = np.zeros((h, w), dtype=bool)
    for y, x, d in zip(ys.tolist(), xs.tolist(), best.tolist(), strict=True):
        if done[y, x]:
            continue
        disp[y - r: y + r + 1, x - r: x + r + 1] = d
        done[y - r: y + r + 1, x - r: x + r + 1] = True
    return disp


def frame_area_reference(left: np.ndarray, right: np.ndarray, params: FrameAreaParams | None = None, *,
                         resolution: tuple[int, int] = DEFAULT_RESOLUTION) -> np.ndarray:
    """Match a whole stereo stream with the frame-area algorithm, window by window.

    Returns
    -------
    (M,) ndarray of MATCH_DTYPE
        Per window (stamped with its end), the reference camera's pixels that saw events and got a disparity,
        row-major; ``p`` = 1 where the reference frame is > 0.

    See Also
    --------
    cvstereo.matchers._shared.reference : the arguments, the same for every reference function.
    """
    prm = params if params is not None else FrameAreaParams()
    frame_gains = FrameGains(prm, n_frames=len(frame_signs(prm.polarity)), unit=filtered_unit(prm),
                             units=prm.value_units)
    level = SignalLevel(prm, absolute=prm.threshold, unit=filtered_unit(prm), n_parts=frame_gains.parts,
                        value_name="filtered value" if prm.gaussian else "frame value")
    parts = []
    for t_end, ev_l, ev_r in window_events(left, right, prm.window_us, every=True):
        k = (t_end - prm.window_us) // prm.level_window_us
        thresholds = level.thresholds(k)
        threshold = thresholds[prm.reference_camera]
        gains = frame_gains.gains(k, thresholds, level)  # each scan in its own camera's units: [camera, frame]
        ref_ev, oth_ev = (ev_r, ev_l) if prm.reference_camera == 1 else (ev_l, ev_r)
        for slot, signs in enumerate(frame_signs(prm.polarity)):  # each frame of the polarity mode on its own
            gain, back_gain = gains[prm.reference_camera, slot], gains[1 - prm.reference_camera, slot]
            # This frame's events (p = 1 ON, 0 OFF), and their signed frame.
            sel_ref, sel_oth = (ev[np.isin(ev["p"], [int(s > 0) for s in signs])] for ev in (ref_ev, oth_ev))
            ref, oth = (signed_frame(ev, resolution=resolution, signs=signs) for ev in (sel_ref, sel_oth))
            if prm.gaussian:
                ref, oth = (gaussian_filter(f, sigma=prm.kernel_sigma, kernel_size=prm.kernel_size)
                            for f in (ref, oth))
            # The signal level sees each camera's values at its pixels with events (of the frame's polarity).
            for cam, frame, sel in ((prm.reference_camera, ref, sel_ref), (1 - prm.reference_camera, oth, sel_oth)):
                level.add(k, cam, values_at_events(frame, sel), part=frame_gains.part_of(slot))
            if not (ev_l.size and ev_r.size):
                continue
            volume = sad_volume(ref, np.asarray(oth, np.float64) * gain, max_disparity=prm.max_disparity,
                                block=prm.block, reference_camera=prm.reference_camera)
            disp = scan_disparity_map(ref, volume, threshold=threshold, block=prm.block, uniqueness=prm.uniqueness)
            keep = ~np.isnan(disp)
            if prm.lr_check:  # the other camera scanned as the reference, and both maps compared
                back_volume = sad_volume(oth, np.asarray(ref, np.float64) * back_gain,
                                         max_disparity=prm.max_disparity, block=prm.block,
                                         reference_camera=1 - prm.reference_camera)
                back = scan_disparity_map(oth, back_volume, threshold=thresholds[1 - prm.reference_camera],
                                          block=prm.block, uniqueness=prm.uniqueness)
                keep = lr_consistent(disp, back, reference_camera=prm.reference_camera)
            seen = np.zeros(ref.shape, bool)
            seen[sel_ref["y"], sel_ref["x"]] = True
            y, x = np.nonzero(seen & keep)
            parts.append(make_matches(t_end, x, y, (ref[y, x] > 0).astype(np.int8), prm.reference_camera,
                                      disp[y, x]))
    # The border rule (adaptive set) decides on the whole output, in its order.
    return border_rule_of(np.concatenate(parts) if parts else empty_matches(), prm, resolution)
