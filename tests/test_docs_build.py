"""The documentation site builds with ``mkdocs build --strict``, offline, and its generated CLI reference is what
the command line prints."""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys

import pytest
import yaml

from tests._docs_blocks import ROOT
from tests._hostile import run_cli

#: Plugins of mkdocs-material that fetch from the network at build time (fonts, images, cards).
NETWORK_PLUGINS = {"social", "privacy", "optimize", "blog"}


def _hooks():
    spec = importlib.util.spec_from_file_location("docs_hooks", ROOT / "tools" / "docs_hooks.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _config() -> dict:
    return yaml.safe_load((ROOT / "mkdocs.yml").read_text())


def test_the_site_fetches_nothing_at_build_time():
    config = _config()
    assert config["theme"]["font"] is False  # no web fonts
    names = {next(iter(p)) if isinstance(p, dict) else p for p in config["plugins"]}
    assert not names & NETWORK_PLUGINS
    assert config["hooks"] == ["tools/docs_hooks.py"]


def test_nav_lists_every_page_once():
    """Every page of docs/ is reachable from the navigation (strict mode only reports pages it cannot find)."""
    def leaves(items):
        for item in items:
            value = next(iter(item.values())) if isinstance(item, dict) else item
            yield from leaves(value) if isinstance(value, list) else [value]

    listed = list(leaves(_config()["nav"]))
    hooks = _hooks()
    pages = sorted(p.relative_to(ROOT / "docs").as_posix() for p in (ROOT / "docs").rglob("*.md"))
    assert sorted(listed) == sorted([*pages, hooks.CLI_PAGE])


def test_cli_reference_is_each_commands_help(monkeypatch, capsys):
    """The generated page holds, for every command, exactly what ``cvstereo CMD --help`` prints on a terminal of
    the page's width (argparse wraps at COLUMNS - 2), and what ``match --list-methods`` prints."""
    hooks = _hooks()
    page = hooks.cli_reference_markdown()
    monkeypatch.setenv("COLUMNS", str(hooks.HELP_WIDTH + 2))
    from cvstereo.cli import COMMANDS

    assert list(hooks.command_helps()) == ["cvstereo", *(f"cvstereo {c}" for c in COMMANDS)]
    for argv in [["--help"], *([c, "--help"] for c in COMMANDS)]:
        code, escaped = run_cli(argv)
        shown = capsys.readouterr().out
        assert (code, escaped) == (0, "")
        assert f"```text\n{shown.rstrip()}\n```" in page, f"cvstereo {' '.join(argv)} differs from the page"
    assert run_cli(["match", "--list-methods"]) == (0, "")
    assert f"```text\n{capsys.readouterr().out.rstrip()}\n```" in page


@pytest.mark.slow
def test_mkdocs_build_strict(tmp_path):
    """The whole site builds with warnings as errors (broken links, missing API objects, bad nav)."""
    site = tmp_path / "site"
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}
    done = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--quiet",
                           "--config-file", str(ROOT / "mkdocs.yml"), "--site-dir", str(site)],
                          cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-4000:]
    cli = (site / "reference" / "cli" / "index.html").read_text()
    assert "usage: cvstereo sweep" in cli and "event-vector:" in cli
    api = (site / "reference" / "api" / "index.html").read_text()
    assert "read_recording" in api and "Parameters" in api


def test_changes_page_lists_every_moved_module_and_the_changelog(tmp_path):
    """The changes page gets one row per entry of the table that keeps the old import paths working, and the
    repository's CHANGELOG.md under its own heading (headings one level down)."""
    from cvstereo._compat import MOVED

    hooks = _hooks()
    page = (ROOT / "docs" / hooks.CHANGES_PAGE).read_text()
    assert hooks.MOVED_MARKER in page
    changelog = tmp_path / "CHANGELOG.md"
    changelog.write_text("# Changelog\n\n## 0.3.0\n\n- moved\n")
    out = hooks.changes_markdown(page, changelog)
    assert hooks.MOVED_MARKER not in out
    for old, new in MOVED.items():
        assert f"| `{old}` | `{new}` |" in out
    assert out.endswith("## CHANGELOG.md\n\n## Changelog\n\n### 0.3.0\n\n- moved\n")
    assert hooks.changes_markdown(page, tmp_path / "absent.md") == page.replace(
        hooks.MOVED_MARKER, hooks.moved_modules_markdown())
