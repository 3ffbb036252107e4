"""Text the CLI shows users: names and contents of files made safe for a terminal, numbers without NaN."""

from __future__ import annotations

import math
import re


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


#: reStructuredText markup that docstrings carry into help texts: ``literal``, :role:`target`, *emphasis* and
#: **strong** (opened after a space or bracket only, so that globs like ``recordings/*.npz`` stay), ``text::``.
_LITERAL = re.compile(r"``(?P<body>.+?)``", re.S)
_ROLE = re.compile(r":(?:[a-z]+:)?[a-z]+:`(?P<body>[^`]+)`")
_EMPHASIS = re.compile(r"(?:(?<=^)|(?<=[\s(\[{'\"]))(?P<mark>\*\*?)(?=[^\s*])(?P<body>[^*\n]*?[^\s*])(?P=mark)"
                       r"(?![\w*])", re.M)
_LITERAL_BLOCK = re.compile(r"(?:(?<=\S)|\s+)::(?=[ \t]*$)", re.M)


def _role_text(match: re.Match) -> str:
    body = match.group("body").strip()
    titled = re.fullmatch(r"(?P<title>.+?)\s*<[^<>]+>", body)  # :ref:`the title <target>`
    if titled:
        return titled.group("title")
    body = body.lstrip("!")
    return body.rsplit(".", 1)[-1] if body.startswith("~") else body  # ~a.b.C shows as C, as Sphinx does


def _literal_block(match: re.Match) -> str:
    return ":" if not match.group(0)[0].isspace() else ""  # "Examples::" -> "Examples:"; a lone " ::" goes


def plain_text(text: str | None) -> str | None:
    """``text`` (a docstring or a help string) without reStructuredText markup, for ``--help`` and listings.

    ````literal```` and *emphasis* keep their words; :role:`target` becomes the target's name (the last part
    after ``~``, the title of ``title <target>``); ``Examples::`` becomes ``Examples:``. Single backticks,
    the plain-text way of quoting a command (`cvstereo match`), and all whitespace stay as they are.

    Examples
    --------
    >>> plain_text("``cvstereo record``: see :func:`~cvstereo.rigcheck.check_rig`, *not* ``--seconds``::")
    'cvstereo record: see check_rig, not --seconds:'
    """
    if not text:
        return text
    text = _ROLE.sub(_role_text, text)
    text = _LITERAL.sub(lambda m: m.group("body"), text)
    text = _EMPHASIS.sub(lambda m: m.group("body"), text)
    return _LITERAL_BLOCK.sub(_literal_block, text)
