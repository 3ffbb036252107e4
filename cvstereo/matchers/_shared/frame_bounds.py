"""Dynamic-frame kernels that keep derived state beside the frames, for the event matchers' searches.

Variants of :func:`cvstereo.frames.dynamic.splat` and :func:`~cvstereo.frames.dynamic.advance_due` that keep,
with every update, either block bounds of |stored| (:func:`splat_bounded`, event-vector's search for
above-threshold pixels, :func:`skip_below`) or column sums of a patch's rows (:func:`splat_summed`, event-area's
lower bound of the SAD). They do the same float64 operations on the frames as the plain kernels, so the frames,
and the matches, are the same bit for bit. Only the matchers use them, so they live with the matchers; the
frames themselves (which the plots draw too) stay in the core.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from cvstereo.frames.dynamic import TOUCHED, advance_due

__all__ = ["BOUND_SHIFT", "SUM_REBUILD", "BoundedFrames", "SummedFrames", "advance_due_bounded", "advance_due_summed",
           "block_bounds", "column_sums", "rebuild_bounds", "rebuild_sums", "skip_below", "splat_bounded",
           "splat_summed", "sum_drift"]


# ----------------------------------------------------------------------------------------------------------
# Block bounds: for each row of a frame and each block of BOUND_BLOCK columns, a number >= |stored| of all its
# pixels (in stored units, so that decay ticks leave it valid). A block whose bound * scale is below a threshold
# holds no pixel at or above it: multiplying by the positive scale rounds monotonically, so
# |stored| <= bound implies |stored * scale| <= bound * scale in float64 too. The matchers that search a row
# for above-threshold pixels (event-vector) or for patches with content skip such blocks without reading
# them, and the result stays the same bit for bit. Bounds only grow between rebuilds, so they may be loose
# where opposite events cancelled, never too small.

#: log2 of the columns per block of :func:`block_bounds` (16 columns: two cache lines of float64).
BOUND_SHIFT = 4


def block_bounds(stored: np.ndarray) -> np.ndarray:
    """Zero block bounds for frames ``stored`` (n_cameras, n_frames, H, W) that are all zero.

    Returns
    -------
    (n_cameras, n_frames, H, ceil(W / 2**BOUND_SHIFT)) float64 ndarray
    """
    n_cameras, n_frames, height, width = stored.shape
    return np.zeros((n_cameras, n_frames, height, (width + (1 << BOUND_SHIFT) - 1) >> BOUND_SHIFT))


class BoundedFrames(NamedTuple):
    """Dynamic frames with their block bounds: the state event-vector's kernel carries, passed as one unit."""

    stored: np.ndarray  #: (n_cameras, n_frames, H, W) float64: the frames, in units of ``scale``
    scale: np.ndarray  #: (n_cameras,) float64: each camera's pending decay factor
    clock: np.ndarray  #: (n_cameras, 2) int64: columns NEXT_TICK and TOUCHED (cvstereo.frames.dynamic)
    bound: np.ndarray  #: (n_cameras, n_frames, H, blocks) float64: the block bounds (:func:`block_bounds`)


@njit(cache=True)
def rebuild_bounds(bound, stored, cam):
    """Set camera ``cam``'s block bounds to the exact maxima of |stored| (after its values were rescaled)."""
    frames = stored[cam]
    for f in range(frames.shape[0]):
        for yy in range(frames.shape[1]):
            for b in range(bound.shape[3]):
                m = 0.0
                for xx in range(b << BOUND_SHIFT, min(frames.shape[2], (b + 1) << BOUND_SHIFT)):
                    m = max(m, abs(frames[f, yy, xx]))
                bound[cam, f, yy, b] = m


@njit(cache=True)
def advance_due_bounded(stored, scale, clock, bound, cam, t, decay, period):
    """:func:`advance_due`, keeping camera ``cam``'s block bounds valid: they are rebuilt after a renormalisation
    or a reset rewrote the stored values."""
    if advance_due(stored, scale, clock, cam, t, decay, period):
        rebuild_bounds(bound, stored, cam)


@njit(cache=True, inline="always")
def splat_bounded(stored, scale, clock, bound, cam, slot, x, y, sign, kernel, rows):
    """:func:`splat` on the rows ``rows = (first, stop)`` of its window (all of them on the sensor, or those a row
    band keeps: :func:`cvstereo.matchers._shared.row_bands.splat_rows`), raising the block bounds of the pixels
    it changes to their new |stored|.

    The same float64 operations as :func:`splat`, in one loop over the kernel's window on the sensor rather than
    :func:`splat` followed by a second loop: in that form numba kept atomic reference counting of the arrays
    around every call. A block's bound is read and written once per row of the window (raised
    to the largest new |stored| of the row's pixels in it) rather than compared per pixel: the same bounds in
    less time an event (bench/results/docstring-figures.md). (Caching ``kernel / c`` between decay ticks instead of
    dividing per pixel measured slower, not faster.)
    """
    r = kernel.shape[0] // 2
    c = scale[cam]
    x0, x1 = max(0, x - r), min(stored.shape[3], x + r + 1)
    for yy in range(rows[0], rows[1]):
        b = x0 >> BOUND_SHIFT
        m = bound[cam, slot, yy, b]
        for xx in range(x0, x1):
            v = stored[cam, slot, yy, xx] + sign * kernel[yy - y + r, xx - x + r] / c
            stored[cam, slot, yy, xx] = v
            if xx >> BOUND_SHIFT != b:  # the window's row crosses into the next block
                bound[cam, slot, yy, b] = m
                b = xx >> BOUND_SHIFT
                m = bound[cam, slot, yy, b]
            m = max(m, abs(v))
        bound[cam, slot, yy, b] = m
    clock[cam, TOUCHED] = 1


@njit(cache=True, inline="always")
def skip_below(stored, bound, cam, slot, y, k, step, end, c, threshold):
    """From column ``k`` (included) in direction ``step`` (+1 or -1) of row ``y`` of frame ``slot``, the first
    column whose value ``|stored * c|`` is >= ``threshold``, or ``end`` (-1 or the width) if none; blocks whose
    bound says that they hold none are skipped whole, the others are read without testing their bound again
    at every pixel."""
    while k != end:
        b = k >> BOUND_SHIFT
        beyond = max(end, (b << BOUND_SHIFT) - 1) if step < 0 else min(end, (b + 1) << BOUND_SHIFT)
        if bound[cam, slot, y, b] * c >= threshold:
            while k != beyond:
                if abs(stored[cam, slot, y, k] * c) >= threshold:
                    return k
                k += step
        k = beyond
    return end


# ----------------------------------------------------------------------------------------------------------
# Column sums: for each camera, frame, row y and column x, ``sums[y, x]`` = the sum of stored[y - h .. y + h, x]
# (rows clipped to the sensor), kept up to date by every splat, so that a search comparing (2h + 1)-row patches
# reads one row of sums rather than 2h + 1 rows of values (event-area's lower bound of the SAD). In stored
# units, so that decay ticks leave them valid. They are not bit-exact: a splat adds its increments to the sums
# as well, so the sums drift from the column sums of ``stored`` by float rounding. :func:`sum_drift` bounds that
# drift; a search using them widens its margin by it. To keep the bound small the sums are rebuilt from the
# frames every :data:`SUM_REBUILD` splats of a camera, and after every rescale of its frames (renormalisation
# or reset), when ``mass`` is also reset.
#
# ``mass[cam]`` (stored units) bounds |stored| of every pixel and |sums| of every entry of camera ``cam`` since
# the last rebuild: at a rebuild it is set to the sum of |stored| over all of its frames, and every splat adds
# the sum of its increments' magnitudes. ``pending[cam]`` counts the splats since the last rebuild.

#: Splats of a camera after which its column sums are rebuilt (~3 a second at 640x480, ~1 ms each).
SUM_REBUILD = 1 << 18


def column_sums(stored: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Zero column sums for frames ``stored`` (n_cameras, n_frames, H, W) that are all zero.

    Returns
    -------
    sums : (n_cameras, n_frames, H, W) float64 ndarray
    mass : (n_cameras,) float64 ndarray
    pending : (n_cameras,) int64 ndarray
    """
    return np.zeros(stored.shape), np.zeros(stored.shape[0]), np.zeros(stored.shape[0], dtype=np.int64)


class SummedFrames(NamedTuple):
    """Dynamic frames with their kept column sums: the state event-area's kernel carries, passed as one unit.

    The kernel unpacks it once per call, so that its per-event code indexes the same six arrays as before
    (:func:`splat_summed` and :func:`advance_due_summed` take them one by one).
    """

    stored: np.ndarray  #: (n_cameras, n_frames, H, W) float64: the frames, in units of ``scale``
    scale: np.ndarray  #: (n_cameras,) float64: each camera's pending decay factor
    clock: np.ndarray  #: (n_cameras, 2) int64: columns NEXT_TICK and TOUCHED (cvstereo.frames.dynamic)
    sums: np.ndarray  #: like ``stored``: column sums of ``block`` rows (:func:`column_sums`)
    mass: np.ndarray  #: (n_cameras,) float64: the magnitude bound of the sums' drift
    pending: np.ndarray  #: (n_cameras,) int64: splats since the sums were last rebuilt


def sum_drift(mass: float, rows: int) -> float:
    """An upper bound of ``|sums - column sums of stored|`` of an entry summing ``rows`` rows, in stored units.

    Each splat since the last rebuild changes an entry by at most ``rows`` additions into the sum and rounds at
    most ``rows`` of the pixels it sums (one per row of its kernel that overlaps them); each rounding
    errs by at most the float64 unit roundoff times a magnitude bounded by ``mass``; the rebuild itself adds
    ``rows`` roundings. At most :data:`SUM_REBUILD` splats lie between rebuilds.
    """
    return (2 * rows * SUM_REBUILD + rows) * np.finfo(np.float64).eps * mass


@njit(cache=True)
def rebuild_sums(sums, mass, pending, stored, cam, half):
    """Recompute camera ``cam``'s column sums of ``2 * half + 1`` rows from its frames; reset its mass and count."""
    frames = stored[cam]
    height = frames.shape[1]
    total = 0.0
    for f in range(frames.shape[0]):
        for yy in range(height):
            row = sums[cam, f, yy]
            row[:] = 0.0
            for r in range(max(0, yy - half), min(height, yy + half + 1)):
                for xx in range(frames.shape[2]):
                    row[xx] += frames[f, r, xx]
            for xx in range(frames.shape[2]):
                total += abs(frames[f, yy, xx])
    mass[cam] = total
    pending[cam] = 0


@njit(cache=True)
def advance_due_summed(stored, scale, clock, sums, mass, pending, cam, t, decay, period, half):
    """:func:`advance_due`, then a rebuild of camera ``cam``'s column sums if its stored values were rewritten (a
    renormalisation or a reset) or :data:`SUM_REBUILD` splats have passed since the last rebuild.

    A caller tests first whether there is anything to do (as :func:`advance` does, or a rebuild due), in its own
    code: an inlined helper holding the test kept reference counting of the six arrays around every event.
    """
    # advance_due first, always: the test after ``or`` must not skip it.
    if advance_due(stored, scale, clock, cam, t, decay, period) or pending[cam] >= SUM_REBUILD:
        rebuild_sums(sums, mass, pending, stored, cam, half)


@njit(cache=True, inline="always")
def splat_summed(stored, scale, clock, sums, mass, pending, half, cam, slot, x, y, sign, kernel, rows):
    """:func:`splat` on the rows ``rows = (first, stop)`` of its window (as for :func:`splat_bounded`), adding
    each increment to the column sums of the ``2 * half + 1`` rows around it too. It counts as a splat of the
    camera (``pending``) even when ``rows`` is empty, so that a row band's sums are rebuilt at the same splats
    as the whole sensor's.

    The same float64 operations on ``stored`` as :func:`splat`, in one loop nest over the kernel's window on the
    sensor (see :func:`splat_bounded` on why one).
    """
    r = kernel.shape[0] // 2
    height = stored.shape[2]
    c = scale[cam]
    added = 0.0
    for yy in range(rows[0], rows[1]):
        for xx in range(max(0, x - r), min(stored.shape[3], x + r + 1)):
            v = sign * kernel[yy - y + r, xx - x + r] / c
            stored[cam, slot, yy, xx] += v
            added += abs(v)
            for rr in range(max(0, yy - half), min(height, yy + half + 1)):
                sums[cam, slot, rr, xx] += v
    mass[cam] += added
    pending[cam] += 1
    clock[cam, TOUCHED] = 1
