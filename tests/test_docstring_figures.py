"""No docstring, comment or parameter-set ``why`` string in the package holds a timing, load or before/after figure.

Issue 25 item 5: docstrings and comments state the invariant and the reason; measured figures (a run's duration,
the machine's load, events per second, times real time, speed-ups, ``x -> y`` results) belong in
``bench/results/`` and commit messages, where their provenance is kept. Parameters and contracts stay allowed:
"40 ms windows", "a fixed 300 us", "within 10 s", "cam0 -> cam1", "Name -> Preset".

The scan reads comments with :mod:`tokenize`, and with :mod:`ast` every bare string statement (the docstrings of
modules, classes and functions, and attribute docstrings) and every string given as ``why=`` (the parameter sets'
reasons that ``cvstereo match --list-methods`` prints).
"""

from __future__ import annotations

import ast
import io
import re
import tokenize
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("cvstereo", "calibration_free")

_NUM = r"~?\d+(?:[.,]\d+)?"
_TIME_UNIT = r"(?:s|ms|us|µs|ns|min)\b"
#: Each pattern is one kind of figure; its name is printed with the hit.
FIGURES = {
    # A run's duration: a time after a verb of running, or a time per window / of CPU.
    # (A run of whitespace counts as one character of the gap, so that a line break does not hide a figure.)
    "duration": re.compile(rf"\b(?:took|takes?|ran|runs?\s+in|spent|costs?|adds?)\b(?:[^.;:\s]|\s+){{0,40}}?"
                           rf"{_NUM}\s*{_TIME_UNIT}"
                           rf"|{_NUM}\s*{_TIME_UNIT}\s+(?:an?|per|of)\s+(?:window|run|call|CPU|kernel|wall|event|pixel)"
                           # nanoseconds are never a setting here: a cost
                           rf"|{_NUM}\s*ns\b",
                           re.IGNORECASE),
    "load": re.compile(rf"\bload(?:\s+average)?\s*[:=]?\s*{_NUM}", re.IGNORECASE),
    "events/s": re.compile(rf"{_NUM}\s*[kM]?\s*ev(?:ents?)?\s*/\s*s\b"),
    "real time": re.compile(rf"{_NUM}\s*(?:x|times)\s+real[\s-]+time", re.IGNORECASE),
    "before -> after": re.compile(rf"{_NUM}\s*%?(?:/{_NUM})*\s*(?:->|→)\s*{_NUM}"),
    "speed-up": re.compile(rf"speed-?up\s+(?:of\s+)?{_NUM}|{_NUM}\s*x\s+speed-?up"
                           rf"|{_NUM}\s*(?:x|times)\s+(?:faster|slower)", re.IGNORECASE),
    "on this machine": re.compile(r"\bon\s+this\s+machine\b", re.IGNORECASE),
}


def figures_in(text: str) -> list[str]:
    """The kinds of figure ``text`` holds, each with the words that matched."""
    return [hit for _, hit in _located(text)]


def _located(text: str):
    """(line offset within ``text``, ``kind: 'words'``) of every figure; the patterns allow a line break between
    words, so a figure that straddles one is found."""
    for kind, pattern in FIGURES.items():
        for m in pattern.finditer(text):
            yield text.count("\n", 0, m.start()), f"{kind}: {' '.join(m.group(0).split())!r}"


def _strings(tree: ast.AST):
    """(line, text) of every bare string statement and every ``why=`` string in ``tree``."""
    for node in ast.walk(tree):
        if isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant) and isinstance(node.value.value, str):
            yield node.lineno, node.value.value
        elif isinstance(node, ast.keyword) and node.arg == "why":
            parts = [n.value for n in ast.walk(node.value) if isinstance(n, ast.Constant) and isinstance(n.value, str)]
            yield node.value.lineno, "".join(parts)


def _comments(source: str):
    """(line, text) of every comment; consecutive comment lines are joined (one line each), so a figure split over
    two is seen."""
    block, start = [], 0
    for tok in tokenize.generate_tokens(io.StringIO(source).readline):
        if tok.type == tokenize.COMMENT:
            if not block:
                start = tok.start[0]
            block.append(tok.string.lstrip("#:").strip())
        elif tok.type not in (tokenize.NL, tokenize.NEWLINE, tokenize.INDENT, tokenize.DEDENT) and block:
            yield start, "\n".join(block)
            block = []
    if block:
        yield start, "\n".join(block)


def scan(path: Path) -> list[str]:
    """``file:line: kind: 'text'`` for every figure in the comments, docstrings and ``why`` strings of ``path``."""
    source = path.read_text(encoding="utf-8")
    rel = path.relative_to(ROOT)
    hits = []
    for line, text in [*_comments(source), *_strings(ast.parse(source, filename=str(path)))]:
        hits += [f"{rel}:{line + offset}: {hit}" for offset, hit in _located(text)]
    return hits


def _package_files():
    return sorted(p for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py"))


@pytest.mark.parametrize("text", [
    "took about 1.53 ms of kernel", "cost 6-8 % of the fastest matchers' time at\n        40 ms packets",
    "a whole window's matching takes now (~1.5 ms)", "2.16 ms a window",
    "one CPU, load 0.7", "load average 4", "a 346x260 recording at 1 M ev/s", "20000 events/s",
    "runs at 3.2 x real time", "around every call (~30 ns an event)", "(8 atomics, ~30 ns)",
    "coverage 88 -> 95 %", "0.18/0.17/0.20/0.24 -> 0.22/0.23/0.28/0.30",
    "42 % → 99.6 %", "ran 3x faster with 40 ms", "a speed-up of 1.2", "bit for bit on this machine",
])
def test_figures_are_found(text):
    assert figures_in(text), text


@pytest.mark.parametrize("text", [
    "40 ms windows", "a fixed 300 us time window", "the command ends within 10 s", "cam0 -> cam1 -> cam2",
    "Name -> Preset, in the thesis' order", "``[\"k=v1,v2\"]`` -> ``((\"k\", (v1, v2)),)``", "a loaded machine",
    "loaded 2 files", "faster than np.add.at", "25 fps with 40 ms windows plays in real time",
    "speed (events per second, times real time, speed-up over the thesis' Matlab)", "346x260 at 64 disparities",
    "about 33 M events per camera",
])
def test_parameters_and_contracts_are_allowed(text):
    assert not figures_in(text), figures_in(text)


def test_comments_are_joined_across_lines():
    source = "x = 1  # coverage 88\ny = 2\n# went from 88 ->\n# 95 % here\n"
    assert [line for line, _ in _comments(source)] == [1, 3]
    assert figures_in(dict(_comments(source))[3])


def test_why_strings_are_scanned(tmp_path):
    src = 'A = D(variant="v", why="Fan_disp8 "\n    "42 % -> 99.6 %")\n'
    assert [figures_in(text) for _, text in _strings(ast.parse(src))] == [["before -> after: '42 % -> 99.6'"]]


def test_no_figures_in_the_package():
    files = _package_files()
    assert len(files) > 100  # the walk found the package
    hits = [hit for path in files for hit in scan(path)]
    assert not hits, f"{len(hits)} figures in docstrings/comments (move them to bench/results/):\n" + "\n".join(hits)
