"""``cvstereo record``: record two eDVS128 boards into a stereo recording ``.npz``.

Events go to a journal first (flushed at least every second); on Ctrl-C, SIGTERM or ``--seconds`` the
journal is turned into the recording, written atomically. ``--from-journal`` converts a journal left by
a crash.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from cvstereo.sensors.session import add_rig_arguments, open_rig, stop_on_signals


def add_parser(subparsers, name: str) -> argparse.ArgumentParser:
    p = subparsers.add_parser(name, help="record two eDVS128 boards (or --simulate) into a recording .npz",
                              description=__doc__)
    add_rig_arguments(p)
    p.add_argument("-o", "--output", required=True, metavar="OUT.npz", help="recording to write")
    p.add_argument("--journal", default=None, metavar="PATH", help="journal file (default: OUT.npz.journal)")
    p.add_argument("--from-journal", default=None, metavar="JOURNAL",
                   help="do not record: convert this journal (e.g. left by a crash) into OUT.npz")
    return p


def _write(journal_path: Path, out: str) -> None:
    from cvstereo.io.npz import write_recording_npz
    from cvstereo.sensors.journal import read_journal

    rec, lost = read_journal(journal_path)
    write_recording_npz(out, rec)
    print(f"wrote {out}: {rec.left.size} left and {rec.right.size} right events, {rec.duration_s:.2f} s"
          + (f" ({lost} bytes of a cut-short last journal record dropped)" if lost else ""), file=sys.stderr)


def run(args: argparse.Namespace) -> int:
    from cvstereo.sensors.journal import Journal

    if args.from_journal:
        _write(Path(args.from_journal), args.output)
        return 0
    journal_path = Path(args.journal or args.output + ".journal")
    with stop_on_signals() as stop, open_rig(args) as (rig, devices):
        meta = {"source": "cvstereo record", "ports": [c.port for c in rig.cams],
                "event_format": args.event_format, "clock": args.clock,
                "simulated_from": args.simulate}
        with Journal(journal_path, meta) as journal:
            rig.start()
            t_end = None if args.seconds is None else time.monotonic() + args.seconds
            warned = [False, False]
            reported = set()
            try:
                while not stop.is_set() and (t_end is None or time.monotonic() < t_end):
                    for cam_i, chunk in rig.poll(0.05):
                        journal.append(cam_i, chunk.events)
                    journal.maybe_flush()
                    for i, cam in enumerate(rig.cams):
                        if cam.silent and not warned[i]:
                            print(f"cvstereo record: warning: {cam.name} sensor ({cam.port}) silent for "
                                  f"{cam.silence_s:g} s; still recording the other", file=sys.stderr, flush=True)
                        warned[i] = cam.silent
                        if cam.error is not None and i not in reported:
                            print(f"cvstereo record: warning: {cam.error}", file=sys.stderr, flush=True)
                            reported.add(i)
                    if devices and all(d.done for d in devices) and all(c.queue.empty() for c in rig.cams) \
                            and all(c.silent for c in rig.cams):
                        break  # --simulate: the recording has been played in full
            except KeyboardInterrupt:
                pass
            rig.stop()
            for cam_i, chunk in rig.poll(0):
                journal.append(cam_i, chunk.events)
            status = rig.status()
    for cam in ("left", "right"):
        s = status[cam]
        print(f"{cam}: {s['events']} events, {s['corrupt_bytes']} corrupt bytes, {s['silences']} silences"
              + (f", {s['error']}" if s["error"] else ""), file=sys.stderr)
    if status["residual_offset_us"] is not None and args.clock == "align":
        print(f"clock: residual offset right - left ~ {status['residual_offset_us']} us (estimated)",
              file=sys.stderr)
    _write(journal_path, args.output)
    return 0
