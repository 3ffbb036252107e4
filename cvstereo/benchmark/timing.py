"""Honest speed figures: repeat a timing until two runs agree, and report the machine's load beside it.

On a shared machine one timing says as much about the other processes as about the code. Every speed
figure of ``cvstereo bench`` and of the ``bench/`` scripts therefore comes from :class:`Agreement`: runs
are added until two of them differ by at most :data:`TOLERANCE` (at most :data:`MAX_RUNS` runs); the
figure is the faster of that pair, and the 1-minute load average before the first run and after the last
is kept with it. A figure whose runs never agreed is flagged, so that a loaded machine cannot pass for a
slow matcher.

>>> a = Agreement()
>>> for seconds in (1.30, 1.00, 1.05):
...     if not a.done:
...         a.add(seconds)
>>> a.result().seconds, a.result().runs, a.result().agreed
(1.0, 3, True)
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field

__all__ = ["MAX_RUNS", "TOLERANCE", "Agreement", "Timing", "load_average", "measure"]

#: Two runs agree when the slower is at most this share slower than the faster.
TOLERANCE = 0.10
#: Runs at most per figure (when no two agree, the fastest is reported, flagged).
MAX_RUNS = 6


def load_average() -> float:
    """The 1-minute load average (NaN where the system does not report it)."""
    try:
        return os.getloadavg()[0]
    except (AttributeError, OSError):
        return math.nan


@dataclass(frozen=True)
class Timing:
    """One speed figure and how it was obtained.

    Attributes
    ----------
    seconds : float
        The faster run of the first pair that agreed, or the fastest run when none did.
    runs : int
        Runs made.
    agreed : bool
        Whether two runs agreed within the tolerance.
    all_seconds : tuple of float
        Every run, in order.
    load_before, load_after : float
        1-minute load average before the first run and after the last.
    """

    seconds: float
    runs: int
    agreed: bool
    all_seconds: tuple[float, ...]
    load_before: float
    load_after: float

    def to_dict(self) -> dict:
        """JSON-ready fields."""
        return {"seconds": self.seconds, "runs": self.runs, "agreed": self.agreed,
                "all_seconds": list(self.all_seconds), "load_before": self.load_before,
                "load_after": self.load_after}

    def note(self) -> str:
        """``N runs, load BEFORE -> AFTER`` (plus ``, no two within 10 %`` when none agreed), for tables."""
        flag = "" if self.agreed else f", no two within {TOLERANCE * 100:g} %"
        return f"{self.runs} runs, load {self.load_before:.1f} -> {self.load_after:.1f}{flag}"


@dataclass
class Agreement:
    """Runs of one measurement, added one at a time until two agree (usable for interleaved measurements).

    Parameters
    ----------
    tolerance : float
        Two runs agree when ``slower <= (1 + tolerance) * faster``.
    max_runs : int
        :attr:`done` after this many runs even without agreement.
    load : callable
        Returns the current load figure (default :func:`load_average`); read at the first :meth:`add` (before
        the run, see :meth:`start`) and after every run.
    """

    tolerance: float = TOLERANCE
    max_runs: int = MAX_RUNS
    load: Callable[[], float] = load_average
    seconds: list[float] = field(default_factory=list)
    load_before: float | None = None
    load_after: float = math.nan
    _pair: tuple[float, float] | None = None

    def __post_init__(self):
        if not self.tolerance >= 0:
            raise ValueError(f"tolerance must be >= 0, got {self.tolerance!r}.")
        if self.max_runs < 2:
            raise ValueError(f"max_runs must be at least 2 (two runs have to agree), got {self.max_runs!r}.")

    def start(self) -> None:
        """Note the load before the first run (called by :meth:`measure`; otherwise before your first run)."""
        if self.load_before is None:
            self.load_before = self.load()

    def add(self, seconds: float) -> None:
        """Record one run's duration and the load after it."""
        seconds = float(seconds)
        if not seconds >= 0:
            raise ValueError(f"a run's duration must be a number >= 0, got {seconds!r}.")
        self.start()
        if self._pair is None:
            # The fastest earlier run that agrees with this one: the pair's faster run is the figure.
            agreeing = [s for s in self.seconds if max(s, seconds) <= (1 + self.tolerance) * min(s, seconds)]
            if agreeing:
                self._pair = (min(agreeing), seconds)
        self.seconds.append(seconds)
        self.load_after = self.load()

    @property
    def agreed(self) -> bool:
        return self._pair is not None

    @property
    def done(self) -> bool:
        """Two runs agreed, or :attr:`max_runs` runs were made."""
        return self.agreed or len(self.seconds) >= self.max_runs

    def result(self) -> Timing:
        """The figure so far.

        Raises
        ------
        ValueError
            No run was added.
        """
        if not self.seconds:
            raise ValueError("no run was timed: call add() (or measure()) first.")
        best = min(self._pair) if self._pair is not None else min(self.seconds)
        return Timing(best, len(self.seconds), self.agreed, tuple(self.seconds),
                      math.nan if self.load_before is None else self.load_before, self.load_after)


def measure(run: Callable[[], float | None], *, tolerance: float = TOLERANCE, max_runs: int = MAX_RUNS,
            clock: Callable[[], float] = time.perf_counter, load: Callable[[], float] = load_average) -> Timing:
    """Call ``run`` until two runs agree within ``tolerance`` (at most ``max_runs`` times).

    Parameters
    ----------
    run : callable
        One run. If it returns a number, that is the run's duration in seconds (e.g. the matcher's own
        clock, leaving out set-up the figure should not count); if it returns None, the run is timed with
        ``clock`` around the call.
    tolerance, max_runs : see :class:`Agreement`
    clock : callable
        Seconds (default :func:`time.perf_counter`; a fake clock makes tests deterministic).
    load : callable
        Load figure before and after (default :func:`load_average`).

    Returns
    -------
    Timing
    """
    agreement = Agreement(tolerance=tolerance, max_runs=max_runs, load=load)
    agreement.start()
    while not agreement.done:
        begin = clock()
        own = run()
        agreement.add(clock() - begin if own is None else own)
    return agreement.result()
