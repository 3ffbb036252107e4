"""mkdocs hooks: the pages, or parts of pages, that are generated from the code at build time.

- ``docs/reference/cli.md`` is not a file in the repository: it is written here, on every build, from
  :func:`cvstereo.cli.build_parser` (each command's ``--help``) and ``cvstereo match --list-methods``.
- ``docs/changelog.md`` gets the table of moved modules from :data:`cvstereo._compat.MOVED` (the table that
  makes the old import paths work) where it says ``<!-- moved-modules -->``, and the repository's
  ``CHANGELOG.md`` after it where that file exists.

So the reference cannot drift from the code. mkdocs loads this module through ``hooks:`` in ``mkdocs.yml``.
"""

from __future__ import annotations

import argparse
import re
from pathlib import Path

#: Where the generated page lives in the site (``nav`` in mkdocs.yml names it).
CLI_PAGE = "reference/cli.md"

#: The page that gets the moved-modules table and CHANGELOG.md, and the marker the table replaces.
CHANGES_PAGE = "changelog.md"
MOVED_MARKER = "<!-- moved-modules -->"

#: The width the help texts are wrapped to: fixed, so that the page does not depend on the terminal that
#: built it.
HELP_WIDTH = 100


def _fixed_width(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """The parser, its help wrapped at :data:`HELP_WIDTH` by its own formatter class (some keep their layout)."""
    formatter = parser.formatter_class
    parser.formatter_class = lambda prog: formatter(prog, width=HELP_WIDTH)
    return parser


def command_helps() -> dict[str, str]:
    """``{"cvstereo": main help, "cvstereo CMD": that command's help, ...}`` in the order ``--help`` lists them."""
    from cvstereo.cli import build_parser

    parser = build_parser()
    helps = {"cvstereo": _fixed_width(parser).format_help()}
    subparsers = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    for name, sub in subparsers.choices.items():
        helps[f"cvstereo {name}"] = _fixed_width(sub).format_help()
    return helps


def method_listing() -> str:
    """What ``cvstereo match --list-methods`` prints."""
    from cvstereo.cli.match import list_methods

    return list_methods()


def cli_reference_markdown() -> str:
    """The CLI reference page: every command's help, then the methods' listing, each in a text block."""
    parts = [
        "# CLI reference\n",
        "Generated when the site is built, from the command line's own parsers (`cvstereo CMD --help`) and "
        "`cvstereo match --list-methods`: what is here is what the installed version prints. The "
        "[command line guide](../guide/cli.md) says how the commands fit together.\n",
    ]
    for command, text in command_helps().items():
        parts.append(f"## `{command}`\n\n```text\n{text.rstrip()}\n```\n")
    parts.append("## Methods: `cvstereo match --list-methods`\n\n"
                 "Every registered matcher, its variants, its two parameter sets and its parameters with "
                 "their defaults (`--param key=value`).\n\n"
                 f"```text\n{method_listing().rstrip()}\n```\n")
    return "\n".join(parts)


def on_files(files, config):
    """Add the generated CLI reference page to the site's files."""
    from mkdocs.structure.files import File

    files.append(File.generated(config, CLI_PAGE, content=cli_reference_markdown()))
    return files


def moved_modules_markdown() -> str:
    """The old module names of 0.2 and the module each now is, as a Markdown table."""
    from cvstereo._compat import MOVED

    rows = [f"| `{old}` | `{new}` |" for old, new in sorted(MOVED.items())]
    return "\n".join(["| 0.2 module | 0.3 module |", "|---|---|", *rows])


def changes_markdown(markdown: str, changelog: Path) -> str:
    """The changes page: the moved-modules table in place of its marker, then ``changelog`` (headings one level
    down, under the page's own) where it exists."""
    markdown = markdown.replace(MOVED_MARKER, moved_modules_markdown())
    if changelog.is_file():
        text = re.sub(r"^(#+) ", r"#\1 ", changelog.read_text(), flags=re.M)
        markdown = f"{markdown.rstrip()}\n\n## CHANGELOG.md\n\n{text}"
    return markdown


def on_page_markdown(markdown, page, config, files):
    """Fill the changes page from the code and the repository's CHANGELOG.md."""
    if page.file.src_uri != CHANGES_PAGE:
        return markdown
    return changes_markdown(markdown, Path(config["config_file_path"]).parent / "CHANGELOG.md")
