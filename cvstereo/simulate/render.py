"""Rendering: intensity and depth of every raw pixel of one camera at a batch of instants.

Two renderers, both returning ``(intensity, depth)`` arrays of shape (T, H, W):

- :func:`render_planes` ray-casts textured planar rectangles (arms, walls, objects, test targets) through
  each raw pixel's undistorted ray; numba, one frame per thread.
- :func:`render_image` samples a real image through the rays, shifted by a pan (the motorcycle pair).

The depth is the Z of the surface point seen at the pixel, in the rig frame (metres along the optical axis),
so that :meth:`~cvstereo.simulate.rig.Rig.disparity_from_depth` turns it into the true disparity. It is the
depth of the nearest surface that covers at least :data:`ALPHA_TRUTH_MIN` of the pixel, NaN where none does.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numba import njit, prange

__all__ = ["ALPHA_TRUTH_MIN", "layer_hits", "render_image", "render_planes"]

#: A surface counts as "seen" at a pixel from this coverage on. Where everything else stands still, any
#: visible part of a moving surface is what changes the pixel: with the log response, a bright dot covering
#: 0.1 % of a pixel on a dark background still moves the level by 0.03, enough to fire the last OFF event of
#: a trailing edge. So the truth is the nearest surface with any coverage (the blur kernel ends at 4 sigma).
ALPHA_TRUTH_MIN = 1e-6

#: Compositing stops once less than this much light from further surfaces can reach the pixel.
_OPAQUE_REMAINDER = 1e-4


@njit(inline="always")
def _bilinear(img, layer, a, b):
    j = math.floor(a)
    i = math.floor(b)
    fa = a - j
    fb = b - i
    top = img[layer, i, j] * (1.0 - fa) + img[layer, i, j + 1] * fa
    bottom = img[layer, i + 1, j] * (1.0 - fa) + img[layer, i + 1, j + 1] * fa
    return top * (1.0 - fb) + bottom * fb


# fastmath without "nnan"/"ninf": the kernels test for NaN depth.
_FASTMATH = {"nsz", "arcp", "contract", "afn", "reassoc"}


@njit(inline="always", fastmath=_FASTMATH, error_model="numpy")
def _ray_direction(rot, rx, ry):
    """World direction of the camera ray through normalised image point (rx, ry): rot @ (rx, ry, 1)."""
    return (rot[0, 0] * rx + rot[0, 1] * ry + rot[0, 2], rot[1, 0] * rx + rot[1, 1] * ry + rot[1, 2],
            rot[2, 0] * rx + rot[2, 1] * ry + rot[2, 2])


@njit(inline="always", fastmath=_FASTMATH, error_model="numpy")
def _frame_geometry(k, rot, c, origins, u_axis, v_axis, texel, size):
    """Per frame and layer: screen bounding box, plane normal, origin - centre and normal . (origin - centre)."""
    n_layers = u_axis.shape[0]
    bbox = np.empty((n_layers, 4))
    normal = np.empty((n_layers, 3))
    rel = np.empty((n_layers, 3))
    num = np.empty(n_layers)
    for m in range(n_layers):
        normal[m, 0] = u_axis[m, 1] * v_axis[m, 2] - u_axis[m, 2] * v_axis[m, 1]
        normal[m, 1] = u_axis[m, 2] * v_axis[m, 0] - u_axis[m, 0] * v_axis[m, 2]
        normal[m, 2] = u_axis[m, 0] * v_axis[m, 1] - u_axis[m, 1] * v_axis[m, 0]
        for i in range(3):
            rel[m, i] = origins[k, m, i] - c[i]
        num[m] = normal[m, 0] * rel[m, 0] + normal[m, 1] * rel[m, 1] + normal[m, 2] * rel[m, 2]
        # A planar rectangle in front of the camera projects to a convex quadrilateral: its corners bound it
        # (in undistorted normalised coordinates, where the rays are).
        half_a = (size[m, 0] - 1) * 0.5 * texel[m]
        half_b = (size[m, 1] - 1) * 0.5 * texel[m]
        lo_x, hi_x, lo_y, hi_y = np.inf, -np.inf, np.inf, -np.inf
        behind = False
        for sa in (-1.0, 1.0):
            for sb in (-1.0, 1.0):
                p0 = rel[m, 0] + sa * half_a * u_axis[m, 0] + sb * half_b * v_axis[m, 0]
                p1 = rel[m, 1] + sa * half_a * u_axis[m, 1] + sb * half_b * v_axis[m, 1]
                p2 = rel[m, 2] + sa * half_a * u_axis[m, 2] + sb * half_b * v_axis[m, 2]
                qx = rot[0, 0] * p0 + rot[1, 0] * p1 + rot[2, 0] * p2  # camera frame = rot^T p
                qy = rot[0, 1] * p0 + rot[1, 1] * p1 + rot[2, 1] * p2
                qz = rot[0, 2] * p0 + rot[1, 2] * p1 + rot[2, 2] * p2
                if qz <= 1e-9:
                    behind = True
                else:
                    lo_x = min(lo_x, qx / qz)
                    hi_x = max(hi_x, qx / qz)
                    lo_y = min(lo_y, qy / qz)
                    hi_y = max(hi_y, qy / qz)
        if behind:
            lo_x, hi_x, lo_y, hi_y = -np.inf, np.inf, -np.inf, np.inf
        bbox[m, 0], bbox[m, 1], bbox[m, 2], bbox[m, 3] = lo_x, hi_x, lo_y, hi_y
    return bbox, normal, rel, num


@njit(inline="always", fastmath=_FASTMATH, error_model="numpy")
def _intersect(m, rx, ry, d0, d1, d2, bbox, normal, rel, num, u_axis, v_axis, texel, size, tex, alpha):
    """Ray (direction d, through normalised (rx, ry)) against layer m: (depth s, coverage, intensity)."""
    if rx < bbox[m, 0] or rx > bbox[m, 1] or ry < bbox[m, 2] or ry > bbox[m, 3]:
        return 0.0, 0.0, 0.0
    den = normal[m, 0] * d0 + normal[m, 1] * d1 + normal[m, 2] * d2
    if abs(den) < 1e-12:
        return 0.0, 0.0, 0.0
    s = num[m] / den
    if s <= 0.0:
        return 0.0, 0.0, 0.0
    r0 = s * d0 - rel[m, 0]
    r1 = s * d1 - rel[m, 1]
    r2 = s * d2 - rel[m, 2]
    a = (r0 * u_axis[m, 0] + r1 * u_axis[m, 1] + r2 * u_axis[m, 2]) / texel[m] + (size[m, 0] - 1) * 0.5
    b = (r0 * v_axis[m, 0] + r1 * v_axis[m, 1] + r2 * v_axis[m, 2]) / texel[m] + (size[m, 1] - 1) * 0.5
    if a < 0.0 or b < 0.0 or a >= size[m, 0] - 1 or b >= size[m, 1] - 1:
        return 0.0, 0.0, 0.0
    al = _bilinear(alpha, m, a, b)
    if al <= 0.0:
        return 0.0, 0.0, 0.0
    return s, al, _bilinear(tex, m, a, b)


@njit(parallel=True, cache=True, fastmath=_FASTMATH, error_model="numpy")
def _layer_hits_kernel(xn, yn, cam_pos, cam_rot, origins, u_axis, v_axis, texel, size, tex, alpha, out_s, out_a,
                       out_i):
    # Frame 0 only: depth, coverage and intensity of each layer at each pixel, (L, H, W) each.
    h, w = xn.shape
    rot = cam_rot[0]
    bbox, normal, rel, num = _frame_geometry(0, rot, cam_pos[0], origins, u_axis, v_axis, texel, size)
    for y in prange(h):
        for x in range(w):
            rx = xn[y, x]
            ry = yn[y, x]
            d0, d1, d2 = _ray_direction(rot, rx, ry)
            for m in range(u_axis.shape[0]):
                out_s[m, y, x], out_a[m, y, x], out_i[m, y, x] = _intersect(
                    m, rx, ry, d0, d1, d2, bbox, normal, rel, num, u_axis, v_axis, texel, size, tex, alpha)


@njit(parallel=True, cache=True, fastmath=_FASTMATH, error_model="numpy")
def _render_planes_kernel(xn, yn, cam_pos, cam_rot, origins, u_axis, v_axis, texel, size, tex, alpha, gain,
                          background, alpha_truth, static_s, static_a, static_i, still_i, still_z, out_i, out_z):
    n_frames = cam_pos.shape[0]
    h, w = xn.shape
    n_layers = u_axis.shape[0]
    n_static = static_s.shape[0]
    for k in prange(n_frames):
        rot = cam_rot[k]
        bbox, normal, rel, num = _frame_geometry(k, rot, cam_pos[k], origins, u_axis, v_axis, texel, size)
        hit_s = np.empty(n_layers + n_static)
        hit_a = np.empty(n_layers + n_static)
        hit_i = np.empty(n_layers + n_static)
        for y in range(h):
            for x in range(w):
                rx = xn[y, x]
                ry = yn[y, x]
                d0, d1, d2 = _ray_direction(rot, rx, ry)
                if still_i.shape[0]:
                    # Where no moving layer can reach, the pixel shows the pre-composited still layers.
                    reached = False
                    for m in range(n_layers):
                        if bbox[m, 0] <= rx <= bbox[m, 1] and bbox[m, 2] <= ry <= bbox[m, 3]:
                            reached = True
                            break
                    if not reached:
                        out_i[k, y, x] = still_i[y, x] * gain[k]
                        out_z[k, y, x] = still_z[y, x]
                        continue
                n_hits = 0
                for m in range(n_layers + n_static):
                    if m < n_static:  # pre-rendered layers that do not move
                        s, al, val = static_s[m, y, x], static_a[m, y, x], static_i[m, y, x]
                    else:
                        s, al, val = _intersect(m - n_static, rx, ry, d0, d1, d2, bbox, normal, rel, num, u_axis,
                                                v_axis, texel, size, tex, alpha)
                    if al <= 0.0:
                        continue
                    j = n_hits  # insertion, front to back
                    while j > 0 and hit_s[j - 1] > s:
                        hit_s[j] = hit_s[j - 1]
                        hit_a[j] = hit_a[j - 1]
                        hit_i[j] = hit_i[j - 1]
                        j -= 1
                    hit_s[j] = s
                    hit_a[j] = al
                    hit_i[j] = val
                    n_hits += 1
                acc = 0.0
                remaining = 1.0
                depth = np.nan
                for j in range(n_hits):
                    acc += remaining * hit_a[j] * hit_i[j]
                    if hit_a[j] >= alpha_truth and np.isnan(depth):
                        depth = hit_s[j]
                    remaining *= 1.0 - hit_a[j]
                    if remaining < _OPAQUE_REMAINDER:
                        break
                acc += remaining * background
                out_i[k, y, x] = acc * gain[k]
                out_z[k, y, x] = depth


def _layer_args(layers):
    xs = ("origins", "u_axis", "v_axis", "texel", "size", "tex", "alpha")
    return tuple(np.ascontiguousarray(layers[key], np.int64 if key == "size" else
                                      np.float32 if key in ("tex", "alpha") else np.float64) for key in xs)


def layer_hits(rays, cam_pos, cam_rot, layers):
    """Where the rays meet each layer at one instant: depth, coverage and intensity, each (L, H, W) float32.

    Parameters
    ----------
    rays : ((H, W) ndarray, (H, W) ndarray)
        Undistorted normalised ray coordinates ``(xn, yn)`` of the raw pixels.
    cam_pos : (3,) ndarray
    cam_rot : (3, 3) ndarray
    layers : dict
        As for :func:`render_planes`, with ``origins`` of shape (L, 3).

    Returns
    -------
    depth, coverage, intensity : (L, H, W) float32 ndarray
        Coverage 0 where a ray misses a layer.
    """
    xn, yn = rays
    n = len(layers["texel"])
    out = [np.zeros((n, *xn.shape), np.float32) for _ in range(3)]
    origins, *rest = _layer_args(layers)
    _layer_hits_kernel(np.ascontiguousarray(xn, np.float64), np.ascontiguousarray(yn, np.float64),
                       np.asarray(cam_pos, np.float64).reshape(1, 3), np.asarray(cam_rot, np.float64).reshape(1, 3, 3),
                       origins.reshape(1, n, 3), *rest, *out)
    return tuple(out)


def render_planes(rays, cam_pos, cam_rot, layers, *, gain, background, static=None):
    """Ray-cast textured rectangles for a batch of frames.

    Parameters
    ----------
    rays : ((H, W) ndarray, (H, W) ndarray)
        Undistorted normalised ray coordinates ``(xn, yn)`` of the raw pixels.
    cam_pos : (T, 3) ndarray
        Optical centre in the world at each frame.
    cam_rot : (T, 3, 3) ndarray
        Camera-to-world rotation at each frame (columns: camera X, Y, Z axes in the world).
    layers : dict
        The moving rectangles: ``origins`` (T, L, 3) world position of each centre at each frame;
        ``u_axis``, ``v_axis`` (L, 3) unit world directions of the texture's columns and rows; ``texel`` (L,)
        metres per texel; ``size`` (L, 2) texture width and height (textures are padded to a common shape);
        ``tex``, ``alpha`` (L, Hmax, Wmax) linear intensity and coverage.
    gain : (T,) ndarray, keyword-only
        Illumination factor applied to the whole frame.
    background : float, keyword-only
        Intensity where no surface is hit.
    static : (depth, coverage, intensity) or None, keyword-only
        Layers that do not move relative to the camera, pre-computed by :func:`layer_hits`.

    Returns
    -------
    intensity, depth : (T, H, W) float32 ndarray
    """
    xn, yn = rays
    n_frames = cam_pos.shape[0]
    out_i = np.empty((n_frames, *xn.shape), np.float32)
    out_z = np.empty((n_frames, *xn.shape), np.float32)
    xn, yn = np.ascontiguousarray(xn, np.float64), np.ascontiguousarray(yn, np.float64)
    none = np.zeros((0, 0), np.float64), np.zeros((0, 0), np.float32)
    still = none
    if static is None:
        static = tuple(np.zeros((0, *xn.shape), np.float32) for _ in range(3))
    elif len(layers["texel"]):
        # The still layers alone, composited once in float64 (as the kernel does per pixel): pixels that no
        # moving layer reaches copy it, bit for bit what the full composite would give.
        still_i, still_z = np.empty((1, *xn.shape), np.float64), np.empty((1, *xn.shape), np.float32)
        empty = {key: value[:0] for key, value in layers.items() if key != "origins"}
        empty["origins"] = np.zeros((1, 0, 3))
        _render_planes_kernel(xn, yn, np.ascontiguousarray(cam_pos[:1], np.float64),
                              np.ascontiguousarray(cam_rot[:1], np.float64), *_layer_args(empty), np.ones(1),
                              float(background), ALPHA_TRUTH_MIN, *static, *none, still_i, still_z)
        still = still_i[0], still_z[0]
    _render_planes_kernel(
        xn, yn, np.ascontiguousarray(cam_pos, np.float64), np.ascontiguousarray(cam_rot, np.float64),
        *_layer_args(layers), np.ascontiguousarray(gain, np.float64), float(background), ALPHA_TRUTH_MIN,
        *static, *still, out_i, out_z,
    )
    return out_i, out_z


#: cv2.remap takes maps of at most 32767 rows; frames are stacked into one map below that.
_REMAP_MAX_ROWS = 32000


def render_image(rays, focal_px, image, depth, pan):
    """Sample an image and its depth map through the rays of a camera, shifted by a pan.

    The ideal (undistorted) pixel ``f * (xn, yn)`` looks at image point ``f * (xn, yn) + pan``; the image
    is at sensor scale (one image pixel = one sensor pixel at the optical axis).

    Parameters
    ----------
    rays : ((H, W) ndarray, (H, W) ndarray)
        Undistorted normalised ray coordinates of the raw pixels.
    focal_px : float
    image : (Hi, Wi) float32 ndarray
        Linear intensity; sampled bilinearly, reflected at the border.
    depth : (Hi, Wi) float32 ndarray
        Depth of each image pixel, NaN where unknown; sampled at the nearest pixel (never blended across a
        depth edge), NaN outside the image.
    pan : (T, 2) ndarray
        Image coordinates ``(x, y)`` seen by the principal ray at each frame.

    Returns
    -------
    intensity, depth : (T, H, W) float32 ndarray
    """
    xn, yn = rays
    h, w = xn.shape
    pan = np.asarray(pan, np.float64)
    out_i = np.empty((pan.shape[0], h, w), np.float32)
    out_z = np.empty_like(out_i)
    step = max(1, _REMAP_MAX_ROWS // h)
    for lo in range(0, pan.shape[0], step):
        p = pan[lo:lo + step]
        map_x = (focal_px * xn[None] + p[:, 0, None, None]).astype(np.float32).reshape(-1, w)
        map_y = (focal_px * yn[None] + p[:, 1, None, None]).astype(np.float32).reshape(-1, w)
        out_i[lo:lo + step] = cv2.remap(image, map_x, map_y, cv2.INTER_LINEAR,
                                        borderMode=cv2.BORDER_REFLECT).reshape(-1, h, w)
        out_z[lo:lo + step] = cv2.remap(depth, map_x, map_y, cv2.INTER_NEAREST, borderMode=cv2.BORDER_CONSTANT,
                                        borderValue=float("nan")).reshape(-1, h, w)
    return out_i, out_z
