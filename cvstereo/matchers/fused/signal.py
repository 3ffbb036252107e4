"""The signal level of the fused matcher: one camera's features of a window, normalised (design part 3 of
:mod:`cvstereo.matchers.fused.matcher`).

One function, shared by the kernel path and the reference, so that a change of the level (e.g. to the causal one
of :mod:`cvstereo.matchers._shared.signal_level`, see design part 3 of :mod:`cvstereo.matchers.fused.matcher` for why
not yet) is made in one
place.
"""

from __future__ import annotations

import numpy as np

from cvstereo.matchers.fused._features import percentile

__all__ = ["LEVEL_PERCENTILE", "level_of", "signal_level"]

#: Percentile of the non-zero feature values taken as a window's signal level.
LEVEL_PERCENTILE = 90.0


def level_of(nonzero: np.ndarray) -> float:
    """The signal level of a window from its non-zero feature values (in any order): their
    :data:`LEVEL_PERCENTILE` percentile, NumPy's linear one, computed by the kernel's
    :func:`~cvstereo.matchers.fused._features.percentile` (fast path and reference alike)."""
    return float(percentile(nonzero, LEVEL_PERCENTILE))


def signal_level(features: np.ndarray) -> np.ndarray:
    """Normalise one camera's features of a window by their robust level.

    Parameters
    ----------
    features : (2, H, W) float64 ndarray
        Support-summed time surfaces, OFF and ON.

    Returns
    -------
    (2, H, W) float64 ndarray
        ``features / level``, level = the :data:`LEVEL_PERCENTILE` percentile of the non-zero values (the
        features unchanged when all are zero).

    Examples
    --------
    >>> f = np.zeros((2, 1, 4)); f[1, 0, :] = [0.0, 1.0, 2.0, 4.0]
    >>> signal_level(f)[1, 0].tolist()  # the 90th percentile of 1, 2, 4 is 3.6
    [0.0, 0.2777777777777778, 0.5555555555555556, 1.1111111111111112]
    """
    nonzero = features[features > 0]
    if nonzero.size == 0:
        return features
    return features / level_of(nonzero)
