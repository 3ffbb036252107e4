"""matplotlib plumbing shared by the plots: the optional import, new figures, saving, sensor images, metres axes.

Figures are created as :class:`matplotlib.figure.Figure` objects, not through pyplot: nothing global is kept,
so a loop that makes hundreds of pictures neither leaks memory nor trips pyplot's "too many figures" warning.
They display in Jupyter as they are; in a script, save them with :func:`save_figure`.
"""

from __future__ import annotations

import os

import numpy as np

from cvstereo.errors import require_extra
from cvstereo.geometry.depth import DepthModel
from cvstereo.io.atomic import atomic_path
from cvstereo.viz.colormaps import DISPARITY_CMAP  # the disparity maps' default, kept importable from here

__all__ = ["COLUMN_WIDTH_IN", "DEFAULT_DPI", "DISPARITY_CMAP", "MIN_PAPER_FONT_PT", "SIGNED_CMAP", "add_metres_axis",
           "cmap_with_background", "figure_title", "metres_ticks", "new_figure", "recording_name",
           "require_matplotlib", "save_figure", "set_paper_width", "show_sensor_image"]


#: Diverging colormap of signed frames (filtered, dynamic): OFF (negative) orange, zero white, ON (positive) blue:
#: the hues of the event frames (:data:`~cvstereo.viz._images.ON_RGB`), so a colour means one polarity everywhere.
SIGNED_CMAP = "cvstereo-signed"

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


def save_figure(fig, path: str | os.PathLike, *, dpi: float | None = None, width_in: float | None = None) -> None:
    """Write a figure to ``path`` atomically (temporary file, then rename); the format follows the extension.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
    path : path-like
        ``.png``, ``.pdf``, ``.svg``, ... (anything matplotlib writes).
    dpi : float, optional, keyword-only
        Default: the figure's.
    width_in : float, optional, keyword-only
        Resize the figure to this width first (:func:`set_paper_width`), e.g. :data:`COLUMN_WIDTH_IN`.
    """
    if width_in is not None:
        set_paper_width(fig, width_in)
    fmt = os.path.splitext(os.fspath(path))[1].lstrip(".").lower() or "png"
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format=fmt, dpi=dpi if dpi is not None else "figure")


#: Width of one column of a two-column paper (IEEE, ACM, Springer LNCS are 3.3-3.5 in), inches.
COLUMN_WIDTH_IN = 3.5

#: Smallest font size a resized figure keeps, points: what print stays readable at.
MIN_PAPER_FONT_PT = 6.5


def set_paper_width(fig, width_in: float) -> None:
    """Scale a figure to ``width_in`` inches wide, keeping its aspect; text shrinks with it down to 6.5 pt.

    Raises
    ------
    ValueError
        ``width_in`` is not between 1 and 50 inches.
    """
    if not 1.0 <= width_in <= 50.0:
        raise ValueError(f"figure width {width_in:g} in is outside 1..50 inches (a paper column is "
                         f"{COLUMN_WIDTH_IN:g}).")
    from matplotlib.text import Text

    w, h = fig.get_size_inches()
    scale = width_in / w
    fig.set_size_inches(width_in, h * scale)
    for text in fig.findobj(Text):
        text.set_fontsize(max(MIN_PAPER_FONT_PT, text.get_fontsize() * scale))


def cmap_with_background(name: str, background=(0.0, 0.0, 0.0)):
    """The named colormap (a matplotlib name, or :data:`SIGNED_CMAP`) with NaN (no data) drawn in ``background``."""
    from matplotlib import colormaps

    cmap = _signed_cmap() if name == SIGNED_CMAP else colormaps[name]
    return cmap.with_extremes(bad=background)


def _signed_cmap():
    from matplotlib.colors import LinearSegmentedColormap

    from cvstereo.viz._images import OFF_DARK_RGB, OFF_RGB, ON_DARK_RGB, ON_RGB

    stops = [OFF_DARK_RGB, OFF_RGB, (255, 255, 255), ON_RGB, ON_DARK_RGB]
    return LinearSegmentedColormap.from_list(SIGNED_CMAP, [tuple(c / 255 for c in rgb) for rgb in stops])


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

    Taken from :data:`_NICE_METRES`; where fewer than three of them fall in the range (a colour scale zoomed on
    one depth), from a grid of 1, 2 or 5 cm, 10 or 20 cm instead.

    Examples
    --------
    >>> metres_ticks(DepthModel(a=16.5), 0.0, 40.0)
    [0.5, 0.6, 0.75, 1.0, 1.25, 2.0, 3.0, 10.0]
    >>> metres_ticks(DepthModel(a=16.5, c=3.0), 27.0, 32.0)
    [0.48, 0.5, 0.52, 0.54]
    """
    lo, hi = min(d_lo, d_hi), max(d_lo, d_hi)
    kept = _spaced_ticks(depth, _NICE_METRES, lo, hi)
    if len(kept) >= 3 or hi <= lo:
        return kept
    z_near, z_far = float(depth.distance(hi)), float(depth.distance(lo))
    z_far = z_far if np.isfinite(z_far) and z_far > 0 else z_near * 10
    for step in _FINE_STEPS_M:
        grid = np.arange(np.ceil(z_near / step), np.floor(z_far / step) + 1) * step
        if 3 <= grid.size <= 6:
            return _spaced_ticks(depth, [round(float(z), 6) for z in grid], lo, hi) or kept
    return kept


#: Steps (m) of the fine metres grid, tried in order until 3-6 ticks fall in the range.
_FINE_STEPS_M = (0.01, 0.02, 0.05, 0.1, 0.2, 0.5)


def _spaced_ticks(depth: DepthModel, distances, lo: float, hi: float) -> list[float]:
    gap = (hi - lo) * _MIN_TICK_GAP
    kept: list[float] = []
    last = None
    # Nearest first (largest disparity), where the round distances are furthest apart.
    for z in sorted(distances):
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
    >>> figure_title({"method": "event-area", "variant": "gaussian", "input": ["data/Fan_disp8.dat"]}, {})
    'event-area (gaussian) on Fan_disp8.dat'
    """
    parts = []
    if result_meta and result_meta.get("method"):
        variant = result_meta.get("variant")
        parts.append(f"{result_meta['method']} ({variant})" if variant else str(result_meta["method"]))
    scene = recording_name(recording_meta or {}) or _input_name(result_meta or {})
    if scene:
        parts.append(scene)
    return " on ".join(parts)


def _input_name(result_meta: dict) -> str:
    """The file(s) a matches file was computed on (real recordings have no preset or scene to name)."""
    files = result_meta.get("input")
    files = [files] if isinstance(files, str) else files
    if not isinstance(files, list) or not all(isinstance(f, str) for f in files) or files in ([], ["memory"]):
        return ""
    return " + ".join(os.path.basename(f) for f in files)


def recording_name(meta: dict) -> str:
    """What a recording is, for titles: its preset, ``name`` (the CLI sets the file name), or its scene."""
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
