"""What ``cvstereo record`` and ``cvstereo live`` share: building the rig (real or simulated), the
options for it, and stopping cleanly on Ctrl-C or SIGTERM."""

from __future__ import annotations

import argparse
import contextlib
import math
import signal
import threading
from collections.abc import Iterator
from typing import TYPE_CHECKING

from cvstereo.sensors.protocol import DEFAULT_BAUD, FORMATS, ProtocolSettings

__all__ = ["Stop", "add_rig_arguments", "end_finished_streams", "open_rig", "positive_number", "protocol_settings",
           "stop_on_signals", "streams_over"]

if TYPE_CHECKING:  # the boards' modules load numba; the CLI imports them only when it runs
    from cvstereo.sensors.stereo import StereoRig
    from cvstereo.sensors.virtual import VirtualEDVS


def positive_number(what: str):
    """An argparse type: a finite number > 0 (a usage error otherwise)."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{what} must be a number, got '{text}'") from None
        if not (math.isfinite(value) and value > 0):
            raise argparse.ArgumentTypeError(f"{what} must be a finite number greater than 0, got '{text}'")
        return value

    return parse


def _baud(text: str) -> int:
    value = positive_number("--baud")(text)
    if value != int(value) or value > 100_000_000:
        raise argparse.ArgumentTypeError(f"--baud must be a whole number of bit/s up to 100000000, got '{text}'")
    return int(value)


def add_rig_arguments(parser: argparse.ArgumentParser) -> None:
    """``--left/--right/--dv/--simulate`` and the protocol settings drivers disagree on."""
    parser.add_argument("--left", metavar="PORT", help="serial port of the left eDVS")
    parser.add_argument("--right", metavar="PORT", help="serial port of the right eDVS")
    parser.add_argument("--dv", nargs=2, metavar=("LEFT", "RIGHT"), default=None,
                        help="two DV cameras instead of eDVS boards, each a DV network stream tcp://HOST:PORT (the DV "
                        "software's or dv-processing's network output) or a camera's serial number (needs the dv "
                        "extra)")
    parser.add_argument("--simulate", metavar="RECORDING", default=None,
                        help="start two virtual eDVS streaming this recording instead of real boards")
    parser.add_argument("--speed", type=positive_number("--speed"), default=1.0,
                        help="--simulate: stream time per wall time")
    parser.add_argument("--event-format", choices=["auto", *FORMATS], default="auto",
                        help="event format (default auto: detected from the first bytes; a value given is checked "
                        "against the stream)")
    parser.add_argument("--baud", type=_baud, default=DEFAULT_BAUD, help="link speed (default 4000000)")
    parser.add_argument("--seconds", type=positive_number("--seconds"), default=None,
                        help="stop after this long (default: Ctrl-C)")
    g = parser.add_argument_group("protocol details where firmware and drivers differ")
    g.add_argument("--clock", choices=("master-slave", "align"), default="master-slave",
                   help="timestamp sync: firmware master/slave, or reset both and estimate the residual offset")
    g.add_argument("--sync-bit", choices=("auto", "set", "clear"), default="auto",
                   help="bit 7 of an event's first byte (default auto: detected; set = 1yyyyyyy)")
    g.add_argument("--off-bit", choices=("set", "clear"), default="set",
                   help="polarity bit value meaning OFF (default set, as jAER)")
    g.add_argument("--numbering", choices=("current", "legacy"), default="current",
                   help="!Ex numbering: current firmware, or legacy (!E1 = 16-bit timestamps)")
    g.add_argument("--crlf", action="store_true", help="end commands with \\r\\n instead of \\n")


def protocol_settings(args: argparse.Namespace) -> ProtocolSettings:
    """The settings asked for (``auto`` asks the board for E2 and decodes what the stream turns out to be)."""
    return ProtocolSettings(event_format="E2" if args.event_format == "auto" else args.event_format,
                            sync_bit_set=args.sync_bit != "clear",
                            off_bit_set=args.off_bit == "set", numbering=args.numbering,
                            line_ending="\r\n" if args.crlf else "\n")


@contextlib.contextmanager
def open_rig(args: argparse.Namespace) -> Iterator[tuple[StereoRig, list[VirtualEDVS]]]:
    """Open the two cameras named on the command line: eDVS boards, DV cameras or streams (``--dv``), or two
    virtual boards (``--simulate``)."""
    from cvstereo.sensors.stereo import StereoEDVS, StereoSettings
    from cvstereo.sensors.virtual import VirtualClock, VirtualEDVS

    settings = protocol_settings(args)
    devices: list[VirtualEDVS] = []
    with contextlib.ExitStack() as stack:
        if args.dv:
            yield stack.enter_context(_dv_rig(args)), devices
            return
        if args.simulate:
            from cvstereo.io.npz import read_recording_npz

            rec = read_recording_npz(args.simulate)
            # One clock and one scene start for both devices (as real boards after !ETM), so a camera whose
            # first event comes later also starts later in the stream.
            clock = VirtualClock()
            ports = []
            for ev in (rec.left, rec.right):
                dev = VirtualEDVS(ev, baud=args.baud, speed=args.speed, settings=settings, clock=clock,
                                  time_origin_us=rec.t_start)
                ports.append(stack.enter_context(dev))
                devices.append(dev)
            left, right = ports
        else:
            if not args.left or not args.right:
                raise ValueError("give both --left PORT and --right PORT, --dv LEFT RIGHT for DV cameras, or "
                                 "--simulate RECORDING to try without hardware.")
            left, right = args.left, args.right
        rig = StereoEDVS(left, right, baud=args.baud, settings=settings, stereo=StereoSettings(clock=args.clock),
                         auto_format=args.event_format == "auto", auto_sync=args.sync_bit == "auto")
        stack.enter_context(rig)
        yield rig, devices


def _dv_rig(args: argparse.Namespace) -> StereoRig:
    """The rig of ``--dv LEFT RIGHT`` (not opened), the addresses checked first."""
    from cvstereo.sensors.dvlive import dv_sources, parse_dv_address
    from cvstereo.sensors.stereo import StereoRig, StereoSettings

    if args.simulate or args.left or args.right:
        raise ValueError("--dv names both cameras: give it without --left, --right or --simulate.")
    for where in args.dv:
        try:
            parse_dv_address(where)
        except ValueError as exc:
            raise ValueError(f"--dv {exc}") from None
    return StereoRig(dv_sources(*args.dv), stereo=StereoSettings(clock=args.clock))


def _stream_over(rig: StereoRig, devices: list[VirtualEDVS], camera: int) -> bool:
    """Camera ``camera`` will send nothing more, and every event it sent was delivered: a simulated board that
    played its recording to the end, or a source whose stream ended (a DV stream). Real boards never end."""
    side = rig.sides[camera]
    if devices:
        return devices[camera].done and side.events >= devices[camera].sent_events
    return getattr(side.cam, "ended", False)


def end_finished_streams(rig: StereoRig, devices: list[VirtualEDVS]) -> None:
    """Tell the rig which cameras' streams are over (:meth:`StereoRig.end_stream`): the last events of the
    other camera then need not wait for the bounded wait of a silent camera."""
    for camera, side in enumerate(rig.sides):
        if not side.ended and _stream_over(rig, devices, camera):
            rig.end_stream(camera)


def streams_over(rig: StereoRig, devices: list[VirtualEDVS]) -> bool:
    """Both cameras will send nothing more and their readers have delivered what they sent (simulated boards
    that played their recording and went silent, DV streams that ended): the run can end once the rig's
    queues are empty."""
    if devices:
        return all(d.done for d in devices) and all(c.silent for c in rig.cams)
    return all(getattr(c, "ended", False) for c in rig.cams)


class Stop(threading.Event):
    """Set by a stop signal, which it remembers (:attr:`signum`)."""

    signum: int = signal.SIGINT

    def raise_if_set(self) -> None:
        """A stop before the boards stream (while they were opened) ends the command: raise it as the signal's
        exception (:func:`cvstereo._signals.stop_exception`), since there is nothing to keep yet."""
        if self.is_set():
            from cvstereo._signals import stop_exception

            raise stop_exception(self.signum)


@contextlib.contextmanager
def stop_on_signals() -> Iterator[Stop]:
    """A :class:`Stop` set by SIGTERM (and SIGINT): the loop stops cleanly and keeps what it has."""
    stop = Stop()
    old = {}

    def handler(signum, frame):
        stop.signum = signum
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
