"""Surfaces of the generalization suite: procedural patterns and photos that ship with scikit-image.

A surface is a pair of (H, W) float32 arrays, linear intensity and coverage, at a texel size (metres per
texel), as in :mod:`cvstereo.simulate.textures`. Every source is brought to one scale: a *pattern* of zero mean
(unit standard deviation, or +-1 for the binary ones) sets the log intensity,
``intensity = level * exp(contrast * pattern)``, so that ``contrast`` is the spread of log intensity that a
DVS pixel answers to, whatever drew the pattern (a DVS fires per step of log intensity; a photo's own
exposure would otherwise decide how many events it gives).

Patterns: :data:`PROCEDURAL` (noise at several scales, blobs, a nearly plain finish, and the periodic
:data:`PERIODIC` ones that make stereo ambiguous) and :data:`PHOTOS`, the photos of ``skimage.data`` that the
scikit-image wheel carries (no download). The Middlebury motorcycle pair, which the motorcycle scene uses, is
not one of them: the generalization suite must not show the matchers a scene they were tuned on.
"""

from __future__ import annotations

import functools

import cv2
import numpy as np

from cvstereo.simulate import textures

__all__ = ["PERIODIC", "PHOTOS", "PROCEDURAL", "noise", "pattern", "photo", "photo_patch", "surface"]

#: Photos of ``skimage.data`` in the scikit-image wheel (loading them needs no network).
PHOTOS = ("astronaut", "brick", "camera", "cell", "chelsea", "clock", "coffee", "coins", "grass", "gravel",
          "hubble_deep_field", "immunohistochemistry", "moon", "page", "retina", "rocket", "text")

#: Patterns that repeat with a period (``period_m``): the ambiguous case of stereo.
PERIODIC = ("checker", "stripes", "grid", "dots")

#: Procedural patterns: ``noise`` (three scales), ``fine-noise``, ``blobs`` (patches with edges), ``plain``
#: (a surface with hardly any texture: a painted wall), and :data:`PERIODIC`.
PROCEDURAL = ("noise", "fine-noise", "blobs", "plain", *PERIODIC)

#: Added to linear luminance before a photo's log is taken, as the sensor's dark level does.
_PHOTO_DARK = 0.01

#: Lowest linear intensity of a surface: keeps the log response finite in the darkest texels.
_MIN_INTENSITY = 0.01


@functools.lru_cache(maxsize=4)
def photo(name: str) -> np.ndarray:
    """A photo of ``skimage.data`` as a pattern: standardised log luminance, (H, W) float32 (read-only)."""
    if name not in PHOTOS:
        raise ValueError(f"unknown photo {name!r}; choose one of {', '.join(PHOTOS)}.")
    from skimage import data

    img = np.asarray(getattr(data, name)(), np.float32)
    if img.ndim == 3:  # sRGB to linear luminance (alpha, where a photo has one, dropped)
        lin = (img[..., :3] / 255) ** 2.2
        lum = lin @ np.array([0.2126, 0.7152, 0.0722], np.float32)
    else:
        lum = (img / (255 if img.max() > 1 else 1)) ** 2.2
    out = _standardised(np.log(lum + _PHOTO_DARK))
    out.flags.writeable = False
    return out


def _standardised(a: np.ndarray) -> np.ndarray:
    a = a.astype(np.float32)
    return (a - a.mean()) / (a.std() + 1e-9)


def photo_patch(name: str, rng: np.random.Generator, shape: tuple[int, int], *, grain: float = 1.0) -> np.ndarray:
    """A random crop of a photo with the aspect of ``shape`` (H, W), resampled to it and standardised.

    The crop spans 60-100 % of the largest one the photo allows, so that two surfaces from one photo rarely
    show the same part. It is resampled to ``shape / grain`` first (averaging, no aliasing), then cubically up
    to ``shape``: a photo pixel covers at least ``grain`` texels, as the noise patterns' finest features do.
    """
    img = photo(name)
    ph, pw = img.shape
    h, w = shape
    scale = min(pw / w, ph / h) * rng.uniform(0.6, 1.0)
    cw, ch = max(2, min(pw, round(w * scale))), max(2, min(ph, round(h * scale)))
    x0, y0 = int(rng.integers(0, pw - cw + 1)), int(rng.integers(0, ph - ch + 1))
    crop = np.ascontiguousarray(img[y0:y0 + ch, x0:x0 + cw])
    coarse = (max(2, min(cw, round(w / grain))), max(2, min(ch, round(h / grain))))
    if coarse != (cw, ch):
        crop = cv2.resize(crop, coarse, interpolation=cv2.INTER_AREA)
    return _standardised(cv2.resize(crop, (w, h), interpolation=cv2.INTER_CUBIC))


def noise(rng: np.random.Generator, shape: tuple[int, int], scale_texels: float) -> np.ndarray:
    """Band-limited noise, zero mean, unit standard deviation, features about ``scale_texels`` wide, (H, W).

    Coarse noise is drawn on a grid a third of its scale and resized up: a blur as wide as the features would
    cost that width per texel.
    """
    h, w = shape
    step = max(1, int(scale_texels / 3))
    small = rng.standard_normal((h // step + 3, w // step + 3)).astype(np.float32)
    small = cv2.GaussianBlur(small, (0, 0), max(scale_texels / step, 0.5), borderType=cv2.BORDER_REFLECT)
    if step > 1:
        small = cv2.resize(small, (small.shape[1] * step, small.shape[0] * step), interpolation=cv2.INTER_CUBIC)
    return _standardised(small[:h, :w])


def pattern(kind: str, rng: np.random.Generator, shape: tuple[int, int], texel_m: float, *,
            period_m: float | None = None, angle_deg: float = 0.0, grain: float = 1.0) -> np.ndarray:
    """A pattern of zero mean, (H, W) float32: a photo's crop or one of :data:`PROCEDURAL`.

    Parameters
    ----------
    kind : str
        One of :data:`PHOTOS` or :data:`PROCEDURAL`.
    rng : numpy.random.Generator
    shape : (H, W)
        Texels.
    texel_m : float
        Metres per texel (the periodic patterns' period is metric).
    period_m : float, keyword-only
        Period of a :data:`PERIODIC` pattern.
    angle_deg : float, keyword-only
        Stripes turned from vertical by this much.
    grain : float, keyword-only
        Texels per unit of the noise patterns' feature sizes (``noise``: 1, 3 and 9 units, ``fine-noise`` 0.6,
        ``blobs`` 5), and the fewest texels per photo pixel: the caller makes the unit metric, so that a finer
        sensor sees the same surface.
    """
    if kind in PHOTOS:
        return photo_patch(kind, rng, shape, grain=grain)
    if kind in ("noise", "fine-noise", "blobs", "plain"):
        scales = {"noise": (1.0, 3.0, 9.0), "fine-noise": (0.6,), "blobs": (5.0,)}.get(kind, (max(shape) / 6,))
        weights = rng.uniform(0.5, 1.0, len(scales))
        n = sum(wt * noise(rng, shape, sc * (grain if kind != "plain" else 1.0))
                for wt, sc in zip(weights, scales, strict=True))
        return _standardised(np.tanh(2.5 * n) if kind == "blobs" else n)
    if kind not in PERIODIC:
        raise ValueError(f"unknown surface {kind!r}; choose one of {', '.join(PROCEDURAL + PHOTOS)}.")
    if not period_m or period_m <= 0:
        raise ValueError(f"surface {kind!r} repeats: give it a positive period_m, got {period_m}.")
    p = period_m / texel_m
    yy, xx = np.mgrid[0:shape[0], 0:shape[1]].astype(np.float32)
    phase = rng.uniform(0, p, 2).astype(np.float32)
    xx, yy = xx + phase[0], yy + phase[1]
    if kind == "stripes":
        a = np.deg2rad(angle_deg)
        return np.sign(np.sin(2 * np.pi * (xx * np.cos(a) + yy * np.sin(a)) / p)).astype(np.float32)
    fx, fy = (xx % p) / p, (yy % p) / p  # position within the period, [0, 1)
    if kind == "checker":
        return np.where((fx < 0.5) ^ (fy < 0.5), 1.0, -1.0).astype(np.float32)
    if kind == "grid":  # lines of a sixth of the period on a plain ground
        return np.where((fx < 1 / 6) | (fy < 1 / 6), 1.0, -1.0).astype(np.float32)
    return np.where(np.hypot(fx - 0.5, fy - 0.5) < 0.25, 1.0, -1.0).astype(np.float32)  # dots


def surface(kind: str, rng: np.random.Generator, size_m: tuple[float, float], texel_m: float, *, level: float,
            contrast: float, blur_texels: float, blur_y_texels: float | None = None, period_m: float | None = None,
            angle_deg: float = 0.0, grain: float = 1.0, border: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """An opaque rectangle of ``size_m`` (width, height) with a pattern: (intensity, alpha), (H, W) float32.

    Parameters
    ----------
    kind, period_m, angle_deg, grain
        The pattern (:func:`pattern`).
    level : float, keyword-only
        Linear intensity at the pattern's mean.
    contrast : float, keyword-only
        Standard deviation of the log intensity (of the pattern's +-1 steps for the binary ones).
    blur_texels, blur_y_texels : float, keyword-only
        The optics' blur (:func:`cvstereo.simulate.textures.blur`), along the rows as well where given.
    border : bool, keyword-only
        Pad with a transparent margin of three blur sigmas, so that the outline fades into what lies behind
        (an object); False: opaque to the edge (a wall larger than the view, a strip of a ground).
    """
    w, h = max(2, round(size_m[0] / texel_m)), max(2, round(size_m[1] / texel_m))
    value = level * np.exp(contrast * pattern(kind, rng, (h, w), texel_m, period_m=period_m, angle_deg=angle_deg,
                                              grain=grain))
    value = np.maximum(value, _MIN_INTENSITY).astype(np.float32)
    alpha = np.ones((h, w), np.float32)
    if not border:  # opaque to its edge (where planes meet, as a ground's strips, no background shows through)
        return cv2.GaussianBlur(value, (0, 0), blur_texels, sigmaY=blur_y_texels or 0,
                                borderType=cv2.BORDER_REFLECT), alpha
    m = max(2, int(np.ceil(3 * max(blur_texels, blur_y_texels or 0.0))))
    value, alpha = np.pad(value, m, mode="edge"), np.pad(alpha, m)
    return textures.blur(value, alpha, blur_texels, sigma_y_texels=blur_y_texels)
