"""Disparity estimates ("matches") as produced by every matcher, and their metadata (docs/formats.md).

The data only; the matches ``.npz`` is read and written by :mod:`cvstereo.io.npz`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from cvstereo.errors import EventFormatError

__all__ = ["MATCH_DTYPE", "REQUIRED_META", "MatchResult", "cameras_swapped", "concat_matches", "empty_matches",
           "join_records", "make_matches", "sort_matches", "validate_matches"]

#: One disparity estimate anchored at pixel (x, y) of ``camera`` (0 = left, 1 = right) at time t.
MATCH_DTYPE = np.dtype(
    [("t", "<i8"), ("x", "<i2"), ("y", "<i2"), ("p", "i1"), ("camera", "u1"), ("disparity", "<f4")]
)

#: Meta keys every matches file carries (docs/formats.md); more may be added.
REQUIRED_META = ("method", "variant", "params", "anchor", "window_us")


def empty_matches(n: int = 0) -> np.ndarray:
    """Return a zero-filled matches array of length ``n``."""
    return np.zeros(n, dtype=MATCH_DTYPE)


def make_matches(t, x, y, p, camera, disparity) -> np.ndarray:
    """Build a matches array from columns (scalars broadcast).

    Parameters
    ----------
    t, x, y, p, camera, disparity : array_like or scalar

    Returns
    -------
    (N,) ndarray of MATCH_DTYPE
    """
    cols = [np.asarray(c) for c in (t, x, y, p, camera, disparity)]
    lengths = {c.shape[0] for c in cols if c.ndim}
    if len(lengths) > 1:
        raise ValueError(f"make_matches: columns have different lengths {sorted(lengths)}.")
    out = np.empty(lengths.pop() if lengths else 1, dtype=MATCH_DTYPE)
    # Assigning a scalar column broadcasts it; no broadcast_arrays copies (this runs once per window).
    for name, col in zip(MATCH_DTYPE.names, cols, strict=True):
        out[name] = col
    return out


def concat_matches(parts) -> np.ndarray:
    """Concatenate matches arrays (an empty list gives an empty array)."""
    parts = [p for p in parts if p is not None and p.size]
    if not parts:
        return empty_matches()
    # As records: numpy's own concatenation of structured arrays is slower (bench/results/docstring-figures.md).
    return join_records(parts) if all(p.dtype == MATCH_DTYPE for p in parts) else np.concatenate(parts)


def join_records(chunks: list[np.ndarray]) -> np.ndarray:
    """``np.concatenate`` of 1-D structured arrays of one dtype (events, matches), copied as raw records.

    Numpy copies a packed structured dtype (unaligned fields, as EVENT_DTYPE and MATCH_DTYPE) field by field,
    element by element: many times slower than copying the records' bytes through a void view.
    """
    out = np.empty(sum(c.size for c in chunks), dtype=chunks[0].dtype)
    raw = out.view(np.void)
    i = 0
    for c in chunks:
        raw[i: i + c.size] = c.view(np.void)
        i += c.size
    return out


def sort_matches(matches: np.ndarray) -> np.ndarray:
    """Stable sort by time (the file contract requires time order)."""
    return matches[np.argsort(matches["t"], kind="stable")]


def validate_matches(matches: np.ndarray, *, source: str = "matches") -> None:
    """Check dtype and time order of a matches array.

    Raises
    ------
    EventFormatError
    """
    if matches.dtype != MATCH_DTYPE:
        raise EventFormatError(f"{source}: dtype {matches.dtype} is not MATCH_DTYPE {MATCH_DTYPE}.")
    back = np.flatnonzero(np.diff(matches["t"]) < 0)
    if back.size:
        i = int(back[0]) + 1
        raise EventFormatError(f"{source}: field 't' at index {i} goes backwards; matches must be time-ordered.")
    bad = np.flatnonzero(matches["camera"] > 1)
    if bad.size:
        raise EventFormatError(f"{source}: field 'camera' at index {int(bad[0])} is not 0 or 1.")


@dataclass(eq=False)
class MatchResult:
    """A matches array with its metadata: what :func:`cvstereo.run.match` returns.

    Written and read by :func:`cvstereo.io.write_matches` and :func:`cvstereo.io.read_matches`.

    Attributes
    ----------
    matches : (N,) ndarray of MATCH_DTYPE
    meta : dict
        method, variant, params, anchor, window_us, elapsed_s, input_events, ... (docs/formats.md).
    arrays : dict of str to (N,) float32 ndarray
        Optional per-match arrays, one value per match in the same order (docs/formats.md: e.g. ``depth_m``).
    """

    matches: np.ndarray
    meta: dict = field(default_factory=dict)
    arrays: dict = field(default_factory=dict)

    @property
    def disparity(self) -> np.ndarray:
        """The disparities, px."""
        return self.matches["disparity"]

    def __len__(self) -> int:
        return int(self.matches.size)


def cameras_swapped(meta: Mapping) -> bool:
    """Whether the matches were computed with the recording's cameras exchanged (the rig check, or a geometry
    source, found them the wrong way round: ``rigcheck.applied.swap`` or ``geometry.side.swap`` of the meta), so
    that their left camera is the recording's right one."""
    def swap_in(entry, key):
        value = meta.get(entry)
        value = value.get(key) if isinstance(value, Mapping) else None
        return isinstance(value, Mapping) and value.get("swap") is True

    return swap_in("geometry", "side") or swap_in("rigcheck", "applied")
