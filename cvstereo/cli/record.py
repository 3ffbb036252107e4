"""``cvstereo record``: record two eDVS128 boards or DV cameras / streams (``--dv``) into a stereo recording ``.npz``.

Events go to a journal first (flushed at least every second); on Ctrl-C, SIGTERM or ``--seconds`` the
journal is turned into the recording, written atomically, and the journal is removed (exit 0). A stop before
the boards stream ends the command with nothing written (exit 130 / 143); a second stop while the recording
is written keeps the journal. A journal left by a crash is never overwritten: ``--from-journal`` converts it.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

from cvstereo.sensors.session import add_rig_arguments, open_rig, stop_on_signals, streams_over

__all__ = ["add_parser", "run"]


def add_parser(subparsers, name: str) -> argparse.ArgumentParser:
    p = subparsers.add_parser(name, help="record two eDVS128 boards, DV cameras or streams (or --simulate) into a "
                              "recording .npz",
                              description=__doc__)
    add_rig_arguments(p)
    p.add_argument("-o", "--output", required=True, metavar="OUT.npz", help="recording to write")
    p.add_argument("--journal", default=None, metavar="PATH",
                   help="journal file, which must not exist yet (default: OUT.npz.journal)")
    p.add_argument("--from-journal", default=None, metavar="JOURNAL",
                   help="do not record: convert this journal (e.g. left by a crash) into OUT.npz")
    return p


def _refuse_output_over_inputs(output: str, inputs: dict[str, str | None]) -> None:
    """``-o`` must not be the file of any of these options (through symlinks and hard links too)."""
    from cvstereo.io.paths import refuse_output_over_input

    for option, path in inputs.items():
        refuse_output_over_input(output, [path], what=f"{option} file")


def _write(journal_path: Path, out: str, extra_meta: dict | None = None) -> None:
    from cvstereo.io.npz import write_recording_npz
    from cvstereo.sensors.journal import read_journal

    rec, lost = read_journal(journal_path)
    rec.meta.update(extra_meta or {})
    write_recording_npz(out, rec)
    print(f"wrote {out}: {rec.left.size} left and {rec.right.size} right events, {rec.duration_s:.2f} s"
          + (f" ({lost} bytes of a cut-short last journal record dropped)" if lost else ""), file=sys.stderr)


def _report(rig, devices, args) -> None:
    from cvstereo.sensors.detect import ProtocolMismatchError

    status = rig.status()
    for i, cam in enumerate(("left", "right")):
        s = status[cam]
        received = s["bytes"]
        share = f" ({s['corrupt_bytes'] / received:.1%} of {received} bytes received)" if received else ""
        sent = f" (the virtual board sent {devices[i].sent_events})" if devices else ""
        # A DV source reads decoded events, not bytes (None): it has no corrupt bytes to report.
        corrupt = "" if received is None else f"{s['corrupt_bytes']} corrupt bytes{share}, "
        print(f"{cam}: {s['events']} events{sent}, {s['protocol'] or 'no bytes to tell the protocol'}, "
              f"{corrupt}{s['silences']} silences"
              + (f", {s['ambiguous_wraps']} ambiguous timestamp wraps (the host read late: times after them may"
                 " be off by whole 65.536 ms wraps; record with --event-format E3 or E4 to avoid this)"
                 if s.get("ambiguous_wraps") else "")
              + (f", {s['error']}" if s["error"] else ""), file=sys.stderr)
    if status["residual_offset_us"] is not None and args.clock == "align":
        print(f"clock: residual offset right - left ~ {status['residual_offset_us']} us (estimated)",
              file=sys.stderr)
    for cam in rig.cams:
        if isinstance(cam.error, ProtocolMismatchError):
            raise cam.error


def run(args: argparse.Namespace) -> int:
    from cvstereo.sensors.detect import ProtocolMismatchError
    from cvstereo.sensors.journal import Journal, journal_exists_message

    if args.from_journal:
        _refuse_output_over_inputs(args.output, {"--from-journal": args.from_journal})
        _write(Path(args.from_journal), args.output)
        print(f"journal {args.from_journal} kept; delete it once {args.output} is checked", file=sys.stderr)
        return 0
    journal_path = Path(args.journal or args.output + ".journal")
    _refuse_output_over_inputs(args.output, {"--simulate": args.simulate, "--journal": str(journal_path)})
    if os.path.lexists(journal_path):
        raise FileExistsError(journal_exists_message(journal_path))
    with stop_on_signals() as stop, open_rig(args) as (rig, devices):
        stop.raise_if_set()  # stopped while the boards were opened: nothing received, no journal yet
        meta = {"source": "cvstereo record", "ports": [c.port for c in rig.cams],
                "event_format": "dv" if args.dv else args.event_format, "clock": args.clock,
                "simulated_from": args.simulate, "resolution": list(rig.resolution)}
        journal = Journal(journal_path, meta)  # refuses an existing file: never truncates it
        try:
            _record(rig, devices, journal, stop, args)
        finally:
            journal.close()
        try:
            _report(rig, devices, args)
        except ProtocolMismatchError:
            journal_path.unlink()  # this run's own journal: the settings were refused, nothing to keep
            raise
    try:
        _write(journal_path, args.output, {"protocol": {cam.name: cam.protocol for cam in rig.cams}})
    except KeyboardInterrupt as exc:  # a second stop while the recording is written: the journal has it all
        exc.add_note(f"journal {journal_path} kept with every event received; convert it with cvstereo record "
                     f"--from-journal {journal_path} -o {args.output}")
        raise
    journal_path.unlink()  # everything is in the recording now
    return 0


def _record(rig, devices, journal, stop, args) -> None:
    from cvstereo.sensors.detect import ProtocolMismatchError

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
                    if isinstance(cam.error, ProtocolMismatchError):
                        return  # refused: the other board is stopped too, and the run reports why
                    print(f"cvstereo record: warning: {cam.error}", file=sys.stderr, flush=True)
                    reported.add(i)
            if streams_over(rig, devices) and all(c.queue.empty() for c in rig.cams):
                break  # the recording has been played in full (--simulate), the DV streams ended
    except KeyboardInterrupt:
        pass
    finally:
        # Every event received before the stop: the readers drain the ports, then the queues are emptied.
        rig.stop()
        for cam_i, chunk in rig.poll(0):
            journal.append(cam_i, chunk.events)
