"""A rotating fan in front of a wall: the scene of the real TUM recordings (``Fan_disp8.dat``).

The fan is a flat disc facing the rig at a known depth: a hub and ``blades`` identical blades that turn at a
constant rate, so that a blade passes any point every ``blade_period_s`` (the period a time-offset search
can lock onto, issue 12). Every event the fan causes carries the fan's depth, hence the disparity
``f*B/Z - c`` of an ideal rig; the plain wall behind stands still and gives only noise.

The fan's stand and housing (a "post" from the hub down, in the fan's plane, in front of the blades; by
default as wide as the fan) hide the lower half of the disc, so the number of blade edges in view, hence
the event rate, rises and falls with period ``blade_period_s``, the same in both cameras (the post is at the
fan's depth), which lets the two cameras' clocks be compared. A whole disc without a post would give a flat
rate: each edge sweeps the same area per unit time at any angle. Blades and background differ by more than
an ON plus an OFF threshold in log intensity; a smaller contrast lets every pixel settle between its levels
after a few passes and fall silent.

The blades are rendered analytically (numba, one frame per thread): for each pixel's ray, the point where it
meets the fan's plane, in polar coordinates around the hub; a blade's coverage there is a Gaussian-blurred
step (the optics' blur of :data:`~cvstereo.simulate.textures.OPTICS_BLUR_PX` pixels) across each of its
edges, so that the edges move smoothly between render instants.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from cvstereo.simulate import textures
from cvstereo.simulate.render import ALPHA_TRUTH_MIN
from cvstereo.simulate.rig import Rig

__all__ = ["FAN_RENDER_HZ", "FanScene"]

#: Render rate the fan needs: its blade tips sweep about 1,900 px/s at the defaults, 0.4 px per step here.
FAN_RENDER_HZ = 5_000.0


@njit(inline="always")
def _step(d):
    """Coverage of a Gaussian-blurred edge at signed distance ``d`` (in blur sigmas; > 0 inside)."""
    return 0.5 * (1.0 + math.erf(d * 0.7071067811865476))


@njit(parallel=True, cache=True, error_model="numpy")
def _render_fan_kernel(xn, yn, cam_x, depth, hub_x, hub_y, angles, blades, blade_fraction, hub_radius, tip_radius,
                       post_half_width, post_level, sigma, level, bg_i, bg_z, alpha_truth, out_i, out_z):
    n_frames = angles.shape[0]
    h, w = xn.shape
    sector = 2.0 * math.pi / blades
    width = blade_fraction * sector
    reach = tip_radius + 5.0 * sigma
    for k in prange(n_frames):
        turn = angles[k]
        for y in range(h):
            for x in range(w):
                px = cam_x + xn[y, x] * depth - hub_x
                py = yn[y, x] * depth - hub_y
                r = math.sqrt(px * px + py * py)
                cov = 0.0
                if r < reach:
                    # angle from the leading edge of the blade behind, in [0, sector)
                    u = (math.atan2(py, px) - turn) % sector
                    if u < width:
                        arc = min(u, width - u) * r
                    else:
                        arc = -min(u - width, sector - u) * r
                    cov = max(_step((hub_radius - r) / sigma), _step(arc / sigma) * _step((tip_radius - r) / sigma))
                post = 0.0
                if post_half_width > 0.0:
                    post = _step((post_half_width - abs(px)) / sigma) * _step(py / sigma)
                value = post * post_level + (1.0 - post) * (cov * level + (1.0 - cov) * bg_i[y, x])
                out_i[k, y, x] = value
                out_z[k, y, x] = depth if max(cov, post) >= alpha_truth else bg_z[y, x]


@dataclass(frozen=True)
class FanScene:
    """A fan of ``blades`` blades turning at a constant rate at ``distance_m``, in front of a still wall.

    Parameters
    ----------
    blades : int
        Number of identical blades.
    blade_period_s : float
        Time between two blades passing the same point (one revolution takes ``blades`` periods). 18 ms at
        the default: the real fan's time-offset search found a peak 18 ms from the right one.
    distance_m : float
        Depth of the fan's plane (1.5 m gives 8 px on the thesis' rig, as ``Fan_disp8.dat``).
    radius_m, hub_radius_m : float
        Blade tips and hub.
    blade_fraction : float
        Share of each blade's sector that the blade covers.
    center_view : (float, float)
        Hub position (X right, Y down) in the fan's plane as a fraction of the view's half-width and
        half-height there (0, 0: on the rig's centre line; 1: at the sensor's border).
    post_width_m : float
        Width of the post from the hub down (0: none, and a flat event rate; the fan's diameter: the lower
        half is hidden).
    blade_level, post_level : float
        Linear intensity of blades and hub, and of the post (darker than the wall: the log contrast sets
        the events per edge).
    background : float
        Linear intensity of the plain wall.
    background_m : float
        Depth of the wall behind.
    clockwise : bool
        Turning direction as the rig sees it.
    seed : int
        Wall texture and the fan's starting angle.
    """

    blades: int = 3
    blade_period_s: float = 0.018
    distance_m: float = 1.5
    radius_m: float = 0.1
    hub_radius_m: float = 0.02
    blade_fraction: float = 0.4
    center_view: tuple[float, float] = (0.0, 0.0)
    post_width_m: float = 0.2
    blade_level: float = 0.2
    post_level: float = 0.3
    background: float = 0.55
    background_m: float = 3.0
    clockwise: bool = True
    seed: int = 0
    kind = "fan"
    render_hz = FAN_RENDER_HZ  # what simulate() renders it at unless told otherwise

    def __post_init__(self):
        if int(self.blades) != self.blades or self.blades < 1:
            raise ValueError(f"FanScene.blades must be a whole number >= 1, got {self.blades}.")
        for name in ("blade_period_s", "radius_m", "hub_radius_m"):
            if not getattr(self, name) > 0:
                raise ValueError(f"FanScene.{name} must be positive, got {getattr(self, name)}.")
        if self.post_width_m < 0:
            raise ValueError(f"FanScene.post_width_m must be >= 0, got {self.post_width_m}.")
        if not 0 < self.blade_fraction < 1:
            raise ValueError(f"FanScene.blade_fraction must lie in (0, 1), got {self.blade_fraction}.")
        if not 0.1 <= self.distance_m < self.background_m:
            raise ValueError(f"FanScene.distance_m={self.distance_m} must be >= 0.1 m and in front of the wall "
                             f"(background_m={self.background_m}).")
        if self.hub_radius_m >= self.radius_m:
            raise ValueError(f"FanScene.hub_radius_m={self.hub_radius_m} must be smaller than "
                             f"radius_m={self.radius_m}.")

    @property
    def revolutions_per_s(self) -> float:
        """Revolutions per second: one blade period per blade."""
        return 1.0 / (self.blades * self.blade_period_s)

    def angle(self, times_s: np.ndarray) -> np.ndarray:
        """The fan's turn (radians, image orientation: x right, y down) at ``times_s``."""
        start = np.random.default_rng([self.seed, 0xFA]).uniform(0, 2 * np.pi)
        sign = 1.0 if self.clockwise else -1.0  # with y down, a growing angle turns clockwise on screen
        return start + sign * 2 * np.pi * self.revolutions_per_s * np.asarray(times_s, np.float64)

    def hub(self, rig: Rig) -> tuple[float, float]:
        """The hub's X, Y (metres, rig frame) in the fan's plane."""
        w, h = rig.resolution
        return (self.center_view[0] * w / 2 / rig.focal_px * self.distance_m,
                self.center_view[1] * h / 2 / rig.focal_px * self.distance_m)

    def render(self, rig: Rig, index: int, times_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Intensity and depth, each (T, H, W) float32, of camera ``index`` at ``times_s`` (T,)."""
        camera = rig.camera(index)
        xn, yn = camera.rays
        bg_i = np.full(xn.shape, self.background, np.float32)
        bg_z = np.full(xn.shape, self.background_m, np.float32)
        hub_x, hub_y = self.hub(rig)
        angles = self.angle(times_s)
        out_i = np.empty((angles.size, *xn.shape), np.float32)
        out_z = np.empty_like(out_i)
        sigma = textures.OPTICS_BLUR_PX * self.distance_m / rig.focal_px  # the blur in metres on the fan
        _render_fan_kernel(np.ascontiguousarray(xn, np.float64), np.ascontiguousarray(yn, np.float64),
                           float(camera.position_x), float(self.distance_m), hub_x, hub_y, angles,
                           int(self.blades), float(self.blade_fraction), float(self.hub_radius_m),
                           float(self.radius_m), 0.5 * float(self.post_width_m), float(self.post_level), float(sigma),
                           float(self.blade_level),
                           bg_i, bg_z, ALPHA_TRUTH_MIN, out_i, out_z)
        return out_i, out_z

    def describe(self) -> dict:
        return {"type": self.kind, **dataclasses.asdict(self), "center_view": list(self.center_view),
                "revolutions_per_s": self.revolutions_per_s,
                "truth": "every event of the fan carries its depth distance_m (ideal rig: f*B/distance_m - c)"}
