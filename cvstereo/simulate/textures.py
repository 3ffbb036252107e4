"""Procedural textures in metric units: arms (sleeve and hand), walls, objects, test targets.

Every texture is a pair of (H, W) float32 arrays, linear intensity and coverage (alpha), drawn at a given
texel size (metres per texel) and blurred by the optics: a Gaussian of :data:`OPTICS_BLUR_PX` sensor pixels
at the distance the texture will be seen from, so that sampling it at the pixel centres does not alias.
"""

from __future__ import annotations

import cv2
import numpy as np

__all__ = ["NATURAL_IMAGES", "NATURAL_PIXEL_M", "OPTICS_BLUR_PX", "SLEEVE_PATTERNS", "arm", "blur", "checkerboard",
           "dot", "natural_patch", "panel", "sleeve_pattern", "smooth_noise", "texel_size", "wall"]

#: Standard deviation of the lens blur plus pixel area, in sensor pixels. About half a pixel makes a
#: silhouette cross a pixel over two render steps or more, so that event timestamps follow the edge.
OPTICS_BLUR_PX = 0.6

#: Patterns of the arm's sleeve (:func:`arm`).
SLEEVE_PATTERNS = ("checks", "stripes", "checker", "natural")

#: Photos of scikit-image's data that ``natural`` sleeves take a patch from (shipped with it, no download).
NATURAL_IMAGES = ("camera", "grass", "gravel", "brick", "coins", "moon")

#: Metres per photo pixel on a ``natural`` sleeve (a 512-pixel photo spans 1 m).
NATURAL_PIXEL_M = 0.002


def texel_size(distance_m: float, focal_px: float, *, texels_per_pixel: float = 2.0) -> float:
    """Metres per texel for a texture seen from ``distance_m``: ``texels_per_pixel`` texels per sensor pixel."""
    return distance_m / focal_px / texels_per_pixel


def blur(intensity: np.ndarray, alpha: np.ndarray, sigma_texels: float, *,
         sigma_y_texels: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Blur a texture with coverage: premultiplied, so that edges fade into what lies behind, not into black.

    Parameters
    ----------
    intensity, alpha : (H, W) float32 ndarray
    sigma_texels : float
    sigma_y_texels : float or None, keyword-only
        Another sigma along the rows (a surface seen at a grazing angle, whose pixels' footprints are longer
        in depth than across); None: ``sigma_texels``.

    Returns
    -------
    intensity, alpha : (H, W) float32 ndarray
    """
    if sigma_texels <= 0:
        return intensity.astype(np.float32), alpha.astype(np.float32)
    sigma_y = 0 if sigma_y_texels is None else sigma_y_texels  # 0: OpenCV takes sigma_texels
    pre = cv2.GaussianBlur((intensity * alpha).astype(np.float32), (0, 0), sigma_texels, sigmaY=sigma_y,
                           borderType=cv2.BORDER_CONSTANT)
    a = cv2.GaussianBlur(alpha.astype(np.float32), (0, 0), sigma_texels, sigmaY=sigma_y,
                         borderType=cv2.BORDER_CONSTANT)
    with np.errstate(invalid="ignore", divide="ignore"):
        out = np.where(a > 1e-6, pre / np.maximum(a, 1e-6), 0.0)
    return out.astype(np.float32), np.clip(a, 0.0, 1.0).astype(np.float32)


def smooth_noise(rng: np.random.Generator, shape: tuple[int, int], scale_texels: float) -> np.ndarray:
    """Band-limited noise, zero mean, unit standard deviation, features about ``scale_texels`` wide."""
    n = rng.standard_normal(shape).astype(np.float32)
    n = cv2.GaussianBlur(n, (0, 0), max(scale_texels, 0.5), borderType=cv2.BORDER_REFLECT)
    return (n - n.mean()) / (n.std() + 1e-9)


def arm(rng: np.random.Generator, texel_m: float, *, sleeve_contrast: float = 0.35, sleeve_level: float = 0.30,
        skin_level: float = 0.65, length_m: float = 1.1, pattern: str = "checks",
        blur_texels: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """A raised forearm and hand, fingers up, seen from the palm side: (intensity, alpha).

    The texture's top row is just above the fingertips; the sleeve (a checked shirt, shaded like a
    cylinder) runs down to ``length_m`` below, beyond the bottom of the view at the thesis' distances.

    Parameters
    ----------
    rng : numpy.random.Generator
        Pattern phases and colours, skin blotches.
    texel_m : float
        Metres per texel.
    sleeve_contrast : float
        Relative amplitude of the shirt's pattern; sets how many events the sleeve gives.
    sleeve_level, skin_level : float
        Mean linear intensities of sleeve and skin.
    length_m : float
    pattern : str
        One of :data:`SLEEVE_PATTERNS`: ``checks`` a soft plaid (two square waves of 28 mm crossing);
        ``stripes`` vertical stripes of 28 mm (one period: stereo's repetitive case); ``checker`` a hard
        checkerboard of 14 mm squares; ``natural`` a patch of one of :data:`NATURAL_IMAGES`. All have the
        plaid's standard deviation, so ``sleeve_contrast`` means the same.
    blur_texels : float
        Optical blur (texels).

    Returns
    -------
    intensity, alpha : (H, W) float32 ndarray
        About 0.17 m wide and ``length_m`` tall.
    """
    width_m = 0.17
    w, h = round(width_m / texel_m) | 1, round(length_m / texel_m) | 1
    alpha = np.zeros((h, w), np.float32)
    value = np.zeros((h, w), np.float32)

    def px(x_m, y_m):  # metric (x from the centre line, y down from the top) -> texel coordinates
        return round(x_m / texel_m + (w - 1) / 2), round(y_m / texel_m)

    def r(m):
        return max(1, round(m / texel_m))

    skin = np.zeros((h, w), np.uint8)
    # fingers (index to little finger), palm, thumb, wrist
    for x_m, top_m in ((-0.028, 0.022), (-0.009, 0.012), (0.010, 0.016), (0.028, 0.034)):
        cv2.line(skin, px(x_m, top_m), px(x_m * 0.9, 0.11), 255, r(0.017), cv2.LINE_AA)
        cv2.circle(skin, px(x_m, top_m), r(0.0085), 255, -1, cv2.LINE_AA)
    cv2.ellipse(skin, px(0.0, 0.135), (r(0.045), r(0.055)), 0, 0, 360, 255, -1, cv2.LINE_AA)
    cv2.line(skin, px(-0.04, 0.15), px(-0.072, 0.085), 255, r(0.022), cv2.LINE_AA)
    cv2.rectangle(skin, px(-0.03, 0.15), px(0.03, 0.215), 255, -1, cv2.LINE_AA)
    skin_a = skin.astype(np.float32) / 255
    blotch = smooth_noise(rng, (h, w), 0.01 / texel_m)
    value += skin_a * skin_level * (1 + 0.06 * blotch)
    alpha = np.maximum(alpha, skin_a)

    sleeve = np.zeros((h, w), np.uint8)
    half = 0.052
    cv2.rectangle(sleeve, px(-half, 0.205), px(half, length_m), 255, -1, cv2.LINE_AA)
    sleeve_a = sleeve.astype(np.float32) / 255
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32) * texel_m
    xx -= (w - 1) / 2 * texel_m
    phase = rng.uniform(0, 2 * np.pi, 2)
    checks = sleeve_pattern(pattern, xx, yy, phase, texel_m)
    folds = smooth_noise(rng, (h, w), 0.02 / texel_m)
    # cylinder shading across the sleeve: a lit centre line, darker flanks
    shade = 0.75 + 0.25 * np.cos(np.clip(xx / half, -1, 1) * np.pi / 2)
    sleeve_v = sleeve_level * shade * (1 + sleeve_contrast * checks) * (1 + 0.08 * folds)
    value = value * (1 - sleeve_a) + sleeve_v * sleeve_a
    alpha = np.maximum(alpha, sleeve_a)
    return blur(np.clip(value, 0.0, None), alpha, blur_texels)


def sleeve_pattern(pattern: str, xx: np.ndarray, yy: np.ndarray, phase: np.ndarray, texel_m: float) -> np.ndarray:
    """A shirt's pattern around zero, at metric coordinates ``xx``, ``yy`` (H, W), phases ``phase`` (2,).

    See :func:`arm`. The phases (drawn by the caller for every pattern, so that the random stream after
    them does not depend on the pattern) shift the pattern, and pick the photo and patch for ``natural``.
    """
    period = 0.028
    sx = np.tanh(3 * np.sin(2 * np.pi * xx / period + phase[0]))
    sy = np.tanh(3 * np.sin(2 * np.pi * yy / period + phase[1]))
    checks = (sx + sy) / 2  # the presets' plaid: two softened square waves crossing
    if pattern == "checks":
        return checks
    if pattern == "stripes":
        out = sx
    elif pattern == "checker":
        out = np.tanh(3 * np.sin(np.pi * xx / period + phase[0])) * np.tanh(3 * np.sin(np.pi * yy / period + phase[1]))
    elif pattern == "natural":
        out = natural_patch(xx, yy, phase, texel_m)
    else:
        raise ValueError(f"unknown sleeve pattern {pattern!r}; choose one of {', '.join(SLEEVE_PATTERNS)}.")
    out = out - out.mean()
    return (out * (checks.std() / max(float(out.std()), 1e-9))).astype(np.float32)


def natural_patch(xx: np.ndarray, yy: np.ndarray, phase: np.ndarray, texel_m: float) -> np.ndarray:
    """A patch of a scikit-image photo, :data:`NATURAL_PIXEL_M` metres per photo pixel, sampled at ``xx``, ``yy``.

    ``phase[0]`` picks the photo, ``phase[1]`` where the patch starts; the photo is mirrored at its borders.
    """
    from skimage import data

    name = NATURAL_IMAGES[int(phase[0] / (2 * np.pi) * len(NATURAL_IMAGES)) % len(NATURAL_IMAGES)]
    img = getattr(data, name)().astype(np.float32)
    if img.ndim == 3:
        img = img.mean(axis=2)
    img = ((img / 255) ** 2.2).astype(np.float32)  # sRGB to linear
    # smooth to the texel size first when texels are coarser than the photo's pixels (no aliasing)
    if texel_m > NATURAL_PIXEL_M:
        img = cv2.GaussianBlur(img, (0, 0), 0.5 * texel_m / NATURAL_PIXEL_M, borderType=cv2.BORDER_REFLECT)
    start = phase[1] / (2 * np.pi) * img.shape[1]
    map_x = (xx - xx.min()) / NATURAL_PIXEL_M + start
    map_y = (yy - yy.min()) / NATURAL_PIXEL_M
    return cv2.remap(img, map_x.astype(np.float32), map_y.astype(np.float32), cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_REFLECT_101)


def wall(rng: np.random.Generator, size_m: tuple[float, float], texel_m: float, *, level: float = 0.55,
         contrast: float = 0.25, posters: int = 6, blur_texels: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """A painted wall with a few posters and frames: opaque, (intensity, alpha) of ``size_m`` = (width, height)."""
    w, h = round(size_m[0] / texel_m) | 1, round(size_m[1] / texel_m) | 1
    value = level * (1 + 0.5 * contrast * smooth_noise(rng, (h, w), 0.1 / texel_m))
    for _ in range(posters):
        pw, ph = rng.uniform(0.1, 0.35) * size_m[0], rng.uniform(0.1, 0.35) * size_m[1]
        x0, y0 = rng.uniform(0, size_m[0] - pw), rng.uniform(0, size_m[1] - ph)
        sl = (slice(round(y0 / texel_m), round((y0 + ph) / texel_m)),
              slice(round(x0 / texel_m), round((x0 + pw) / texel_m)))
        patch_shape = value[sl].shape
        poster = level * (1 + contrast * rng.uniform(-2, 2)) * (
            1 + contrast * smooth_noise(rng, patch_shape, rng.uniform(0.01, 0.05) / texel_m))
        value[sl] = poster
    return blur(np.clip(value, 0.02, None).astype(np.float32), np.ones((h, w), np.float32), blur_texels)


def panel(rng: np.random.Generator, size_m: tuple[float, float], texel_m: float, *, level: float = 0.5,
          contrast: float = 0.5, blur_texels: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """A textured object face (a box side, a cabinet, a plant pot): opaque with a soft outline."""
    w, h = round(size_m[0] / texel_m) | 1, round(size_m[1] / texel_m) | 1
    value = level * (1 + contrast * smooth_noise(rng, (h, w), rng.uniform(0.01, 0.04) / texel_m))
    alpha = np.zeros((h, w), np.float32)
    margin = max(2, round(3 * blur_texels))
    alpha[margin:-margin, margin:-margin] = 1.0
    return blur(np.clip(value, 0.02, None).astype(np.float32), alpha, blur_texels)


def checkerboard(size_m: tuple[float, float], texel_m: float, square_m: float, *, dark: float = 0.2,
                 bright: float = 0.8, blur_texels: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """An opaque checkerboard with squares of ``square_m`` (the test plane)."""
    w, h = round(size_m[0] / texel_m) | 1, round(size_m[1] / texel_m) | 1
    yy, xx = np.mgrid[0:h, 0:w]
    board = ((xx * texel_m // square_m + yy * texel_m // square_m) % 2).astype(np.float32)
    return blur(dark + (bright - dark) * board, np.ones((h, w), np.float32), blur_texels)


def dot(radius_m: float, texel_m: float, *, level: float = 1.0, blur_texels: float = 1.0):
    """A small bright disc on a transparent square (the test dot)."""
    n = 2 * round(3 * radius_m / texel_m + 4 * blur_texels) + 1
    alpha = np.zeros((n, n), np.float32)
    c = (n - 1) / 2
    yy, xx = np.mgrid[0:n, 0:n]
    alpha[np.hypot(xx - c, yy - c) <= radius_m / texel_m] = 1.0
    return blur(np.full((n, n), level, np.float32), alpha, blur_texels)
