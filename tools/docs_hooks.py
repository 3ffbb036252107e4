"""mkdocs hook: the CLI reference page, generated at build time from the command line's own parsers.

``docs/reference/cli.md`` is not a file in the repository: it is written here, on every build, from
:func:`cvstereo.cli.build_parser` (each command's ``--help``) and ``cvstereo match --list-methods``, so that
the reference cannot drift from the code. mkdocs loads this module through ``hooks:`` in ``mkdocs.yml``.
"""

from __future__ import annotations

import argparse

#: Where the generated page lives in the site (``nav`` in mkdocs.yml names it).
CLI_PAGE = "reference/cli.md"

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
