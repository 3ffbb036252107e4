"""Lag per packet of a live run: from the host time a packet's latest event was delivered by its reader to the
host time the matcher returned the matches of that packet (docs/guide/live.md).

>>> meter = LagMeter()
>>> for arrival, out in ((1_000, 3_000), (2_000, 3_000), (5_000, 9_000)):
...     meter.record(arrival, out)
>>> meter.percentiles()["max_ms"]
4.0
"""

from __future__ import annotations

import numpy as np

__all__ = ["LAG_PERCENTILES", "LagMeter"]

#: The percentiles reported (with the maximum).
LAG_PERCENTILES = (50, 90, 99)


class LagMeter:
    """Lags of every packet recorded, from the first on (nothing is left out as a warm-up).

    Packets without events have no arrival and are not recorded.
    """

    def __init__(self):
        self._lags_us: list[int] = []

    def record(self, arrival_us: int | None, out_us: int) -> None:
        """One packet: its latest event arrived at host time ``arrival_us`` (None: an empty packet, skipped)
        and the matcher returned at ``out_us`` (both on :func:`cvstereo.sensors.edvs.host_us`'s clock)."""
        if arrival_us is not None:
            self._lags_us.append(int(out_us) - int(arrival_us))

    @property
    def packets(self) -> int:
        """Packets recorded."""
        return len(self._lags_us)

    def percentiles(self) -> dict:
        """``packets`` and ``p50_ms``, ``p90_ms``, ``p99_ms``, ``max_ms`` over every packet recorded (None
        each before the first)."""
        lags = np.asarray(self._lags_us, dtype=np.float64) / 1e3
        out: dict = {"packets": int(lags.size)}
        for q in LAG_PERCENTILES:
            out[f"p{q}_ms"] = float(np.percentile(lags, q)) if lags.size else None
        out["max_ms"] = float(lags.max()) if lags.size else None
        return out

    def line(self) -> str:
        """The percentiles as one line of the run's summary."""
        p = self.percentiles()
        if not p["packets"]:
            return "lag per packet (delivery -> matches out): no packet with events"
        figures = ", ".join(f"p{q} {p[f'p{q}_ms']:.1f}" for q in LAG_PERCENTILES)
        return (f"lag per packet (delivery -> matches out), all {p['packets']} packets from the first: "
                f"{figures}, max {p['max_ms']:.1f} ms")
