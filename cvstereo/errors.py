"""Exception classes of cvstereo.

Each subclasses a built-in so that callers can catch ``ValueError`` or ``OSError`` without importing
cvstereo; the CLI turns all of them into one line on stderr and exit code 1.
"""

from __future__ import annotations

__all__ = ["CorruptFileError", "EventFormatError", "MissingExtraError", "NoMatchersError", "SensorError",
           "StreamEndedError", "require_extra"]


class EventFormatError(ValueError):
    """An event array or recording does not follow the contract of docs/formats.md."""


class CorruptFileError(ValueError):
    """A file is truncated or holds bytes or lines that cannot be decoded."""


class StreamEndedError(ValueError):
    """A packet fed to a matcher after its ``flush()``: the stream has ended (as a closed file refuses I/O
    with a ValueError); a new stream needs a new matcher."""


class MissingExtraError(ImportError):
    """An optional dependency is not installed; the message names the extra that brings it."""


class SensorError(OSError):
    """A sensor port cannot be opened, or the sensor does not answer as an eDVS does."""


class NoMatchersError(RuntimeError):
    """Raised by cvstereo 0.2 when no installed distribution registered a matcher. Since 0.3 the built-in
    matchers are listed without installed metadata (:mod:`cvstereo.matchers._registry`), so nothing raises
    it; the name stays through 0.x for code that catches it."""


def require_extra(module: str, extra: str):
    """Import an optional dependency or raise an error that says how to install it.

    Parameters
    ----------
    module : str
        Module to import, e.g. ``"matplotlib.pyplot"``.
    extra : str
        The cvstereo extra that installs it, e.g. ``"viz"``.

    Returns
    -------
    module
        The imported module.
    """
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise MissingExtraError(
            f"{module} is needed for this and is not installed. Install it with: pip install 'cvstereo[{extra}]'"
        ) from exc
