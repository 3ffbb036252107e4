"""The calibration-free stereo matchers of the 2013 TU München thesis, as streaming objects.

The matchers register themselves in the entry-point group ``cvstereo.matchers`` (``pyproject.toml``);
:func:`match`, :func:`create_matcher` and the registry live in cvstereo (:mod:`cvstereo.run`,
:mod:`cvstereo.matchers.registry`) and are re-exported here as the thesis-facing entry point. Readable reference
implementations of every matcher, which the tests hold the fast ones to, are in
:mod:`calibration_free.reference`.

>>> from calibration_free import match                       # doctest: +SKIP
>>> result = match("recording.npz", method="frame", variant="separate")   # doctest: +SKIP
>>> result.matches["disparity"].mean()                          # doctest: +SKIP
"""

from cvstereo.matchers.registry import METHODS, available_methods, create_matcher, matcher_class
from cvstereo.run import match

__all__ = ["METHODS", "available_methods", "create_matcher", "match", "matcher_class"]
