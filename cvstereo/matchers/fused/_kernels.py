"""The matching kernel of the fused matcher (:mod:`cvstereo.matchers.fused.matcher` describes the method).

Per window, on the features of :mod:`cvstereo.matchers.fused._features`: :func:`match_features` (cost and
semi-global aggregation, :mod:`cvstereo.matchers.fused._sgm`; winner, left-right check, sub-pixel, uncertainty and
fill, :mod:`cvstereo.matchers.fused._answers`), built twice (:mod:`cvstereo.matchers.fused._parallel`): serial,
the two direction passes one after the other, and parallel, both at once (two threads) or the split passes (rows,
column blocks and filled answers in chunks). Every floating-point expression is evaluated in the same order as in
:mod:`cvstereo.matchers.fused.reference`, so that all give bit-identical matches (tests/test_fused.py).

Why the kernels are shaped as they are (the figures that led here are in bench/results/docstring-figures.md).
Typical windows: 2arms-50cm, 128x128, 64 disparities, about 6000 active pixels; a 346x260 recording at a million
events a second, about 26000 active pixels and 171 disparities.

* Memory traffic, not arithmetic, set the pace when the cost and the four paths were stored as (active pixels x
  disparities) arrays of several MB. Now a window keeps two such arrays, in float32 (half the bytes, twice the
  vector lanes): the sums of each pass direction. Each pass (:func:`~cvstereo.matchers.fused._sgm._row_pass`)
  keeps its row path in a vector, its column path in two sensor rows and the costs of its next pixels in a ring;
  the forward pass writes left + above, the backward pass right + below, in ascending order of memory (mirrored:
  a descending stream of stores is slower), and adds the two where it answers the row. Cost, paths and sums are
  float32 in the reference too, in the same order. Keeping the paths out of memory pays most where the arrays
  outgrow the caches (the 346x260 and 640x480 windows); so does computing the costs in each pass rather than
  storing them once and reading them back, which the fused passes still do where the planes fit the caches
  (:data:`STORED_COSTS_MAX_BYTES`).
* Each pixel's semi-global step is one plain loop over the disparities, which the compiler vectorises: it steps the
  row and the column path, adds them to the sums and takes their minima (a reduction the compiler vectorises too,
  :func:`~cvstereo.matchers.fused._sgm._least`: numba's ``min`` kept it scalar, one instruction per value, in a
  pass of its own). The path vectors carry a column of inf at either end, so that the first and last disparity need
  no case of their own outside the loop.
* No array is sliced or passed to an inlined helper inside the per-pixel loops: each such view or binding is a new
  array whose reference count numba updates with two atomic instructions, and with a dozen a pixel those dominated
  the kernel's time (perf: NRT_incref/NRT_decref). The loops are written out in
  :func:`~cvstereo.matchers.fused._sgm._row_pass` and index rows of 2-D arrays in place;
  :func:`~cvstereo.matchers.fused._sgm._step` takes scalars only.
* The left-right check needs the right pixels' winners of a row, each one disparity of many different left pixels:
  they are found in one sweep over the row's sums (contiguous, branch-free, mirrored like the cost) as soon as the
  second pass has finished the row, while its sums are in the cache, instead of a scattered walk per anchor.
* The cost reads the right camera's row backwards (disparity 0, 1, ... is column x, x - 1, ...): a mirrored copy of
  the right features makes those loops contiguous and branch-free, so they vectorise. Its index is unsigned: numba
  wraps negative indices around, and testing a signed one kept the loop scalar.
* The fill's median and the level's percentile select in place (:func:`~cvstereo.matchers.fused._features.select`)
  rather than sort; the median first counts its values in bins and selects within one
  (:func:`~cvstereo.matchers.fused._answers.median_of`), and the fill reads the consistent answers from per-row
  runs rather than scanning its square (2arms-50cm: about 200 filled pixels a window, 25x25 squares).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import prange

from cvstereo.matchers.fused._answers import consistent_rows, fill_answers, row_answers
from cvstereo.matchers.fused._parallel import COLUMN_BLOCK, chunk_count, serial_and_parallel, take_turn
from cvstereo.matchers.fused._sgm import COST_RUN, DIRECTIONS, FUSED, SPLIT, _column_run, _row_pass

__all__ = ["KernelParams", "KernelScratch", "kernel_params", "match_features", "match_features_parallel", "way_for"]

class KernelParams(NamedTuple):
    """The :class:`~cvstereo.matchers.fused.params.FusedParams` fields the kernel reads, typed for numba (one
    compiled kernel for every parameter set); :func:`kernel_params` makes them."""

    max_d: int
    row_tol: int
    p1: np.float32  # float32 steps throughout (see the module docstring)
    p2: np.float32
    paths: int
    temporal_weight: float
    lr_tol: int
    subpixel: bool
    min_neighbours: int
    isolated_below: float  # isolated_max_uncertainty
    fill_radius: int
    confirm: bool  # fill_confirms


def kernel_params(prm) -> KernelParams:
    """The kernel's view of a :class:`~cvstereo.matchers.fused.params.FusedParams`."""
    return KernelParams(int(prm.max_disparity), int(prm.row_tolerance), np.float32(prm.p1), np.float32(prm.p2),
                        int(prm.sgm_paths), float(prm.temporal_weight), int(prm.lr_tolerance), bool(prm.subpixel),
                        int(prm.min_neighbours), float(prm.isolated_max_uncertainty), int(prm.fill_radius),
                        bool(prm.fill_confirms))


class KernelScratch(NamedTuple):
    """Scratch of :func:`match_features`, kept between windows by the caller (fresh pages cost more than the
    arithmetic).

    ``work``: (3, n, max_d + 1) float32 for at least the n active pixels: the sum of their paths (the forward pass's
    share first), then with the direction passes the backward pass's share (mirrored) and, with the split passes,
    their cost and their column path from below. ``cols``, ``vecs``: (2, 2 W + 1, max_d + 3) and (2, 3, max_d + 3)
    float32, one of each per pass direction: the column path's current and previous sensor row (row ``cur * W + x``)
    and the row path's current and previous vector, each with a last row of zeros, and a first and last column of
    inf, that are never written (:func:`~cvstereo.matchers.fused._sgm._row_pass`). ``right_rev``:
    (H, 2, W + max_d + 1) float32 zeros; ``index``: (H, W) int64.
    """

    work: np.ndarray
    cols: np.ndarray
    vecs: np.ndarray
    right_rev: np.ndarray
    index: np.ndarray


#: False here; True in the parallel build's globals (:func:`~cvstereo.matchers.fused._parallel.serial_and_parallel`).
PARALLEL_BUILD = False

#: A window's (active pixels x disparities) float32 plane up to this size: on one thread the fused passes, which
#: store the costs once and read them back; above it the direction passes, which compute them twice. Reading back
#: is cheaper than computing while the plane stays in the caches, dearer once it outgrows them; the limit lies
#: between the window sizes measured (bench/results/docstring-figures.md).
STORED_COSTS_MAX_BYTES = 8 << 20


def way_for(threads: int, paths: int, plane_bytes: int) -> int:
    """The way through the semi-global passes (:mod:`cvstereo.matchers.fused._sgm`) for a match on ``threads``
    threads with ``paths`` paths, whose (active pixels x disparities) planes take ``plane_bytes``: the two direction
    passes (one after the other on one thread, at once on two; on one thread the fused passes where the plane fits
    the caches, :data:`STORED_COSTS_MAX_BYTES`), and the split passes (rows and column blocks in as many chunks as
    asked) on more, or without paths.

    The split passes keep any number of cores busy, but move each plane through memory about twice as often as
    the direction passes, whose fused order keeps each pixel's costs and paths in the cache.
    """
    if threads == 1:
        return FUSED if plane_bytes <= STORED_COSTS_MAX_BYTES else DIRECTIONS
    return DIRECTIONS if threads == 2 and paths > 0 else SPLIT


def _match_features(fl, fr, counts, active, recent, prior, prm, scratch, way, chunks):
    """Match one window's normalised features; return the answers at the left camera's event pixels.

    Parameters
    ----------
    fl, fr : (2, H, W) float64 ndarray
        Normalised features of the left and right camera (rounded to float32 where they are compared).
    counts : (2, H, W) int ndarray
        The left camera's event counts of the window per polarity (anchors: pixels with events).
    active : (H, W) bool ndarray
        The left pixels the semi-global paths run through (anchors must be among them).
    recent : (H, W) bool ndarray
        Left pixels with an event in the last two windows (the noise filter's neighbours).
    prior : (H, W) float64 ndarray
        Disparity of the previous window per pixel, NaN where none (temporal coherence).
    prm : KernelParams
    scratch : KernelScratch
    way : int
        The way through the passes (:func:`way_for`): :data:`~cvstereo.matchers.fused._sgm.FUSED` (the serial build
        only), ``DIRECTIONS`` (the serial build: one after the other) or ``SPLIT`` (rows and column blocks in
        parallel chunks); all give the same answers (:mod:`cvstereo.matchers.fused._sgm`).
    chunks : int
        How many chunks the parallel loops split their rows, column blocks and answers into (at least 1; the
        answers do not depend on it).

    Returns
    -------
    x, y, pol : (M,) int ndarrays; disparity, uncertainty : (M,) float64 ndarrays
        Every answer, in raster order (row, then column): uncertainty is at most 1, and the caller keeps those
        within ``max_uncertainty`` after the occlusion test (:func:`cvstereo.matchers.fused.matcher.finish_window`).
    """
    _, h, w = fl.shape
    nd = prm.max_d + 1
    right_rev, index = scratch.right_rev, scratch.index
    # Compact storage of the active pixels, raster order: row y's are row_start[y] .. row_start[y + 1] - 1, its
    # anchors take the output slots slot_start[y] .. slot_start[y + 1] - 1.
    row_start = np.zeros(h + 1, np.int64)
    slot_start = np.zeros(h + 1, np.int64)
    n_rows = chunk_count(h, chunks)
    for ch in prange(n_rows):
        for yy in range(ch, h, n_rows):
            # Counted locally, stored once: neighbouring rows' counts share a cache line, and rows are taken by
            # different threads, which would pass that line back and forth at every pixel.
            n_active = 0
            n_anchors = 0
            for xx in range(w):
                if active[yy, xx]:
                    n_active += 1
                    if counts[0, yy, xx] + counts[1, yy, xx] > 0:
                        n_anchors += 1
            row_start[yy + 1] = n_active
            slot_start[yy + 1] = n_anchors
    for yy in range(h):
        row_start[yy + 1] += row_start[yy]
        slot_start[yy + 1] += slot_start[yy]
    n, n_anchor = row_start[h], slot_start[h]
    if n_anchor == 0:
        none = np.empty(0, np.int64)
        return none, none.copy(), none.copy(), np.empty(0), np.empty(0)
    ax = np.empty(n, np.int64)
    for ch in prange(n_rows):
        for yy in range(ch, h, n_rows):
            k = row_start[yy]
            for xx in range(w):
                index[yy, xx] = k if active[yy, xx] else -1
                if active[yy, xx]:
                    ax[k] = xx
                    k += 1
            # The right features mirrored along the row, zero beyond the left edge (see _sgm._costs_of; the
            # zeros were written when the array was made).
            for c in range(2):
                for xx in range(w):
                    right_rev[yy, c, w - 1 - xx] = fr[c, yy, xx]
    total, costs, below = scratch.work[0, :n], scratch.work[1, :n], scratch.work[2, :n]
    ints = np.empty((3, n_anchor), np.int64)  # x, y, polarity per output slot
    reals = np.empty((2, n_anchor))  # disparity, uncertainty
    flags = np.zeros((2, n_anchor), np.bool_)  # left-right consistent, answered
    if way != SPLIT or not PARALLEL_BUILD:  # (the serial build runs the direction passes for the split ones)
        # The forward pass (top to bottom, left to right: left + above, into total) and the backward pass (bottom to
        # top, right to left: right + below, into below, mirrored), each with path vectors and costs of its own: at
        # once on two threads, one after the other on one. A row's answers come from the pass that finishes it
        # second, while its own sums of the row are in the cache: with one thread, the backward pass, row by row.
        # Fused (one thread): the forward pass stores the costs, the backward pass reads them and adds to total.
        passes = 2 if prm.paths > 0 else 1
        stored = way == FUSED and not PARALLEL_BUILD  # (the parallel build runs the direction passes for the fused)
        turns = np.zeros(h, np.int64)
        for task in prange(passes):
            step = 1 - 2 * task
            own_vecs, own_cols = scratch.vecs[task], scratch.cols[task]
            own_min = np.empty((2, w), np.float32)
            ring = np.empty((COST_RUN, nd), np.float32)
            right_v = np.empty(w, np.float32)  # the right pixels' least total and its disparity (-1: none), mirrored
            right_d = np.empty(w, np.int32)
            cur = 0
            for i in range(h):
                yy = i if step > 0 else h - 1 - i
                k0, k1 = row_start[yy], row_start[yy + 1]
                if k0 == k1:
                    continue
                # Each call names its way and step: inlined with constants, the per-pixel loop of each is compiled
                # for its case alone (with the way a variable, one loop serves all cases, with a test per value).
                # PARALLEL_BUILD (a constant) prunes the fused way's loops from the parallel build, and the split
                # passes from the serial one, before they are compiled.
                if step > 0 and stored and not PARALLEL_BUILD:
                    _row_pass(fl, right_rev, prior, index, ax, yy, k0, k1, 1, prm, FUSED, total, costs, below,
                              own_vecs, own_cols, own_min, cur)
                elif step > 0:
                    _row_pass(fl, right_rev, prior, index, ax, yy, k0, k1, 1, prm, DIRECTIONS, total, ring, below,
                              own_vecs, own_cols, own_min, cur)
                elif stored and not PARALLEL_BUILD:
                    _row_pass(fl, right_rev, prior, index, ax, yy, k1 - 1, k0 - 1, -1, prm, FUSED, total, costs,
                              below, own_vecs, own_cols, own_min, cur)
                else:
                    _row_pass(fl, right_rev, prior, index, ax, yy, k1 - 1, k0 - 1, -1, prm, DIRECTIONS, below, ring,
                              costs, own_vecs, own_cols, own_min, cur)
                cur = 1 - cur
                if take_turn(turns, yy) == passes - 1 and slot_start[yy] < slot_start[yy + 1]:
                    if passes == 2 and not stored:
                        for k in range(k0, k1):
                            for d in range(nd):
                                total[k, d] = total[k, d] + below[n - 1 - k, d]
                    row_answers(yy, k0, k1, slot_start[yy], counts, recent, total, ax, prm, right_v, right_d, ints,
                                reals, flags)
    else:
        cols, cols_min = scratch.cols[0], np.empty((2, w), np.float32)
        if prm.paths == 4:
            # Column paths, chunks of adjacent column blocks in parallel: down (costs, and total = above), then up
            # (below). Adjacent blocks, so that a chunk's pixels of a row are one run of the (active pixels x nd)
            # planes rather than several apart, which cost the memory's prefetch.
            n_blocks = (w + COLUMN_BLOCK - 1) // COLUMN_BLOCK
            n_cols = chunk_count(n_blocks, chunks)
            for ch in prange(n_cols):
                x0 = ch * n_blocks // n_cols * COLUMN_BLOCK
                x1 = min((ch + 1) * n_blocks // n_cols * COLUMN_BLOCK, w)
                for s in range(2):
                    step = 1 - 2 * s
                    cur = 0
                    for i in range(h):
                        yy = i if step > 0 else h - 1 - i
                        _column_run(fl, right_rev, prior, index, ax, yy, x0, x1, step, prm,
                                    total if step > 0 else below, costs, cols, cols_min, cur)
                        cur = 1 - cur
        # Row paths and answers, rows in parallel.
        for ch in prange(n_rows):
            own = np.zeros((3, nd + 2), np.float32)  # this chunk's row path vectors, as vecs
            for r in range(3):
                own[r, 0] = own[r, nd + 1] = np.inf
            right_v = np.empty(w, np.float32)
            right_d = np.empty(w, np.int32)
            for yy in range(ch, h, n_rows):
                k0, k1 = row_start[yy], row_start[yy + 1]
                if k0 == k1:
                    continue
                _row_pass(fl, right_rev, prior, index, ax, yy, k0, k1, 1, prm, SPLIT, total, costs, below, own,
                          cols, cols_min, 0)
                if prm.paths > 0:
                    _row_pass(fl, right_rev, prior, index, ax, yy, k1 - 1, k0 - 1, -1, prm, SPLIT, total, costs,
                              below, own, cols, cols_min, 0)
                if slot_start[yy] < slot_start[yy + 1]:
                    row_answers(yy, k0, k1, slot_start[yy], counts, recent, total, ax, prm, right_v, right_d, ints,
                                reals, flags)
    has = flags[1]
    x, y, pol = ints[0][has], ints[1][has], ints[2][has]
    disparity, uncertainty, ok = reals[0][has], reals[1][has], flags[0][has]
    if prm.fill_radius > 0:
        cons = consistent_rows(x, y, ok, h)
        n_fill = chunk_count(x.size, chunks)
        for ch in prange(n_fill):
            fill_answers(ch, n_fill, x, y, ok, disparity, uncertainty, cons, prm, h, nd)
    return x, y, pol, disparity, uncertainty


#: The serial build (one thread: the direction passes in turn) and the parallel one, of one source.
match_features, match_features_parallel = serial_and_parallel(_match_features)
