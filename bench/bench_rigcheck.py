"""The rig check's speed on the three real files, and what ``--auto`` does for the matchers on Fan_disp8.dat.

1. **Speed**: ``check_rig`` time as a share of each recording's duration, for the code at a base revision
   (``--before REV``, default ``main``; extracted with ``git archive`` and run in its own process) and for
   this tree, alternately in the same run, with the load average before and after each timing. Each is
   repeated until two runs agree within 10 % (at most ``--repeats``, :mod:`cvstereo.benchmark.timing`); the faster of
   the agreeing pair is shown, with its CPU time.
2. **Accuracy**: share of a matcher's estimates within 1 px of 8 px on Fan_disp8.dat, before and after
   ``--auto``. "Before" is the recording as read with retina 0 as the left camera (wrong for this file,
   README) and with the README's retina 1; "after" runs the rig check first and applies its findings (swap,
   row and time offset), as ``cvstereo match --auto`` does.

Prints the tables and writes rigcheck.md and .json into bench/results/ (``-o`` for another folder).

Run: ``.venv/bin/python bench/bench_rigcheck.py [--before REV] [--skip-accuracy]`` (needs the shared data;
$CVSTEREO_SHARED or ../shared).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from cvstereo.benchmark.timing import Agreement  # noqa: E402

SHARED = Path(os.environ.get("CVSTEREO_SHARED", ROOT.parent / "shared"))
TUM = SHARED / "data" / "tum-stereo"
FAN = TUM / "Fan_disp8.dat"
REAL_FILES = ("Fan_disp8.dat", "NSTlogo_disp12-8-3.dat", "movingPersons.dat")

#: Run in a child process on the code under test: reads a file (retina 0 as left, as a user who does not
#: know), times check_rig on it and prints JSON.
_TIMER = """
import json, os, sys, time
from cvstereo.io import read_recording
from cvstereo.rigcheck import check_rig
rec = read_recording(sys.argv[1], left_retina=0)
load = os.getloadavg()[0]
start, cpu = time.perf_counter(), time.process_time()
report = check_rig(rec)
elapsed, cpu = time.perf_counter() - start, time.process_time() - cpu
print(json.dumps({"elapsed_s": elapsed, "cpu_s": cpu, "duration_s": rec.duration_s, "load_before": load,
                  "load_after": os.getloadavg()[0], "swap": bool(report.swap)}))
"""
#: Matchers tried, in order of preference (frame and event-time first).
METHODS = ("frame", "event-time", "frame-area", "event-area", "event-vector")
NOMINAL_PX = 8.0


def share_near(disparity: np.ndarray, target: float = NOMINAL_PX, tol: float = 1.0) -> float:
    """Share of estimates within ``tol`` px of ``target`` (NaN without estimates)."""
    return float(np.mean(np.abs(disparity - target) <= tol)) if disparity.size else float("nan")


def time_check(code_dir: Path | None, path: Path) -> dict:
    """One timing of check_rig on ``path`` in a child process running the code in ``code_dir`` (None: this
    tree as installed)."""
    env = dict(os.environ)
    if code_dir is not None:
        env["PYTHONPATH"] = str(code_dir) + os.pathsep + env.get("PYTHONPATH", "")
    out = subprocess.run([sys.executable, "-c", _TIMER, str(path)], capture_output=True, text=True, env=env,
                         cwd=code_dir or ROOT)
    if out.returncode:
        raise RuntimeError(f"timing {path.name} with {code_dir or 'this tree'} failed:\n{out.stderr}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def speed(before: str, repeats: int) -> tuple[list[str], list[dict]]:
    """Timings of the base revision and this tree on the real files, alternately: (markdown lines, rows)."""
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        archive = Path(tmp) / "base.tar"
        subprocess.run(["git", "-C", str(ROOT), "archive", "-o", str(archive), before], check=True)
        base_dir = Path(tmp) / "base"
        with tarfile.open(archive) as tar:
            tar.extractall(base_dir, filter="data")
        for name in REAL_FILES:
            runs = {"before": [], "after": []}
            agreements = {label: Agreement(max_runs=repeats) for label in runs}
            for a in agreements.values():
                a.start()
            # Before and after in turn, each until two of its runs agree.
            while not all(a.done for a in agreements.values()):
                for label, code in (("before", base_dir), ("after", None)):
                    if not agreements[label].done:
                        runs[label].append(time_check(code, TUM / name))
                        agreements[label].add(runs[label][-1]["elapsed_s"])
            for label, r in runs.items():
                t = agreements[label].result()
                best = next(x for x in r if x["elapsed_s"] == t.seconds)
                rows.append({"file": name, "code": label, **best, "runs": t.runs, "agreed": t.agreed,
                             "load_before": t.load_before, "load_after": t.load_after,
                             "share": t.seconds / best["duration_s"], "cpu_share": best["cpu_s"] / best["duration_s"]})
                print(f"{name:24s} {label:6s} {t.seconds:.2f} s = {rows[-1]['share']:.1%} of "
                      f"{best['duration_s']:.1f} s, CPU {best['cpu_s']:.2f} s = {rows[-1]['cpu_share']:.1%} "
                      f"({t.note()})", flush=True)
    lines = [
        f"## Speed: `check_rig` time as a share of the recording's duration (before = `{before}`, after = this "
        "tree)", "",
        "Each cell: wall time (share of the duration) and CPU time of the process (share), the faster of the "
        "first two runs within 10 % of each other (in a child process, file already read, retina 0 given as "
        "left), with the runs needed and the 1-minute load average on this machine before and after. Before "
        "and after ran in turn in the same run; on a loaded machine the wall time is several times the CPU "
        "time. Target: at most 10 % of the duration.", "",
        "| file | duration | before: wall (share), CPU (share) | after: wall (share), CPU (share) | speed-up | "
        "runs before, after | load before -> after |",
        "|---|---|---|---|---|---|---|",
    ]
    for name in REAL_FILES:
        b, a = (next(r for r in rows if r["file"] == name and r["code"] == c) for c in ("before", "after"))

        def cell(r):
            return (f"{r['elapsed_s']:.2f} s ({r['share']:.1%}), {r['cpu_s']:.2f} s ({r['cpu_share']:.1%})"
                    + ("" if r["agreed"] else " *"))
        lines.append(f"| {name} | {b['duration_s']:.1f} s | {cell(b)} | {cell(a)} | "
                     f"{b['elapsed_s'] / a['elapsed_s']:.1f}x | {b['runs']}, {a['runs']} | "
                     f"{min(a['load_before'], b['load_before']):.1f} -> {max(a['load_after'], b['load_after']):.1f} |")
    lines += ["", "`*`: no two runs agreed within 10 % (the fastest is shown).", ""]
    return lines, rows


def update_speed(speed_lines: list[str], speed_rows: list[dict], out: Path) -> None:
    """Replace the speed section of rigcheck.md and .json in ``out``, keeping the accuracy results."""
    out.mkdir(parents=True, exist_ok=True)
    md, js = out / "rigcheck.md", out / "rigcheck.json"
    rest = md.read_text() if md.exists() else ""
    cut = rest.find("## Fan_disp8.dat")
    rest = rest[cut:] if cut >= 0 else ""
    md.write_text("\n".join(["# Rig self-check", "", *speed_lines, rest]))
    data = json.loads(js.read_text()) if js.exists() else {}
    js.write_text(json.dumps({**data, "speed": speed_rows}, indent=2, default=float))
    print("\n".join(speed_lines))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--before", default="main", help="base revision for the speed comparison")
    parser.add_argument("--repeats", type=int, default=6, help="timings per file and code at most")
    parser.add_argument("--skip-accuracy", action="store_true", help="only the speed table")
    parser.add_argument("-o", "--output", default=str(ROOT / "bench" / "results"),
                        help="folder for rigcheck.md/.json")
    args = parser.parse_args()
    speed_lines, speed_rows = speed(args.before, args.repeats)
    if args.skip_accuracy:
        update_speed(speed_lines, speed_rows, Path(args.output))
        return
    accuracy(speed_lines, speed_rows, Path(args.output))


def accuracy(speed_lines: list[str], speed_rows: list[dict], out: Path) -> None:
    """The --auto table on Fan_disp8.dat; writes both tables."""
    from cvstereo.io import read_recording
    from cvstereo.matchers.registry import available_methods
    from cvstereo.rigcheck import check_rig
    from cvstereo.run import match

    methods = [m for m in METHODS if m in available_methods()]
    rows, reports = [], {}
    for left_retina in (0, 1):
        rec = read_recording(FAN, left_retina=left_retina)
        start = time.perf_counter()
        report = check_rig(rec)
        check_s = time.perf_counter() - start
        reports[left_retina] = {**report.to_dict(), "elapsed_s": check_s}
        fixed = report.prepare(rec)
        kwargs = report.match_kwargs()
        for method in methods:
            before = match(rec, method=method).disparity
            after = match(fixed, method=method, **kwargs).disparity
            rows.append({"left_retina": left_retina, "method": method, "matches_before": int(before.size),
                         "share_before": share_near(before), "matches_after": int(after.size),
                         "share_after": share_near(after), "swap": report.swap, **kwargs})
            print(f"retina {left_retina} as left, {method:12s}: {rows[-1]['share_before']:.3f} of "
                  f"{before.size} -> {rows[-1]['share_after']:.3f} of {after.size} "
                  f"(auto: swap={report.swap}, {kwargs})", flush=True)
    lines = [
        "# Rig self-check", "", *speed_lines,
        "## Fan_disp8.dat: share of estimates within 1 px of 8 px, before and after `--auto`",
        "",
        "Generated by `bench/bench_rigcheck.py`. 'Before': the recording as read with the given retina as left "
        "(README: retina 1 is the left camera in this file). 'After': `check_rig` first, then its swap and "
        "row/time offsets applied (what `cvstereo match --auto` does). Empty matches give n/a.",
        "",
        "| retina as left | method | before: share (matches) | after: share (matches) | auto applied |",
        "|---|---|---|---|---|",
    ]
    for r in rows:
        def cell(share, n):
            return "n/a (0)" if n == 0 else f"{share:.3f} ({n})"
        lines.append(f"| {r['left_retina']} | {r['method']} | {cell(r['share_before'], r['matches_before'])} | "
                     f"{cell(r['share_after'], r['matches_after'])} | swap={r['swap']}, row {r['row_offset']}, "
                     f"time {r['time_offset_us']} us |")
    lines += ["", "Rig check (retina 0 given as left):", "", "```", check_rig(read_recording(FAN, left_retina=0))
              .summary(), "```", ""]
    out.mkdir(parents=True, exist_ok=True)
    (out / "rigcheck.md").write_text("\n".join(lines))
    (out / "rigcheck.json").write_text(json.dumps({"speed": speed_rows, "rows": rows, "reports": reports},
                                                  indent=2, default=float))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
