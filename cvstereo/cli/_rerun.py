"""``--rerun [FILE.rrd]``: the option of the commands that can show their windows in the rerun viewer."""

from __future__ import annotations

import argparse
from dataclasses import dataclass

from cvstereo.errors import require_extra

__all__ = ["RerunTarget", "add_rerun_option", "rerun_target"]


@dataclass(frozen=True)
class RerunTarget:
    """Where ``--rerun`` sends the data: nowhere (``wanted`` False), a viewer (``path`` None) or an ``.rrd`` file."""

    wanted: bool
    path: str | None = None


def add_rerun_option(p: argparse.ArgumentParser) -> None:
    """``--rerun [FILE.rrd]``: the same windows in the rerun viewer (no file: a viewer is started)."""
    p.add_argument("--rerun", nargs="?", const="", default=None, metavar="FILE.rrd",
                   help="also log events, disparity, depth and 3D points per window for the rerun viewer: into "
                   "FILE.rrd (open it with `rerun FILE.rrd`), or without FILE to a viewer started now (extra: rerun)")


def rerun_target(args: argparse.Namespace) -> RerunTarget:
    """What ``--rerun`` asks for; the SDK is imported at once, so that a missing extra is said before any work."""
    value = getattr(args, "rerun", None)
    if value is None:
        return RerunTarget(False)
    require_extra("rerun", "rerun")
    return RerunTarget(True, value or None)
