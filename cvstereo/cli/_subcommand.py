"""How a command module registers its subcommand: summary and description, the description kept once."""

from __future__ import annotations

import argparse

__all__ = ["subcommand"]


def subcommand(sub, name: str, summary: str, doc: str, **options) -> argparse.ArgumentParser:
    """Add subcommand ``name`` to ``sub`` (argparse's subparsers) and return its parser.

    ``summary`` is its line in ``cvstereo --help``. Its description (``cvstereo NAME --help``) is the second
    paragraph of ``doc``, the command module's docstring, with whitespace runs folded to one space: the module's
    reader and the command's user read the same text, written once. The first paragraph is the usage line;
    paragraphs after the second are for readers of the code only. ``options`` go to ``add_parser`` as they are
    (``epilog``, ``formatter_class``; ``description`` to give a computed one instead of the docstring's).

    Raises
    ------
    ValueError
        ``doc`` has no second paragraph (a command module without a description).
    """
    if "description" not in options:
        paragraphs = (doc or "").split("\n\n")
        if len(paragraphs) < 2 or not paragraphs[1].strip():
            raise ValueError(f"cvstereo {name}: the command module's docstring has no description paragraph")
        options["description"] = " ".join(paragraphs[1].split())
    return sub.add_parser(name, help=summary, **options)
