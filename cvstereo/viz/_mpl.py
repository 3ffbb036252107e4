"""matplotlib plumbing shared by the plots: the optional import, new figures, saving, sensor images, metres axes.

Figures are created as :class:`matplotlib.figure.Figure` objects, not through pyplot: nothing global is kept,
so a loop that makes hundreds of pictures neither leaks memory nor trips pyplot's "too many figures" warning.
They display in Jupyter as they are; in a script, save them with :func:`save_figure`.
"""

from __future__ import annotations

import os

import numpy as np

from cvstereo.depth import DepthModel
from cvstereo.errors import require_extra
from cvstereo.io._atomic import atomic_path

#: Colormap of disparities, the same map as the video's (OpenCV's COLORMAP_TURBO): a rainbow that, unlike the
#: thesis' Matlab "jet", has no false bands; pixels without a disparity are black (not the colour of 0 px).
DISPARITY_CMAP = "turbo"

#: Diverging colormap of signed frames: red = ON (positive), blue = OFF, as the thesis' fig. 3.3.
SIGNED_CMAP = "RdBu_r"

#: Resolution of saved pictures: sensor pixels of a 128x128 sensor come out several screen pixels wide.
DEFAULT_DPI = 120

#: Distances (m) labelled on metres axes where they fall in the plotted disparity range.
_NICE_METRES = (0.1, 0.15, 0.2, 0.25, 0.3, 0.4, 0.5, 0.6, 0.75, 1.0, 1.25, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 10.0,
                15.0, 20.0, 30.0, 50.0, 100.0)


def require_matplotlib():
    """Import matplotlib (the ``viz`` extra) or raise MissingExtraError naming the extra."""
    require_extra("matplotlib.pyplot", "viz")
    import matplotlib

    return matplotlib


def new_figure(width: float, height: float):
    """A new :class:`~matplotlib.figure.Figure` of ``width`` x ``height`` inches, laid out constrained."""
    require_matplotlib()
    from matplotlib.figure import Figure

    return Figure(figsize=(width, height), layout="constrained", dpi=DEFAULT_DPI)


def save_figure(fig, path: str | os.PathLike, *, dpi: float | None = None) -> None:
    """Write a figure to ``path`` atomically (temporary file, then rename); the format follows the extension.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
    path : path-like
        ``.png``, ``.pdf``, ``.svg``, ... (anything matplotlib writes).
    dpi : float, optional, keyword-only
        Default: the figure's.
    """
    fmt = os.path.splitext(os.fspath(path))[1].lstrip(".").lower() or "png"
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format=fmt, dpi=dpi if dpi is not None else "figure")


def cmap_with_background(name: str, background=(0.0, 0.0, 0.0)):
    """The named colormap with NaN (no data) drawn in ``background``."""
    from matplotlib import colormaps

    return colormaps[name].with_extremes(bad=background)


def show_sensor_image(ax, image: np.ndarray, *, title: str | None = None, **imshow_kw):
    """Draw a sensor image with pixel (x, y) centred on data coordinates (x, y), y = 0 at the top.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
    image : (H, W) or (H, W, 3) ndarray
    title : str, optional, keyword-only
    **imshow_kw
        Passed to :meth:`~matplotlib.axes.Axes.imshow` (cmap, norm, ...).

    Returns
    -------
    matplotlib.image.AxesImage
    """
    h, w = image.shape[:2]
    im = ax.imshow(image, origin="upper", interpolation="nearest", extent=(-0.5, w - 0.5, h - 0.5, -0.5),
                   **imshow_kw)
    ax.set_xlabel("x (px)")
    ax.set_ylabel("y (px)")
    if title:
        ax.set_title(title)
    return im


#: Metres ticks closer than this share of the axis (in disparity) are thinned out: distance is ~1/disparity, so
#: round distances crowd together at small disparities.
_MIN_TICK_GAP = 1 / 15


def metres_ticks(depth: DepthModel, d_lo: float, d_hi: float) -> list[float]:
    """Round distances (m) whose disparity lies within ``[d_lo, d_hi]`` px, at least 1/15 of the range apart.

    Examples
    --------
    >>> metres_ticks(DepthModel(a=16.5), 0.0, 40.0)
    [0.5, 0.6, 0.75, 1.0, 1.25, 2.0, 3.0, 10.0]
    """
    lo, hi = min(d_lo, d_hi), max(d_lo, d_hi)
    gap = (hi - lo) * _MIN_TICK_GAP
    kept: list[float] = []
    last = None
    # Nearest first (largest disparity), where the round distances are furthest apart.
    for z in _NICE_METRES:
        d = float(depth.disparity(z))
        if lo <= d <= hi and (last is None or last - d >= gap):
            kept.append(z)
            last = d
    return kept


def add_metres_axis(ax, depth: DepthModel, *, which: str = "y", location: str = "right"):
    """Add a secondary axis in metres to an axis in disparity px, through ``Z = a / (d + c)``.

    Call it after the disparity limits are final: the metres ticks are chosen for the current limits.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        An axes whose ``which`` axis is disparity in px.
    depth : DepthModel
    which : {"x", "y"}, keyword-only
    location : str, keyword-only
        Where the secondary axis goes ("right", "left", "top", "bottom").

    Returns
    -------
    matplotlib.axes.Axes
        The secondary axis.
    """
    # Disparities at or beyond infinity (d + c <= 0) map to a large but finite distance, so that matplotlib's
    # transforms stay finite; no tick is placed there.
    floor = 1e-6

    def to_metres(d):
        return depth.a / np.maximum(np.asarray(d, np.float64) + depth.c, floor)

    def to_disparity(z):
        return depth.a / np.maximum(np.asarray(z, np.float64), floor) - depth.c

    make = ax.secondary_yaxis if which == "y" else ax.secondary_xaxis
    sec = make(location, functions=(to_metres, to_disparity))
    lo, hi = ax.get_ylim() if which == "y" else ax.get_xlim()
    ticks = metres_ticks(depth, lo, hi)
    (sec.set_yticks if which == "y" else sec.set_xticks)(ticks, [_metres_label(z) for z in ticks])
    (sec.set_ylabel if which == "y" else sec.set_xlabel)("distance (m)")
    return sec


def _metres_label(z: float) -> str:
    return f"{z:g}"


def figure_title(result_meta: dict | None, recording_meta: dict | None) -> str:
    """A short description of what is shown, for titles: "method (variant) on preset-or-scene".

    Examples
    --------
    >>> figure_title({"method": "frame", "variant": "shared"}, {"scene": {"type": "arms", "distance_m": 0.5}})
    'frame (shared) on arms scene at 0.5 m'
    """
    parts = []
    if result_meta and result_meta.get("method"):
        variant = result_meta.get("variant")
        parts.append(f"{result_meta['method']} ({variant})" if variant else str(result_meta["method"]))
    scene = _scene_name(recording_meta or {})
    if scene:
        parts.append(scene)
    return " on ".join(parts)


def _scene_name(meta: dict) -> str:
    for key in ("preset", "name"):
        if isinstance(meta.get(key), str):
            return meta[key]
    scene = meta.get("scene")
    if isinstance(scene, str):
        return scene
    if isinstance(scene, dict):
        name = scene.get("name") or scene.get("preset") or scene.get("type")
        if isinstance(name, str):
            dist = scene.get("distance_m")
            return f"{name} scene" + (f" at {dist:g} m" if isinstance(dist, int | float) else "")
    return ""
