"""The stereo rig and the sensors: geometry (pinhole, barrel distortion, misalignment) and DVS pixel parameters.

Coordinates
-----------
The rig frame has X to the right, Y down and Z forward (along both optical axes, which are parallel).
The left camera sits at ``X = -B/2``, the right one at ``X = +B/2``, so that a scene point has the larger
``x`` in the left camera (docs/formats.md) and the disparity ``d = x_left - x_right`` is positive.

A camera maps a point ``(X, Y, Z)`` of its own frame to raw sensor coordinates in three steps:

1. pinhole: ``xn = X / Z``, ``yn = Y / Z`` (undistorted, normalised);
2. radial (barrel) distortion: ``(xd, yd) = (xn, yn) * (1 + k1 * (xn**2 + yn**2))`` with ``k1 < 0``;
3. intrinsics: ``u = cx + f * xd``, ``v = cy + f * yd`` (pixel centres at integers, 0 = left / top).

The misalignment of the thesis' rig is modelled by the principal points: the left camera's lies ``c/2`` to
the left of the sensor centre and the right camera's ``c/2`` to the right, so that an undistorted rig gives
exactly ``d = f*B/Z - c``; this is the small-angle equivalent of optical axes that diverge by ``c / f``
radians. The right camera's principal point also lies ``dy`` rows lower than the left one's (the vertical
offset of about one row between the sensors).

Real uncalibrated rigs differ between their cameras in more ways, each a :class:`Rig` field that is neutral by
default: a roll (each sensor turned about its optical axis, by ``-/+roll_deg/2``: between steps 1 and 2 the
normalised coordinates are rotated, ``x`` towards ``y`` for a positive angle), a focal mismatch (the right
camera's focal length is ``focal_ratio`` times the left one's) and its own barrel distortion
(``right_distortion_k1``).

The true disparity of a scene point is ``x_left - x_right`` of where it lands in the two *recorded* (distorted,
misaligned) images, at sub-pixel precision. Where the two images put it on different rows (the vertical offset,
a roll), the disparity is still the difference of the columns alone: the row it lands on in the other camera
is not part of it (:meth:`Rig.project` gives both).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from cvstereo.geometry.rig import THESIS_RIG

__all__ = ["EDVS1_RIGHT", "EDVS2_LEFT", "MAX_ROLL_DEG", "SENSORS", "Camera", "Rig", "SensorModel"]

#: Fixed-point iterations that invert the radial distortion; 12 reach 1e-9 for |k1 * r^2| < 0.2.
_UNDISTORT_ITERATIONS = 12

#: A rig's cameras turned against each other by more than this (degrees) are not an accident of mounting.
MAX_ROLL_DEG = 10.0

#: The rig fields that differ between real uncalibrated cameras beyond the thesis' rig, at their neutral values.
_NEUTRAL_RIG = {"roll_deg": 0.0, "focal_ratio": 1.0, "right_distortion_k1": None}

#: Sensor sizes (width x height) the suites use: DVS128, DAVIS240, DAVIS346, a VGA event camera.
SENSORS = ("128x128", "240x180", "346x260", "640x480")


def _describe(obj, neutral: dict) -> dict:
    """``dataclasses.asdict(obj)`` without the fields that hold their ``neutral`` value.

    Fields added after recordings were first cached (hot pixels, roll, ...) are left out of a description while
    they do nothing, so that the meta and cache keys of recordings made before them stay exactly what they were.
    """
    d = dataclasses.asdict(obj)
    for name, value in neutral.items():
        if d[name] == value:
            del d[name]
    return d


@dataclass(frozen=True)
class SensorModel:
    """The pixel model of one DVS128: contrast thresholds, their mismatch, refractory period, noise, jitter.

    Parameters
    ----------
    on_threshold, off_threshold : float
        Mean log-intensity change that fires an ON / OFF event. A lower ON threshold makes ON events
        outnumber OFF events (thesis table 4.1: by 15-23 %).
    threshold_mismatch : float
        Standard deviation of the per-pixel thresholds, as a fraction of the mean (fixed-pattern mismatch).
    min_threshold : float
        Per-pixel thresholds are clipped below at this value, so that a badly mismatched pixel stays finite.
    refractory_us : float
        After an event a pixel ignores threshold crossings for this long (the crossed levels are consumed).
    noise_rate_hz : float
        Background-activity noise, Poisson, per pixel (events / s); noise events carry NaN ground truth.
    noise_on_fraction : float
        Share of noise events that are ON.
    jitter_us : float
        Standard deviation of the Gaussian timestamp jitter (readout latency) added to every event.
    hot_pixel_fraction : float
        Share of the pixels that are hot: each fires on its own, whatever it sees, at ``hot_pixel_rate_hz``
        (Poisson; ON with ``noise_on_fraction``, as leakage), beside the scene's events. Their events carry NaN
        truth. ``round(fraction * W * H)`` pixels, drawn per sensor.
    hot_pixel_rate_hz : float
        Events per second of each hot pixel.
    """

    on_threshold: float = 0.25
    off_threshold: float = 0.30
    threshold_mismatch: float = 0.08
    min_threshold: float = 0.05
    refractory_us: float = 100.0
    noise_rate_hz: float = 0.05
    # Background activity of a DVS is mostly ON (junction leakage slowly raises the pixel's level).
    noise_on_fraction: float = 0.6
    jitter_us: float = 30.0
    hot_pixel_fraction: float = 0.0
    hot_pixel_rate_hz: float = 0.0

    def __post_init__(self):
        for name in ("on_threshold", "off_threshold", "min_threshold"):
            if not getattr(self, name) > 0:
                raise ValueError(f"SensorModel.{name} must be positive, got {getattr(self, name)}.")
        for name in ("threshold_mismatch", "refractory_us", "noise_rate_hz", "jitter_us", "hot_pixel_rate_hz"):
            if getattr(self, name) < 0:
                raise ValueError(f"SensorModel.{name} must be >= 0, got {getattr(self, name)}.")
        for name in ("noise_on_fraction", "hot_pixel_fraction"):
            if not 0 <= getattr(self, name) <= 1:
                raise ValueError(f"SensorModel.{name} must lie in [0, 1], got {getattr(self, name)}.")

    def ideal(self) -> SensorModel:
        """The same thresholds without mismatch, refractory period, noise, hot pixels or jitter (for tests)."""
        return dataclasses.replace(self, threshold_mismatch=0.0, refractory_us=0.0, noise_rate_hz=0.0,
                                   jitter_us=0.0, hot_pixel_fraction=0.0)

    def describe(self) -> dict:
        """JSON-serialisable fields (hot pixels only when there are any)."""
        return _describe(self, {"hot_pixel_fraction": 0.0, "hot_pixel_rate_hz": 0.0})


# The thesis' eDVS2 (our left camera) gives 23 % more ON than OFF events and the fewer events; eDVS1 (our
# right camera) 15 % more ON than OFF and 7-28 % more events in all (table 4.1). ON/OFF ratios follow the
# threshold ratio (a little less: noise and the shirt's weak edges dilute it), so the ratios are set a few
# per cent above the thesis'; the right camera's lower thresholds make it the busier one. Tuned with
# bench/bench_simulate.py against table 4.1.
#: The thesis' eDVS2, our left camera.
EDVS2_LEFT = SensorModel(on_threshold=0.245, off_threshold=0.305, noise_rate_hz=0.05)
#: The thesis' eDVS1, our right camera (the busier one).
EDVS1_RIGHT = SensorModel(on_threshold=0.23, off_threshold=0.272, noise_rate_hz=0.06)


@dataclass(frozen=True)
class Camera:
    """One camera of a rig: intrinsics, distortion, roll, position, and the rays of its raw pixels.

    Build it with :meth:`Rig.camera`; the fields are derived from the rig.

    Parameters
    ----------
    index : int
        0 = left, 1 = right.
    focal_px, cx, cy, k1 : float
        Focal length, principal point (raw pixels), radial distortion coefficient.
    position_x : float
        X of the optical centre in the rig frame (metres).
    resolution : (width, height)
    roll_rad : float
        The sensor's turn about the optical axis: normalised coordinates are rotated by it (``x`` towards ``y``)
        before the distortion.
    """

    index: int
    focal_px: float
    cx: float
    cy: float
    k1: float
    position_x: float
    resolution: tuple[int, int]
    roll_rad: float = 0.0
    _rays: tuple[np.ndarray, np.ndarray] = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        w, h = self.resolution
        v, u = np.mgrid[0:h, 0:w].astype(np.float64)
        object.__setattr__(self, "_rays", self.undistort_pixels(u, v))

    @property
    def rays(self) -> tuple[np.ndarray, np.ndarray]:
        """Undistorted normalised ray coordinates ``(xn, yn)`` of every raw pixel centre, each (H, W)."""
        return self._rays

    @staticmethod
    def _turn(x, y, angle: float):
        """``(x, y)`` rotated by ``angle`` radians, ``x`` towards ``y`` (unchanged at 0: no rounding either)."""
        if angle == 0.0:
            return x, y
        c, s = np.cos(angle), np.sin(angle)
        return c * x - s * y, s * x + c * y

    def distort(self, xn: np.ndarray, yn: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Raw pixel coordinates ``(u, v)`` of undistorted normalised coordinates (same shapes)."""
        xn, yn = self._turn(xn, yn, self.roll_rad)
        g = 1.0 + self.k1 * (xn * xn + yn * yn)
        return self.cx + self.focal_px * xn * g, self.cy + self.focal_px * yn * g

    def undistort_pixels(self, u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Undistorted normalised coordinates ``(xn, yn)`` of raw pixel coordinates (same shapes)."""
        xd = (np.asarray(u, np.float64) - self.cx) / self.focal_px
        yd = (np.asarray(v, np.float64) - self.cy) / self.focal_px
        xn, yn = xd, yd
        for _ in range(_UNDISTORT_ITERATIONS):
            g = 1.0 + self.k1 * (xn * xn + yn * yn)
            xn, yn = xd / g, yd / g
        return self._turn(xn, yn, -self.roll_rad)


@dataclass(frozen=True)
class Rig:
    """Two DVS128 side by side with parallel optical axes: by default the thesis rig
    (:data:`cvstereo.geometry.rig.THESIS_RIG`: baseline, focal length, axis offset, resolution).

    Parameters
    ----------
    baseline_m : float
        Distance B between the optical centres.
    focal_px : float
        Focal length f in pixels (both cameras).
    axis_offset_px : float
        The offset c of d = f*B/Z - c, from optical axes that are not exactly parallel (see module doc).
    vertical_offset_px : float
        How many rows lower the right camera sees a scene point than the left one (about one row).
    distortion_k1 : float
        Radial distortion coefficient of both lenses; negative = barrel. -0.08 moves the sensor corners
        about 2 px towards the centre ("slight barrel distortion", thesis 3.2).
    resolution : (width, height)
    left, right : SensorModel
        The pixel models of the left (thesis: eDVS2) and right (eDVS1) sensors.
    time_offset_us : float
        How much later the right camera stamps the same change than the left one (its clock runs behind):
        ``t_right = t_left + time_offset_us``, the convention of :mod:`cvstereo.rigcheck`. Negative: the right
        camera stamps early. Events whose stamp falls outside the recording are lost, as with a real late start.
    roll_deg : float
        How much the right sensor is turned against the left one about the optical axis (each by half, in
        opposite senses; positive: the right image turns from x towards y, i.e. clockwise on screen).
    focal_ratio : float
        The right camera's focal length over the left one's (a focal mismatch; the left one has ``focal_px``).
    right_distortion_k1 : float or None
        The right lens' own distortion coefficient; None: ``distortion_k1``, as the left one.
    """

    baseline_m: float = THESIS_RIG.baseline_m
    focal_px: float = THESIS_RIG.focal_px
    axis_offset_px: float = THESIS_RIG.axis_offset_px
    vertical_offset_px: float = 1.0
    distortion_k1: float = -0.08
    resolution: tuple[int, int] = THESIS_RIG.resolution
    left: SensorModel = EDVS2_LEFT
    right: SensorModel = EDVS1_RIGHT
    time_offset_us: float = 0.0
    roll_deg: float = 0.0
    focal_ratio: float = 1.0
    right_distortion_k1: float | None = None

    def __post_init__(self):
        object.__setattr__(self, "resolution", (int(self.resolution[0]), int(self.resolution[1])))
        for name in ("time_offset_us", "roll_deg"):
            if not np.isfinite(getattr(self, name)):
                raise ValueError(f"Rig.{name} must be finite, got {getattr(self, name)}.")
        if abs(self.roll_deg) > MAX_ROLL_DEG:
            raise ValueError(f"Rig.roll_deg must lie within +-{MAX_ROLL_DEG:g} (a rig mounted on purpose), "
                             f"got {self.roll_deg}.")
        if self.baseline_m < 0:
            raise ValueError(f"Rig.baseline_m must be >= 0, got {self.baseline_m}.")
        if not self.focal_px > 0:
            raise ValueError(f"Rig.focal_px must be positive, got {self.focal_px}.")
        if not 0.5 <= self.focal_ratio <= 2.0:
            raise ValueError(f"Rig.focal_ratio must lie in [0.5, 2] (the right focal length over the left one), "
                             f"got {self.focal_ratio}.")
        w, h = self.resolution
        if w < 2 or h < 2:
            raise ValueError(f"Rig.resolution must be at least 2x2, got {w}x{h}.")
        for index in (0, 1):
            name = "distortion_k1" if index == 0 or self.right_distortion_k1 is None else "right_distortion_k1"
            k1, focal = getattr(self, name), self.focal_px * (self.focal_ratio if index else 1.0)
            corner_r2 = ((w / 2) ** 2 + (h / 2) ** 2) / focal**2
            if not -0.2 < k1 * corner_r2 < 0.2:
                raise ValueError(
                    f"Rig.{name}={k1} distorts the sensor corners by more than 20 %; "
                    f"the model is meant for slight distortion (|k1| < {0.2 / corner_r2:.2f} at f={focal:g})."
                )

    def ideal(self) -> Rig:
        """The same rig without distortion, axis or vertical offset, roll or focal mismatch."""
        return dataclasses.replace(self, axis_offset_px=0.0, vertical_offset_px=0.0, distortion_k1=0.0,
                                   roll_deg=0.0, focal_ratio=1.0, right_distortion_k1=None)

    def for_sensor(self, resolution: tuple[int, int]) -> Rig:
        """The same optics on a sensor of another size: the view angle stays, so everything in pixels scales.

        Focal length, axis offset and vertical offset scale with the width (``resolution[0] / width``): the
        same lens on a sensor with more pixels across, so disparities in pixels (hence the disparity range a
        matcher needs, e.g. ``round(64 * width / 128)``) scale by the same factor. ``k1`` stays (it acts on
        normalised coordinates).
        """
        scale = int(resolution[0]) / self.resolution[0]
        return dataclasses.replace(self, resolution=(int(resolution[0]), int(resolution[1])),
                                   focal_px=self.focal_px * scale, axis_offset_px=self.axis_offset_px * scale,
                                   vertical_offset_px=self.vertical_offset_px * scale)

    def sensor(self, index: int) -> SensorModel:
        """The sensor model of camera 0 (left) or 1 (right)."""
        return self.left if index == 0 else self.right

    def camera(self, index: int) -> Camera:
        """Camera 0 (left) or 1 (right)."""
        if index not in (0, 1):
            raise ValueError(f"camera index must be 0 (left) or 1 (right), got {index}.")
        w, h = self.resolution
        side = -1.0 if index == 0 else 1.0
        right_k1 = self.distortion_k1 if self.right_distortion_k1 is None else self.right_distortion_k1
        return Camera(
            index=index,
            focal_px=self.focal_px if index == 0 else self.focal_px * self.focal_ratio,
            cx=(w - 1) / 2 + side * self.axis_offset_px / 2,
            cy=(h - 1) / 2 + side * self.vertical_offset_px / 2,
            k1=self.distortion_k1 if index == 0 else right_k1,
            position_x=side * self.baseline_m / 2,
            resolution=self.resolution,
            roll_rad=float(np.deg2rad(side * self.roll_deg / 2)),
        )

    def project(self, index: int, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Raw pixel coordinates ``(u, v)`` in camera ``index`` of points ``(X, Y, Z)`` of the rig frame, (N, 3).

        The exact forward model (pinhole, roll, distortion, intrinsics) that the renderer inverts.
        """
        camera = self.camera(index)
        p = np.asarray(points, np.float64).reshape(-1, 3)
        return camera.distort((p[:, 0] - camera.position_x) / p[:, 2], p[:, 1] / p[:, 2])

    def disparity_from_depth(self, index: int, x: np.ndarray, y: np.ndarray, z: np.ndarray) -> np.ndarray:
        """True disparity of the scene points seen at raw pixels of one camera, from their depth.

        The point seen at pixel ``(x, y)`` of camera ``index`` at depth ``z`` (rig frame, along the optical
        axis) is projected into the other camera; the result is ``x_left - x_right`` in raw coordinates.

        Parameters
        ----------
        index : int
            Camera that saw the points, 0 = left, 1 = right.
        x, y : (N,) array_like
            Raw pixel coordinates in that camera.
        z : (N,) array_like
            Depth in metres; NaN gives NaN, inf gives the disparity of a point at infinity (``-c``).

        Returns
        -------
        (N,) float64 ndarray
        """
        own, other = self.camera(index), self.camera(1 - index)
        xn, yn = own.undistort_pixels(x, y)
        with np.errstate(divide="ignore", invalid="ignore"):
            shift = (own.position_x - other.position_x) / np.asarray(z, np.float64)
        shift = np.where(np.isinf(np.asarray(z, np.float64)), 0.0, shift)
        u_other, _ = other.distort(xn + shift, yn)
        x = np.asarray(x, np.float64)
        return x - u_other if index == 0 else u_other - x

    def right_row_shift(self) -> np.ndarray:
        """The rows to add to each right-camera pixel's y to reach the left camera's row of the same ray (a
        point at infinity), (H, W) float64: the vertical misalignment a whole-image row offset can only
        approximate. ``-vertical_offset_px`` everywhere on a rig without roll, focal mismatch or distortion; a roll
        makes it grow along x, a focal mismatch along y, different lenses towards the corners. A nearer point
        moves along x only, so its row differs from this by the roll's and the distortion's cross terms alone.
        """
        w, h = self.resolution
        right, left = self.camera(1), self.camera(0)
        v, u = np.mgrid[0:h, 0:w].astype(np.float64)
        _, v_left = left.distort(*right.undistort_pixels(u, v))
        return v_left - v

    def describe(self) -> dict:
        """JSON-serialisable description for a recording's meta (roll, focal ratio and the right lens' own
        distortion only where they are set)."""
        d = _describe(self, _NEUTRAL_RIG)
        d["resolution"] = list(self.resolution)
        d.pop("left"), d.pop("right")
        d["left_sensor"], d["right_sensor"] = self.left.describe(), self.right.describe()
        d["model"] = ("pinhole, radial distortion (xd = xn*(1+k1*r^2)), principal points shifted by "
                      "-/+axis_offset_px/2 and -/+vertical_offset_px/2 (left/right); d = f*B/Z - c undistorted")
        if set(d) & set(_NEUTRAL_RIG):
            d["model"] += ("; roll -/+roll_deg/2 before the distortion, right focal length focal_px*focal_ratio, "
                           "right lens right_distortion_k1")
        return d
