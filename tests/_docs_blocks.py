"""The code blocks of the README and of docs/: found, and run as a reader would run them.

A fenced block is ``python`` (run, in one namespace per page, in order), ``bash`` (each ``cvstereo ...`` line
run in-process through :func:`cvstereo.cli.main`, exit 0 expected) or ``text`` (output shown, not run). A
block that cannot run on a test machine is preceded by ``<!-- skip: REASON -->``.
"""

from __future__ import annotations

import re
import shlex
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
#: Fence languages: run, or shown as they are.
RUN_LANGUAGES = ("python", "bash")
SHOWN_LANGUAGES = ("text",)
_FENCE = re.compile(r"^(?:<!-- skip: (?P<reason>[^>]*?) -->\n)?```(?P<lang>[\w-]*)[^\n]*\n(?P<code>.*?)^```\s*$",
                    flags=re.S | re.M)


@dataclass(frozen=True)
class Block:
    page: str
    line: int
    lang: str
    code: str
    skip: str | None

    def where(self) -> str:
        return f"{self.page}:{self.line}"


def doc_pages() -> list[Path]:
    """Every Markdown page of docs/, sorted."""
    return sorted(DOCS.rglob("*.md"))


def blocks(path: Path) -> list[Block]:
    """The fenced blocks of one Markdown file, in order."""
    text = path.read_text()
    name = path.relative_to(ROOT).as_posix()
    return [Block(name, text.count("\n", 0, m.start("code")), m["lang"], m["code"],
                  None if m["reason"] is None else m["reason"].strip()) for m in _FENCE.finditer(text)]


def command_lines(code: str) -> list[list[str]]:
    """The ``cvstereo`` command lines of a bash block (continuations joined, comments dropped) as argv lists
    without the program name. Any other line is a mistake: a block that runs something else is skipped."""
    lines = []
    for line in code.replace("\\\n", " ").splitlines():
        argv = shlex.split(line, comments=True)
        if not argv:
            continue
        if argv[0] != "cvstereo":
            raise ValueError(f"not a cvstereo command: {line!r} (mark the block <!-- skip: REASON -->)")
        lines.append(argv[1:])
    return lines


def run_page(path: Path, capsys) -> dict:
    """Run every block of one page that is not skipped, in the current folder; raise AssertionError naming the
    block on the first failure. Returns the namespace the python blocks ran in."""
    from tests._hostile import run_cli

    namespace: dict = {"__name__": "__docs__"}
    for block in blocks(path):
        if block.skip is not None or block.lang in SHOWN_LANGUAGES:
            continue
        if block.lang == "python":
            try:
                exec(compile(block.code, block.where(), "exec"), namespace)
            except Exception as exc:  # the failing block, named
                raise AssertionError(f"{block.where()}: python block failed: {type(exc).__name__}: {exc}\n"
                                     f"{block.code}") from exc
        elif block.lang == "bash":
            for argv in command_lines(block.code):
                code, escaped = run_cli(argv)
                err = capsys.readouterr().err
                assert code == 0 and not escaped, (
                    f"{block.where()}: `cvstereo {shlex.join(argv)}` exited {code} {escaped}\n{err}")
        else:
            raise AssertionError(f"{block.where()}: fence language {block.lang!r} is neither run "
                                 f"({', '.join(RUN_LANGUAGES)}) nor shown ({', '.join(SHOWN_LANGUAGES)})")
    return namespace
