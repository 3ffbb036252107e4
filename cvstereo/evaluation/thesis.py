"""The numbers the 2013 thesis published, for printing beside ours (never used to produce a result).

Source: docs/algorithms.md, "What the thesis measured" (thesis tables 4.1-4.14 and section 4.5).
Recording names are the simulator's preset names that re-create the thesis' six recordings.
"""

from __future__ import annotations

__all__ = ["DISPARITY_TABLES", "EVENT_COUNTS", "MATLAB_SECONDS", "RECORDINGS", "RECORDING_SECONDS", "thesis_disparity"]

#: The thesis' six recordings, in the order of its tables.
RECORDINGS = ("1arm-50cm", "1arm-100cm", "1arm-150cm", "2arms-50cm", "2arms-100cm", "2arms-150cm")

#: Table 4.1: events per recording, (eDVS1 = our right camera, eDVS2 = our left): (on, off) each.
EVENT_COUNTS: dict[str, dict[str, tuple[int, int]]] = {
    "1arm-50cm": {"right": (199146, 176505), "left": (160854, 133498)},
    "1arm-100cm": {"right": (93221, 79848), "left": (77250, 61010)},
    "1arm-150cm": {"right": (52178, 45655), "left": (43006, 35298)},
    "2arms-50cm": {"right": (323125, 288549), "left": (308605, 261931)},
    "2arms-100cm": {"right": (174696, 149009), "left": (158456, 128643)},
    "2arms-150cm": {"right": (77733, 64721), "left": (72342, 56745)},
}

#: The thesis' tables 4.2-4.14 as printed: method, variant, then mean/std (px) on each of :data:`RECORDINGS`.
_TABLES = """
frame         shared        28.22/4.86  13.27/1.92   7.14/1.57  26.60/5.66  13.07/4.32   9.19/3.05
frame         separate      30.08/2.24  13.62/0.93   7.56/0.81  27.61/4.12  13.14/3.28   9.20/2.97
frame         on            30.16/2.49  13.64/1.01   7.57/0.90  27.61/4.30  13.14/3.38   9.20/3.07
frame         off           29.99/1.90  13.61/0.83   7.55/0.64  27.67/3.70  13.06/3.09   9.55/2.81
event-time    shared        30.00/4.24  13.37/2.07   8.50/3.89  26.01/9.33  15.98/7.90  11.48/6.42
event-time    separate      29.56/3.56  13.24/2.10   7.56/2.86  27.50/8.55  14.46/7.61   9.56/6.35
event-time    on            29.51/4.12  13.21/2.30   7.60/2.77  27.34/8.66  14.74/7.65  10.43/6.12
event-time    off           29.61/3.34  13.28/1.80   7.35/3.22  27.66/8.16  13.59/7.56   9.93/6.56
frame-area    gaussian      29.14/2.71  13.60/1.14   7.52/0.98 29.96/15.62 17.22/11.17  11.62/8.29
frame-area    no-gaussian   29.36/3.58  13.62/1.33   7.31/1.54 25.31/10.18  12.95/5.19   8.95/4.99
event-area    gaussian      27.24/3.31  13.10/1.86   7.40/0.76  20.94/6.65  13.05/3.21   9.85/4.26
event-area    no-gaussian   29.01/4.13  13.66/2.10   8.00/4.33 25.85/12.89 15.93/10.05 12.53/10.07
event-vector  default       28.55/3.56  12.75/1.60   6.49/1.53  23.63/7.19  13.64/5.62   9.32/4.90
"""

#: Tables 4.2-4.14: (method, variant) -> recording -> (mean, std) in px.
DISPARITY_TABLES: dict[tuple[str, str], dict[str, tuple[float, float]]] = {
    (method, variant): {
        rec: (float(m), float(s)) for rec, (m, s) in zip(RECORDINGS, (cell.split("/") for cell in cells), strict=True)
    }
    for method, variant, *cells in (line.split() for line in _TABLES.strip().splitlines())
}

#: Section 4.5: Matlab run time on 2arms-50cm (11 s of data), seconds, per (method, variant).
MATLAB_SECONDS: dict[tuple[str, str], float] = {
    ("frame", "shared"): 8.23,
    ("frame", "separate"): 14.21,
    ("event-time", "shared"): 6.52,
    ("event-time", "separate"): 7.3,
    ("frame-area", "gaussian"): 32.98,
    ("event-area", "gaussian"): 65.53,
    ("event-vector", "default"): 10.43,
}

#: Length of each of the thesis' recordings, seconds.
RECORDING_SECONDS = 11.0


def thesis_disparity(method: str, variant: str, recording: str) -> tuple[float, float] | None:
    """The thesis' (mean, std) for a matcher variant on one of its recordings, or None if it has none."""
    return DISPARITY_TABLES.get((method, variant), {}).get(recording)
