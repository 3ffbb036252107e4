"""The DVS pixel: contrast-threshold events from log intensity, background noise, hot pixels, timestamp jitter.

Each pixel keeps a reference log intensity. Between two render instants the log intensity is taken to
change linearly; every time it crosses the reference plus the ON threshold (or minus the OFF threshold) the
pixel emits an event at the interpolated crossing time and moves its reference by one threshold, so a change
of k thresholds within one step gives k events. Crossings within the refractory period after the pixel's last
event are consumed without an event (the pixel's reset is held). Each event also records the depth of the
surface that caused it: the nearer of the surfaces seen at the pixel at the two instants (a silhouette moving
over the background is the occluding surface's edge); NaN only if neither is known.

:class:`PixelArray` runs the numba kernel; :func:`reference_events` is a plain-Python reading of the same
model, kept to test the kernel against.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from cvstereo.simulate.rig import SensorModel

__all__ = ["DARK_LEVEL", "PixelArray", "background_noise", "hot_pixels", "jitter", "log_intensity", "reference_events"]

#: Added to the linear intensity before the log: the photoreceptor's dark current keeps log(0) finite and
#: makes very dark regions less sensitive, as in a real DVS.
DARK_LEVEL = 0.01


#: Events per kernel call before the buffers grow; a chunk of 200 frames of a busy scene holds about this many.
_INITIAL_CAPACITY = 1 << 18


def log_intensity(intensity: np.ndarray, *, out: np.ndarray | None = None) -> np.ndarray:
    """Log of linear intensity plus :data:`DARK_LEVEL` (float32, same shape; ``out=intensity`` works in place)."""
    out = np.maximum(np.asarray(intensity, np.float32), 0.0, out=out)
    out += DARK_LEVEL
    return np.log(out, out=out)


@njit(cache=True)
def _events_kernel(logi, depth, times_us, t_prev, prev_log, prev_depth, ref, last_event, thr_on, thr_off,
                   refractory_us, out_t, out_x, out_y, out_p, out_z):
    """Process frames until done or until the next frame might not fit into the output buffers.

    Returns (frames done, events written). The state arrays are updated in place, frame by frame, so a
    call can resume at the first frame not done (numba cannot grow arrays in a hot loop cheaply).
    """
    n_frames, h, w = logi.shape
    cap = out_t.shape[0]
    n = 0
    t0 = t_prev
    for k in range(n_frames):
        # Upper bound of this frame's events (refractory drops only lower it): stop before overflowing.
        bound = 0
        for y in range(h):
            for x in range(w):
                dl = logi[k, y, x] - ref[y, x]
                if dl > 0:
                    bound += int(dl / thr_on[y, x] + 1e-9)  # + rounding of the loop below
                else:
                    bound += int(-dl / thr_off[y, x] + 1e-9)
        if n + bound > cap:
            return k, n
        t1 = times_us[k]
        for y in range(h):
            for x in range(w):
                lc = logi[k, y, x]
                lp = prev_log[y, x]
                zc = depth[k, y, x]
                zp = prev_depth[y, x]
                if zc != zc:  # the nearer surface; an unknown depth only where neither is known
                    z = zp
                elif zp != zp:
                    z = zc
                else:
                    z = min(zc, zp)
                r = ref[y, x]
                on = thr_on[y, x]
                off = thr_off[y, x]
                while lc - r >= on:
                    r += on
                    te = t0 + (r - lp) / (lc - lp) * (t1 - t0)
                    if te - last_event[y, x] >= refractory_us:
                        out_t[n], out_x[n], out_y[n], out_p[n], out_z[n] = te, x, y, 1, z
                        n += 1
                        last_event[y, x] = te
                while r - lc >= off:
                    r -= off
                    te = t0 + (r - lp) / (lc - lp) * (t1 - t0)
                    if te - last_event[y, x] >= refractory_us:
                        out_t[n], out_x[n], out_y[n], out_p[n], out_z[n] = te, x, y, 0, z
                        n += 1
                        last_event[y, x] = te
                ref[y, x] = r
                prev_log[y, x] = lc
                prev_depth[y, x] = zc
        t0 = t1
    return n_frames, n


class PixelArray:
    """The state of one sensor's pixels, fed frame batch by frame batch.

    Parameters
    ----------
    sensor : SensorModel
    shape : (H, W)
    rng : numpy.random.Generator
        Draws the per-pixel thresholds (fixed-pattern mismatch).

    Examples
    --------
    >>> import numpy as np
    >>> from cvstereo.simulate.rig import SensorModel
    >>> px = PixelArray(SensorModel().ideal(), (1, 1), np.random.default_rng(0))
    >>> px.start(np.zeros((1, 1), np.float32), np.ones((1, 1), np.float32), 0.0)
    >>> t, x, y, p, z = px.feed(np.full((1, 1, 1), 0.6, np.float32), np.ones((1, 1, 1), np.float32), np.array([1000.0]))
    >>> p.tolist()  # 0.6 = two ON thresholds of 0.25 and a bit
    [1, 1]
    """

    def __init__(self, sensor: SensorModel, shape: tuple[int, int], rng: np.random.Generator):
        self.sensor = sensor
        spread_on = rng.standard_normal(shape) * sensor.threshold_mismatch
        spread_off = rng.standard_normal(shape) * sensor.threshold_mismatch
        self.thr_on = np.maximum(sensor.on_threshold * (1 + spread_on), sensor.min_threshold)
        self.thr_off = np.maximum(sensor.off_threshold * (1 + spread_off), sensor.min_threshold)
        self._state = None
        self._capacity = _INITIAL_CAPACITY
        self._buffers = None

    def start(self, log_frame: np.ndarray, depth_frame: np.ndarray, t_us: float) -> None:
        """Set the reference levels to the first frame, (H, W), seen at time ``t_us``."""
        self._state = dict(
            t_prev=float(t_us),
            prev_log=np.array(log_frame, np.float32),
            prev_depth=np.array(depth_frame, np.float32),
            ref=np.array(log_frame, np.float64),
            last_event=np.full(log_frame.shape, -np.inf),
        )

    def feed(self, log_frames: np.ndarray, depth_frames: np.ndarray, times_us: np.ndarray):
        """Events of the next frames.

        Parameters
        ----------
        log_frames : (T, H, W) float32 ndarray
            Log intensity (see :func:`log_intensity`).
        depth_frames : (T, H, W) float32 ndarray
            Depth of the surface seen at each pixel, NaN where unknown.
        times_us : (T,) ndarray
            Instants of the frames, increasing, after the previous ones.

        Returns
        -------
        t : (N,) float64 ndarray
            Event times (us), not sorted (pixel order within each frame step).
        x, y : (N,) int16 ndarray
        p : (N,) int8 ndarray
        z : (N,) float32 ndarray
            Depth of the surface that caused each event.
        """
        if self._state is None:
            raise RuntimeError("PixelArray.feed() called before start(); give it the first frame first.")
        s = self._state
        log_frames = np.ascontiguousarray(log_frames, np.float32)
        depth_frames = np.ascontiguousarray(depth_frames, np.float32)
        times_us = np.asarray(times_us, np.float64)
        parts = []
        done = 0
        while done < len(times_us):
            if self._buffers is None or self._buffers[0].size < self._capacity:
                self._buffers = (np.empty(self._capacity, np.float64), np.empty(self._capacity, np.int16),
                                 np.empty(self._capacity, np.int16), np.empty(self._capacity, np.int8),
                                 np.empty(self._capacity, np.float32))
            t_prev = s["t_prev"] if done == 0 else float(times_us[done - 1])
            k, n = _events_kernel(log_frames[done:], depth_frames[done:], times_us[done:], t_prev,
                                  s["prev_log"], s["prev_depth"], s["ref"], s["last_event"], self.thr_on,
                                  self.thr_off, float(self.sensor.refractory_us), *self._buffers)
            parts.append(tuple(b[:n].copy() for b in self._buffers))
            if k == 0:  # not even one frame fits: grow the buffers
                self._capacity *= 2
            done += k
        s["t_prev"] = float(times_us[-1])
        return tuple(np.concatenate(col) for col in zip(*parts, strict=True))


def reference_events(log_frames, depth_frames, times_us, thr_on, thr_off, refractory_us):
    """The contrast-threshold model in plain Python (slow; for testing the kernel on small inputs).

    Parameters
    ----------
    log_frames, depth_frames : (T, H, W) ndarray
        Frame 0 sets the reference levels; events come from frames 1 .. T-1.
    times_us : (T,) ndarray
    thr_on, thr_off : (H, W) ndarray
    refractory_us : float

    Returns
    -------
    list of (t, x, y, p, z) tuples in the kernel's order.
    """
    _, h, w = log_frames.shape
    ref = np.array(log_frames[0], np.float64)
    last = np.full((h, w), -np.inf)
    events = []
    for k in range(1, len(times_us)):
        t0, t1 = float(times_us[k - 1]), float(times_us[k])
        for y in range(h):
            for x in range(w):
                lp, lc = float(log_frames[k - 1, y, x]), float(log_frames[k, y, x])
                zp, zc = float(depth_frames[k - 1, y, x]), float(depth_frames[k, y, x])
                z = np.nan if np.isnan(zp) and np.isnan(zc) else np.nanmin([zp, zc])
                for polarity, step in ((1, thr_on[y, x]), (0, -thr_off[y, x])):
                    # ON crossings happen while the signal is above the next level up; OFF ones below.
                    while (lc - ref[y, x] >= step) if polarity else (ref[y, x] - lc >= -step):
                        ref[y, x] += step
                        te = t0 + (ref[y, x] - lp) / (lc - lp) * (t1 - t0)
                        if te - last[y, x] >= refractory_us:
                            events.append((te, x, y, polarity, z))
                            last[y, x] = te
    return events


def background_noise(sensor: SensorModel, shape: tuple[int, int], duration_us: float, rng: np.random.Generator):
    """Background-activity noise: Poisson per pixel, uniform in time, random polarity.

    Returns
    -------
    t : (N,) float64, x, y : (N,) int16, p : (N,) int8
        Unsorted.
    """
    h, w = shape
    return _poisson_events(np.arange(h * w), sensor.noise_rate_hz, duration_us, sensor.noise_on_fraction, w, rng)


def hot_pixels(sensor: SensorModel, shape: tuple[int, int], duration_us: float, rng: np.random.Generator):
    """Events of the hot pixels: ``round(hot_pixel_fraction * H * W)`` pixels drawn at random, each firing at
    ``hot_pixel_rate_hz`` (Poisson, uniform in time, ON with ``noise_on_fraction``) whatever it sees.

    Draws nothing from ``rng`` when the sensor has no hot pixels, so that adding the model left the events of
    every earlier seed as they were.

    Returns
    -------
    t : (N,) float64, x, y : (N,) int16, p : (N,) int8
        Unsorted.
    """
    h, w = shape
    n_hot = round(sensor.hot_pixel_fraction * h * w)
    if n_hot == 0 or sensor.hot_pixel_rate_hz == 0:
        return _poisson_events(np.zeros(0, np.int64), 0.0, duration_us, 0.0, w, rng)
    pixels = rng.choice(h * w, size=n_hot, replace=False)
    return _poisson_events(pixels, sensor.hot_pixel_rate_hz, duration_us, sensor.noise_on_fraction, w, rng)


def _poisson_events(pixels: np.ndarray, rate_hz: float, duration_us: float, on_fraction: float, width: int,
                    rng: np.random.Generator):
    """Poisson events at ``rate_hz`` on each of the flat pixel indices ``pixels``: (t, x, y, p), unsorted."""
    counts = rng.poisson(rate_hz * duration_us * 1e-6, size=pixels.size)
    n = int(counts.sum())
    pix = np.repeat(pixels, counts)
    t = rng.uniform(0.0, duration_us, size=n)
    p = (rng.random(n) < on_fraction).astype(np.int8)
    return t, (pix % width).astype(np.int16), (pix // width).astype(np.int16), p


def jitter(t_us: np.ndarray, sensor: SensorModel, duration_us: float, rng: np.random.Generator) -> np.ndarray:
    """Timestamps with Gaussian jitter, rounded to whole microseconds and kept within the recording.

    Returns
    -------
    (N,) int64 ndarray
    """
    if sensor.jitter_us > 0:
        t_us = t_us + rng.normal(0.0, sensor.jitter_us, size=t_us.shape)
    return np.clip(np.rint(t_us), 0, max(0.0, duration_us - 1)).astype(np.int64)
