"""Tally a hostile corpus by kind of failure, on this tree or on an older commit.

Usage::

    python bench/hostile_tally.py tests/test_hostile2_*.py                 # this tree
    python bench/hostile_tally.py tests/test_hostile2_*.py --against REV   # the same cases on commit REV

With ``--against`` the test files (and ``tests/_*.py``, their helpers) are copied into a temporary worktree
of REV and run there with REV's code. Every case counts once: ``clean`` when it passes, else the kind its
failure message starts with (``tests/_hostile.py``: TRACEBACK, HANG, DATALOSS, SILENT, MESSAGE, LEFTOVER);
a failure without a kind (an import error of a name REV lacks, an assertion without a kind) counts as
``other``. A case stopped by pytest-timeout counts as HANG.
Prints a Markdown table and the cases not clean on this tree; ``--json`` writes the table too.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET
from collections import Counter
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
KINDS = ("TRACEBACK", "HANG", "DATALOSS", "SILENT", "MESSAGE", "LEFTOVER")
COLUMNS = ("tried", "clean", "traceback", "hang", "data loss", "silent wrong", "unclear", "leftover", "other")


def kind_of(testcase: ET.Element) -> str:
    """The kind of one junit ``testcase``: ``clean``, one of :data:`KINDS` or ``other``."""
    failure = testcase.find("failure")
    if failure is None:
        failure = testcase.find("error")
    if failure is None:
        return "clean" if testcase.find("skipped") is None else "skipped"
    text = (failure.get("message") or "") + "\n" + (failure.text or "")
    if ("Timeout" in text and "pytest-timeout" in text) or "Failed: Timeout" in text:
        return "HANG"
    found = [(text.find(k + ":"), k) for k in KINDS if k + ":" in text]
    return min(found)[1] if found else "other"


def _sigint_as_in_a_terminal() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def run(files: list[str], root: Path, timeout: int, not_clean: list | None = None) -> Counter:
    """Run the corpus under ``root`` and tally its cases by kind; append ``(case, kind)`` of every case that
    is not clean to ``not_clean`` when given (a case that fails only under load shows here by name)."""
    with tempfile.TemporaryDirectory() as tmp:
        xml = Path(tmp) / "junit.xml"
        cmd = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-n", "2", f"--timeout={timeout}",
               f"--junitxml={xml}", "-o", "addopts=", "-W", "error", *files]
        # SIGINT as a terminal gives it, also when this script runs in a background job (which ignores it,
        # and every process it starts would inherit that): the signal cases press Ctrl-C.
        subprocess.run(cmd, cwd=root, env={**os.environ, "PYTHONPATH": str(root)}, check=False,
                       stdout=subprocess.DEVNULL, preexec_fn=_sigint_as_in_a_terminal)
        tally = Counter()
        if xml.exists():
            for tc in ET.parse(xml).getroot().iter("testcase"):
                kind = kind_of(tc)
                tally[kind] += 1
                if not_clean is not None and kind not in ("clean", "skipped"):
                    not_clean.append((f"{tc.get('classname')}::{tc.get('name')}", kind))
        return tally


def against(rev: str, files: list[str], timeout: int) -> Counter:
    with tempfile.TemporaryDirectory() as tmp:
        tree = Path(tmp) / "old"
        subprocess.run(["git", "worktree", "add", "--detach", str(tree), rev], cwd=REPO, check=True,
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            for helper in (REPO / "tests").glob("_*.py"):
                shutil.copy2(helper, tree / "tests" / helper.name)
            for f in files:
                shutil.copy2(REPO / f, tree / f)
            return run(files, tree, timeout)
        finally:
            subprocess.run(["git", "worktree", "remove", "--force", str(tree)], cwd=REPO, check=False)


def table(rows: dict[str, Counter]) -> str:
    names = {"clean": "clean", "TRACEBACK": "traceback", "HANG": "hang", "DATALOSS": "data loss",
             "SILENT": "silent wrong", "MESSAGE": "unclear", "LEFTOVER": "leftover", "other": "other"}
    lines = ["| code | " + " | ".join(COLUMNS) + " |", "|---" * (len(COLUMNS) + 1) + "|"]
    for label, tally in rows.items():
        counts = {names[k]: v for k, v in tally.items() if k in names}
        tried = sum(counts.values())
        lines.append(f"| {label} | {tried} | " + " | ".join(str(counts.get(c, 0)) for c in COLUMNS[1:]) + " |")
    return "\n".join(lines)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("files", nargs="+", help="test files of the corpus, relative to the repository")
    ap.add_argument("--against", metavar="REV", help="also run the same cases on this commit")
    ap.add_argument("--timeout", type=int, default=60, help="seconds per case before it counts as a hang")
    ap.add_argument("--json", metavar="FILE", help="also write the tallies as JSON")
    args = ap.parse_args()
    files = [os.path.relpath(Path(f).resolve(), REPO) for f in args.files]
    rows = {}
    if args.against:
        rows[args.against] = against(args.against, files, args.timeout)
    not_clean: list[tuple[str, str]] = []
    rows["this tree"] = run(files, REPO, args.timeout, not_clean)
    print(table(rows))
    for name, kind in not_clean:
        print(f"not clean on this tree: {kind} {name}")
    if args.json:
        Path(args.json).write_text(json.dumps({k: dict(v) for k, v in rows.items()}, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
