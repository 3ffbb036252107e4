"""The frame-area SAD matcher (thesis 3.5.1, Algorithm 2; algorithms.md section 3).

Per 40 ms window: signed frames as for the cluster matcher (Gaussian-filtered, or not in the variant
``no-gaussian``). The reference frame (default: the right camera, the thesis' eDVS1) is scanned row by row,
x ascending; a pixel with ``|value| >= threshold`` and no disparity yet gets the disparity whose 5x5 block in
the other frame, on the same row and on the geometrically possible side, has the least sum of absolute
differences (ties: the smaller disparity); the winner is written into the whole 5x5 neighbourhood of the
disparity map, overwriting, so that those pixels are not searched again. With ``polarity="separate"`` (not
the thesis': its frame is ``shared``) each camera has an OFF and an ON frame, and each pair is scanned and
matched on its own, so that ON and OFF events of one window cannot cancel each other. With ``lr_check`` (not
the thesis') the other camera's frame is scanned as well and a disparity stands only where both scans agree
(:func:`cvstereo.support.lr_consistent`).

The scan is one numba kernel (:func:`scan_sad`) that computes the SAD only for the pixels it actually searches
(each search fills a whole block of the disparity map, so most above-threshold pixels are never searched).
Its readable twin, a full cost volume from OpenCV kernels (``cv2.absdiff`` and an unnormalised
``cv2.boxFilter`` per disparity) and the scan over it, is :mod:`calibration_free.reference.frame_area`.

Relative thresholds (``threshold_mode="relative"``, :mod:`cvstereo.signal_level`): the search threshold (2 on
the filtered frame, 4 unfiltered) becomes ``threshold_scale`` times the reference camera's signal level (the 0.9
quantile of |frame value| at its pixels with events over the last second), since a frame's values grow with
the events per pixel. The SAD needs no threshold of its own: candidates are compared with each other (least
SAD wins); block size and disparity range are geometry.
"""

from __future__ import annotations

from typing import ClassVar

import numba
import numpy as np

from calibration_free.params import FrameAreaParams
from cvstereo.frames import event_mask, filtered_unit, gaussian_filter, polarity_counts, polarity_frames
from cvstereo.matches import empty_matches, make_matches
from cvstereo.signal_level import SignalLevel
from cvstereo.support import lr_consistent
from cvstereo.windows import FrameMatcher, Window


def scan_sad(reference: np.ndarray, other: np.ndarray, *, threshold: float, max_disparity: int, block: int = 5,
             reference_camera: int = 1) -> np.ndarray:
    """Algorithm 2 with the SAD computed only for the pixels the scan actually searches (numba).

    Same result as the reference ``scan_disparity_map(reference, sad_volume(reference, other, ...), ...)``
    (:mod:`calibration_free.reference.frame_area`), but much faster: each search fills a whole block of the
    disparity map, so only a small part of the above-threshold pixels is ever searched.

    Parameters
    ----------
    reference, other : (height, width) float ndarray
    threshold, max_disparity, block, reference_camera : keyword-only
        See :class:`FrameAreaParams`.

    Returns
    -------
    (height, width) float32 ndarray
        Disparity, NaN where none was written.
    """
    ref = np.ascontiguousarray(reference, dtype=np.float64)
    oth = np.ascontiguousarray(other, dtype=np.float64)
    h, w = ref.shape
    r = block // 2
    inner = np.zeros((h, w), dtype=bool)
    inner[r: h - r, r: w - r] = True
    ys, xs = np.nonzero((np.abs(ref) >= threshold) & inner)
    step = 1 if reference_camera == 1 else -1
    return _scan_sad_kernel(ref, oth, ys, xs, int(max_disparity), r, step)


@numba.njit(cache=True, nogil=True)
def _scan_sad_kernel(ref, oth, ys, xs, max_disparity, r, step):  # pragma: no cover - compiled
    h, w = ref.shape
    disp = np.full((h, w), np.nan, dtype=np.float32)
    done = np.zeros((h, w), dtype=np.bool_)
    for k in range(ys.size):
        y = ys[k]
        x = xs[k]
        if done[y, x]:
            continue
        best = np.inf
        best_d = 0
        for d in range(max_disparity + 1):
            xo = x + step * d
            if xo - r < 0 or xo + r >= w:
                break  # larger disparities only move further out of the sensor
            sad = 0.0
            for j in range(-r, r + 1):
                for i in range(-r, r + 1):
                    sad += abs(ref[y + j, x + i] - oth[y + j, xo + i])
            if sad < best:  # strict: ties go to the smaller disparity
                best = sad
                best_d = d
        for j in range(y - r, y + r + 1):
            for i in range(x - r, x + r + 1):
                disp[j, i] = best_d
                done[j, i] = True
    return disp


class FrameAreaMatcher(FrameMatcher):
    """Frame-area SAD matcher (thesis 3.5.1, Algorithm 2) as a streaming object.

    Results: one row per pixel of the disparity map that holds a value and saw events of the reference camera
    in the window; ``t`` = the window's end, ``camera`` = the reference camera, ``p`` = 1 (ON) where its
    (filtered) frame is > 0 at that pixel, else 0 (OFF).

    Parameters
    ----------
    params : FrameAreaParams, optional
    resolution : (width, height), keyword-only
    """

    Params = FrameAreaParams
    variants: ClassVar[dict[str, dict]] = {
        "gaussian": {"gaussian": True, "threshold": 2.0},
        "no-gaussian": {"gaussian": False, "threshold": 4.0},
    }
    method = "frame-area"

    def __init__(self, params=None, *, resolution=(128, 128)):
        super().__init__(params, resolution=resolution)
        prm = self.params
        self._level = SignalLevel(prm, absolute=prm.threshold, unit=filtered_unit(prm),
                                  value_name="filtered value" if prm.gaussian else "frame value")

    def anchor_cameras(self) -> tuple[int, ...]:
        return (self.params.reference_camera,)

    def diagnostics(self) -> dict:
        """The signal-level diagnostics of the run so far (:meth:`cvstereo.signal_level.SignalLevel.diagnostics`)."""
        return self._level.diagnostics()

    def _frames(self, counts: np.ndarray) -> list[tuple[int, np.ndarray]]:
        """(channel, frame) per frame of the polarity mode (one for ``shared``): :func:`polarity_frames`."""
        prm = self.params
        return [(ch, gaussian_filter(f, sigma=prm.kernel_sigma, kernel_size=prm.kernel_size) if prm.gaussian else f)
                for ch, f in polarity_frames(counts, polarity=prm.polarity)]

    def _counts(self, window: Window) -> tuple[np.ndarray, np.ndarray]:
        """ON/OFF counts of the reference and the other camera."""
        ref_ev, oth_ev = (window.right, window.left) if self.params.reference_camera == 1 else \
            (window.left, window.right)
        return polarity_counts(ref_ev, resolution=self.resolution), polarity_counts(oth_ev, resolution=self.resolution)

    def match_window(self, window: Window) -> np.ndarray:
        prm = self.params
        k = window.t_start // prm.level_window_us
        thresholds = self._level.thresholds(k)  # from the windows before this one
        ref_cam = prm.reference_camera
        threshold = thresholds[ref_cam]
        ref_counts, oth_counts = self._counts(window)
        has_ref = (window.right if ref_cam == 1 else window.left).size > 0
        parts = []
        # Each frame of the polarity mode is scanned and matched on its own (``shared``: the one frame).
        for (ch, ref), (_, oth) in zip(self._frames(ref_counts), self._frames(oth_counts), strict=True):
            self._add_levels(k, ch, ref if has_ref else None, oth, ref_counts, oth_counts)
            if not has_ref:
                continue  # no reference events: nothing above threshold, no pixel to report at
            disp = scan_sad(ref, oth, threshold=threshold, max_disparity=prm.max_disparity, block=prm.block,
                            reference_camera=ref_cam)
            keep = ~np.isnan(disp)
            if prm.lr_check:
                back = scan_sad(oth, ref, threshold=thresholds[1 - ref_cam], max_disparity=prm.max_disparity,
                                block=prm.block, reference_camera=1 - ref_cam)
                keep = lr_consistent(disp, back, reference_camera=ref_cam)
            y, x = np.nonzero(event_mask(ref_counts, channel=ch) & keep)
            parts.append(make_matches(window.t_end, x, y, (ref[y, x] > 0).astype(np.int8), ref_cam, disp[y, x]))
        return np.concatenate(parts) if parts else empty_matches()

    def _add_levels(self, k: int, channel: int, ref, oth, ref_counts: np.ndarray, oth_counts: np.ndarray) -> None:
        """Feed the signal level: |frame value| at each camera's pixels with events (of the frame's polarity)."""
        ref_cam = self.params.reference_camera
        if ref is not None:
            self._level.add(k, ref_cam, ref[event_mask(ref_counts, channel=channel)])
        self._level.add(k, 1 - ref_cam, oth[event_mask(oth_counts, channel=channel)])
