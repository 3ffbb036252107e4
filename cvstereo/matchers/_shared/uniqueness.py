"""The uniqueness check of the block matchers (not the thesis'): no answer where another disparity fits about as well.

A winner of least SAD is *ambiguous* when a candidate more than 1 px from it has a SAD at most ``1 + uniqueness``
times the winner's: a repeating texture, a horizontal edge (any disparity along the row fits it), or too little
content to tell. OpenCV's ``uniquenessRatio`` is the same test with the ratio in percent. The candidates within 1 px
of the winner are its own cost valley, not rivals. ``uniqueness = 0`` switches the check off (the thesis).

A search need not compute every candidate's SAD in full to apply it: a candidate whose partial sum already exceeds
``1 + uniqueness`` times the best SAD found so far can be neither the winner nor a rival (sums never decrease, the
best only falls), so the kernels keep the candidates at or below that limit and test them at the end
(:func:`ambiguous`).

>>> import numpy as np
>>> d = np.array([3, 4, 9]); sad = np.array([10.0, 10.5, 11.5])
>>> bool(ambiguous(d, sad, 3, 3, 10.0, 1.0 + 0.2))      # 9 lies 6 px away within 1.2 x the best
True
>>> bool(ambiguous(d, sad, 3, 3, 10.0, 1.0 + 0.1))      # 11.5 > 11: no rival; 4 is the winner's valley
False
"""

from __future__ import annotations

from numba import njit

__all__ = ["ambiguous"]


@njit(cache=True, nogil=True, inline="always")
def ambiguous(cand_d, cand_sad, n_cand: int, best_d: int, best_sad: float, rival: float) -> bool:
    """True when one of the first ``n_cand`` candidates (disparity ``cand_d``, SAD ``cand_sad``) lies more than
    1 px from ``best_d`` with a SAD at most ``rival`` times ``best_sad``."""
    limit = best_sad * rival
    for m in range(n_cand):
        if abs(cand_d[m] - best_d) > 1 and cand_sad[m] <= limit:
            return True
    return False
