"""``cvstereo warm-up``: numba's compile cache filled for every method ahead of time.

:mod:`cvstereo._compile_watch` makes a matcher's kernels ready when it is built (once per process and compiled
path); on a new machine that still compiles them. :func:`warm_up` (``cvstereo warm-up``, run by ``make`` after
installing) builds each available method's default matcher under both parameter sets now, on one thread and on
two (the serial and the parallel kernels: docs/guide/threads.md), and the default rig check's kernel, so that
numba's cache holds every kernel and later processes only load them.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable

from cvstereo._compile_watch import COMPILE_MESSAGE, compile_seconds, watch_compiles
from cvstereo.matchers.sets import PARAM_SETS  # the parameter sets whose default variants are warmed

__all__ = ["COMPILE_MESSAGE", "PARAM_SETS", "compile_seconds", "warm_up"]

#: The thread counts warmed: one (the serial kernels) and more than one (the parallel ones).
_THREAD_COUNTS = (1, 2)


def warm_up(methods: Iterable[str] | None = None, param_sets: Iterable[str] = PARAM_SETS, *,
            on_method: Callable[[str, str, float], None] | None = None) -> float:
    """Fill numba's compile cache for ``methods`` (default: every available one) under each of ``param_sets``.

    Parameters
    ----------
    methods : iterable of str, optional
    param_sets : iterable of str
    on_method : callable, optional, keyword-only
        ``on_method(method, param_set, compile_s)`` after each, with the seconds spent compiling for it.

    Returns
    -------
    float
        Seconds spent compiling in all (0 when the cache held everything).
    """
    from cvstereo.matchers.registry import available_methods, create_matcher

    watch_compiles()
    start = compile_seconds()
    for method in available_methods() if methods is None else methods:
        for param_set in param_sets:
            before = compile_seconds()
            for threads in _THREAD_COUNTS:  # create_matcher prepares its kernels (see the module's text)
                create_matcher(method, param_set=param_set, threads=threads)
            if on_method is not None:
                on_method(method, param_set, compile_seconds() - before)
    _warm_rig_check()
    return compile_seconds() - start


def _warm_rig_check() -> None:
    """The default rig check's own kernels (its noise count, its time offset's sums of cross-spectra), which every
    ``match()`` runs."""
    import numpy as np

    from cvstereo.model.events import make_events
    from cvstereo.rigcheck.stats import isolated_events
    from cvstereo.rigcheck.time_offset import RowSpectra, cross_spectra

    isolated_events(make_events([0, 5], [1, 2], [1, 1], [1, 0]), window_us=10, resolution=(4, 4))
    spectra = RowSpectra(np.ones((1, 3), np.complex64), np.zeros((1, 1), np.int64), np.ones((1, 1), np.float32))
    cross_spectra(spectra, np.zeros(1, np.int64), spectra, np.zeros(1, np.int64), 0, 1)
