"""What the rig check found, and how it is told: :class:`RigReport` (text summary, JSON, match options).

A figure that could not be estimated is NaN in the report's fields; users never see NaN: the summary
says ``n/a`` and :meth:`RigReport.to_dict` (``rigcheck --json``, the matches meta) gives ``null``.
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass

from cvstereo.model.recording import Recording
from cvstereo.rigcheck.params import RigCheckParams

__all__ = ["RigReport"]


@dataclass(frozen=True)
class RigReport:
    """What :func:`~cvstereo.rigcheck.check_rig` found. Offsets and disparities refer to the recording after
    :meth:`prepare`.

    Attributes
    ----------
    swap : bool
        True when the camera given as left is the right one: exchange them (``Recording.swapped()``).
    swap_confidence : float
    row_offset : float
        Rows to add to the right camera's y to line it up with the left (``y_left ~ y_right + row_offset``).
    row_offset_confidence : float
    row_offset_bands : tuple of float
        The same per horizontal band of the image (``band_rows`` gives each band's left-camera rows).
    band_rows : tuple of (int, int)
        ``[start, stop)`` rows of each band.
    row_offset_band_confidence : tuple of float
    row_offset_varies : bool
        True when confident bands disagree by more than one row.
    time_offset_us : float
        How much later the right camera stamps the same change (``t_right ~ t_left + time_offset_us``).
    time_offset_confidence : float
    time_offset_ambiguous : bool
        True when the pixel coincidences peak as high at other offsets too (a periodic scene such as a fan:
        one peak per blade period): the reported offset is the one nearest 0, and :meth:`match_kwargs` does
        not apply it (:meth:`time_offset_applicable`).
    time_offset_alternatives_us : tuple of float
        Those other offsets, nearest to the reported one first (empty when not ambiguous).
    time_offset_period_us : float
        Their spacing (the scene's period), NaN when not ambiguous.
    disparity_peak : float
        The disparity that overlays the most events (sub-pixel), px.
    disparity_peaks : tuple of float
        Local maxima of the global overlay profile that stand out from its background, strongest first.
    disparity_percentiles : dict
        Percentile (int) -> disparity (px) of the local best overlays (``RigCheckParams.disparity_percentiles``);
        NaN without any local overlay on the possible side.
    disparity_range : (float, float)
        5th and 95th percentile.
    disparity_confidence : float
        Share of the local overlays that agree in sign with the decision (1 = all on the possible side).
    events : (int, int)
        Events of the left and right camera.
    rate_ratio : float
        Right / left event count.
    rate_ratio_confidence : float
    burst_ratio_p95 : float
        95th percentile, over 5 ms windows with events in both cameras, of the larger camera's count over the
        smaller's (the thesis saw up to 3x); NaN without such windows.
    on_fraction : (float, float)
        Share of ON events, left and right.
    on_fraction_confidence : float
    noise_rate_hz : (float, float)
        Isolated events per second, left and right.
    noise_fraction : (float, float)
        Share of isolated events.
    noise_confidence : float
    duration_s : float
        Seconds analysed.
    settings : dict
        The :class:`RigCheckParams` the check ran with (``window_us`` resolved), and ``time_offset_method``.
    """

    swap: bool
    swap_confidence: float
    row_offset: float
    row_offset_confidence: float
    row_offset_bands: tuple[float, ...]
    band_rows: tuple[tuple[int, int], ...]
    row_offset_band_confidence: tuple[float, ...]
    row_offset_varies: bool
    time_offset_us: float
    time_offset_confidence: float
    time_offset_ambiguous: bool
    time_offset_alternatives_us: tuple[float, ...]
    time_offset_period_us: float
    disparity_peak: float
    disparity_peaks: tuple[float, ...]
    disparity_percentiles: dict
    disparity_range: tuple[float, float]
    disparity_confidence: float
    events: tuple[int, int]
    rate_ratio: float
    rate_ratio_confidence: float
    burst_ratio_p95: float
    on_fraction: tuple[float, float]
    on_fraction_confidence: float
    noise_rate_hz: tuple[float, float]
    noise_fraction: tuple[float, float]
    noise_confidence: float
    duration_s: float
    settings: dict

    def prepare(self, recording: Recording, *, min_confidence: float = 0.3) -> Recording:
        """The recording with the cameras exchanged if :attr:`swap` (with at least ``min_confidence``)."""
        return recording.swapped() if self.swap and self.swap_confidence >= min_confidence else recording

    def time_offset_applicable(self, *, min_confidence: float | None = None) -> bool:
        """Whether the time offset may be applied: confident enough and not ambiguous.

        ``min_confidence`` defaults to ``RigCheckParams.time_apply_confidence`` of the run. An ambiguous offset
        (:attr:`time_offset_ambiguous`, a periodic scene) is never applicable: one period off ruins the
        event-time matcher's matches, while an unapplied offset only costs some of them.
        """
        if min_confidence is None:
            min_confidence = self.settings.get("time_apply_confidence", RigCheckParams.time_apply_confidence)
        return bool(self.time_offset_confidence >= min_confidence and not self.time_offset_ambiguous)

    def match_kwargs(self, *, min_confidence: float = 0.3, min_time_confidence: float | None = None) -> dict:
        """``row_offset`` and ``time_offset_us`` for :func:`calibration_free.match`.

        An offset whose confidence is below ``min_confidence`` (rows) is left at 0, and so is the time offset
        unless :meth:`time_offset_applicable` (with ``min_time_confidence``); the row offset is rounded
        (matchers work on whole rows), the time offset to whole microseconds.
        """
        row = round(self.row_offset) if self.row_offset_confidence >= min_confidence else 0
        apply_time = self.time_offset_applicable(min_confidence=min_time_confidence)
        dt = round(self.time_offset_us) if apply_time else 0
        return {"row_offset": int(row), "time_offset_us": int(dt)}

    def to_dict(self) -> dict:
        """A JSON-serialisable dict of every field; a figure that is NaN (not estimated) is None."""
        out = dataclasses.asdict(self)
        out["disparity_percentiles"] = {str(k): v for k, v in self.disparity_percentiles.items()}
        return json.loads(json.dumps(_finite_or_none(out), allow_nan=False))

    def summary(self) -> str:
        """A short human report, one finding per line (``n/a`` for a figure that could not be estimated)."""
        def c(v):
            return f"(confidence {_fmt(v, '.2f')})"

        side = ("SWAP: the camera given as right is the left one" if self.swap
                else "cameras in the given order: left is left")
        bands = ", ".join(f"{a}-{b - 1}: {_fmt(v, '+.1f')}"
                          for (a, b), v in zip(self.band_rows, self.row_offset_bands, strict=True))
        pct = self.disparity_percentiles
        lines = [
            f"rig check of {_fmt(self.duration_s, '.1f')} s, {self.events[0]} + {self.events[1]} events",
            f"  left/right:    {side} {c(self.swap_confidence)}",
            f"  row offset:    {_fmt(self.row_offset, '+.2f')} rows (add to the right camera's y) "
            f"{c(self.row_offset_confidence)}",
            f"    per band:    {bands}" + ("  -> varies across the image" if self.row_offset_varies else ""),
            f"  time offset:   {_fmt(self.time_offset_us / 1000, '+.2f')} ms (right camera later) "
            f"{c(self.time_offset_confidence)}",
            *self._ambiguity(),
            f"  disparity:     peak {_fmt(self.disparity_peak, '.1f')} px, 5-95 % {_fmt(pct[5], '.0f')}.."
            f"{_fmt(pct[95], '.0f')} px, median {_fmt(pct[50], '.0f')} px, profile peaks "
            + (", ".join(_fmt(d, ".1f") for d in self.disparity_peaks) or "none")
            + f" {c(self.disparity_confidence)}",
            f"  event rate:    right/left {_fmt(self.rate_ratio, '.2f')}, 5 ms bursts up to "
            f"{_fmt(self.burst_ratio_p95, '.1f')}x (p95) {c(self.rate_ratio_confidence)}",
            f"  ON share:      left {_fmt(self.on_fraction[0], '.0%')}, right {_fmt(self.on_fraction[1], '.0%')} "
            f"{c(self.on_fraction_confidence)}",
            f"  noise:         left {_fmt(self.noise_rate_hz[0], '.0f')}/s ({_fmt(self.noise_fraction[0], '.0%')}), "
            f"right {_fmt(self.noise_rate_hz[1], '.0f')}/s ({_fmt(self.noise_fraction[1], '.0%')}) isolated "
            f"{c(self.noise_confidence)}",
        ]
        return "\n".join(lines)


    def _ambiguity(self) -> list[str]:
        """The time offset's period ambiguity as summary lines (none when there is none)."""
        if not self.time_offset_ambiguous:
            return []
        also = ", ".join(_fmt(a / 1000, "+.1f") for a in self.time_offset_alternatives_us[:3])
        return [f"    ambiguous:   peaks as high every {_fmt(self.time_offset_period_us / 1000, '.1f')} ms (also at "
                f"{also} ms: a periodic scene); the one nearest 0 is reported, --auto does not apply it"]


def _fmt(value: float, spec: str) -> str:
    """``value`` formatted by ``spec``, or ``n/a`` when it is not a finite number."""
    return format(value, spec) if math.isfinite(value) else "n/a"


def _finite_or_none(obj):
    """``obj`` with every non-finite float (NaN, inf) replaced by None, numpy scalars made Python ones."""
    if isinstance(obj, dict):
        return {k: _finite_or_none(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite_or_none(v) for v in obj]
    if hasattr(obj, "item") and not isinstance(obj, (str, bytes)):
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj
