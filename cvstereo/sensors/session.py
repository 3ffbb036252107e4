"""What ``cvstereo record`` and ``cvstereo live`` share: building the rig (real or simulated), the
options for it, and stopping cleanly on Ctrl-C or SIGTERM."""

from __future__ import annotations

import argparse
import contextlib
import signal
import threading
from collections.abc import Iterator
from typing import TYPE_CHECKING

from cvstereo.sensors.protocol import DEFAULT_BAUD, FORMATS, ProtocolSettings

if TYPE_CHECKING:  # the boards' modules load numba; the CLI imports them only when it runs
    from cvstereo.sensors.stereo import StereoEDVS
    from cvstereo.sensors.virtual import VirtualEDVS


def add_rig_arguments(parser: argparse.ArgumentParser) -> None:
    """``--left/--right/--simulate`` and the protocol settings drivers disagree on."""
    parser.add_argument("--left", metavar="PORT", help="serial port of the left eDVS")
    parser.add_argument("--right", metavar="PORT", help="serial port of the right eDVS")
    parser.add_argument("--simulate", metavar="RECORDING", default=None,
                        help="start two virtual eDVS streaming this recording instead of real boards")
    parser.add_argument("--speed", type=float, default=1.0, help="--simulate: stream time per wall time")
    parser.add_argument("--event-format", choices=list(FORMATS), default="E2", help="event format (default E2)")
    parser.add_argument("--baud", type=int, default=DEFAULT_BAUD, help="link speed (default 4000000)")
    parser.add_argument("--seconds", type=float, default=None, help="stop after this long (default: Ctrl-C)")
    g = parser.add_argument_group("protocol details where firmware and drivers differ")
    g.add_argument("--clock", choices=("master-slave", "align"), default="master-slave",
                   help="timestamp sync: firmware master/slave, or reset both and estimate the residual offset")
    g.add_argument("--sync-bit", choices=("set", "clear"), default="set",
                   help="bit 7 of an event's first byte (default set: 1yyyyyyy)")
    g.add_argument("--off-bit", choices=("set", "clear"), default="set",
                   help="polarity bit value meaning OFF (default set, as jAER)")
    g.add_argument("--numbering", choices=("current", "legacy"), default="current",
                   help="!Ex numbering: current firmware, or legacy (!E1 = 16-bit timestamps)")
    g.add_argument("--crlf", action="store_true", help="end commands with \\r\\n instead of \\n")


def protocol_settings(args: argparse.Namespace) -> ProtocolSettings:
    return ProtocolSettings(event_format=args.event_format, sync_bit_set=args.sync_bit == "set",
                            off_bit_set=args.off_bit == "set", numbering=args.numbering,
                            line_ending="\r\n" if args.crlf else "\n")


@contextlib.contextmanager
def open_rig(args: argparse.Namespace) -> Iterator[tuple[StereoEDVS, list[VirtualEDVS]]]:
    """Open the two boards named on the command line (or two virtual ones with --simulate)."""
    from cvstereo.sensors.stereo import StereoEDVS, StereoSettings
    from cvstereo.sensors.virtual import VirtualEDVS

    settings = protocol_settings(args)
    devices: list[VirtualEDVS] = []
    with contextlib.ExitStack() as stack:
        if args.simulate:
            from cvstereo.io.npz import read_recording_npz

            rec = read_recording_npz(args.simulate)
            t0 = rec.t_start
            ports = []
            for ev in (rec.left, rec.right):
                # Both devices count from the recording's first event, so their clocks agree.
                ev = ev.copy()
                ev["t"] -= t0
                dev = VirtualEDVS(ev, baud=args.baud, speed=args.speed, settings=settings)
                ports.append(stack.enter_context(dev))
                devices.append(dev)
            left, right = ports
        else:
            if not args.left or not args.right:
                raise ValueError("give both --left PORT and --right PORT, or --simulate RECORDING to try without "
                                 "hardware.")
            left, right = args.left, args.right
        rig = StereoEDVS(left, right, baud=args.baud, settings=settings,
                         stereo=StereoSettings(clock=args.clock))
        stack.enter_context(rig)
        yield rig, devices


@contextlib.contextmanager
def stop_on_signals() -> Iterator[threading.Event]:
    """An event set by SIGTERM (and SIGINT): the loop stops cleanly and keeps what it has."""
    stop = threading.Event()
    old = {}

    def handler(signum, frame):
        stop.set()

    for sig in (signal.SIGTERM, signal.SIGINT):
        try:
            old[sig] = signal.signal(sig, handler)
        except ValueError:  # not the main thread: the caller stops us instead
            pass
    try:
        yield stop
    finally:
        for sig, h in old.items():
            signal.signal(sig, h)
