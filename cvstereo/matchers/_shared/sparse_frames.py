"""A window's frames kept sparse: only the pixels near events are accumulated, filtered and read.

At 640x480 a 40 ms window touches a few percent of the pixels, yet a dense frame costs a pass over all of them
for the accumulation, for each of the Gaussian's two passes and for each search. :class:`SparseFrames` keeps
the frames of a window (planes: camera x polarity frame) in buffers that stay zero between windows, and marks
per frame row, as bitmaps of 64-bit words:

- ``touched``: pixels with events (of that frame);
- ``row_support``: pixels within two columns of a touched one, where the Gaussian's row pass can be nonzero;
- ``support``: pixels within two rows of those, where the filtered frame can be nonzero.
- ``above`` (given thresholds): pixels where the filtered value reaches the camera's threshold, marked as the
  filter computes them, so that a matcher's scans visit only the pixels its threshold keeps.

The Gaussian is evaluated only on the support, with the arithmetic of OpenCV's separable filter for float32
(what :func:`cvstereo.frames.accumulate.gaussian_filter` calls), so that every filtered value is the one
``cv2.GaussianBlur`` gives, bit for bit: per pass ``c*k0 + (l1+r1)*k1 + (l2+r2)*k2`` (centre, neighbours at
1 and 2 px, zeros beyond the border), with fused multiply-adds in the pixels OpenCV's SIMD loop covers and
plain float32 arithmetic in its scalar tail. Where those pixels lie and whether fused multiply-adds are used
depend on the CPU and the OpenCV build, so :func:`cv2_layout` finds the layout once per frame width on a
random probe; when none reproduces OpenCV exactly (or the kernel is not 5 wide), :attr:`SparseFrames.exact`
is False and the matchers keep their dense path.
"""

from __future__ import annotations

import functools

import cv2
import numba
import numpy as np
from llvmlite import ir
from numba.core import cgutils, types
from numba.cpython.unsafe.numbers import trailing_zeros
from numba.extending import intrinsic

from cvstereo.errors import EventFormatError
from cvstereo.frames.accumulate import OFF_SENSOR, event_channel, frame_shape, gaussian_filter, polarity_sign

#: Kernel side the sparse Gaussian reproduces (the thesis' 5x5).
SPARSE_KERNEL_SIZE = 5


@intrinsic
def _fma32(typingctx, a, b, c):
    """float32 fused multiply-add a * b + c (one rounding), as OpenCV's v_muladd on FMA hardware."""
    sig = types.float32(types.float32, types.float32, types.float32)

    def codegen(context, builder, signature, args):
        fnty = ir.FunctionType(ir.FloatType(), [ir.FloatType()] * 3)
        return builder.call(cgutils.get_or_insert_function(builder.module, fnty, "llvm.fma.f32"), args)

    return sig, codegen


class SparseFrames:
    """Reusable sparse frames of one window: ``n_planes`` frames of the sensor, filtered or not.

    Parameters
    ----------
    n_planes : int
        Frames per window (cameras x polarity frames), plane ``cam * frames_per_camera + slot``.
    resolution : (width, height)
    gaussian : bool
        Filter with the Gaussian of ``kernel_sigma`` (``kernel_size`` must be 5 for the sparse path).
    kernel_sigma : float
    kernel_size : int

    Attributes
    ----------
    exact : bool
        The sparse frames equal the dense ones bit for bit: always without the Gaussian; with it, when
        :func:`cv2_layout` found the OpenCV build's layout for this CPU and frame width.
    values : (n_planes, height, width) float32 ndarray
        The (filtered) frames after :meth:`fill`; zero outside ``support``.
    touched, support : (n_planes, height, words) uint64 ndarray
        Bitmaps of the pixels with events and of the pixels where ``values`` may be nonzero.
    above : (n_planes, height, words) uint64 ndarray
        Bitmap of the pixels where ``|values|`` reaches the plane's threshold given to :meth:`fill` (none
        without thresholds): the pixels a matcher's threshold keeps, so that its scans visit only those.
    """

    def __init__(self, n_planes: int, *, resolution: tuple[int, int], gaussian: bool, kernel_sigma: float = 1.0,
                 kernel_size: int = 5):
        self.height, self.width = frame_shape(resolution)
        self.gaussian = bool(gaussian)
        self.layout = cv2_layout(self.width, float(kernel_sigma), int(kernel_size)) if gaussian else (0, 0, 0)
        self.exact = self.layout is not None
        if not self.exact:
            return
        shape = (n_planes, self.height, self.width)
        words = (n_planes, self.height, (self.width + 63) // 64)
        self._acc = np.zeros(shape, np.float32)
        self.touched = np.zeros(words, np.uint64)
        self.above = np.zeros(words, np.uint64)
        if self.gaussian:
            k = cv2.getGaussianKernel(SPARSE_KERNEL_SIZE, kernel_sigma, ktype=cv2.CV_32F).ravel()
            self._k = (np.float32(k[2]), np.float32(k[1]), np.float32(k[0]))  # centre, 1 px, 2 px
            self._rows = np.zeros(shape, np.float32)
            self.values = np.zeros(shape, np.float32)
            self._row_support = np.zeros(words, np.uint64)
            self.support = np.zeros(words, np.uint64)
        else:
            self.values, self.support = self._acc, self.touched

    def fill(self, cameras, channel_of: np.ndarray, frames_per_camera: int, thresholds=None) -> None:
        """Accumulate each camera's events (sum of signs, into plane ``cam * frames_per_camera +
        channel_of[p]``; -1 drops the event) and filter; the frames must be empty (:meth:`clear`).

        ``thresholds`` (one per camera, compared as float64: ``|value| >= threshold``) fills ``above``; None
        leaves it empty.

        Raises
        ------
        EventFormatError
            An event lies outside the sensor (the frames are cleared).
        """
        h, w = self.height, self.width
        for cam, ev in enumerate(cameras):
            bad = _accumulate(ev["x"], ev["y"], ev["p"], channel_of, cam * frames_per_camera, h, w, self._acc,
                              self.touched)
            if bad >= 0:
                self.clear()
                raise EventFormatError(f"camera {cam}: event {bad} at (x={int(ev['x'][bad])}, "
                                       f"y={int(ev['y'][bad])}) lies outside the {w}x{h} sensor.")
        per_plane = np.full(self.touched.shape[0], np.inf)  # inf: no pixel is above
        if thresholds is not None:
            per_plane = np.repeat(np.asarray(thresholds, np.float64), frames_per_camera)
        if self.gaussian:
            _gaussian_on_support(self._acc, self.touched, self._rows, self.values, self._row_support, self.support,
                                 *self._k, *self.layout, per_plane, self.above)
        elif thresholds is not None:
            _mark_above(self.values, self.support, per_plane, self.above)

    def values_at_events(self, first_plane: int, n_planes: int, capacity: int) -> np.ndarray:
        """``values`` at the touched pixels of planes ``first_plane ..``, plane by plane, row by row, x ascending
        (``capacity``: at least their number, e.g. the events in them)."""
        return _values_at(self.values, self.touched, first_plane, n_planes, capacity)

    def clear(self) -> None:
        """Zero the frames where the last window wrote (the buffers are reused)."""
        self.above[:] = 0
        if self.gaussian:
            _clear(self._rows, self._row_support)
            _clear(self.values, self.support)
        _clear(self._acc, self.touched)


@functools.cache
def cv2_layout(width: int, kernel_sigma: float, kernel_size: int) -> tuple[int, int, int] | None:
    """(fused multiply-adds?, columns of the row pass's SIMD part, of the column pass's) that reproduce
    ``cv2.GaussianBlur`` on frames ``width`` wide, found on a random probe; None if no layout does.

    OpenCV's loops cover the first ``width - width % lanes`` columns with SIMD vectors and the rest with
    scalar code; the lane counts (per pass) and the use of FMA depend on the CPU and the OpenCV build.
    """
    if kernel_size != SPARSE_KERNEL_SIZE:
        return None
    rng = np.random.default_rng(12345)
    probe = (rng.integers(-6, 7, (2, 40, width)) * (rng.random((2, 40, width)) < 0.5)).astype(np.float32)
    probe[0, :3] = 0  # an empty band, and a plane border next to values: the edges of the support
    expected = np.stack([gaussian_filter(p, sigma=kernel_sigma, kernel_size=kernel_size) for p in probe])
    candidates = [(0, 0, 0)] + [(1, width - width % a, width - width % b)
                                for a in (2, 4, 8, 16, 1, 32) for b in (8, 4, 16, 2, 1, 32)]
    for layout in candidates:
        if _probe_filter(probe, kernel_sigma, layout).tobytes() == expected.tobytes():
            return layout
    return None


def _probe_filter(probe: np.ndarray, kernel_sigma: float, layout) -> np.ndarray:
    """The sparse Gaussian of dense planes (for :func:`cv2_layout`)."""
    n, h, w = probe.shape
    words = (n, h, (w + 63) // 64)
    touched = np.zeros(words, np.uint64)
    ys, xs = np.nonzero(probe.reshape(n * h, w))
    bits = np.left_shift(np.uint64(1), (xs & 63).astype(np.uint64))
    np.bitwise_or.at(touched.reshape(n * h, -1), (ys, xs >> 6), bits)
    k = cv2.getGaussianKernel(SPARSE_KERNEL_SIZE, kernel_sigma, ktype=cv2.CV_32F).ravel()
    out = np.zeros_like(probe)
    _gaussian_on_support(probe.copy(), touched, np.zeros_like(probe), out, np.zeros(words, np.uint64),
                         np.zeros(words, np.uint64), np.float32(k[2]), np.float32(k[1]), np.float32(k[0]), *layout,
                         np.full(n, np.inf), np.zeros(words, np.uint64))
    return out


@numba.njit(cache=True, nogil=True, inline="always")
def bit_positions(word, i):  # pragma: no cover - compiled
    """The column of the lowest set bit of ``word`` (word ``i`` of a bitmap row) and the word without it."""
    return i * 64 + trailing_zeros(word), word & (word - np.uint64(1))


@numba.njit(cache=True, nogil=True)
def _accumulate(x, y, p, channel_of, first_plane, height, width, acc, touched):  # pragma: no cover - compiled
    """Add each event's sign into its plane and mark its pixel; the index of the first event off the sensor, or -1."""
    for i in range(x.size):
        c = event_channel(x, y, p, i, channel_of, width, height)
        if c == OFF_SENSOR:
            return i
        if c >= 0:  # (a negative channel: a polarity the mode drops)
            plane = first_plane + c
            xi, yi = np.int64(x[i]), np.int64(y[i])
            acc[plane, yi, xi] += np.float32(polarity_sign(p[i]))
            touched[plane, yi, xi >> 6] |= np.uint64(1) << np.uint64(xi & 63)
    return -1


@numba.njit(cache=True, nogil=True, inline="always")
def _dilate_row(src, dst, width):  # pragma: no cover - compiled
    """dst |= src widened by two columns on each side (bit x of word x // 64), cut at ``width``."""
    n = src.size
    for w in range(n):
        s = src[w]
        lo = src[w - 1] if w > 0 else np.uint64(0)
        hi = src[w + 1] if w + 1 < n else np.uint64(0)
        d = s | (s << np.uint64(1)) | (s << np.uint64(2)) | (lo >> np.uint64(63)) | (lo >> np.uint64(62))
        d |= (s >> np.uint64(1)) | (s >> np.uint64(2)) | (hi << np.uint64(63)) | (hi << np.uint64(62))
        dst[w] |= d
    tail = width & 63
    if tail:
        dst[n - 1] &= (np.uint64(1) << np.uint64(tail)) - np.uint64(1)


@numba.njit(cache=True, nogil=True)
def band_of_rows(bits, y, r, width):  # pragma: no cover - compiled
    """Row ``y``'s band: the set bits of rows y - r .. y + r of ``bits`` (a plane's bitmap), widened by r columns
    on each side; bit x says whether the (2r+1)-square centred at (y, x) holds a set bit."""
    h, n_words = bits.shape
    band = np.zeros(n_words, np.uint64)
    for yy in range(max(0, y - r), min(h, y + r + 1)):
        for i in range(n_words):
            band[i] |= bits[yy, i]
    one = np.uint64(1)
    for _ in range(r):  # one column per pass
        wider = band.copy()
        for i in range(n_words):
            s = band[i]
            wider[i] |= (s << one) | (s >> one)
            if i > 0:
                wider[i] |= band[i - 1] >> np.uint64(63)
            if i + 1 < n_words:
                wider[i] |= band[i + 1] << np.uint64(63)
        band = wider
    if width & 63:
        band[n_words - 1] &= (one << np.uint64(width & 63)) - one
    return band


@numba.njit(cache=True, nogil=True, inline="always")
def _tap5(c, p1, p2, k0, k1, k2, fused_product_first, fused):  # pragma: no cover - compiled
    """One output of a 5-tap symmetric pass: centre c, neighbour sums p1 (1 px) and p2 (2 px).

    OpenCV's SIMD row pass computes fma(p2, k2, fma(c, k0, p1 * k1)), its column pass
    fma(p2, k2, fma(p1, k1, c * k0)); its scalar code (c * k0 + p1 * k1) + p2 * k2.
    """
    if not fused:
        return (c * k0 + p1 * k1) + p2 * k2
    if fused_product_first:
        return _fma32(p2, k2, _fma32(c, k0, p1 * k1))
    return _fma32(p2, k2, _fma32(p1, k1, c * k0))


@numba.njit(cache=True, nogil=True)
def _gaussian_on_support(acc, touched, rows, out, row_support, support, k0, k1, k2, use_fma, split_row,
                         split_col, thresholds, above):  # pragma: no cover - compiled
    """The 5x5 Gaussian of each plane of ``acc`` (zero border), evaluated on the support only (module doc);
    ``above`` marks where ``|out|`` reaches the plane's threshold (:attr:`SparseFrames.above`)."""
    n_planes, h, w = acc.shape
    n_words = touched.shape[2]
    zero = np.float32(0.0)
    for pl in range(n_planes):
        for y in range(h):
            t = touched[pl, y]
            nonempty = False
            for i in range(n_words):
                if t[i]:
                    nonempty = True
                    break
            if not nonempty:
                continue
            _dilate_row(t, row_support[pl, y], w)
            for yy in range(max(0, y - 2), min(h, y + 3)):
                for i in range(n_words):
                    support[pl, yy, i] |= row_support[pl, y, i]
            a = acc[pl, y]
            for i in range(n_words):
                word = row_support[pl, y, i]
                while word:
                    x, word = bit_positions(word, i)
                    p1 = (a[x - 1] if x >= 1 else zero) + (a[x + 1] if x + 1 < w else zero)
                    p2 = (a[x - 2] if x >= 2 else zero) + (a[x + 2] if x + 2 < w else zero)
                    rows[pl, y, x] = _tap5(a[x], p1, p2, k0, k1, k2, True, use_fma != 0 and x < split_row)
        for y in range(h):
            for i in range(n_words):
                word = support[pl, y, i]
                hits = np.uint64(0)
                while word:
                    x, word = bit_positions(word, i)
                    p1 = (rows[pl, y - 1, x] if y >= 1 else zero) + (rows[pl, y + 1, x] if y + 1 < h else zero)
                    p2 = (rows[pl, y - 2, x] if y >= 2 else zero) + (rows[pl, y + 2, x] if y + 2 < h else zero)
                    v = _tap5(rows[pl, y, x], p1, p2, k0, k1, k2, False, use_fma != 0 and x < split_col)
                    out[pl, y, x] = v
                    hits |= _above_bit(v, thresholds[pl], x)
                above[pl, y, i] = hits


@numba.njit(cache=True, nogil=True, inline="always")
def _above_bit(value, threshold, x):  # pragma: no cover - compiled
    """Column ``x``'s bit of its 64-bit word where ``|value|`` reaches ``threshold``, else 0: the one test of
    :attr:`SparseFrames.above`, compared as float64 as the matchers' dense paths compare."""
    return np.uint64(1) << np.uint64(x & 63) if abs(np.float64(value)) >= threshold else np.uint64(0)


@numba.njit(cache=True, nogil=True)
def _mark_above(values, bits, thresholds, above):  # pragma: no cover - compiled
    """above = the set bits of ``bits`` where ``|values|`` reaches the plane's threshold."""
    n_planes, h, n_words = bits.shape
    for pl in range(n_planes):
        for y in range(h):
            for i in range(n_words):
                word = bits[pl, y, i]
                hits = np.uint64(0)
                while word:
                    x, word = bit_positions(word, i)
                    hits |= _above_bit(values[pl, y, x], thresholds[pl], x)
                above[pl, y, i] = hits


@numba.njit(cache=True, nogil=True)
def _values_at(values, touched, first_plane, n_planes, capacity):  # pragma: no cover - compiled
    out = np.empty(capacity, np.float32)
    n = 0
    n_words = touched.shape[2]
    for pl in range(first_plane, first_plane + n_planes):
        for y in range(values.shape[1]):
            for i in range(n_words):
                word = touched[pl, y, i]
                while word:
                    x, word = bit_positions(word, i)
                    out[n] = values[pl, y, x]
                    n += 1
    return out[:n]


@numba.njit(cache=True, nogil=True)
def _clear(values, bits):  # pragma: no cover - compiled
    """values = 0 at the set bits; bits = 0."""
    n_planes, h, n_words = bits.shape
    for pl in range(n_planes):
        for y in range(h):
            for i in range(n_words):
                word = bits[pl, y, i]
                if word == 0:
                    continue
                bits[pl, y, i] = 0
                while word:
                    x, word = bit_positions(word, i)
                    values[pl, y, x] = 0.0
