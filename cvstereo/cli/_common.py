"""Options and helpers shared by several subcommands."""

from __future__ import annotations

import argparse
import contextlib
import math
import os
from collections.abc import Iterable, Iterator

#: How the commands that read a recording take it: ``RECORDING [RIGHT]`` as positional arguments, the right
#: camera's file also as ``--right RIGHT`` (the spelling ``plot``, ``video`` and ``evaluate`` had); the
#: commands that also read a matches file take it after them: ``RECORDING [RIGHT] [MATCHES]``.
MATCHES_MODES = (None, "optional", "required")


def add_recording_arguments(parser: argparse.ArgumentParser, *, matches: str | None = None,
                            required: bool = True) -> None:
    """Add ``RECORDING [RIGHT]`` (``[MATCHES]`` or ``MATCHES`` after them), ``--right`` and the format options.

    Every command that reads a recording takes it this one way; :func:`settle_recording_inputs` (run by the CLI
    before the command) turns what was given into ``args.recording``, ``args.right`` and ``args.matches``.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The subcommand's parser.
    matches : {None, "optional", "required"}
        Whether a matches file (written by `cvstereo match`) follows the recording.
    required : bool
        False where the command can run without a recording (``match --list-methods``).
    """
    if matches not in MATCHES_MODES:
        raise ValueError(f"matches={matches!r}: choose one of {MATCHES_MODES}")
    parser.add_argument("recording", metavar="RECORDING", nargs=None if required else "?", default=None,
                        help="the recording file, or the left camera's file where each camera has its own "
                        "(DSEC events.h5, eDVS text, AEDAT4)")
    parser.add_argument("right", metavar="RIGHT", nargs="?", default=None,
                        help="the right camera's file, for formats with one file per camera")
    if matches is not None:
        parser.add_argument("matches", metavar="MATCHES", nargs="?" if matches == "optional" else None, default=None,
                            help="matches .npz written by `cvstereo match` (a file after RECORDING named .npz "
                            "is MATCHES: a right camera's file never is one)")
    parser.add_argument("--right", dest="right_option", metavar="RIGHT", default=None,
                        help="the right camera's file, as an option: the same as the RIGHT argument")
    parser.set_defaults(_settle_inputs=settle_recording_inputs, _inputs_parser=parser, _matches_mode=matches)
    add_format_options(parser)


def settle_recording_inputs(args: argparse.Namespace) -> None:
    """Set ``args.recording``, ``args.right`` (and ``args.matches``) from the positionals and ``--right``.

    argparse fills the positionals left to right, so with ``RECORDING X [MATCHES]`` it cannot know whether X is
    the right camera's file or the matches file: X is the matches file when ``--right`` names the right camera,
    or when X is named ``.npz`` (matches files are .npz; a right camera's file never is: a recording .npz holds
    both cameras). The name decides, not the content, so that a missing file or a FIFO is reported as such.
    Giving the right camera's file both ways is a usage error (exit 2). Running it twice changes nothing.
    """
    option = getattr(args, "right_option", None)
    mode = getattr(args, "_matches_mode", None)
    # X in RECORDING X (no third positional) is the matches file where the command takes one and X says so.
    x_is_matches = (mode is not None and getattr(args, "matches", None) is None
                    and str(args.right or "").lower().endswith(".npz"))
    if option is not None:
        if args.right is not None and not x_is_matches:
            args._inputs_parser.error(f"the right camera's file is given twice (RIGHT {args.right} and --right "
                                      f"{option}): give it once")
        if x_is_matches:
            args.matches = args.right  # RECORDING MATCHES --right RIGHT
        args.right, args.right_option = option, None
    elif x_is_matches and mode == "optional":
        args.matches, args.right = args.right, None


def is_matches_file(path, file_format: str | None = None) -> bool:
    """Whether ``path`` is a matches .npz (written by `cvstereo match`) rather than a recording; False for a
    missing file (the command says that itself, with the other inputs)."""
    from cvstereo.io.npz import npz_keys

    if file_format not in (None, "npz") or not str(path).lower().endswith(".npz") or not os.path.isfile(path):
        return False
    keys = npz_keys(path)
    return "matches" in keys and "left" not in keys


def add_matcher_options(parser: argparse.ArgumentParser, *, what: str = "matcher") -> None:
    """``-m/--method``, ``-v/--variant``, ``-p/--param`` and ``--param-set``: one matcher, as `match` and `live`
    take it (default: the registry's default method and the parameter set's default variant)."""
    from cvstereo.matchers.registry import DEFAULT_METHOD
    from cvstereo.matchers.sets import DEFAULT_PARAM_SET, PARAM_SETS

    g = parser.add_argument_group(what)
    g.add_argument("-m", "--method", default=DEFAULT_METHOD,
                   help=f"matcher name (default: {DEFAULT_METHOD}; see `cvstereo match --list-methods`)")
    g.add_argument("-v", "--variant", default=None,
                   help="variant name (default: the parameter set's default variant; see --list-methods)")
    g.add_argument("--param-set", choices=PARAM_SETS, default=DEFAULT_PARAM_SET,
                   help="adaptive (default): thresholds relative to the recording's own signal level and each "
                   "method's best variant; thesis: the thesis' constants and default variants, as published")
    g.add_argument("-p", "--param", action="append", default=[], metavar="KEY=VALUE",
                   help="override a parameter (repeatable); names as in --list-methods")
    add_threads_option(g)


def add_threads_option(parser, *, default: str = "the cores this process may use") -> None:
    """``--threads N``: the threads a matcher runs on (:mod:`cvstereo._threads`); read by :func:`matcher_threads`."""
    parser.add_argument("--threads", default=None, metavar="N",
                        help=f"threads the matcher runs on: numba's and OpenCV's (default: {default}); the matches "
                        "do not depend on it")


def matcher_threads(args: argparse.Namespace, *, default: int | None = None) -> int | None:
    """``--threads`` checked (a whole number from 1 to :data:`cvstereo._threads.MAX_THREADS`), or ``default`` when
    not given (None: the library's, the cores this process may use).

    More threads than the process has cores are taken, with a note on stderr: numba's and OpenCV's pools run at
    most numba's pool size (the cores unless ``NUMBA_NUM_THREADS`` says otherwise), and the matches are the same.

    Raises
    ------
    ValueError
        Not a whole number from 1 to ``MAX_THREADS`` (one line naming ``--threads``).
    """
    import sys

    from cvstereo._threads import MAX_THREADS, available_cores, pool_size

    if args.threads is None:
        return default
    text = str(args.threads).strip()
    try:
        threads = int(text)
    except ValueError:
        threads = 0
    if not (text.isascii() and text.lstrip("+").isdigit()) or not 1 <= threads <= MAX_THREADS:
        raise ValueError(f"--threads {args.threads}: give a whole number of threads from 1 to {MAX_THREADS} "
                         f"({available_cores()} cores here).")
    if threads > pool_size():
        print(f"note: --threads {threads}: this process runs at most {pool_size()} threads at once (its cores); "
              "the work is split as asked, the matches are the same.", file=sys.stderr)
    return threads


def matcher_overrides(args: argparse.Namespace) -> dict:
    """Check ``--method``, ``--variant``, ``--param-set`` and ``--param`` together, before any file is read; return
    the ``--param`` values, typed, as keyword arguments for the matcher.

    Raises
    ------
    ValueError
        An unknown method (the known ones listed), a method not installed here, an unknown variant, or a
        parameter name or value the method does not take (the allowed ones named).
    """
    from cvstereo.matchers.registry import available_methods, matcher_class, parse_param_strings
    from cvstereo.matchers.sets import resolve

    try:
        cls = matcher_class(args.method)  # ValueError listing the known methods
    except ImportError:
        raise ValueError(f"--method {args.method}: not available here; available: "
                         f"{', '.join(available_methods()) or 'none'}.") from None
    overrides = parse_param_strings(cls.Params, args.param)
    variant, set_params = resolve(args.method, args.variant, args.param_set)
    cls.make_params(variant, **{**set_params, **overrides})
    return overrides


def add_format_options(parser: argparse.ArgumentParser) -> None:
    """``--format``, ``--left-retina``, ``--one-based``, ``--resolution``, ``--columns``, ``--topics``."""
    from cvstereo.io import FORMATS

    g = parser.add_argument_group("input format (where the file cannot tell)")
    g.add_argument("--format", choices=FORMATS, default=None, help="input format (default: from the extension)")
    g.add_argument("--left-retina", type=int, choices=(0, 1), default=None,
                   help="merged text files: which retina id is the left camera (default: detect from the data)")
    g.add_argument("--one-based", action=argparse.BooleanOptionalAction, default=None,
                   help="text files: coordinates count from 1 (default: detect)")
    g.add_argument("--resolution", type=_resolution, default=None, metavar="WxH",
                   help="sensor size (default: from the file, else 128x128)")
    g.add_argument("--columns", default=None, metavar="ORDER",
                   help="Metavision CSV: the column order, e.g. t,x,y,p (default: x,y,p,t, as Metavision writes)")
    g.add_argument("--topics", default=None, metavar="LEFT,RIGHT",
                   help="ROS bags: the left and right cameras' event topics (default: the two event topics whose "
                        "names say left/right or cam0/cam1)")


def _resolution(text: str) -> tuple[int, int]:
    from cvstereo.model.events import check_resolution

    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not WIDTHxHEIGHT, e.g. 128x128") from None
    try:
        return check_resolution((w, h), source="size")
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def format_options(args: argparse.Namespace) -> dict:
    """The format options given on the command line, as keyword arguments for the readers."""
    opts = {}
    if getattr(args, "format", None):
        opts["format"] = args.format
    for key in ("left_retina", "one_based", "resolution", "columns", "topics"):
        if getattr(args, key, None) is not None:
            opts[key] = getattr(args, key)
    return opts


def recording_plan(args: argparse.Namespace):
    """The output plan of a command that reads the recording :func:`add_recording_arguments` took: the
    recording, the right camera's file, the matches file and a ``--depth MODEL.json`` declared as its inputs; the
    command adds its outputs and checks the plan (:class:`~cvstereo.io.output_plan.OutputPlan`) before reading
    anything."""
    from cvstereo.geometry.depth_file import WHAT
    from cvstereo.io.output_plan import OutputPlan

    settle_recording_inputs(args)
    plan = OutputPlan()
    plan.read(args.recording, args.right, getattr(args, "matches", None))
    plan.read(depth_file(args), what=WHAT)
    return plan


def load_recording(args: argparse.Namespace):
    """Read the recording that :func:`add_recording_arguments` took, with its format options (errors name the
    file); its plan (:func:`recording_plan`) has checked the files."""
    from cvstereo.io import read_recording

    settle_recording_inputs(args)
    with naming(args.recording, args.right):
        return read_recording(args.recording, args.right, **format_options(args))


def open_recording_stream(args: argparse.Namespace):
    """Open the recording that :func:`add_recording_arguments` took for streaming, with its format options.

    Errors name the file, those found while its packets are read (in the middle of a match) as well as those
    found when it is opened; its plan (:func:`recording_plan`) has checked the files.
    """
    import dataclasses

    from cvstereo.io import open_recording

    settle_recording_inputs(args)
    names = (args.recording, args.right)
    with naming(*names):
        stream = open_recording(args.recording, args.right, **format_options(args))

    def open_chunks(camera: str):
        with naming(*names):
            yield from stream.open_chunks(camera)

    return dataclasses.replace(stream, open_chunks=open_chunks)


def load_matches(path: str | os.PathLike):
    """Read a matches file named on the command line (errors name the file)."""
    from cvstereo.io import read_matches

    check_files([path])
    with naming(path):
        return read_matches(path)


def load_matches_for(args: argparse.Namespace, recording):
    """The matches file ``args.matches`` and the recording as the matches used it.

    Unless ``--force``, the matches must come from this recording
    (:func:`cvstereo.evaluation.metrics.check_same_recording`: one line saying what differs); a file too old to tell is
    read with a note on stderr. The recording comes back with its cameras in the matches' order
    (:func:`cvstereo.geometry.source.as_matched`).

    Returns
    -------
    (Recording, MatchResult)
    """
    import sys

    from cvstereo.evaluation.metrics import check_same_recording
    from cvstereo.geometry.source import as_matched

    result = load_matches(args.matches)
    if not args.force:
        with naming(args.matches):
            note = check_same_recording(recording, result.meta, result.matches)
        if note is not None:
            print(f"note: {args.matches}: {note}", file=sys.stderr)
    return as_matched(recording, result.meta), result


def load_matches_streamed(args: argparse.Namespace):
    """The matches file ``args.matches``, checked against the recording without holding the recording.

    The recording's fingerprint is taken one chunk at a time (:func:`cvstereo.model.fingerprint.fingerprint_of_stream`);
    only when it is not the matches' (another recording, or a matches file too old to carry one) is the recording
    read whole, by :func:`load_matches_for`, to say what differs. For commands that need the matches and not the
    events (scoring against dense ground truth, DSEC's export): a DSEC sequence may be larger than memory.

    Returns
    -------
    MatchResult
    """
    from cvstereo.model.fingerprint import is_fingerprint_of_stream

    result = load_matches(args.matches)
    if args.force:
        return result
    stream = open_recording_stream(args)
    with naming(args.recording, args.right):
        if is_fingerprint_of_stream(result.meta.get("fingerprint"), stream):
            return result
    return load_matches_for(args, load_recording(args))[1]


def add_force_option(parser: argparse.ArgumentParser, verb: str) -> None:
    """``--force``: use a matches file that says it was computed on another recording."""
    parser.add_argument("--force", action="store_true",
                        help=f"{verb} even when the matches file says it was computed on another recording (other "
                        "events, another clock or sensor size)")


def check_files(inputs: Iterable) -> None:
    """Before reading anything: every input is a regular file (the input check of an output plan).

    Raises
    ------
    OSError
        An input is missing, a folder, a FIFO or a device (said as such).
    """
    from cvstereo.io.output_plan import OutputPlan

    plan = OutputPlan()
    plan.read(*inputs)
    plan.check()


@contextlib.contextmanager
def naming(*paths) -> Iterator[None]:
    """Prefix ``paths`` (those given) to a ValueError/OSError raised inside that names none of them."""
    names = [os.fspath(p) for p in paths if p is not None]
    try:
        yield
    except (ValueError, OSError) as exc:
        text = str(exc)
        if not names or any(n in text or os.path.basename(n) in text for n in names):
            raise
        message = f"{', '.join(names)}: {text or type(exc).__name__}"
        try:
            renamed = type(exc)(message)
        except Exception:  # an exception class with another signature: keep the family
            renamed = (OSError if isinstance(exc, OSError) else ValueError)(message)
        raise renamed from exc


def require_range(value, option: str, *, gt: float | None = None, ge: float | None = None,
                  le: float | None = None) -> None:
    """Raise a ValueError naming ``option`` and its limits unless ``value`` is finite and within them."""
    if value is None:
        return
    ok = isinstance(value, int | float) and math.isfinite(value)
    ok = ok and (gt is None or value > gt) and (ge is None or value >= ge) and (le is None or value <= le)
    if not ok:
        limits = [f"> {gt:g}" if gt is not None else None, f">= {ge:g}" if ge is not None else None,
                  f"<= {le:g}" if le is not None else None]
        raise ValueError(f"{option} must be a finite number {' and '.join(x for x in limits if x)}, got {value:g}.")


def add_depth_options(p: argparse.ArgumentParser) -> None:
    """``--depth A C`` and ``--metres/--no-metres``: a distance axis from d = A/Z - C."""
    g = p.add_argument_group("distance in metres (d = A/Z - C)")
    g.add_argument("--depth", nargs="+", default=None, metavar="A C | MODEL.json",
                   help="A = focal length (px) x baseline (m) and C (px), or the file `cvstereo depth-fit -o` "
                   "wrote (default: from the recording's rig, where it has one)")
    g.add_argument("--metres", action=argparse.BooleanOptionalAction, default=True,
                   help="show distances where a depth model is known (default: yes)")


def depth_file(args: argparse.Namespace) -> str | None:
    """The depth-model file ``--depth MODEL.json`` names (an input of the command), or None."""
    depth = getattr(args, "depth", None)
    return depth[0] if depth is not None and len(depth) == 1 else None


@contextlib.contextmanager
def conflicts_as_usage_errors(args: argparse.Namespace) -> Iterator[None]:
    """Report options that exclude each other (:class:`~cvstereo.geometry.source.GeometryConflict`) as usage
    errors (exit 2), as argparse does for its own."""
    from cvstereo.geometry.source import GeometryConflict

    try:
        yield
    except GeometryConflict as exc:
        args._parser.error(str(exc))


def picture_depth(args: argparse.Namespace, recording, result):
    """The depth model of pictures (:func:`cvstereo.geometry.source.depth_for_matches`): from ``--depth``, the
    matches file, the recording's rig; None with ``--no-metres``."""
    from cvstereo.geometry.source import depth_for_matches

    explicit = parse_depth_option(args.depth) if args.depth is not None and args.metres else None
    names = (getattr(args, "matches", None) or "the matches file", getattr(args, "recording", None) or "the recording")
    return depth_for_matches({} if result is None else result.meta, recording.meta, depth=explicit,
                             metres=args.metres, names=names)


def parse_depth_option(values: list[str]):
    """``--depth A C`` (two numbers) or ``--depth MODEL.json`` (a depth-model file) as a DepthModel."""
    from cvstereo.geometry.depth import DepthModel

    if len(values) == 1:
        from cvstereo.geometry.depth_file import load_depth_model

        return load_depth_model(values[0])
    try:
        a, c = (float(v) for v in values)
    except ValueError:
        raise ValueError(f"--depth takes two numbers A C or one depth-model file, got {' '.join(values)!r}.") from None
    try:
        return DepthModel(a=a, c=c)
    except ValueError as exc:
        raise ValueError(f"--depth A C: {exc}") from None


def add_progress_option(parser: argparse.ArgumentParser) -> None:
    """``--progress/--no-progress``: progress bars on stderr, by default only when stderr is a terminal (a log
    file or a pipe gets no carriage-return animation)."""
    parser.add_argument("--progress", action=argparse.BooleanOptionalAction, default=None,
                        help="show progress bars (default: when stderr is a terminal)")


def progress_wanted(args: argparse.Namespace) -> bool:
    """What ``--progress/--no-progress`` asks for; by default whether stderr is a terminal."""
    import sys

    return sys.stderr.isatty() if getattr(args, "progress", None) is None else bool(args.progress)
