"""The frame-area SAD matcher (thesis 3.5.1, Algorithm 2; algorithms.md section 3).

Per 40 ms window: signed frames as for the cluster matcher (Gaussian-filtered, or not in the variant
``no-gaussian``). The reference frame (default: the right camera, the thesis' eDVS1) is scanned row by row,
x ascending; a pixel with ``|value| >= threshold`` and no disparity yet gets the disparity whose 5x5 block in
the other frame, on the same row and on the geometrically possible side, has the least sum of absolute
differences (ties: the smaller disparity); the winner is written into the whole 5x5 neighbourhood of the
disparity map, overwriting, so that those pixels are not searched again.

The SAD of every pixel and disparity comes from OpenCV kernels at once (a cost volume from ``cv2.absdiff``
and an unnormalised ``cv2.boxFilter`` per disparity); only the scan, whose result depends on its order,
remains a loop, and it visits only the above-threshold pixels.

Relative thresholds (``threshold_mode="relative"``, :mod:`cvstereo.signal_level`): the search threshold (2 on
the filtered frame, 4 unfiltered) becomes ``threshold_scale`` times the reference camera's signal level (the 0.9
quantile of |frame value| at its pixels with events over the last second), since a frame's values grow with
the events per pixel. The SAD needs no threshold of its own: candidates are compared with each other (least
SAD wins); block size and disparity range are geometry.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar, Literal

import cv2
import numba
import numpy as np

from calibration_free.frame_clusters import filtered_unit
from cvstereo.frames import (
    FrameMatcher,
    Window,
    WindowFrameParams,
    event_mask,
    gaussian_filter,
    polarity_counts,
    polarity_frames,
)
from cvstereo.matches import empty_matches, make_matches
from cvstereo.signal_level import SignalLevel, SignalLevelParams


@dataclass(frozen=True, kw_only=True)
class FrameAreaParams(SignalLevelParams, WindowFrameParams):
    """Parameters of the frame-area SAD matcher (thesis defaults; algorithms.md section 3).

    The window and Gaussian fields (window_us, gaussian, sigma, kernel_size) are those of
    :class:`~cvstereo.frames.WindowFrameParams`, the relative-threshold fields (threshold_mode,
    threshold_scale, level_*) those of :class:`~cvstereo.signal_level.SignalLevelParams`.

    Attributes
    ----------
    threshold : float
        Reference pixels with ``|value| >= threshold`` are searched (2, or 4 without the Gaussian).
    block : int
        Odd side of the SAD block, and of the neighbourhood the winner is written into.
    max_disparity : int
        Largest disparity searched, px (the search also stops where the block would leave the sensor).
    reference_camera : {0, 1}
        The scanned camera, whose pixels carry the results (1 = right, the thesis' eDVS1; 0 = left).
    """

    threshold: float = 2.0
    block: int = 5
    max_disparity: int = 64
    reference_camera: Literal[0, 1] = 1

    def __post_init__(self):
        super().__post_init__()
        where = type(self).__name__
        if not self.threshold > 0:
            raise ValueError(f"{where}: threshold must be > 0 (the thesis uses 2, or 4 without the Gaussian), "
                             f"got {self.threshold}.")
        if self.block < 1 or self.block % 2 == 0:
            raise ValueError(f"{where}: block must be a positive odd number (the thesis uses 5), got {self.block}.")
        if int(self.max_disparity) != self.max_disparity or self.max_disparity < 0:
            raise ValueError(f"{where}: max_disparity must be a whole number >= 0 (e.g. 64), "
                             f"got {self.max_disparity}.")
        if self.reference_camera not in (0, 1):
            raise ValueError(f"{where}: reference_camera must be 0 (left) or 1 (right), "
                             f"got {self.reference_camera}.")


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
                       block: int = 5) -> np.ndarray:
    """Algorithm 2's scan: row by row, x ascending; search unset pixels above threshold; write the block.

    Parameters
    ----------
    reference : (height, width) float ndarray
        The reference frame (decides which pixels are searched).
    volume : (D + 1, height, width) float ndarray
        SAD per disparity (:func:`sad_volume`).
    threshold : float, keyword-only
    block : int, keyword-only

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
    best = np.argmin(volume[:, ys, xs], axis=0).astype(np.float32)
    done = np.zeros((h, w), dtype=bool)
    for y, x, d in zip(ys.tolist(), xs.tolist(), best.tolist(), strict=True):
        if done[y, x]:
            continue
        disp[y - r: y + r + 1, x - r: x + r + 1] = d
        done[y - r: y + r + 1, x - r: x + r + 1] = True
    return disp


def scan_sad(reference: np.ndarray, other: np.ndarray, *, threshold: float, max_disparity: int, block: int = 5,
             reference_camera: int = 1) -> np.ndarray:
    """Algorithm 2 with the SAD computed only for the pixels the scan actually searches (numba).

    Same result as ``scan_disparity_map(reference, sad_volume(reference, other, ...), ...)``, the readable
    reference implementation, but much faster: each search fills a whole block of the disparity map, so only a
    small part of the above-threshold pixels is ever searched, and a full cost volume is mostly wasted.

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
        p = self.params
        self._level = SignalLevel(p, absolute=p.threshold, unit=filtered_unit(p),
                                  value_name="filtered value" if p.gaussian else "frame value")

    def anchor_cameras(self) -> tuple[int, ...]:
        return (self.params.reference_camera,)

    def diagnostics(self) -> dict:
        """The signal-level diagnostics of the run so far (:meth:`cvstereo.signal_level.SignalLevel.diagnostics`)."""
        return self._level.diagnostics()

    def _frame(self, counts: np.ndarray) -> np.ndarray:
        (_, frame), = polarity_frames(counts, polarity="shared")
        if self.params.gaussian:
            frame = gaussian_filter(frame, sigma=self.params.sigma, kernel_size=self.params.kernel_size)
        return frame

    def disparity_map(self, window: Window) -> tuple[np.ndarray, np.ndarray]:
        """The window's disparity map and reference frame.

        Returns
        -------
        disparity : (height, width) float32 ndarray
            At the reference camera's pixels; NaN where none was written.
        reference : (height, width) float32 ndarray
            The reference camera's (filtered) frame.
        """
        threshold = self._level.thresholds(window.t_start // self.params.level_window_us)
        return self._disparity_map(*self._counts(window), threshold[self.params.reference_camera])[:2]

    def _counts(self, window: Window) -> tuple[np.ndarray, np.ndarray]:
        """ON/OFF counts of the reference and the other camera."""
        ref_ev, oth_ev = (window.right, window.left) if self.params.reference_camera == 1 else \
            (window.left, window.right)
        return polarity_counts(ref_ev, resolution=self.resolution), polarity_counts(oth_ev, resolution=self.resolution)

    def _disparity_map(self, ref_counts: np.ndarray, oth_counts: np.ndarray, threshold: float):
        p = self.params
        ref, oth = self._frame(ref_counts), self._frame(oth_counts)
        disp = scan_sad(ref, oth, threshold=threshold, max_disparity=p.max_disparity, block=p.block,
                        reference_camera=p.reference_camera)
        return disp, ref, oth

    def match_window(self, window: Window) -> np.ndarray:
        p = self.params
        k = window.t_start // p.level_window_us
        threshold = self._level.thresholds(k)[p.reference_camera]  # from the windows before this one
        ref_cam = p.reference_camera
        ref_counts, oth_counts = self._counts(window)
        if not (window.right if ref_cam == 1 else window.left).size:
            self._add_levels(k, None, self._frame(oth_counts), ref_counts, oth_counts)
            return empty_matches()  # no reference events: nothing above threshold, no pixel to report at
        disp, ref, oth = self._disparity_map(ref_counts, oth_counts, threshold)
        self._add_levels(k, ref, oth, ref_counts, oth_counts)
        y, x = np.nonzero(event_mask(ref_counts) & ~np.isnan(disp))
        return make_matches(window.t_end, x, y, (ref[y, x] > 0).astype(np.int8), p.reference_camera, disp[y, x])

    def _add_levels(self, k: int, ref, oth, ref_counts: np.ndarray, oth_counts: np.ndarray) -> None:
        """Feed the signal level: |frame value| at each camera's pixels with events."""
        ref_cam = self.params.reference_camera
        if ref is not None:
            self._level.add(k, ref_cam, ref[event_mask(ref_counts)])
        self._level.add(k, 1 - ref_cam, oth[event_mask(oth_counts)])
