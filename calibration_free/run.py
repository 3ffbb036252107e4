"""Run a matcher over a whole recording: :func:`match`."""

from __future__ import annotations

import os
import time

import cvstereo
from calibration_free.registry import create_matcher
from cvstereo.matches import MatchResult, concat_matches, sort_matches
from cvstereo.recording import Recording

#: Packet length used to stream a recording through a matcher. The result does not depend on it; the speed
#: does: one frame window per packet saves the frame matchers from joining partial windows, and the event
#: matchers pay a fixed cost per call (on 2arms-50cm event-time ran 3x faster with 40 ms than with 10 ms).
DEFAULT_PACKET_US = 40_000


def match(recording, right=None, *, method: str = "frame", variant: str | None = None,
          packet_us: int = DEFAULT_PACKET_US, progress: bool = False, row_offset: float = 0,
          time_offset_us: int = 0, param_set: str = "adaptive", **params) -> MatchResult:
    """Run one matcher over a recording, streaming it packet by packet.

    Parameters
    ----------
    recording : Recording or path-like
        A recording, or a file that :func:`cvstereo.io.read_recording` can read.
    right : path-like, optional
        The right camera's file, for formats with one file per camera.
    method : str, keyword-only
        ``frame``, ``frame-area``, ``event-time``, ``event-area``, ``event-vector``, ``stereobm``, ``sgbm``.
    variant : str, optional
        Variant name (formats.md); default: the parameter set's default variant (``thesis``: the method's first).
    packet_us : int
        Packet length for streaming.
    progress : bool
        Show a progress bar.
    row_offset, time_offset_us : keyword-only
        The rig's offsets (:mod:`cvstereo.rigcorrect`): the right camera's rows are shifted by ``row_offset``
        and its times by ``-time_offset_us`` before matching, and right-anchored matches are mapped back;
        recorded in meta under ``rig_correction``. :func:`cvstereo.rigcheck.check_rig` estimates both.
    param_set : {"adaptive", "thesis"}, keyword-only
        :mod:`cvstereo.param_sets`; recorded in meta under ``param_set``.
    **params
        Parameter overrides (field names of the method's parameter dataclass), on top of the set's values.

    Returns
    -------
    MatchResult
        Time-ordered matches and the meta of formats.md. ``meta["diagnostics"]`` says how much of the
        recording answered (:func:`cvstereo.signal_level.silence_warning` turns it into one line): windows with
        events and with matches (40 ms, absolute clock), and for the thesis matchers windows seen, windows with
        candidates, the highest value against its threshold and the threshold in force over time.
    """
    source = None
    if not isinstance(recording, Recording):
        from cvstereo.io import read_recording

        source = [os.fspath(recording)] + ([os.fspath(right)] if right is not None else [])
        recording = read_recording(recording, right)
    matcher = create_matcher(method, variant, resolution=recording.resolution, param_set=param_set, **params)
    parts = []
    bar = _progress_bar(progress, recording, method)
    start = time.perf_counter()
    packets = recording.packets(packet_us)
    correction = None
    if row_offset or time_offset_us:
        from cvstereo.rigcorrect import RigCorrection

        correction = RigCorrection(row_offset, int(time_offset_us), recording.resolution)
        packets = correction.stream(packets)
    for packet in packets:
        parts.append(matcher.feed(packet.left, packet.right, until=packet.until))
        if bar is not None:
            bar.update(packet.left.size + packet.right.size)
    parts.append(matcher.flush())
    elapsed = time.perf_counter() - start
    if bar is not None:
        bar.close()
    meta = matcher.describe()
    meta.update(
        elapsed_s=elapsed,
        input_events=int(recording.left.size + recording.right.size),
        duration_s=recording.duration_s,
        resolution=list(recording.resolution),
        version=cvstereo.__version__,
        input=source if source is not None else recording.meta.get("source", "memory"),
    )
    meta["param_set"] = param_set
    matches = concat_matches(parts)
    if correction is not None:
        matches = correction.restore(matches)
        meta["rig_correction"] = {**correction.describe(), "dropped_events": packets.dropped_rows +
                                  packets.dropped_times}
    matches = sort_matches(matches)
    meta["diagnostics"] = _diagnostics(matcher, recording, matches, meta)
    return MatchResult(matches, meta)


def _diagnostics(matcher, recording: Recording, matches, meta: dict) -> dict:
    """How much of the recording answered: windows with events and with matches, and the matcher's own."""
    from cvstereo.signal_level import coverage_of_windows

    with_matches, with_events = coverage_of_windows(recording, matches, meta)
    out = {"window_us": 40_000, "windows_with_events": with_events, "windows_with_matches": with_matches}
    if hasattr(matcher, "diagnostics"):
        out.update(matcher.diagnostics())
    return out


def _progress_bar(enabled: bool, recording: Recording, method: str):
    if not enabled:
        return None
    from tqdm.auto import tqdm

    return tqdm(total=recording.left.size + recording.right.size, unit="ev", unit_scale=True, desc=method,
                leave=False)
