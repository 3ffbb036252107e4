"""Row bands: the event matchers' merged stream processed by several threads at once, with the same matches.

Event-area and event-vector process both cameras' events in one merged order, each event reading its own row
(event-vector) or the ``2 h + 1`` rows around it (event-area's patches) of both cameras' frames and splatting
rows ``y - r .. y + r`` of its own. The dependencies are local in rows, so the sensor's rows are cut into bands
``[lo, hi)``, one per thread, and each band keeps a private copy of the state in which the rows
``[lo - halo, hi + halo)`` (``halo`` = the rows an event reads beyond its own) are exact. The cut follows the
events' rows, so that the bands own about equal shares of them (:meth:`BandedState.layout`):

* every band walks the whole merged stream. Decay ticks are time-driven and applied at the same events in every
  band, so each band's scale and clock are the one-thread run's bit for bit; so is the count of splats since
  the last rebuild of event-area's column sums (every splat counts, clipped to nothing by :func:`splat_rows`
  or not), so that the sums are rebuilt at the same events;
* each event's splat is applied to the band's kept rows only (:func:`band_rows`): a kept row sees exactly the
  one-thread run's float operations in the same order, so its values are bit-identical;
* only a band's own events (``lo <= y < hi``) are searched and read for the signal level, so each event is
  searched once, by its owner, on exact rows. Event-area's column sums only prune the search (a lower bound
  with a margin for their drift); a band's magnitude bound ``mass`` sums the rows it keeps (since its last
  rebuild: its own splats), which bounds the drift of its sums there as the whole sensor's bounds the
  one-thread run's.

The matches of each band carry their position in the merged stream and are merged back into the stream's
order (:func:`merge_band_matches`); the per-event values are gathered from their owner bands
(:func:`gather_band_values`). The private copies persist from packet to packet (:class:`BandedState`), so
that nothing is copied per packet; a change of the number of bands assembles the full state from the owners' rows
and copies it into the new bands, and a cut anew (the events moved to other rows) moves the rows that change hands
only. With one band
the state is the matcher's own arrays and every row is kept: the one-thread path.

Each kernel is one Python function compiled twice (:func:`compile_twice`): serially, where its ``prange`` over
the bands is a plain loop, and in parallel; the matcher calls the parallel compile only with more than one
band. Each matcher writes that loop around its own band kernel: a loop taking the kernel as an argument, or
closing over it, gets a new entry in numba's on-disk cache in every process (compiled anew each time), where a
loop naming its kernel is cached once.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit, prange

from cvstereo.matchers._shared.merge_order import ROW_CAM, ROW_INDEX, ROW_Y
from cvstereo.matchers._shared.twin_kernels import compile_twice

__all__ = ["REBALANCE_EVENTS", "REBALANCE_SHARE", "BandedState", "band_rows", "compile_twice", "emit_at", "even_cuts",
           "gather_band_values", "merge_band_matches", "splat_rows"]

#: A band owning more than this times its fair share (1 / bands) of a window's events is a reason to cut anew
#: (the threads wait for the busiest band) ...
REBALANCE_SHARE = 1.1
#: ... once at least this many events have passed since the last cut (a cut anew copies the rows that change hands
#: and adds to the bands' ``mass``, which loosens event-area's bounds until its next rebuild).
REBALANCE_EVENTS = 1 << 17


@njit(cache=True, inline="always")
def band_rows(cuts, band, height, halo):  # pragma: no cover - compiled
    """Band ``band`` of the cut ``cuts`` (the rows where bands begin, then the sensor's height): its own rows
    ``[lo, hi)`` and the rows ``[keep_lo, keep_hi)`` it keeps exact (its own and ``halo`` rows on each side, on
    the sensor)."""
    lo = cuts[band]
    hi = cuts[band + 1]
    return lo, hi, max(0, lo - halo), min(height, hi + halo)


def even_cuts(n_bands: int, height: int, rows: np.ndarray | None = None) -> np.ndarray:
    """Where ``n_bands`` bands of a sensor ``height`` rows high begin (then ``height``): each owning about as many
    of the events at ``rows`` (their y), or as many rows when there are none; every band at least one row.

    Returns
    -------
    (n_bands + 1,) int64 ndarray, strictly increasing from 0 to ``height``
    """
    if rows is None or rows.size == 0:
        inner = np.arange(1, n_bands) * height // n_bands
    else:  # the rows of the sorted events k = i * size // n_bands, from the events per row (no sort of them)
        on_or_before = np.cumsum(np.bincount(rows, minlength=height))
        inner = np.searchsorted(on_or_before, np.arange(1, n_bands) * rows.size // n_bands, side="right")
    cuts = np.concatenate([[0], inner, [height]]).astype(np.int64)
    for b in range(1, n_bands):  # at least one row per band, and room for the bands after it
        cuts[b] = min(max(cuts[b], cuts[b - 1] + 1), height - (n_bands - b))
    return cuts


@njit(cache=True, inline="always")
def splat_rows(y, r, keep_lo, keep_hi):  # pragma: no cover - compiled
    """The rows ``[first, stop)`` of a splat of radius ``r`` at row ``y`` that a band keeping rows
    ``[keep_lo, keep_hi)`` applies (empty when it touches none of them)."""
    return max(keep_lo, y - r), min(keep_hi, y + r + 1)


@njit(cache=True, inline="always")
def emit_at(out_pos, out_disparity, n, k, disparity):  # pragma: no cover - compiled
    """Write the ``n``-th match of a band's output (the merged stream's event ``k``) where ``disparity`` >= 0 (a
    negative one: the event found no match); the count of matches after it."""
    if disparity < 0:
        return n
    out_pos[n] = k
    out_disparity[n] = disparity
    return n + 1


def _merge_chunks(size, counts, out_pos, out_disparity, pos, disparity, n_chunks):  # pragma: no cover - compiled
    """:func:`merge_band_matches` in ``n_chunks`` pieces of the stream (``size`` positions cut evenly), each merged
    on its own (in parallel in the parallel compile): a piece's matches start after those of every earlier
    position, counted in each band's sorted positions."""
    n_bands = counts.shape[0]
    for c in prange(n_chunks):
        first, stop = c * size // n_chunks, (c + 1) * size // n_chunks
        head = np.empty(n_bands, np.int64)
        end = np.empty(n_bands, np.int64)
        m = 0
        for b in range(n_bands):
            head[b] = np.searchsorted(out_pos[b, :counts[b]], first)
            end[b] = np.searchsorted(out_pos[b, :counts[b]], stop)
            m += head[b]
        while True:
            best = -1
            for b in range(n_bands):
                if head[b] < end[b] and (best < 0 or out_pos[b, head[b]] < out_pos[best, head[best]]):
                    best = b
            if best < 0:
                break
            pos[m] = out_pos[best, head[best]]
            disparity[m] = out_disparity[best, head[best]]
            head[best] += 1
            m += 1


def _gather_chunks(stream, band_values, values, right_start, cuts, n_chunks):  # pragma: no cover - compiled
    """:func:`gather_band_values` in ``n_chunks`` pieces of the stream, in parallel in the parallel compile."""
    size = stream.shape[1]
    for c in prange(n_chunks):
        for k in range(c * size // n_chunks, (c + 1) * size // n_chunks):
            y = stream[ROW_Y, k]
            band = 0
            while cuts[band + 1] <= y:
                band += 1
            at = stream[ROW_CAM, k] * right_start + stream[ROW_INDEX, k]
            values[at] = band_values[band, at]


#: :func:`_merge_chunks` and :func:`_gather_chunks`, serial and parallel: with several bands the merge-back runs
#: on the bands' threads too, so that it does not add to the serial part of a run.
_MERGE_KERNELS = compile_twice(_merge_chunks)
_GATHER_KERNELS = compile_twice(_gather_chunks)


def merge_band_matches(size, counts, out_pos, out_disparity, pos, disparity) -> int:
    """The matches of several bands (band ``b``: ``counts[b]`` rows of ``out_pos[b]``, ``out_disparity[b]``, each
    in stream order) merged into the merged stream's order (of ``size`` events): the position in the stream and
    the disparity of each, into ``pos`` and ``disparity``; returns their number. Each event has one owner band, so
    positions never repeat. One piece of the stream per band, merged in parallel. (One band's matches are in
    order already: no merge.)"""
    n_bands = counts.shape[0]
    _MERGE_KERNELS[n_bands > 1](size, counts, out_pos, out_disparity, pos, disparity, n_bands)
    return int(counts.sum())


def gather_band_values(stream, band_values, values, right_start, cuts) -> None:
    """Each event's value from its owner band's buffer (``band_values[b]``, written at the event's place in
    ``values``: the left camera's i-th event at ``i``, the right camera's at ``right_start + i``) into
    ``values``, one piece of the stream per band in parallel. Each band writes a buffer of its own: bands writing
    neighbouring entries of one array would share its cache lines at almost every event."""
    n_bands = band_values.shape[0]
    _GATHER_KERNELS[n_bands > 1](stream, band_values, values, right_start, cuts, n_bands)


class BandedState:
    """A matcher's frame state (a NamedTuple of arrays, each with the camera first) as the kernels take it: every
    field with a leading axis of bands, one private copy per band.

    Parameters
    ----------
    state : NamedTuple of ndarrays
        The one-thread state; its arrays are kept and used in place while there is one band.
    row_fields : tuple of str
        The fields laid out by row, ``(n_cameras, n_frames, H, ...)``: a band's copy is exact on the rows it keeps
        only, so the full state takes each row from its owner band. The other fields are per camera and equal in
        every band, except ``summed_fields``.
    summed_fields : tuple of str
        Per-camera bounds over a band's rows (event-area's ``mass``): the full state's is their sum, which bounds
        the whole sensor.
    halo : int
        The rows an event reads beyond its own row, on each side.
    """

    def __init__(self, state: NamedTuple, *, row_fields: tuple[str, ...], summed_fields: tuple[str, ...] = (),
                 halo: int):
        self._full = state
        self._row_fields, self._summed_fields, self._halo = row_fields, summed_fields, int(halo)
        self._height = state[0].shape[2]
        self.n_bands = 1
        self.cuts = even_cuts(1, self._height)
        self._since_cut = 0  # events since the last cut
        self.bands = type(state)(*(a[np.newaxis] for a in state))  # views: the one-thread path works in place

    def rows_of(self, band: int) -> tuple[int, int, int, int]:
        """:func:`band_rows` of band ``band`` of the current cut."""
        lo, hi = int(self.cuts[band]), int(self.cuts[band + 1])
        return lo, hi, max(0, lo - self._halo), min(self._height, hi + self._halo)

    def full(self) -> NamedTuple:
        """The one-thread state, assembled from the bands' own rows when there are several (the matcher's arrays,
        updated in place)."""
        if self.n_bands > 1:
            for name, full in zip(self._full._fields, self._full, strict=True):
                banded = getattr(self.bands, name)
                if name in self._row_fields:
                    for b in range(self.n_bands):
                        lo, hi, _, _ = self.rows_of(b)
                        full[:, :, lo:hi] = banded[b, :, :, lo:hi]
                elif name in self._summed_fields:
                    full[...] = banded.sum(axis=0)
                else:
                    full[...] = banded[0]
        return self._full

    def layout(self, n_bands: int, rows: np.ndarray) -> NamedTuple:
        """The state cut into ``n_bands`` bands (at most one per row) for a window whose events lie on ``rows``.

        The bands own about equal shares of the events (:func:`even_cuts` of ``rows``), so that no thread waits
        long for another; the state is cut anew only when the number of bands changes, or when a band owns more
        than :data:`REBALANCE_SHARE` times its share of the window's events and :data:`REBALANCE_EVENTS` have
        passed since the last cut, when the bands' boundaries move (:meth:`_move_cuts`). A new number of bands
        gives each band a copy of the full state; either way a band is zero outside the rows it keeps (so that its
        ``mass``, which a rebuild sums over all rows, counts the rows it keeps only).
        """
        if n_bands == 1 == self.n_bands:  # the one-thread path: its arrays in place, nothing to cut or count
            return self.bands
        n_bands = max(1, min(int(n_bands), self._height))
        self._since_cut += rows.size
        if n_bands == self.n_bands:
            if n_bands > 1 and self._unbalanced(rows):
                self._move_cuts(even_cuts(n_bands, self._height, rows))
            return self.bands
        full = self.full()
        self.n_bands, self.cuts, self._since_cut = n_bands, even_cuts(n_bands, self._height, rows), 0
        if n_bands == 1:
            self.bands = type(full)(*(a[np.newaxis] for a in full))
        else:
            copies = [np.repeat(a[np.newaxis], n_bands, axis=0) for a in full]
            for name, banded in zip(full._fields, copies, strict=True):
                if name in self._row_fields:
                    for b in range(n_bands):
                        _, _, keep_lo, keep_hi = self.rows_of(b)
                        banded[b, :, :, :keep_lo] = 0
                        banded[b, :, :, keep_hi:] = 0
            self.bands = type(full)(*copies)
        return self.bands

    def _unbalanced(self, rows: np.ndarray) -> bool:
        if self._since_cut < REBALANCE_EVENTS or rows.size == 0:
            return False
        owned = np.add.reduceat(np.bincount(rows, minlength=self._height), self.cuts[:-1])
        return owned.max() > REBALANCE_SHARE * rows.size / self.n_bands

    def _move_cuts(self, cuts: np.ndarray) -> None:
        """Move the bands' boundaries to ``cuts`` in place: each band takes the rows it keeps and did not own from
        their old owners (exact there) and zeroes those it no longer keeps, so that a new cut copies the rows that
        changed hands only, not the whole state. A band's summed bound (``mass``) adds those of the bands it took rows
        from: its rows now hold their entries too."""
        old = self.cuts
        keep = [(self.rows_of(b)[2:], (max(0, cuts[b] - self._halo), min(self._height, cuts[b + 1] + self._halo)))
                for b in range(self.n_bands)]
        taken = []  # per band: (old owner, first row, stop) of each stretch it takes
        for b, (_, (lo, hi)) in enumerate(keep):
            # The rows kept now and not owned before, the halo too: a band's column sums are exact on its own rows
            # only (a halo row's sums lack the splats on the rows beyond it).
            stretches = [(lo, min(hi, old[b])), (max(lo, old[b + 1]), hi)]
            taken.append([(o, max(a, old[o]), min(z, old[o + 1])) for a, z in stretches
                          for o in range(self.n_bands) if max(a, old[o]) < min(z, old[o + 1])])
        for name in self._row_fields:  # every copy first: a band's dropped rows may be another's new ones
            banded = getattr(self.bands, name)
            for b, stretches in enumerate(taken):
                for o, a, z in stretches:  # an old owner's own rows: never its own new rows, so not written here
                    banded[b, :, :, a:z] = banded[o, :, :, a:z]
            for b, ((old_lo, old_hi), (lo, hi)) in enumerate(keep):
                banded[b, :, :, old_lo:min(old_hi, lo)] = 0
                banded[b, :, :, max(old_lo, hi):old_hi] = 0
        for name in self._summed_fields:
            banded = getattr(self.bands, name)
            before = banded.copy()
            for b, stretches in enumerate(taken):
                for o in {o for o, _, _ in stretches}:
                    banded[b] += before[o]
        self.cuts, self._since_cut = cuts, 0
