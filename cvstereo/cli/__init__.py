"""The ``cvstereo`` command line: one module per subcommand, each with ``add_parser`` and ``run``.

User errors (bad files, bad values, missing extras, unplugged sensors) print one line on stderr and exit
1; usage errors exit 2 (argparse); nothing prints a traceback. File names and contents in messages are
escaped (no raw terminal codes). SIGTERM and SIGHUP stop a command like Ctrl-C does, at any moment from the
first import on: one line ``cvstereo CMD: stopped by SIGNAL``, temporary files removed, exit 128 + signal
number; a closed stdout (``cvstereo info a b | head -1``) ends it quietly (141).
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import os
import select
import signal
import sys
import threading

import cvstereo
from cvstereo._signals import STOP_SIGNALS, TERMINATING_SIGNALS, Terminated, signal_of

__all__ = ["COMMANDS", "build_parser", "main", "plain_help"]

#: Subcommand name -> module under cvstereo.cli that implements it.
COMMANDS: dict[str, str] = {
    "info": "info",
    "convert": "convert",
    "evaluate": "evaluate",
    "export-dsec": "export_dsec",
    "demo": "demo",
    "bench": "bench",
    "depth-fit": "depth_fit",
    "match": "match",
    "plot": "plot",
    "video": "video",
    "record": "record",
    "live": "live",
    "rigcheck": "rigcheck",
    "simulate": "simulate",
    "sweep": "sweep",
    "warm-up": "warm_up",
}


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every subcommand."""
    parser = argparse.ArgumentParser(
        prog="cvstereo",
        description="Depth from a pair of event cameras (DVS128 / eDVS128) without calibration.",
    )
    parser.add_argument("--version", action="version", version=f"cvstereo {cvstereo.__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name, module in COMMANDS.items():
        mod = importlib.import_module(f"cvstereo.cli.{module}")
        p = mod.add_parser(sub, name)
        p.set_defaults(_run=mod.run)
    plain_help(parser)
    return parser


def plain_help(parser: argparse.ArgumentParser) -> None:
    """Strip reStructuredText markup from every text ``parser --help`` shows, subcommands included, in place.

    Much help text comes from docstrings (descriptions, listings); cleaning it here, once, keeps every command's
    ``--help`` plain whatever its module writes. argparse keeps these texts in attributes that are not public
    but have not changed since Python 3.2 (``_actions``, ``_action_groups``, ``_choices_actions``).
    """
    from cvstereo.cli._text import plain_text

    parser.description, parser.epilog = plain_text(parser.description), plain_text(parser.epilog)
    for group in parser._action_groups:
        group.description = plain_text(group.description)
    for action in parser._actions:
        if action.help is not argparse.SUPPRESS:
            action.help = plain_text(action.help)
        if isinstance(action, argparse._SubParsersAction):
            for choice in action._choices_actions:
                choice.help = plain_text(choice.help)
            for subparser in action.choices.values():
                plain_help(subparser)


def _raise_terminated(signum, frame):
    raise Terminated(signum)


@contextlib.contextmanager
def _stop_signals_raise():
    """Turn SIGTERM/SIGHUP into :class:`Terminated` while a command runs (main thread only); restore after.

    SIGINT keeps Python's handler (KeyboardInterrupt), or stays ignored (a background job of a shell).
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {s: signal.getsignal(s) for s in STOP_SIGNALS}
    for s in TERMINATING_SIGNALS:
        signal.signal(s, _raise_terminated)
    try:
        yield
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)


def _ignore_stop_signals() -> None:
    """A stop is being reported: a second one (Ctrl-C pressed twice) must not cut the report into a traceback.
    :func:`_stop_signals_raise` restores the handlers after."""
    if threading.current_thread() is threading.main_thread():
        for s in STOP_SIGNALS:
            signal.signal(s, signal.SIG_IGN)


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; return the exit code.

    The stop signals are handled before the commands are imported: a Ctrl-C or SIGTERM while their modules load
    (numpy, numba, OpenCV: a second or more) is a stop like any other, one line and exit 128 + signal number.
    A stop may carry notes (``exc.add_note``: what was kept, how to resume), printed on the same line.
    """
    given = sys.argv[1:] if argv is None else argv
    command = " ".join(["cvstereo", *(a for a in given[:1] if a in COMMANDS)])  # named before the parser exists
    with _stop_signals_raise():
        try:
            args = build_parser().parse_args(argv)
            command = f"cvstereo {args.command}"
            settle = getattr(args, "_settle_inputs", None)
            if settle is not None:  # RECORDING [RIGHT] [MATCHES] and --right: see _common.add_recording_arguments
                settle(args)
            return int(args._run(args) or 0)
        except KeyboardInterrupt as exc:  # Ctrl-C, and SIGTERM/SIGHUP as Terminated
            _ignore_stop_signals()
            signum = signal_of(exc)
            notes = "".join(f"; {note}" for note in getattr(exc, "__notes__", ()))
            print(f"{command}: stopped by {signal.Signals(signum).name}{_one_line(notes) if notes else ''}",
                  file=sys.stderr)
            return 128 + signum
        except BrokenPipeError as exc:
            if _stdout_closed():
                return 141  # as a shell reports a reader gone (128 + SIGPIPE); nothing to say: nobody reads
            print(f"{command}: error: {_one_line(exc)}", file=sys.stderr)
            return 1
        except (ValueError, OSError, ImportError, TimeoutError, RuntimeError) as exc:
            print(f"{command}: error: {_one_line(exc)}", file=sys.stderr)
            return 1


def _stdout_closed() -> bool:
    """Whether stdout's reader has gone; if so, point stdout at /dev/null so that the final flush at exit
    does not fail again (the Python docs' recipe for SIGPIPE)."""
    try:
        sys.stdout.flush()
    except BrokenPipeError:
        closed = True
    except (OSError, ValueError):
        closed = False
    else:
        closed = _pipe_reader_gone()
    if closed:
        with contextlib.suppress(OSError, ValueError, AttributeError):
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
            os.close(devnull)
    return closed


def _pipe_reader_gone() -> bool:
    try:
        poller = select.poll()
        poller.register(sys.stdout.fileno(), 0)  # POLLERR is reported on a pipe with no reader
        return any(ev & select.POLLERR for _, ev in poller.poll(0))
    except (OSError, ValueError, AttributeError):
        return False


def _one_line(exc: BaseException) -> str:
    from cvstereo.cli._text import printable

    return printable(str(exc) or type(exc).__name__)
