"""Text the CLI shows users: names and contents of files made safe for a terminal, numbers without NaN."""

from __future__ import annotations

import math


def printable(text: object, *, collapse: bool = True) -> str:
    """``text`` with every non-printable character escaped (``\\x1b``, ``\\u202e``, ...).

    File names and file contents reach error messages and reports; raw escape codes in them could rewrite
    the user's terminal. With ``collapse`` (for messages), whitespace runs, newlines included, become one
    space, so a message is one line; without it (table lines), spaces stay and other whitespace is escaped.
    """
    one_line = " ".join(str(text).split()) if collapse else str(text)
    if one_line.isprintable():
        return one_line
    return "".join(c if c.isprintable() else c.encode("unicode_escape").decode("ascii") for c in one_line)


def number(value, spec: str = ".2f", unit: str = "") -> str:
    """``format(value, spec)`` plus ``unit``; ``"n/a"`` for None, NaN and infinities (never "nan" to users)."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        return "n/a"
    if not math.isfinite(v):
        return "n/a"
    return format(v, spec) + unit
