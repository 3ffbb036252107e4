"""The calibration-free stereo matchers of the 2013 TU München thesis, as streaming objects.

>>> from calibration_free import match                       # doctest: +SKIP
>>> result = match("recording.npz", method="frame", variant="separate")   # doctest: +SKIP
>>> result.matches["disparity"].mean()                          # doctest: +SKIP
"""

from calibration_free.registry import METHODS, available_methods, create_matcher, matcher_class
from calibration_free.run import match

__all__ = ["METHODS", "available_methods", "create_matcher", "match", "matcher_class"]
