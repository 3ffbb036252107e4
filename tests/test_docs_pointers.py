"""No docstring or comment in the package points outside the repository: references to the contracts name the
pages of docs/, which exist."""

from __future__ import annotations

import io
import re
import tokenize

import pytest

from tests._docs_blocks import DOCS, ROOT

PACKAGES = ("cvstereo", "calibration_free")
#: A page named without its folder, or the shared specification it came from (not in the repository or wheel).
OUTSIDE = re.compile(r"(?<![\w/.-])(?:algorithms|formats|evaluation|design)\.md|\.\./shared/spec|shared/spec/|"
                     r"\.\./seed/")
POINTER = re.compile(r"docs/([\w/-]+\.md)")


def _texts(path):
    """(line, text) of every comment and string literal (docstrings included) of one module."""
    tokens = tokenize.generate_tokens(io.StringIO(path.read_text()).readline)
    return [(t.start[0], t.string) for t in tokens if t.type in (tokenize.COMMENT, tokenize.STRING)]


def _modules():
    return sorted(p for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py"))


@pytest.mark.parametrize("text, outside", [
    ("(formats.md, section 2)", True), ("see ../shared/spec/design.md", True),
    ("(docs/formats.md)", False), ("docs/algorithms.md section 1", False), ("a README.md", False),
])
def test_the_pattern_tells_outside_pointers(text, outside):
    assert bool(OUTSIDE.search(text)) is outside


def test_no_docstring_or_comment_points_outside_the_repository():
    found = [f"{path.relative_to(ROOT)}:{line}: {m.group(0)}" for path in _modules()
             for line, text in _texts(path) for m in OUTSIDE.finditer(text)]
    assert not found, "\n".join(found)


def test_every_docs_pointer_names_a_page_that_exists():
    pointers = {m.group(1) for path in _modules() for _, text in _texts(path) for m in POINTER.finditer(text)}
    assert pointers >= {"formats.md", "algorithms.md", "evaluation.md"}
    assert {p for p in pointers if not (DOCS / p).is_file()} == set()
