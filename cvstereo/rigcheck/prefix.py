"""The light rig check that :func:`cvstereo.match` runs by default: :class:`PrefixRigCheck`.

Real rigs are never aligned: the camera called left may be the right one, and the rows a few apart. The full
check (:func:`~cvstereo.rigcheck.check_rig`, ``match --auto``) reads the whole recording first; this one looks
at a prefix of the stream only: its packets are held, checked, and then matched like the rest, which streams on
(nothing is read twice). The prefix runs from the first event until :data:`PREFIX_MIN_US` have passed and each
camera has :data:`PREFIX_EVENTS` events, or until :data:`PREFIX_MAX_US` have passed (a sparse recording: the
whole of a short one). What it found is applied to the whole stream:

- the cameras are exchanged when the check says so with confidence :attr:`PrefixRigCheck.swap_min_confidence`
  or more (a swap in error ruins every match, one not made is obvious from the negative disparities); below it,
  when the side by matching (:mod:`cvstereo.rigcheck.side_by_matching`: ``frame-area`` on the prefix's first
  80 ms, or 100,000 events per camera, in both orders) answers at least three times as often with the cameras
  exchanged;
- the row offset when its confidence reaches :attr:`PrefixRigCheck.row_min_confidence`; below it, the rows by
  matching (:mod:`cvstereo.rigcheck.rows_by_matching`: the offset, of -8 to 8, at which a matcher answers most on
  the prefix's first 80 ms, or 100,000 events per camera where they take longer) when their profile's prominence
  reaches :attr:`PrefixRigCheck.matching_min_prominence`, else none;
- the time offset only when :meth:`RigReport.time_offset_applicable
  <cvstereo.rigcheck.report.RigReport.time_offset_applicable>`: confidence 0.6 or more and not ambiguous (a
  periodic scene, a fan, peaks once per period and is never confident).

A prefix too short or too sparse for the check (fewer than ``min_events`` events in a camera) leaves the stream
as recorded, and says why. :meth:`PrefixRigCheck.describe` is the matches-file meta entry ``rigcheck`` of
docs/formats.md: the report's fields, ``applied``, ``scope`` (``"prefix"``), ``prefix_us``,
``rows_by_matching`` (when they were tried: offset, prominence, answers per offset, the span matched, their
``seconds``), ``side_by_matching`` (when it was tried: ``swap``, the answers ``given`` and ``exchanged``,
``span_us``, its ``seconds``) and ``seconds`` (the check's own cost, theirs included, left out of the run's
``elapsed_s``).

>>> import numpy as np
>>> from cvstereo.model.events import make_events, StereoPacket
>>> left = make_events([0, 10], [40, 41], [5, 5], [1, 1])
>>> check = PrefixRigCheck((128, 128))
>>> [p.until for p in check.stream([StereoPacket(left, left, 20)])]
[20]
>>> check.describe()["applied"], check.describe()["skipped"][:53]
({'swap': False, 'row_offset': 0, 'time_offset_us': 0}, 'not checked on the first 0.02 ms: the left camera has')
"""

from __future__ import annotations

import time
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field

import numpy as np
import scipy.fft

from cvstereo.geometry.rigcorrect import RigCorrection
from cvstereo.model.events import StereoPacket
from cvstereo.model.recording import Recording
from cvstereo.rigcheck.params import RigCheckParams

__all__ = ["LIGHT_PARAMS", "MATCHING_MIN_PROMINENCE", "PREFIX_EVENTS", "PREFIX_MAX_US", "PREFIX_MIN_US",
           "ROW_MIN_CONFIDENCE", "SWAP_MIN_CONFIDENCE", "PrefixRigCheck", "swapped_packet"]

#: The prefix lasts at least this long, us, and until each camera has :data:`PREFIX_EVENTS` events ...
PREFIX_MIN_US = 500_000
#: ... events that the row and side estimates need (fewer gave wrong rows at confidences below 0.2 on
#: movingPersons.dat, whose first 2 s hold 200 events: docs/guide/rigcheck.md) ...
PREFIX_EVENTS = 10_000
#: ... or at most this long, us (a sparse recording: NSTlogo holds 1,300 events per camera in 10 s).
PREFIX_MAX_US = 10_000_000
#: The check's options: fewer windows than the full check's (20 frames for rows and sides instead of 100, 40
#: windows for the time regression instead of 150, 100 local overlays per window instead of 200): a check that
#: runs on every match must stay cheap, and these changed no side and no whole row on the real files and a
#: suite v2 recording (its cost: docs/guide/rigcheck.md).
LIGHT_PARAMS = RigCheckParams(max_windows=20, reg_max_windows=40, local_max_points=100)
#: Confidence a swap needs before the default check exchanges the cameras (a swap in error ruins every match).
SWAP_MIN_CONFIDENCE = 0.8
#: Confidence a row offset needs before it is applied (:meth:`RigReport.match_kwargs`' and so ``--auto``'s): the
#: wrong rows of too few events came below 0.2; NSTlogo's, one row off its best on 2,600 events, at 0.26.
ROW_MIN_CONFIDENCE = 0.3
#: Prominence the rows by matching need (1 - median / most answers over the offsets): chosen on suite v2's tuning
#: half, where the profiles of the scenes that cannot tell the rows (thin structures, fine repeating texture at
#: 640x480) stayed within 0.01-0.05 of flat and those that can rose 0.05-0.6 above it.
MATCHING_MIN_PROMINENCE = 0.05


def swapped_packet(packet: StereoPacket) -> StereoPacket:
    """The packet with its cameras exchanged (truth negated, so that it stays x_left - x_right)."""
    def neg(d):
        return None if d is None else -d

    return StereoPacket(packet.right, packet.left, packet.until, neg(packet.right_disparity),
                        neg(packet.left_disparity))


@dataclass
class PrefixRigCheck:
    """Check the rig on a stream's prefix, then pass the whole stream on with what was found applied.

    Use once: :meth:`stream` wraps the packets (between the reader and the matcher), :meth:`restore` maps the
    matches back to the recording's rows and clock (right-anchored ones; a swap is kept: the matches refer to the
    cameras in the order used, as recorded in :meth:`describe`).

    Parameters
    ----------
    resolution : (width, height)
    min_us, min_events, max_us : int
        The prefix checked, from the first event's time: at least ``min_us`` and ``min_events`` per camera, at most
        ``max_us``.
    params : RigCheckParams
        The check's options (``time_apply_confidence`` decides the time offset); default :data:`LIGHT_PARAMS`.
    swap_min_confidence, row_min_confidence : float
        Confidence the swap and the row offset need before they are applied.
    matching_min_prominence : float
        Prominence the rows by matching need, tried where the row offset's confidence is below
        ``row_min_confidence`` (None: not tried).
    threads : int
        Threads of the check's transforms and of the rows by matching (the match's ``threads``; the same result on
        any number).
    side_by_matching : bool
        Where the overlay's side is below ``swap_min_confidence``, let the matcher's answers in both orders decide
        (:mod:`cvstereo.rigcheck.side_by_matching`).
    row_field : bool
        Also look for rows that differ across the image (:mod:`cvstereo.rigcheck.row_field`) around the row offset
        found, and where a field is found apply it instead of that offset.
    """

    resolution: tuple[int, int]
    min_us: int = PREFIX_MIN_US
    min_events: int = PREFIX_EVENTS
    max_us: int = PREFIX_MAX_US
    params: RigCheckParams = LIGHT_PARAMS
    swap_min_confidence: float = SWAP_MIN_CONFIDENCE
    row_min_confidence: float = ROW_MIN_CONFIDENCE
    matching_min_prominence: float | None = MATCHING_MIN_PROMINENCE
    threads: int = 1
    row_field: bool = False
    side_by_matching: bool = True
    report: object = field(default=None, init=False)
    side_found: object = field(default=None, init=False)  # the SideByMatching, where it was tried
    by_matching: object = field(default=None, init=False)  # the RowsByMatching, where they were tried
    skipped: str | None = field(default=None, init=False)
    applied: dict = field(default_factory=lambda: {"swap": False, "row_offset": 0, "time_offset_us": 0},
                          init=False)
    seconds: float = field(default=0.0, init=False)
    prefix_us: int = field(default=0, init=False)  # the span checked, from the first event to the last packet's end
    corrected: object = field(default=None, init=False)  # the CorrectedStream, for its counts of dropped events
    field_search: object = field(default=None, init=False)  # the RowFieldSearch, where the field was looked for
    field_seconds: float = field(default=0.0, init=False)  # of `seconds`, the row field's search
    side_seconds: float = field(default=0.0, init=False)  # of `seconds`, the side by matching
    rows_seconds: float = field(default=0.0, init=False)  # of `seconds`, the rows by matching
    fielded: object = field(default=None, init=False)  # the row field's stream, for its restore and dropped events

    def __post_init__(self):
        if not 0 < int(self.min_us) <= int(self.max_us) or int(self.min_events) < 0:
            raise ValueError(f"rig check: prefix min_us={self.min_us}, max_us={self.max_us}, min_events="
                             f"{self.min_events} are out of range; give 0 < min_us <= max_us and min_events >= 0.")

    def stream(self, packets: Iterable[StereoPacket]) -> Iterator[StereoPacket]:
        """The packets as the matcher gets them: those of the prefix held until it is checked, then all of them
        with the cameras exchanged and the offsets removed as found."""
        if self.row_field:  # its search matches more events than the check reads: the prefix is held on for them
            from cvstereo.rigcheck.row_field import SPAN_EVENTS, SPAN_MAX_US

            hold_us, hold_events = SPAN_MAX_US, SPAN_EVENTS
        else:
            hold_us = hold_events = 0
        packets = iter(packets)
        held = []
        checked = None  # how many of the held packets the check reads
        t_first = None
        counts = np.zeros(2, np.int64)
        for packet in packets:
            held.append(packet)
            counts += (packet.left.size, packet.right.size)
            if t_first is None:
                starts = [int(ev["t"][0]) for ev in (packet.left, packet.right) if ev.size]
                t_first = min(starts) if starts else None
            if t_first is None:
                continue
            span = int(packet.until) - t_first
            if checked is None:
                self.prefix_us = span
                if span >= self.max_us or (span >= self.min_us and counts.min() >= self.min_events):
                    checked = len(held)
            if checked is not None and (span >= hold_us or counts.min() >= hold_events):
                break
        self._check(held, len(held) if checked is None else checked)
        out = _chained(held, packets)
        if self.applied["swap"]:
            out = map(swapped_packet, out)
        field_stage = None if self.field_search is None else self.field_search.stage
        rows = 0 if field_stage is not None else self.applied["row_offset"]
        correction = RigCorrection(rows, self.applied["time_offset_us"], self.resolution)
        if not correction.is_identity:
            self.corrected = out = correction.stream(out)
        if field_stage is not None:
            self.fielded = out = field_stage.stream(out)
        return (yield from out)

    def restore(self, matches: np.ndarray, *, anchor: str = "event") -> np.ndarray:
        """Matches of the corrected stream in the recording's rows and clock (the row field's restore, then
        :meth:`RigCorrection.restore <cvstereo.geometry.rigcorrect.RigCorrection.restore>`; ``anchor``: the
        matcher's)."""
        if self.fielded is not None:
            matches = self.fielded.restore(matches, anchor=anchor)
        return matches if self.corrected is None else self.corrected.correction.restore(matches, anchor=anchor)

    def describe(self) -> dict:
        """The meta entry ``rigcheck``: the report (when the check ran), ``applied``, ``scope``, ``prefix_us``,
        ``seconds``, ``skipped`` (why it did not run, or None) and ``dropped_events`` (of the correction)."""
        out = {} if self.report is None else self.report.to_dict()
        dropped = 0 if self.corrected is None else self.corrected.dropped_rows + self.corrected.dropped_times
        dropped += 0 if self.fielded is None else sum(self.fielded.dropped)
        found = self.by_matching
        by_matching = None if found is None else {
            "offset": found.offset, "prominence": round(found.prominence, 4), "span_us": found.span_us,
            "counts": {str(k): v for k, v in found.counts.items()}, "seconds": self.rows_seconds}
        out.update(scope="prefix", prefix_us=int(self.prefix_us), seconds=self.seconds, skipped=self.skipped,
                   applied=dict(self.applied), dropped_events=dropped, rows_by_matching=by_matching,
                   side_by_matching=None if self.side_found is None else {**self.side_found._asdict(),
                                                                           "seconds": self.side_seconds})
        if self.row_field:
            out["row_field"] = None if self.field_search is None else {
                "seconds": self.field_seconds, **self.field_search.describe()}
        return out

    def _check(self, held: list[StereoPacket], checked: int) -> None:
        """Check the rig on the first ``checked`` of the packets ``held``; with ``row_field``, look for the field on
        all of them."""
        from cvstereo.rigcheck.check import check_rig

        start = time.perf_counter()
        # Each camera's held events once; the check reads their first part (the packets are time slices).
        pair = [np.concatenate([getattr(p, cam) for p in held]) if held else None for cam in ("left", "right")]
        left, right = (None if whole is None else whole[:sum(getattr(p, cam).size for p in held[:checked])]
                       for whole, cam in zip(pair, ("left", "right"), strict=True))
        try:
            if left is None:
                raise ValueError("the stream has no events")
            with scipy.fft.set_workers(self.threads):
                self.report = report = check_rig(Recording(left, right, resolution=self.resolution), self.params,
                                                 max_seconds=None)
        except ValueError as exc:
            reason = str(exc).removeprefix("check_rig: ")
            self.skipped = f"not checked on the first {self.prefix_us / 1000:g} ms: {reason}"
        else:
            swap = bool(report.swap and report.swap_confidence >= self.swap_min_confidence)
            if report.swap_confidence < self.swap_min_confidence and self.side_by_matching:
                swap = self._side_by_matching(left, right, report)
            # The report's offsets refer to the cameras after its swap: negated, they are the given order's.
            sign = 1 if swap == report.swap else -1
            if report.row_offset_confidence >= self.row_min_confidence:
                rows = sign * round(report.row_offset)
            elif self.matching_min_prominence is not None:  # the overlay is unsure: the rows by matching
                rows = self._rows_by_matching(*((right, left) if swap else (left, right)))
            else:
                rows = 0
            dt = round(report.time_offset_us) if report.time_offset_applicable() else 0
            self.applied = {"swap": swap, "row_offset": int(rows), "time_offset_us": sign * int(dt)}
            if self.row_field:
                self._row_field(*(pair[::-1] if swap else pair))
        self.seconds = time.perf_counter() - start

    def _side_by_matching(self, left: np.ndarray, right: np.ndarray, report) -> bool:
        """The camera order by matching (:mod:`cvstereo.rigcheck.side_by_matching`), the overlay's rows applied."""
        from cvstereo.rigcheck.side_by_matching import side_by_matching

        rows = (-1 if report.swap else 1) * round(report.row_offset)  # in the given order
        self.side_found, self.side_seconds = _timed(side_by_matching, left, right, resolution=self.resolution,
                                                    rows=rows, threads=self.threads)
        return self.side_found.swap

    def _rows_by_matching(self, left: np.ndarray, right: np.ndarray) -> int:
        """The rows by matching (in the cameras' order used) where they stand out, else 0."""
        from cvstereo.rigcheck.rows_by_matching import rows_by_matching

        reach = min(self.params.max_row_offset, self.resolution[1] - 1)
        self.by_matching, self.rows_seconds = _timed(rows_by_matching, left, right, resolution=self.resolution,
                                                     reach=reach, threads=self.threads)
        found = self.by_matching
        return found.offset if found.prominence >= self.matching_min_prominence else 0

    def _row_field(self, left: np.ndarray, right: np.ndarray) -> None:
        """Look for a row field around the row offset found (in the cameras' order used); apply it where found."""
        from cvstereo.rigcheck.row_field import estimate_row_field

        self.field_search, self.field_seconds = _timed(estimate_row_field, left, right, resolution=self.resolution,
                                                       centre=self.applied["row_offset"], threads=self.threads)
        self.applied["row_field"] = self.field_search.field is not None


def _timed(run, *args, **kwargs):
    """``run(*args, **kwargs)`` and the seconds it took (a stage's own share of the check's ``seconds``)."""
    start = time.perf_counter()
    out = run(*args, **kwargs)
    return out, time.perf_counter() - start


def _chained(held: list[StereoPacket], rest: Iterator[StereoPacket]) -> Iterator[StereoPacket]:
    yield from held
    held.clear()  # the prefix's packets are not kept once they are matched
    yield from rest

