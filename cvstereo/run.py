"""Run a matcher over a stream: :func:`run`, the one feed loop, and :func:`match`, a recording through it.

:func:`run` feeds packets to a matcher and gathers its matches, meta and per-match arrays; :func:`match`
adapts what the user gives (a Recording, a file, event arrays), builds the matcher and the stages between the
events and the matcher (rig correction, rectification), and runs it, streaming the file packet by packet."""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Iterable, Iterator

import numpy as np

import cvstereo
from cvstereo.matchers.protocol import StreamMatcher
from cvstereo.matchers.registry import METHODS, create_matcher
from cvstereo.model.events import StereoPacket, distinct_sorted, is_time_ordered
from cvstereo.model.fingerprint import CAMERAS, EventFingerprint
from cvstereo.model.matches import MatchResult, concat_matches
from cvstereo.model.recording import ORIGIN_KEY, Recording, origin_of

__all__ = ["DEFAULT_PACKET_US", "DIAGNOSTICS_WINDOW_US", "match", "run", "run_iter"]

#: Windows of the diagnostics (:func:`cvstereo.evaluation.diagnostics.silence_warning`): 40 ms on the absolute
# clock.
DIAGNOSTICS_WINDOW_US = 40_000

#: Packet length used to stream a recording through a matcher. The result does not depend on it; the speed
#: does: one frame window per packet saves the frame matchers from joining partial windows, and the event
#: matchers pay a fixed cost per call, which longer packets spread over more events.
DEFAULT_PACKET_US = 40_000


class _Counted(Iterator[StereoPacket]):
    """Packets passed through, counting events and the first and last timestamp (for the meta), and taking the
    fingerprint of the events as read (:mod:`cvstereo.model.fingerprint`; the seconds it takes are kept apart, as
    they are not the matcher's)."""

    def __init__(self, packets: Iterator[StereoPacket]):
        self._packets = iter(packets)
        self.events = 0
        self.t_first: int | None = None
        self.t_last: int | None = None
        self.windows: set[int] = set()  # absolute 40 ms windows that hold events (for the diagnostics)
        self.fingerprint = EventFingerprint()
        self.fingerprint_s = 0.0

    def __next__(self) -> StereoPacket:
        packet = next(self._packets)
        start = time.perf_counter()
        self.fingerprint.update(packet.left, packet.right)
        self.fingerprint_s += time.perf_counter() - start
        for ev in (packet.left, packet.right):
            if ev.size:
                first, last = int(ev["t"][0]), int(ev["t"][-1])
                self.t_first = first if self.t_first is None else min(self.t_first, first)
                self.t_last = last if self.t_last is None else max(self.t_last, last)
                self.windows.update(_windows_of(ev["t"], first, last))
        self.events += packet.left.size + packet.right.size
        return packet

    @property
    def duration_s(self) -> float:
        return 0.0 if self.t_first is None else (self.t_last - self.t_first) / 1e6


def _windows_of(t: np.ndarray, first: int, last: int) -> list[int]:
    """The diagnostics windows that hold the time-ordered times ``t`` (``first``, ``last``: its ends).

    A packet's times are ordered (the matcher refuses them otherwise), so the windows come from a pass without
    a sort (``np.unique`` of a packet cost 10 % of the frame matchers' time at 640x480), and from the ends
    alone where both lie in one window.
    """
    k0, k1 = first // DIAGNOSTICS_WINDOW_US, last // DIAGNOSTICS_WINDOW_US
    if k0 == k1:
        return [k0]
    return distinct_sorted(t // DIAGNOSTICS_WINDOW_US).tolist()


def match(recording, right=None, *, method: str = "frame", variant: str | None = None,
          packet_us: int = DEFAULT_PACKET_US, progress: bool = False, row_offset: float | None = None,
          time_offset_us: int | None = None, rectification=None, param_set: str = "adaptive",
          rig_check: bool = True, columns: str | None = None, time_unit: str | None = None,
          resolution: tuple[int, int] | None = None, threads: int | None = None, row_field: bool = False,
          **params) -> MatchResult:
    """Run one matcher over a recording, streaming it packet by packet.

    Parameters
    ----------
    recording : Recording, RecordingStream or path-like
        A recording in memory, a recording opened by :func:`cvstereo.io.open_recording` (with its format
        options), or a file that it can open: the packets of a stream or a file are read as they are matched,
        so memory stays bounded whatever the file's size (only the matches are kept). ``meta["input"]``:
        the file(s) read, or a Recording's ``meta["source"]``.
    right : path-like, optional
        The right camera's file, for formats with one file per camera (with a path only).
    method : str, keyword-only
        A registered method (:data:`cvstereo.matchers.registry.METHODS`): ``frame``, ``frame-area``, ``event-time``,
        ``event-area``, ``event-vector``, ``stereobm``, ``sgbm``, ...
    variant : str, optional
        Variant name (docs/formats.md); default: the parameter set's default variant (``thesis``: the method's first).
    packet_us : int
        Packet length for streaming.
    progress : bool
        Show a progress bar.
    row_offset, time_offset_us : keyword-only
        The rig's offsets (:mod:`cvstereo.geometry.rigcorrect`): the right camera's rows are shifted by ``row_offset``
        and its times by ``-time_offset_us`` before matching, and right-anchored matches are mapped back;
        recorded in meta under ``rig_correction``. :func:`cvstereo.rigcheck.check_rig` estimates both. Either
        given (0 too: "the rig is aligned") turns the default rig check off.
    columns, time_unit, resolution : keyword-only
        For events given as arrays (or lists of rows): the column order of ``(N, 4)`` arrays, the unit of their
        times (required for float times) and the sensor size (default 128x128; tonic's ``sensor_size``
        ``(W, H, 2)`` is accepted as it is); see :func:`cvstereo.model.arrays.events_from`. With a Recording,
        ``resolution`` may only repeat the recording's; ``columns`` and ``time_unit`` are refused (nothing
        would use them).
    rectification : cvstereo.geometry.rectify.Rectification, optional, keyword-only
        Rectify the events with a calibration before matching (:mod:`cvstereo.geometry.rectify`); matches are mapped
        back to the recording's pixels, disparities are the rectified pair's; recorded in meta under
        ``rectification``. Not together with ``row_offset`` / ``time_offset_us``.
    param_set : {"adaptive", "thesis"}, keyword-only
        :mod:`cvstereo.matchers.sets`; recorded in meta under ``param_set``.
    threads : int, optional, keyword-only
        Threads the matcher may run on (default: the cores this process may use; docs/guide/threads.md). The
        matches do not depend on it, so it is not recorded in meta.
    rig_check : bool, keyword-only
        Check the rig on the first second of the stream and apply what it finds with confidence (camera order,
        row offset, a confident time offset) to all of it (:class:`cvstereo.rigcheck.prefix.PrefixRigCheck`;
        the prefix is held, then matched: nothing is read twice); recorded in meta under ``rigcheck``, its cost
        left out of ``elapsed_s``. Not with the ``thesis`` set (the thesis aligned its rig by hand), nor with a
        rectification or offsets given (they win: docs/guide/depth.md). False: the events as recorded. Where the
        cameras were exchanged the matches refer to them in the order used
        (:func:`cvstereo.geometry.source.as_matched` gives the recording in that order).
    row_field : bool, keyword-only
        With the rig check: also look for rows that differ across the image (a roll, focal lengths or lenses
        that differ; :mod:`cvstereo.rigcheck.row_field`) and apply the field found instead of one row offset;
        recorded in ``meta["rigcheck"]["row_field"]``. Refused where the check does not run.
    **params
        Parameter overrides (field names of the method's parameter dataclass, or their old names), on top of the
        set's values.

    Returns
    -------
    MatchResult
        Time-ordered matches and the meta of docs/formats.md. ``meta["fingerprint"]`` identifies the events as read
        (before rig correction or rectification: :mod:`cvstereo.model.fingerprint`), so that the matches can be told
        from those of another recording; ``elapsed_s`` leaves out the time it took. ``meta["diagnostics"]`` says
        how much of the recording answered (:func:`cvstereo.evaluation.diagnostics.silence_warning` turns it
        into one
        line): windows with events and with matches (40 ms, absolute clock), and for the thesis matchers windows
        seen, windows with candidates, the highest value against its threshold and the threshold in force over
        time.

    Examples
    --------
    >>> from cvstereo.model.events import make_events
    >>> left = make_events([0, 0, 0], [40, 41, 42], [5, 5, 5], [1, 1, 1])
    >>> result = match(Recording(left, left), method="frame-area", threshold=0.5)
    >>> result.meta["method"], result.meta["input_events"]
    ('frame-area', 6)
    """
    from cvstereo.io.stream import RecordingStream

    recording = _as_source(recording, right, method, columns=columns, time_unit=time_unit, resolution=resolution)
    if isinstance(recording, Recording):
        stream, source = recording, recording.meta.get("source", "memory")
        total = recording.left.size + recording.right.size
    elif isinstance(recording, RecordingStream):
        stream, source, total = recording, list(recording.given or recording.files), None
    else:
        from cvstereo.io import open_recording

        source = [os.fspath(recording)] + ([os.fspath(right)] if right is not None else [])
        stream, total = open_recording(recording, right), None
    matcher = create_matcher(method, variant, resolution=stream.resolution, param_set=param_set, threads=threads,
                             **params)
    correction = check = None
    if row_offset or time_offset_us:
        from cvstereo.geometry.rigcorrect import RigCorrection

        correction = RigCorrection(row_offset or 0, int(time_offset_us or 0), stream.resolution)
    if rig_check and param_set != "thesis" and rectification is None and row_offset is None \
            and time_offset_us is None:
        from cvstereo.rigcheck.prefix import PrefixRigCheck

        check = PrefixRigCheck(tuple(stream.resolution), threads=matcher.threads, row_field=row_field)
    elif row_field:
        raise ValueError("row_field needs the rig check, which does not run with rig_check=False, the thesis set, "
                         "a rectification or offsets given.")
    if rectification is not None:
        if correction is not None:
            raise ValueError("give a calibration or row/time offsets, not both: rectification already aligns the rows.")
        if tuple(rectification.resolution) != tuple(stream.resolution):
            raise ValueError(f"the calibration is for {rectification.resolution[0]}x{rectification.resolution[1]}, "
                             f"the recording is {stream.resolution[0]}x{stream.resolution[1]}.")
    stages = {}  # the stage objects of this run, for their counts of dropped events

    def through(packets):
        if check is not None:
            packets = check.stream(packets)
        if correction is not None:
            packets = stages["corrected"] = correction.stream(packets)
        if rectification is not None:
            packets = stages["rectified"] = rectification.stream(packets)
        return packets

    def restore(found):
        if "rectified" in stages:
            return stages["rectified"].restore(found, anchor=matcher.anchor)
        if check is not None:
            return check.restore(found, anchor=matcher.anchor)
        return found if correction is None else correction.restore(found, anchor=matcher.anchor)

    bar = _progress_bar(progress, total, method)
    try:
        result = run(matcher, stream.packets(packet_us), through=through, restore=restore,
                     on_packet=None if bar is None else (lambda packet, found: bar.update(
                         0 if packet is None else packet.left.size + packet.right.size)))
    finally:
        if bar is not None:
            bar.close()
    meta = result.meta
    meta.update(resolution=list(stream.resolution), input=source, param_set=param_set)
    origin = origin_of(stream.meta, [meta["fingerprint"][c]["t_first"] for c in CAMERAS])
    if origin is not None:
        meta[ORIGIN_KEY] = origin
    if correction is not None:
        corrected = stages["corrected"]
        meta["rig_correction"] = {**correction.describe(),
                                  "dropped_events": corrected.dropped_rows + corrected.dropped_times}
    if rectification is not None:
        meta["rectification"] = {**rectification.describe(), "dropped_events": sum(stages["rectified"].dropped)}
    if check is not None:
        meta["rigcheck"] = check.describe()
        meta["elapsed_s"] = max(0.0, meta["elapsed_s"] - check.seconds)  # the matcher's time; the check's apart
    return result


def run(matcher: StreamMatcher, packets: Iterable[StereoPacket], *,
        through: Callable[[Iterator[StereoPacket]], Iterator[StereoPacket]] | None = None,
        restore: Callable[[np.ndarray], np.ndarray] | None = None,
        on_packet: Callable[[StereoPacket | None, np.ndarray], None] | None = None) -> MatchResult:
    """The one feed loop: every packet through ``matcher``, then its flush, gathered into one result.

    Parameters
    ----------
    matcher : StreamMatcher
    packets : iterable of StereoPacket
        The events as read, in time order (a recording's or a file's ``packets()``). They are counted and
        fingerprinted (:mod:`cvstereo.model.fingerprint`) before any stage changes them.
    through : callable, optional, keyword-only
        The stages between the events as read and the matcher (rig correction, rectification): takes the
        packets, returns the packets the matcher sees.
    restore : callable, optional, keyword-only
        Maps the matches of every packet back to the recording's pixels and clock (the stages' inverse).
    on_packet : callable, optional, keyword-only
        ``on_packet(packet, found)`` after every packet with its (restored) matches, and ``on_packet(None,
        tail)`` after the flush: where a progress bar or a status line reads the run.

    Returns
    -------
    MatchResult
        The matches in time order; meta: the matcher's :meth:`~cvstereo.matchers.protocol.StreamMatcher.describe`,
        ``elapsed_s`` (without the fingerprint's time), ``input_events``, ``duration_s``, ``version``,
        ``fingerprint`` and ``diagnostics``; arrays: ``uncertainty`` when the matcher rates its matches.
    """
    counted = _Counted(iter(packets))
    parts = []
    start = time.perf_counter()
    for packet, found in run_iter(matcher, counted, through=through, restore=restore):
        parts.append(found)
        if on_packet is not None:
            on_packet(packet, found)
    elapsed = time.perf_counter() - start - counted.fingerprint_s
    meta = matcher.describe()
    meta.update(elapsed_s=elapsed, input_events=int(counted.events), duration_s=counted.duration_s,
                version=cvstereo.__version__, fingerprint=counted.fingerprint.result())
    matches = concat_matches(parts)
    order = _time_order(matches["t"])  # sort_matches' order (None: already in it), for per-match arrays too
    if order is not None:
        matches = matches[order]
    arrays = {}
    uncertainty = matcher.take_uncertainty()  # None: the matcher does not rate its matches
    if uncertainty is not None:
        if uncertainty.size == matches.size:
            arrays["uncertainty"] = uncertainty if order is None else uncertainty[order]
        else:  # a stage in between (rectification) dropped matches: the values no longer line up
            meta["uncertainty"] = "not stored: a stage between matcher and output changed the matches"
    meta["diagnostics"] = _diagnostics(matcher, counted.windows, matches, meta)
    return MatchResult(matches, meta, arrays)


def run_iter(matcher: StreamMatcher, packets: Iterable[StereoPacket], *,
             through: Callable[[Iterator[StereoPacket]], Iterator[StereoPacket]] | None = None,
             restore: Callable[[np.ndarray], np.ndarray] | None = None
             ) -> Iterator[tuple[StereoPacket | None, np.ndarray]]:
    """The feed loop itself, as a generator: ``(packet, matches)`` per packet, then ``(None, tail)`` after the flush.

    :func:`run` gathers what it yields into one result; a live run (:func:`cvstereo.sensors.live.run_live`)
    reads it as it comes and keeps none of it, so that its memory does not grow with the session. The
    matches of a packet are restored (``restore``) before they are yielded; ``through`` and ``restore`` are as
    for :func:`run`. The matcher is flushed once the packets end (a live run's end when it is stopped), not
    when the generator is closed early.
    """
    fed = iter(packets) if through is None else through(iter(packets))
    for packet in fed:
        found = matcher.feed(packet.left, packet.right, until=packet.until)
        yield packet, found if restore is None else restore(found)
    tail = matcher.flush()
    yield None, tail if restore is None else restore(tail)


def _time_order(t: np.ndarray) -> np.ndarray | None:
    """The stable order that sorts the times ``t``, or None when they are in order already.

    Matchers return time-ordered matches (the feed contract), so the stable argsort would be the identity; the
    check is one pass, where the argsort and the gather of every match cost ~5 % of event-area's time at 640x480.
    """
    if is_time_ordered(t):
        return None
    return np.argsort(t, kind="stable")


def _diagnostics(matcher, event_windows: set[int], matches, meta: dict) -> dict:
    """How much of the recording answered: windows with events and with matches, and the matcher's own."""
    from cvstereo.evaluation.diagnostics import coverage_of_windows

    with_matches, with_events = coverage_of_windows(event_windows, matches, meta, DIAGNOSTICS_WINDOW_US)
    out = {"window_us": DIAGNOSTICS_WINDOW_US, "windows_with_events": with_events,
           "windows_with_matches": with_matches}
    out.update(matcher.diagnostics())
    return out


def _as_source(recording, right, method: str, *, columns, time_unit, resolution):
    """A Recording, a RecordingStream or a path for :func:`match`, after catching the easy mistakes with the arguments.

    An argument that would be ignored is refused rather than dropped: ``columns`` and ``time_unit`` apply to
    arrays only, and ``resolution`` to arrays (a Recording and a file carry their own; given with a Recording
    it must agree with it).
    """
    from cvstereo.io.stream import RecordingStream
    from cvstereo.model.arrays import events_from, is_event_data
    from cvstereo.model.events import DEFAULT_RESOLUTION, check_resolution

    if isinstance(right, str) and right in METHODS and not os.path.exists(right):
        raise TypeError(f"match(recording, {right!r}): the method is keyword-only; write "
                        f"match(recording, method={right!r}) (the second argument is the right camera).")
    res = None if resolution is None else check_resolution(resolution, source="match(resolution=...)")
    if isinstance(recording, RecordingStream):
        if right is not None or columns is not None or time_unit is not None or resolution is not None:
            raise TypeError("match(stream, right/columns/time_unit/resolution): an opened recording has its cameras "
                            "and format already; give these to open_recording instead.")
        return recording
    if isinstance(recording, Recording):
        if right is not None:
            raise TypeError("match(recording, right): a Recording holds both cameras already; give right only "
                            "with the left camera's file or events.")
        if columns is not None or time_unit is not None:
            raise TypeError("match(recording, columns=/time_unit=): these say how to read event arrays; a "
                            "Recording's events are converted already.")
        if res is not None and res != tuple(recording.resolution):
            raise ValueError(f"match(recording, resolution={res}): the recording is "
                             f"{recording.resolution[0]}x{recording.resolution[1]}; build it with the right "
                             "resolution (Recording(..., resolution=...)) instead.")
        return recording
    if is_event_data(recording):
        if right is None or not is_event_data(right):
            raise TypeError("match(left_events, right_events, method=...): give the right camera's events too.")
        res = res or DEFAULT_RESOLUTION
        return Recording(events_from(recording, columns=columns, time_unit=time_unit, resolution=res,
                                     source="left events"),
                         events_from(right, columns=columns, time_unit=time_unit, resolution=res,
                                     source="right events"), resolution=res, meta={"source": "arrays"})
    if is_event_data(right):
        raise TypeError("match(path, right_events): give both cameras as files, or both as event arrays.")
    if columns is not None or resolution is not None or time_unit is not None:
        raise TypeError("columns=, time_unit= and resolution= are for events given as arrays; a file says its "
                        "own (or use the --format options of open_recording).")
    return recording


def _progress_bar(enabled: bool, total: int | None, method: str):
    if not enabled:
        return None
    from tqdm.auto import tqdm

    return tqdm(total=total, unit="ev", unit_scale=True, desc=method, leave=False)
