"""simulate(): render both cameras of a rig over time and turn the frames into events with ground truth."""

from __future__ import annotations

import sys

import numpy as np
from tqdm import tqdm

from cvstereo.model.events import make_events
from cvstereo.model.recording import Recording
from cvstereo.simulate.dvs import PixelArray, background_noise, hot_pixels, jitter, log_intensity
from cvstereo.simulate.rig import Rig

__all__ = ["DEFAULT_RENDER_HZ", "GENERATOR_VERSION", "MAX_RENDER_HZ", "MAX_SECONDS", "simulate"]

#: Bump whenever a change alters the events a seed produces: cached presets carry it in their key.
GENERATOR_VERSION = 2

#: Frames rendered per batch on a 128x128 sensor: large enough to amortise the per-call overhead, small enough
#: that a batch of intensity and depth frames (2 x 4 bytes x 128 x 128 x 200 = 26 MB) stays cheap. Larger
#: sensors get proportionally fewer frames per batch (the same memory); frames are independent, so the
#: batch size never changes the events.
_CHUNK_FRAMES = 200
_CHUNK_PIXELS = _CHUNK_FRAMES * 128 * 128

#: Render rate. An arm at 50 cm sweeps at up to about 250 px/s, i.e. 0.25 px per 1 ms step: linear
#: interpolation between instants then places event timestamps within a fraction of the edge's passage.
DEFAULT_RENDER_HZ = 1000.0

#: Longest recording simulate() makes: it holds every event in memory (10 minutes of the busiest preset are
#: about 33 M events per camera, some 2 GB at the peak); make longer ones in pieces.
MAX_SECONDS = 600.0

#: Highest render rate: frames are rendered one by one, so seconds x render_hz bounds the work.
MAX_RENDER_HZ = 100_000.0


def simulate(scene, *, rig: Rig | None = None, seconds: float = 1.0, seed: int = 0,
             render_hz: float | None = None, progress: bool = False) -> Recording:
    """Simulate a stereo pair of DVS128 looking at a scene: events of both cameras with per-event truth.

    Parameters
    ----------
    scene : scene object
        Anything with ``render(rig, index, times_s) -> (intensity, depth)`` and ``describe() -> dict``
        (see :mod:`cvstereo.simulate.scenes`).
    rig : Rig, keyword-only
        Geometry and sensors; default :class:`~cvstereo.simulate.rig.Rig` (the thesis' rig).
    seconds : float, keyword-only
        Length of the recording.
    seed : int, keyword-only
        Seeds threshold mismatch, noise and jitter; the same seed gives the same events.
    render_hz : float or None, keyword-only
        Rate at which each camera's view is rendered; event times are interpolated between renders. None:
        the scene's ``render_hz`` attribute if it has one (a fast scene such as the fan needs more), else
        :data:`DEFAULT_RENDER_HZ`.
    progress : bool, keyword-only
        Show a progress bar on stderr (only when stderr is a terminal).

    Returns
    -------
    Recording
        Events in raw sensor coordinates; ``left_disparity`` / ``right_disparity`` hold the true
        ``x_left - x_right`` of the scene point that caused each event, NaN for noise and unknown depth;
        ``meta`` holds the rig, the scene and the generator's settings.
    """
    rig = Rig() if rig is None else rig
    if render_hz is None:
        render_hz = float(getattr(scene, "render_hz", DEFAULT_RENDER_HZ))
    if not 0 < seconds <= MAX_SECONDS:
        raise ValueError(f"seconds must lie in (0, {MAX_SECONDS:g}] (the simulator keeps every event in memory), "
                         f"got {seconds}.")
    if not 0 < render_hz <= MAX_RENDER_HZ:
        raise ValueError(f"render_hz must lie in (0, {MAX_RENDER_HZ:g}], got {render_hz}.")
    n_steps = max(1, round(seconds * render_hz))
    times_s = np.arange(n_steps + 1) * (seconds / n_steps)
    duration_us = seconds * 1e6
    cam_seeds = np.random.SeedSequence(seed).spawn(2)
    w, h = rig.resolution
    chunk = max(4, min(_CHUNK_FRAMES, _CHUNK_PIXELS // (w * h)))
    results = []
    with tqdm(total=2 * (n_steps + 1), unit="frame", file=sys.stderr, disable=None if progress else True,
              desc="simulate") as bar:
        for index in (0, 1):
            rng = np.random.default_rng(cam_seeds[index])
            sensor = rig.sensor(index)
            pixels = PixelArray(sensor, (h, w), rng)
            parts = []
            for lo in range(0, n_steps + 1, chunk):
                ts = times_s[lo:lo + chunk]
                intensity, depth = scene.render(rig, index, ts)
                logi = log_intensity(intensity, out=intensity)
                if lo == 0:
                    pixels.start(logi[0], depth[0], 0.0)
                    logi, depth, ts = logi[1:], depth[1:], ts[1:]
                if ts.size:
                    parts.append(pixels.feed(logi, depth, ts * 1e6))
                bar.update(ts.size + (lo == 0))
            t, x, y, p, z = (np.concatenate(col) for col in zip(*parts, strict=True))
            truth = rig.disparity_from_depth(index, x, y, z).astype(np.float32)
            noise = (background_noise(sensor, (h, w), duration_us, rng), hot_pixels(sensor, (h, w), duration_us, rng))
            nt, nx, ny, npol = (np.concatenate(col) for col in zip(*noise, strict=True))
            t, x, y, p = (np.concatenate(pair) for pair in ((t, nt), (x, nx), (y, ny), (p, npol)))
            truth = np.concatenate([truth, np.full(nt.size, np.nan, np.float32)])
            if index == 1 and rig.time_offset_us:
                # The right camera's clock: its stamps are shifted, and what falls outside the recording is lost.
                t = t + rig.time_offset_us
                kept = (t >= 0) & (t < duration_us)
                t, x, y, p, truth = t[kept], x[kept], y[kept], p[kept], truth[kept]
            events = make_events(jitter(t, sensor, duration_us, rng), x, y, p)
            order = np.argsort(events["t"], kind="stable")
            results.append((events[order], truth[order]))
    (left, left_truth), (right, right_truth) = results
    meta = {
        "source": "cvstereo.simulate",
        "generator_version": GENERATOR_VERSION,
        "seconds": float(seconds),
        "seed": int(seed),
        "render_hz": float(render_hz),
        "rig": rig.describe(),
        "scene": scene.describe(),
        "truth": "x_left - x_right in raw (distorted, misaligned) sensor coordinates of the scene point that "
                 "caused the event; NaN for background-activity noise and unknown depth",
    }
    return Recording(left, right, left_truth, right_truth, rig.resolution, meta)
