"""Rig self-check: learn from the events alone what a calibration would have told.

The thesis' matchers need no calibration, but they assume a rig that real recordings do not always give:
the camera called "left" may be the right one, the sensors' rows may be a few rows apart, and the two
streams may be offset in time. :func:`check_rig` estimates, from the events of a :class:`Recording`:

- **swap**: whether the camera given as left is really the right one (the left camera sees a scene point at
  the larger x), from the sign of the horizontal shift that best overlays short accumulated frames;
- **row offset** ``r``: rows to add to the right camera's ``y`` so that it lines up with the left
  (``y_left ~ y_right + r``), fractional, also per horizontal band of the image;
- **time offset** ``tau``: how much later the right camera stamps the same scene change
  (``t_right ~ t_left + tau``, microseconds), fractional;
- **disparity range**: percentiles of the disparities (``x_left - x_right``) that overlay best locally,
  the dominant disparity and the peaks of the global overlay profile;
- **imbalance**: event-rate ratio right/left (overall and in 5 ms bursts) and ON share per camera;
- **noise**: events with no event at any of the 8 neighbouring pixels within a few ms, per second.

Each estimate carries a confidence in [0, 1]. The row offset comes from the 2-D cross-correlation of
accumulated signed frames over (dx, dy) (windows long against any time offset). The time offset comes from
two estimators: the histogram of time differences between events at corresponding pixels (same polarity,
that row offset, the dominant disparity +-1 px), precise when the disparities are whole pixels or the scene
nearly static; and the regression of the cameras' apparent shift on the image velocity over 10 ms windows
and image tiles (``s = d + v * tau``: slope tau, one intercept d per tile), which on sideways sweeps is not
fooled by a disparity error ``e`` that the histogram takes for a time offset ``e / v``. The histogram's answer
stands when its peak is sharp, the regression's otherwise. Then the rows once more with the time offset
removed, and the disparity stage on the corrected streams. Known limit: a disparity that changes in step
with the speed (an arm wobbling in depth while it sweeps, over a clip of only a few sweeps) cannot be told
from a time offset by any estimator; on 2 s of the simulated arm presets that leaves errors of 1-4 ms at
confidences mostly below the 0.6 that ``--auto`` needs, and slow one-way drifts (1 arm at 100 cm) are not
determined at all (confidence below 0.2). On a periodic scene (a fan: the same blade pattern passes every
pixel once per blade period) the coincidences peak once per period: of the peaks as high as the highest
within their uncertainty the one nearest 0 is reported, and the report marks the offset ambiguous (with the
other peaks and the period), which keeps ``--auto`` from applying it.

Reported offsets and disparities refer to the recording *as it should be used*: after exchanging the
cameras when ``swap`` is True (:meth:`RigReport.prepare` does that), so that ``row_offset`` and
``time_offset_us`` can go straight to :func:`calibration_free.match` (see :meth:`RigReport.match_kwargs`).

One module per job:

- :mod:`~cvstereo.rigcheck.params`: :class:`RigCheckParams`, every option and tuned constant;
- :mod:`~cvstereo.rigcheck.check`: :func:`check_rig`, the pipeline;
- :mod:`~cvstereo.rigcheck.report`: :class:`RigReport`, its summary and JSON;
- :mod:`~cvstereo.rigcheck.rows`: the row offset;
- :mod:`~cvstereo.rigcheck.time_offset`: the time offset (both estimators);
- :mod:`~cvstereo.rigcheck.disparity`: swap and disparities (on :mod:`cvstereo.geometry.overlay`, shared with the
readers);
- :mod:`~cvstereo.rigcheck.stats`: counts, rate imbalance and noise;
- :mod:`~cvstereo.rigcheck.windows` and :mod:`~cvstereo.rigcheck.peaks`: frames of busy windows, peak helpers.

>>> import numpy as np
>>> from cvstereo.model.recording import Recording
>>> from cvstereo.model.events import make_events
>>> rng = np.random.default_rng(0)
>>> t = np.sort(rng.integers(0, 1_000_000, 4000)); x = rng.integers(20, 100, 4000); y = rng.integers(0, 128, 4000)
>>> ev = make_events(t, x, y, rng.integers(0, 2, 4000))
>>> report = check_rig(Recording(ev, ev))
>>> report.swap, round(report.row_offset), round(report.time_offset_us)
(False, 0, 0)
"""

from cvstereo.rigcheck.check import check_rig
from cvstereo.rigcheck.params import RigCheckParams
from cvstereo.rigcheck.report import RigReport

__all__ = ["RigCheckParams", "RigReport", "check_rig"]
