"""Compatibility: the thesis-facing entry point of cvstereo 0.2, kept through 0.x.

The matchers of the 2013 TU München thesis now live in :mod:`cvstereo.matchers` (one subpackage each), and
:func:`match`, :func:`create_matcher` and the registry in :mod:`cvstereo` (``import cvstereo as cvs``). This
package re-exports them, and :mod:`calibration_free.reference` the readable references; the 0.2 module names
(``calibration_free.frame_clusters``, ...) are answered by :mod:`cvstereo._compat` (CHANGELOG.md lists them).

>>> from calibration_free import match                       # doctest: +SKIP
>>> result = match("recording.npz", method="frame", variant="separate")   # doctest: +SKIP
"""

from cvstereo.matchers.registry import METHODS, available_methods, create_matcher, matcher_class
from cvstereo.run import match

__all__ = ["METHODS", "available_methods", "create_matcher", "match", "matcher_class"]
