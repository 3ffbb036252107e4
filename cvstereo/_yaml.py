"""A minimal YAML reader for calibration files (PyYAML is not a dependency of cvstereo).

It reads the subset that calibration tools write (DSEC's ``cam_to_cam.yaml``, Kalibr's camchain files,
ROS camera_info files):

- block mappings ``key: value`` and ``key:`` followed by an indented block;
- block sequences ``- item``, also at the indentation of their key (as PyYAML writes them) and nested on one
  line (``- - 0.99``), and mappings as sequence items (``- key: value``);
- flow sequences ``[1, 2, [3, 4]]`` and flat flow mappings ``{a: 1, b: 2}``;
- scalars: integers, floats (``1e-05``, ``.inf``, ``.nan``), ``true``/``false``, ``null``/``~``, quoted and plain
  strings; ``#`` comments; a leading ``%YAML`` directive and ``---``; OpenCV's ``!!opencv-matrix`` tags are
  skipped (the mapping under them is returned).

Anchors, aliases, multi-line strings and multiple documents are not supported: they raise ValueError naming
the line.

>>> loads("a:\\n- - 1\\n  - 2.5\\nb: [x, 'y z']  # comment\\n")
{'a': [[1, 2.5]], 'b': ['x', 'y z']}
"""

from __future__ import annotations

import re

_INT = re.compile(r"[-+]?(0|[1-9][0-9_]*)$")
_FLOAT = re.compile(r"[-+]?(\d[\d_]*)?(\.\d*)?([eE][-+]?\d+)?$")


def load(path) -> object:
    """Parse a YAML file (the subset above)."""
    with open(path, encoding="utf-8") as fh:
        return loads(fh.read(), source=str(path))


def loads(text: str, *, source: str = "<yaml>") -> object:
    """Parse YAML text (the subset above).

    Raises
    ------
    ValueError
        Naming the source and line of what is outside the subset or malformed.
    """
    lines = []
    for number, raw in enumerate(text.splitlines(), 1):
        content = _strip_comment(raw).rstrip()
        stripped = content.strip()
        if not stripped or stripped.startswith("%") or stripped in ("---", "..."):
            continue
        if "\t" in raw[: len(raw) - len(raw.lstrip())]:
            raise ValueError(f"{source}: line {number}: tab indentation is not YAML; indent with spaces.")
        lines.append([len(content) - len(content.lstrip(" ")), stripped, number])
    if not lines:
        return None
    parser = _Parser(lines, source)
    value = parser.block(0, lines[0][0])
    if parser.i < len(lines):
        raise ValueError(f"{source}: line {lines[parser.i][2]}: unexpected indentation.")
    return value


def _strip_comment(line: str) -> str:
    quote = None
    for i, ch in enumerate(line):
        if quote:
            quote = None if ch == quote else quote
        elif ch in "'\"":
            quote = ch
        elif ch == "#" and (i == 0 or line[i - 1] in " \t"):
            return line[:i]
    return line


class _Parser:
    def __init__(self, lines: list, source: str):
        self.lines, self.source, self.i = lines, source, 0

    def error(self, message: str, line: int | None = None):
        number = self.lines[min(self.i, len(self.lines) - 1)][2] if line is None else line
        return ValueError(f"{self.source}: line {number}: {message}")

    def block(self, start: int, indent: int):
        self.i = start
        if self.lines[start][1].startswith("- ") or self.lines[start][1] == "-":
            return self.sequence(indent)
        return self.mapping(indent)

    def sequence(self, indent: int) -> list:
        items = []
        while self.i < len(self.lines) and self.lines[self.i][0] == indent and self._is_item(self.lines[self.i][1]):
            line = self.lines[self.i]
            rest = line[1][1:].lstrip()
            if not rest:
                self.i += 1
                items.append(self._nested(indent, allow_same=False))
            elif self._is_item(rest) or self._is_key(rest):
                # "- - x" or "- key: value": the rest opens a block at its own column.
                line[0], line[1] = indent + len(line[1]) - len(rest), rest
                items.append(self.block(self.i, line[0]))
            else:
                items.append(self.scalar(rest, line[2]))
                self.i += 1
        return items

    def mapping(self, indent: int) -> dict:
        out = {}
        while self.i < len(self.lines) and self.lines[self.i][0] == indent:
            number, text = self.lines[self.i][2], self.lines[self.i][1]
            if self._is_item(text):
                raise self.error("a sequence item where a 'key: value' was expected.")
            if not self._is_key(text):
                raise self.error(f"expected 'key: value', got {text!r}.")
            key, _, rest = text.partition(":")
            key = self.scalar(key.strip(), number)
            rest = rest.strip()
            if rest.startswith("!!"):  # a tag (OpenCV's !!opencv-matrix): the block below is the value
                rest = rest.split(None, 1)[1] if " " in rest else ""
            if rest.startswith(("&", "*", "|", ">")):
                raise self.error("anchors, aliases and block strings are not supported by this reader.")
            self.i += 1
            out[key] = self.scalar(rest, number) if rest else self._nested(indent, allow_same=True)
        return out

    def _nested(self, indent: int, *, allow_same: bool):
        if self.i >= len(self.lines):
            return None
        child_indent, text = self.lines[self.i][0], self.lines[self.i][1]
        if child_indent > indent or (allow_same and child_indent == indent and self._is_item(text)):
            return self.block(self.i, child_indent)
        return None

    @staticmethod
    def _is_item(text: str) -> bool:
        return text == "-" or text.startswith("- ")

    @staticmethod
    def _is_key(text: str) -> bool:
        if text[:1] in "'\"[{":
            return bool(re.match(r"""^(['"]).*?\1\s*:(\s|$)""", text))
        return bool(re.match(r"^[^:]+:(\s|$)", text))

    def scalar(self, text: str, number: int):
        text = text.strip()
        if text.startswith("[") or text.startswith("{"):
            value, end = self._flow(text, 0, number)
            if text[end:].strip():
                raise self.error(f"unexpected text after the flow collection: {text[end:]!r}.", number)
            return value
        if len(text) >= 2 and text[0] == text[-1] and text[0] in "'\"":
            return text[1:-1]
        lower = text.lower()
        if lower in ("", "null", "~"):
            return None
        if lower in ("true", "false"):
            return lower == "true"
        if lower in (".inf", "+.inf", "-.inf", ".nan"):
            return float(lower.replace(".", ""))
        if _INT.match(text):
            return int(text.replace("_", ""))
        if _FLOAT.match(text) and any(c.isdigit() for c in text):
            return float(text.replace("_", ""))
        return text

    def _flow(self, text: str, pos: int, number: int):
        opener = text[pos]
        closer = "]" if opener == "[" else "}"
        items, pos = [], pos + 1
        while True:
            while pos < len(text) and text[pos] == " ":
                pos += 1
            if pos >= len(text):
                raise self.error(f"unclosed {opener!r}.", number)
            if text[pos] == closer:
                break
            if text[pos] in "[{":
                value, pos = self._flow(text, pos, number)
            else:
                end = pos
                while end < len(text) and text[end] not in ",]}":
                    end += 1
                value, pos = text[pos:end].strip(), end
            items.append(value)
            while pos < len(text) and text[pos] == " ":
                pos += 1
            if pos < len(text) and text[pos] == ",":
                pos += 1
        pos += 1
        if opener == "[":
            return [v if isinstance(v, (list, dict)) else self.scalar(v, number) for v in items], pos
        out = {}
        for item in items:
            if not isinstance(item, str) or ":" not in item:
                raise self.error(f"flow mapping entry {item!r} is not 'key: value'.", number)
            k, _, v = item.partition(":")
            out[self.scalar(k, number)] = self.scalar(v, number)
        return out, pos
