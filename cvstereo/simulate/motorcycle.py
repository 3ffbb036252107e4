"""The Middlebury motorcycle scene: the view panning over the real stereo pair that scikit-image ships.

Its measured disparity map gives the ground truth, with real textures instead of drawn ones
(docs/evaluation.md, "Where the ground truth comes from").
"""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass

import cv2
import numpy as np

from cvstereo.simulate.motion import Motion
from cvstereo.simulate.render import render_image
from cvstereo.simulate.rig import Rig

__all__ = ["MotorcycleScene"]


@functools.lru_cache(maxsize=2)
def _motorcycle_images(scale: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Left/right linear intensity and left/right disparity (NaN unknown) at ``scale``, as float32 arrays.

    The disparity map of ``skimage.data.stereo_motorcycle`` belongs to the left view (``x_right = x_left - d``,
    full-size pixels, inf where unknown). Resampling the images by ``scale`` scales the disparities by the same
    factor; the right view's map is the left one forward-warped (the nearer point wins), NaN in holes.
    """
    from skimage import data

    left, right, disp = data.stereo_motorcycle()
    h, w = disp.shape
    size = (round(w * scale), round(h * scale))

    def gray(img):  # sRGB to linear luminance, then resampled by area (no aliasing)
        lin = (img.astype(np.float32) / 255) ** 2.2
        lum = lin @ np.array([0.2126, 0.7152, 0.0722], np.float32)
        return cv2.resize(lum, size, interpolation=cv2.INTER_AREA).astype(np.float32)

    d = np.where(np.isfinite(disp), disp, np.nan).astype(np.float32)
    d = cv2.resize(d, size, interpolation=cv2.INTER_NEAREST) * scale
    d_right = np.full_like(d, -np.inf)
    yy, xx = np.nonzero(np.isfinite(d))
    xr = np.rint(xx - d[yy, xx]).astype(int)
    ok = (xr >= 0) & (xr < size[0])
    np.maximum.at(d_right, (yy[ok], xr[ok]), d[yy[ok], xx[ok]])
    d_right[~np.isfinite(d_right)] = np.nan
    # Rounding the warped x leaves one-pixel cracks inside surfaces; fill those from the farther neighbour
    # (wider holes are real: parts of the scene the left camera does not see).
    crack = np.isnan(d_right[:, 1:-1]) & np.isfinite(d_right[:, :-2]) & np.isfinite(d_right[:, 2:])
    d_right[:, 1:-1][crack] = np.fmin(d_right[:, :-2], d_right[:, 2:])[crack]
    return gray(left), gray(right), d, d_right


@dataclass(frozen=True)
class MotorcycleScene:
    """The view panning over the Middlebury "motorcycle" stereo pair shipped with scikit-image.

    The left camera samples the left image and the right camera the right image (real texture, real
    occlusions), both through the rig's distortion and principal points. The images are resampled by
    ``scale`` sensor pixels per image pixel (the 741x500 pair at 0.5 gives a 370x250 scene, of which the
    128x128 sensor sees about a third), so disparities are the map's times ``scale``: 3.6-30 px at 0.5,
    median 19. The truth of an event is that map value at the pixel, carried through the rig's distortion and
    offsets like every other scene (as the depth ``f*B / (scale*d)`` of a rig with this focal length and
    baseline); inf (unknown) in the map gives NaN. Panning is a small rotation of the rig: the whole image
    shifts, sinusoidally in x and y.

    Parameters
    ----------
    scale : float
        Sensor pixels per image pixel.
    pan_period_s : (float, float)
        Periods of the x and y pan.
    pan_fraction : float
        Pan amplitude as a fraction of the room the image leaves around the view.
    seed : int
        Pan phases.
    """

    scale: float = 0.5
    # The real texture is dense: panning at about 25 px/s (peak) keeps the event rate near 300 k/s per
    # camera, below the eDVS' 1 M/s and comparable with the busiest thesis recording's bursts.
    pan_period_s: tuple[float, float] = (15.0, 11.0)
    pan_fraction: float = 0.5
    seed: int = 0
    kind = "motorcycle"

    def __post_init__(self):
        if not 0.2 <= self.scale <= 1.0:
            raise ValueError(f"MotorcycleScene.scale must lie in [0.2, 1.0] (the pair is 741x500), got {self.scale}.")

    def pan(self, rig: Rig, times_s: np.ndarray) -> np.ndarray:
        """(T, 2) image point seen by the principal ray of the left camera at each instant."""
        left, _, _, _ = _motorcycle_images(self.scale)
        h, w = left.shape
        rw, rh = rig.resolution
        margin_x, margin_y = 0.6 * rw + 4, 0.6 * rh + 4  # the half-view plus distortion and offsets
        if w < 2 * margin_x or h < 2 * margin_y:
            raise ValueError(f"the motorcycle image at scale {self.scale} ({w}x{h}) is smaller than the "
                             f"{rw}x{rh} view; raise --scale.")
        phase = np.random.default_rng([self.seed, 0x3C]).uniform(0, 2 * np.pi, 2)
        amp = self.pan_fraction * np.array([w / 2 - margin_x, h / 2 - margin_y])
        motion = Motion(((w - 1) / 2, (h - 1) / 2), terms=((0, amp[0], self.pan_period_s[0], phase[0]),
                                                           (1, amp[1], self.pan_period_s[1], phase[1])))
        return motion.position(times_s)

    def render(self, rig: Rig, index: int, times_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Intensity and depth, each (T, H, W) float32, of camera ``index`` at ``times_s`` (T,)."""
        if rig.baseline_m <= 0:
            raise ValueError("the motorcycle scene has its own baseline (its disparity map); give the rig a "
                             "positive baseline_m, which only encodes the map's disparities as depths.")
        images = _motorcycle_images(self.scale)
        image, disp = images[index], images[2 + index]
        with np.errstate(divide="ignore"):
            depth = (rig.focal_px * rig.baseline_m / disp).astype(np.float32)
        camera = rig.camera(index)  # its own focal length: the rig's focal_ratio scales the right one
        return render_image(camera.rays, camera.focal_px, image, depth, self.pan(rig, times_s))

    def describe(self) -> dict:
        return {"type": self.kind, **dataclasses.asdict(self), "source": "skimage.data.stereo_motorcycle",
                "disparity_scale": self.scale}
