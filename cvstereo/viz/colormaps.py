"""The colours of disparity: one lookup table per colour map, shared by the plots (matplotlib) and the video.

The default, viridis, keeps its order for readers with any common colour-vision deficiency: its lightness rises
monotonically from one end to the other, and lightness is what deuteranopes and protanopes still see. Its dark
end is cut where it would be darker than :data:`MIN_LIGHTNESS`, so that the smallest disparity stays visible on
the black background and beside the dark grey of pixels with events but no disparity.
"""

from __future__ import annotations

import functools

import numpy as np

from cvstereo.errors import require_extra

__all__ = ["DISPARITY_CMAP", "LUT_SIZE", "MIN_LIGHTNESS", "check_cmap", "disparity_lut", "lightness",
           "listed_cmap"]

#: Default colour map of disparities (``--cmap``): perceptually uniform, lightness increasing, colour-blind safe.
DISPARITY_CMAP = "viridis"

#: Smallest CIE L* (0 black .. 100 white) a disparity colour may have: the low end of a map is cut to it. Black
#: (no event) is 0 and the silhouette grey of :data:`cvstereo.viz._images.CONTEXT_RGB` is about 29.
MIN_LIGHTNESS = 40.0

#: Entries of a lookup table: one per 8-bit level.
LUT_SIZE = 256


def lightness(rgb: np.ndarray) -> np.ndarray:
    """CIE L* of sRGB colours (uint8, ``(..., 3)``): 0 black .. 100 white.

    Examples
    --------
    >>> lightness(np.array([[0, 0, 0], [255, 255, 255], [119, 119, 119]], np.uint8)).round(1).tolist()
    [0.0, 100.0, 50.0]
    """
    c = np.asarray(rgb, np.float64) / 255.0
    linear = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    y = linear @ np.array([0.2126, 0.7152, 0.0722])
    return np.where(y > (6 / 29) ** 3, 116 * np.cbrt(y) - 16, y * (29 / 3) ** 3)


def check_cmap(name: str) -> str:
    """``name`` if matplotlib knows the colour map, else a ValueError listing the colour-blind-safe ones."""
    require_extra("matplotlib", "viz")
    from matplotlib import colormaps

    if name not in colormaps:
        raise ValueError(f"--cmap {name!r}: not a matplotlib colour map; colour-blind safe ones: viridis (default), "
                         "cividis, plasma, inferno, magma (any name of matplotlib.colormaps works).")
    return name


@functools.cache
def disparity_lut(name: str = DISPARITY_CMAP) -> np.ndarray:
    """The colours of colour map ``name`` for disparities, low to high: ``(LUT_SIZE, 3)`` uint8 RGB.

    The map's low end is cut where its lightness is below :data:`MIN_LIGHTNESS` (only the low end: a map that is
    dark at the top keeps its top), and the rest spread over the table.

    Raises
    ------
    ValueError
        An unknown colour map name.
    MissingExtraError
        matplotlib (the ``viz`` extra) is not installed.
    """
    from matplotlib import colormaps

    cmap = colormaps[check_cmap(name)]
    fine = np.round(cmap(np.linspace(0.0, 1.0, 4 * LUT_SIZE))[:, :3] * 255).astype(np.uint8)
    dark = lightness(fine) < MIN_LIGHTNESS
    # The first entry from which on the low end is light enough; a map dark everywhere is kept whole.
    start = 0 if dark.all() else int(np.argmin(dark))
    positions = np.linspace(start / (fine.shape[0] - 1), 1.0, LUT_SIZE)
    lut = np.round(cmap(positions)[:, :3] * 255).astype(np.uint8)
    lut.flags.writeable = False
    return lut


def listed_cmap(name: str = DISPARITY_CMAP, bad=(0.0, 0.0, 0.0, 0.0)):
    """The lookup table of ``name`` as a matplotlib colour map, NaN drawn in ``bad`` (default transparent)."""
    from matplotlib.colors import ListedColormap

    return ListedColormap(disparity_lut(name) / 255.0, name=f"{name} (disparity)").with_extremes(bad=bad)
