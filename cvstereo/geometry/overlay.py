"""Horizontal overlay of two cameras' event images: the left/right primitive of the readers and the rig check.

One convention throughout: a shift ``s`` overlays image ``a`` on image ``b`` when ``x_a = x_b + s``. The
left camera sees a scene point at the larger x, so ``s > 0`` at the best overlay means ``a`` is the left
camera. :func:`overlay_shift` scores shifts by the normalised cross-correlation of whole-recording count
images (what the eDVS merged reader uses to tell the retinas apart); :func:`row_correlation` is the
row-wise correlation of two signed frames that the rig check sums over windows, and :func:`side_of_profile`
reads the decision off such a profile.

This module depends on numpy only: readers (:mod:`cvstereo.io`) and the analysis layer both import it.
"""

from __future__ import annotations

import numpy as np

__all__ = ["overlay_scores", "overlay_shift", "row_correlation", "side_of_profile"]


def overlay_scores(image_a: np.ndarray, image_b: np.ndarray, *, max_shift: int) -> np.ndarray:
    """Normalised cross-correlation of log counts at every shift ``-max_shift..max_shift``.

    Parameters
    ----------
    image_a, image_b : (H, W) ndarray
        Event counts per pixel.
    max_shift : int, keyword-only
        Shifts ``-max_shift..max_shift`` are scored.

    Returns
    -------
    (2 * max_shift + 1,) float ndarray
        Index ``s + max_shift``: the correlation over the columns both images cover at shift ``s``, each
        image's mean over them removed; 0 where either is constant there.
    """
    # log counts: a few hot pixels would otherwise dominate the correlation.
    a, b = np.log1p(np.asarray(image_a, float)), np.log1p(np.asarray(image_b, float))
    width = a.shape[1]
    scores = np.zeros(2 * max_shift + 1)
    for s in range(-max_shift, max_shift + 1):
        pa = a[:, max(s, 0): width + min(s, 0)]
        pb = b[:, max(-s, 0): width - max(s, 0)]
        pa, pb = pa - pa.mean(), pb - pb.mean()
        norm = np.sqrt((pa * pa).sum() * (pb * pb).sum())
        scores[s + max_shift] = float((pa * pb).sum() / norm) if norm > 0 else 0.0
    return scores


def overlay_shift(image_a: np.ndarray, image_b: np.ndarray, *, max_shift: int) -> tuple[int, float]:
    """Horizontal shift ``s`` that best overlays two event images, ``x_a = x_b + s``.

    Parameters
    ----------
    image_a, image_b : (H, W) ndarray
        Event counts per pixel.
    max_shift : int, keyword-only
        Shifts ``-max_shift..max_shift`` are tried (:func:`overlay_scores`).

    Returns
    -------
    shift : int
        Positive when a scene point has the larger x in ``image_a`` (``a`` is the left camera); of equal
        scores the most negative shift.
    score : float
        Normalised cross-correlation at that shift, in [-1, 1].

    Examples
    --------
    >>> b = np.zeros((4, 16)); b[:, 3] = 5
    >>> a = np.roll(b, 2, axis=1)
    >>> overlay_shift(a, b, max_shift=4)[0]
    2
    """
    scores = overlay_scores(image_a, image_b, max_shift=max_shift)
    i = int(np.argmax(scores))
    return i - max_shift, float(scores[i])


def row_correlation(frame_a: np.ndarray, frame_b: np.ndarray, *, max_shift: int, nfft: int) -> np.ndarray | None:
    """``sum_y sum_x a(x, y) b(x - s, y)`` for ``s = -max_shift..max_shift``, over the frames' norms.

    Parameters
    ----------
    frame_a, frame_b : (H, W) float ndarray
        Signed (or count) frames of the two cameras.
    max_shift : int, keyword-only
        Largest |s|.
    nfft : int, keyword-only
        FFT length along x, at least ``W + max_shift + 1`` (zero padding keeps shifts from wrapping).

    Returns
    -------
    (2 * max_shift + 1,) float ndarray or None
        Index ``s + max_shift``; None when a frame is all zero.
    """
    c = np.fft.irfft(np.fft.rfft(frame_a, nfft, axis=1) * np.conj(np.fft.rfft(frame_b, nfft, axis=1)), nfft, axis=1)
    c = c.sum(axis=0)
    norm = np.sqrt((frame_a ** 2).sum() * (frame_b ** 2).sum())
    if not norm > 0:
        return None
    return np.concatenate([c[-max_shift:], c[:max_shift + 1]]) / norm


def side_of_profile(profile: np.ndarray) -> tuple[bool, float]:
    """Whether the first camera is the RIGHT one, from an overlay profile over shifts ``-D..D``.

    The strongest overlay at a positive shift is compared with the strongest at a negative one, both above
    the profile's median: ``(first_is_right, confidence)``, the confidence ``|pos - neg| / max(pos, neg)``
    (0 when nothing stands above the median).

    Examples
    --------
    >>> side_of_profile(np.array([0.0, 0.0, 0.1, 0.0, 1.0]))
    (False, 1.0)
    """
    d = (len(profile) - 1) // 2
    base = float(np.median(profile))
    pos, neg = float(profile[d + 1:].max()), float(profile[:d].max())
    top = max(pos, neg) - base
    if top <= 0:
        return False, 0.0
    return bool(neg > pos), float(min(1.0, max(0.0, abs(pos - neg) / top)))
