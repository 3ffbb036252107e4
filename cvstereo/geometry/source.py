"""Where the geometry of a match comes from: one precedence rule, said in one line and kept in the matches file.

The geometry is five things: which camera is left (``side``), how the rows line up (``rows``: a rectification
or a row offset), the time offset between the cameras (``time``), the depth model d = a/Z - c (``depth``) and
the intrinsics of a point cloud (``intrinsics``). Each comes from the first of these sources that gives it
(:data:`SOURCES`):

1. ``calibration``: a calibration file rectifies the rows and gives the depth model and the intrinsics;
2. ``options``: what the user said (``--row-offset``, ``--time-offset-us``, ``--depth``, ``--focal-px``);
3. ``recording``: the rig model a recording carries in its meta (every simulated recording): depth, intrinsics;
4. ``rigcheck``: the automatic rig check (``--auto``; any callable that returns a report like
   :class:`~cvstereo.rigcheck.report.RigReport`): side, rows, time; without ``--auto``, the light check that
   :func:`cvstereo.run.match` runs on the stream's first second when no source above gives side, rows or time
   (:meth:`Geometry.with_prefix_check`; not with the ``thesis`` parameter set, nor with ``--no-rig-check``).

A calibration rectifies the events, so that their disparities are the rectified pair's: the depth model of the
raw rig in a recording's meta does not apply to them (on the simulated 50 cm arm it put the arm at 0.46 m), and
neither do row or time offsets. A calibration together with an option for the same thing is two answers from
the user, refused (:class:`GeometryConflict`) rather than one silently ignored. Nothing given: the rows and times
as recorded, and no depth model.

>>> from cvstereo.geometry.depth import DepthModel
>>> meta = {"rig": {"focal_px": 165.0, "baseline_m": 0.1, "axis_offset_px": 3.0}}
>>> GeometryOptions().resolve(meta, (128, 128)).summary()
"geometry: depth d = 16.50/Z - 3.00 from the recording's rig; rows and time as recorded"
>>> g = GeometryOptions(depth=DepthModel(20.0), row_offset=1).resolve(meta, (128, 128))
>>> g.describe()["source"], g.describe()["depth"]
('options', {'source': 'options', 'a': 20.0, 'c': 0.0})
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace

from cvstereo.geometry.depth import DepthModel, depth_from_meta
from cvstereo.model.matches import cameras_swapped
from cvstereo.model.recording import Recording

__all__ = ["ASPECTS", "OPTION_NAMES", "SOURCES", "Geometry", "GeometryConflict", "GeometryOptions", "as_matched",
           "depth_for_matches", "stored_depth"]

#: The sources of geometry, first = strongest.
SOURCES = ("calibration", "options", "recording", "rigcheck")
#: The parts of the geometry, in the order the summary line names them.
ASPECTS = ("side", "rows", "time", "depth", "intrinsics")
#: How the options source is named per aspect, as the command line spells it.
OPTION_NAMES = {"rows": "--row-offset", "time": "--time-offset-us", "depth": "--depth", "intrinsics": "--focal-px"}


class GeometryConflict(ValueError):
    """Two sources the user gave for the same part of the geometry (a calibration and an option)."""


@dataclass(frozen=True)
class Geometry:
    """The geometry a match uses and where each part came from (:func:`GeometryOptions.resolve`).

    Attributes
    ----------
    swap : bool
        Exchange the cameras before matching.
    rectification : cvstereo.geometry.rectify.Rectification or None
    row_offset, time_offset_us : int
        Added to the right camera's rows, subtracted from its times (:mod:`cvstereo.geometry.rigcorrect`).
    depth : DepthModel or None
    intrinsics : cvstereo.geometry.pointcloud.Intrinsics or None
        Only when a point cloud is wanted.
    sources : dict
        Aspect -> one of :data:`SOURCES`, or ``"none"`` (as recorded, or no depth model).
    labels : dict
        Source -> how the summary names it (``calibration cal.yaml``, ``the recording's rig``, ...).
    rigcheck : dict or None
        The rig check's report (``to_dict``) with what of it was applied, when it ran.
    row_field : dict or None
        The row field the match's check applied instead of :attr:`row_offset` (``match --row-field``:
        :meth:`cvstereo.rigcheck.row_field.RowField.describe`), where it found one.
    in_match : bool
        The side, rows and time were found and applied by the match itself (the prefix check of
        :func:`cvstereo.run.match`): :meth:`prepare` and :meth:`match_kwargs` leave them to it.
    """

    swap: bool = False
    rectification: object = None
    row_offset: int = 0
    time_offset_us: int = 0
    depth: DepthModel | None = None
    intrinsics: object = None
    sources: dict = field(default_factory=dict)
    labels: dict = field(default_factory=dict)
    rigcheck: dict | None = None
    row_field: dict | None = None
    in_match: bool = False

    def prepare(self, recording):
        """The recording (a :class:`~cvstereo.model.recording.Recording` or a stream opened by
        :func:`cvstereo.io.open_recording`) as the matcher gets it: its cameras exchanged when :attr:`swap`."""
        return recording.swapped() if self.swap and not self.in_match else recording

    @property
    def rig_check_wanted(self) -> bool:
        """Whether :func:`cvstereo.run.match` should run its prefix check: no source gave side, rows or time."""
        return not any(a in self.sources for a in ("side", "rows", "time"))

    def matched(self, matches_meta: Mapping) -> Geometry:
        """The geometry as the match applied it: with the side, rows and time of the match's own prefix check
        (``matches_meta["rigcheck"]`` of scope ``prefix``, when this geometry left them to it), else itself."""
        found = matches_meta.get("rigcheck")
        if self.rigcheck is not None or not isinstance(found, Mapping) or found.get("scope") != "prefix":
            return self
        return self.with_prefix_check(found)

    def with_prefix_check(self, found: Mapping) -> Geometry:
        """This geometry with the side, rows and time that the match's prefix check found and applied
        (``found``: the matches' ``meta["rigcheck"]``, :meth:`cvstereo.rigcheck.prefix.PrefixRigCheck.describe`)."""
        applied = found["applied"]
        label = f"the rig check of the first {found['prefix_us'] / 1e6:.3g} s"
        by_matching = found.get("rows_by_matching")
        if by_matching is not None:  # the overlay was unsure of the rows (docs/guide/rigcheck.md)
            label += " (rows by matching)" if by_matching["offset"] == applied["row_offset"] else \
                " (rows: none stood out)"
        side = found.get("side_by_matching")
        if side is not None and side["swap"]:  # the overlay was unsure of the order; the matcher's answers told it
            label += " (side by matching)"
        sources = {**self.sources, **({} if found.get("skipped") else dict.fromkeys(("side", "rows", "time"),
                                                                                  "rigcheck"))}
        row_field = found.get("row_field") if applied.get("row_field") else None
        return replace(self, swap=bool(applied["swap"]), row_offset=int(applied["row_offset"]),
                       time_offset_us=int(applied["time_offset_us"]), sources=sources,
                       labels={**self.labels, "rigcheck": label}, rigcheck=dict(found), row_field=row_field,
                       in_match=True)

    def match_kwargs(self) -> dict:
        """The keywords of :func:`cvstereo.run.match` that apply this geometry's rows and times."""
        if self.in_match:
            return {}
        if self.rectification is not None:
            return {"rectification": self.rectification}
        return {k: v for k, v in (("row_offset", self.row_offset), ("time_offset_us", self.time_offset_us)) if v}

    @property
    def source(self) -> str:
        """The strongest source any part came from, or ``"none"``."""
        used = set(self.sources.values())
        return next((s for s in SOURCES if s in used), "none")

    def describe(self) -> dict:
        """JSON for a matches file's meta (``meta["geometry"]``): the source of each part and its value."""
        out = {"source": self.source,
               "side": {"source": self.sources.get("side", "none"), "swap": self.swap},
               "time": {"source": self.sources.get("time", "none"), "time_offset_us": self.time_offset_us}}
        rows = {"source": self.sources.get("rows", "none")}
        out["rows"] = {**rows, "rectified": True} if self.rectification is not None else {
            **rows, "row_offset": self.row_offset, **({} if self.row_field is None else {"row_field": self.row_field})}
        out["depth"] = {"source": self.sources.get("depth", "none"), **(self.depth.to_dict() if self.depth else {})}
        if self.intrinsics is not None:
            i = self.intrinsics
            out["intrinsics"] = {"source": self.sources["intrinsics"], "focal_px": i.focal_px, "cx": i.cx,
                                 "cy": i.cy}
        return out

    def summary(self) -> str:
        """One line: ``geometry: what from where; ...``."""
        items = {
            "side": "cameras swapped" if self.swap else "cameras in the given order",
            "rows": self._rows_said(),
            "time": f"time offset {self.time_offset_us:+d} us",
            "depth": None if self.depth is None else f"depth d = {self.depth.a:.2f}/Z - {self.depth.c:.2f}",
            "intrinsics": None if self.intrinsics is None else f"focal length {self.intrinsics.focal_px:g} px",
        }
        parts = []
        for source in (*SOURCES, "default"):
            said = [items[a] for a in ASPECTS if self.sources.get(a) == source and items[a] is not None]
            if said:
                parts.append(f"{', '.join(said)} from {self._label(source)}")
        recorded = [a for a in ("rows", "time") if self.sources.get(a, "none") == "none"]
        if recorded:
            parts.append(f"{' and '.join(recorded)} as recorded")
        if self.depth is None:
            parts.append("no depth model" + (f" ({self.labels['depth']})" if "depth" in self.labels else ""))
        return "geometry: " + "; ".join(parts)

    def _rows_said(self) -> str:
        if self.rectification is not None:
            return "rows rectified"
        if self.row_field is not None:
            low, high = self.row_field["rows"]
            return f"rows {low:+d} to {high:+d} across the image"
        return f"rows {self.row_offset:+d}"

    def _label(self, source: str) -> str:
        if source == "options":
            names = [OPTION_NAMES[a] for a in ASPECTS if self.sources.get(a) == "options" and a in OPTION_NAMES]
            return ", ".join(names)
        return self.labels.get(source, source)


@dataclass(frozen=True)
class GeometryOptions:
    """What the user gave towards the geometry; :meth:`resolve` applies the precedence rule.

    Conflicts are refused at construction, before any recording is read.

    Parameters
    ----------
    calibration : cvstereo.geometry.calibration.StereoCalibration, optional
    depth : DepthModel, optional
    focal_px : float, optional
        Finite and > 0.
    row_offset, time_offset_us : int, optional
    metres : bool
        False: no depth model whatever the sources hold (``--no-metres``).
    point_cloud : bool
        Resolve the intrinsics too.
    rig_check : callable, optional
        ``rig_check(recording) -> report`` (e.g. :func:`cvstereo.rigcheck.check_rig`): run when the recording is
        resolved, for the side, rows and time that no stronger source gives.

    Raises
    ------
    GeometryConflict
        A calibration together with ``depth``, ``focal_px``, a row or time offset, or a rig check.
    ValueError
        ``focal_px`` not a finite number > 0.
    """

    calibration: object = None
    depth: DepthModel | None = None
    focal_px: float | None = None
    row_offset: int | None = None
    time_offset_us: int | None = None
    metres: bool = True
    point_cloud: bool = False
    rig_check: Callable | None = None

    def __post_init__(self):
        if self.calibration is not None:
            given = [name for name, value in (("--depth", self.depth), ("--focal-px", self.focal_px),
                                              ("--row-offset", self.row_offset),
                                              ("--time-offset-us", self.time_offset_us),
                                              ("--auto", self.rig_check)) if value is not None]
            if given:
                raise GeometryConflict(f"--calibration gives the geometry itself (it rectifies the rows and gives "
                                       f"the depth model and the focal length): leave out {', '.join(given)}, or "
                                       "the calibration.")
        if self.focal_px is not None:
            from cvstereo.geometry.pointcloud import Intrinsics

            Intrinsics.from_options((2, 2), focal_px=self.focal_px)  # the one check of --focal-px

    def resolve(self, recording_meta: Mapping, resolution: tuple[int, int], *,
                recording: Recording | Callable[[], Recording] | None = None) -> Geometry:
        """The geometry by the precedence rule, for a recording with ``recording_meta`` and ``resolution``.

        ``recording`` (the events) is needed only for a rig check, which looks at all of them: a Recording, or a
        function that reads it (``stream.read`` of an opened recording), called only when the check runs, so
        that a recording matched as a stream is read whole only for the check.
        """
        sources, labels, values = {}, {}, {}
        rigcheck = None
        if self.calibration is not None:
            from cvstereo.geometry.rectify import Rectification

            labels["calibration"] = f"calibration {self.calibration.source}"
            values["rectification"] = Rectification(self.calibration)
            sources["rows"] = "calibration"
        if self.row_offset is not None:
            values["row_offset"], sources["rows"] = int(self.row_offset), "options"
        if self.time_offset_us is not None:
            values["time_offset_us"], sources["time"] = int(self.time_offset_us), "options"
        if self.rig_check is not None:
            if recording is None:
                raise ValueError("a rig check needs the recording's events: pass recording=.")
            rigcheck, found = self._check_rig(recording if isinstance(recording, Recording) else recording())
            labels["rigcheck"] = "the rig check"
            for aspect, key in (("side", "swap"), ("rows", "row_offset"), ("time", "time_offset_us")):
                if aspect not in sources:
                    values[key], sources[aspect] = found[key], "rigcheck"
            rigcheck["applied"] = {"swap": values.get("swap", False), "row_offset": values.get("row_offset", 0),
                                   "time_offset_us": values.get("time_offset_us", 0)}
        depth = self._depth(recording_meta, sources, labels)
        intrinsics = self._intrinsics(recording_meta, resolution, sources, labels) if self.point_cloud else None
        return Geometry(swap=bool(values.get("swap", False)), rectification=values.get("rectification"),
                        row_offset=values.get("row_offset", 0), time_offset_us=values.get("time_offset_us", 0),
                        depth=depth, intrinsics=intrinsics, sources=sources, labels=labels, rigcheck=rigcheck)

    def _check_rig(self, recording: Recording) -> tuple[dict, dict]:
        report = self.rig_check(recording)
        offsets = report.match_kwargs()
        swap = report.prepare(recording) is not recording
        return report.to_dict(), {"swap": swap, **offsets}

    def _depth(self, meta: Mapping, sources: dict, labels: dict) -> DepthModel | None:
        if not self.metres:
            labels["depth"] = "--no-metres"
            return None
        if self.calibration is not None:
            sources["depth"] = "calibration"
            return self.calibration.depth_model()
        if self.depth is not None:
            sources["depth"] = "options"
            return self.depth
        model = stored_depth(meta, "the recording")
        if model is not None:
            sources["depth"], labels["recording"] = "recording", "the recording's rig"
        return model

    def _intrinsics(self, meta: Mapping, resolution, sources: dict, labels: dict):
        from cvstereo.geometry.pointcloud import Intrinsics

        rig = meta.get("rig")
        intrinsics = Intrinsics.from_options(resolution, focal_px=self.focal_px, calibration=self.calibration,
                                             rig=rig)
        if self.calibration is not None:
            sources["intrinsics"] = "calibration"
        elif self.focal_px is not None:
            sources["intrinsics"] = "options"
        elif intrinsics.source.startswith("the recording's rig"):
            sources["intrinsics"], labels["recording"] = "recording", "the recording's rig"
        else:
            sources["intrinsics"], labels["default"] = "default", "the thesis rig's default"
        return intrinsics


def depth_for_matches(matches_meta: Mapping, recording_meta: Mapping, *, depth: DepthModel | None = None,
                      metres: bool = True, names: tuple[str, str] = ("the matches file", "the recording")
                      ) -> DepthModel | None:
    """The depth model for pictures of matches, by the same rule: the depth model the matches were given when
    it came from a calibration (their disparities are the rectified pair's), else ``depth`` (the user's), else
    the one stored with the matches, else the recording's rig; None with ``metres=False``.

    Raises
    ------
    GeometryConflict
        ``depth`` given for matches of a calibrated rig.
    ValueError
        A stored model that is not valid, naming where it is stored (``names``: the matches file's and the
        recording's).
    """
    if not metres:
        return None
    geometry = matches_meta.get("geometry")
    from_calibration = isinstance(geometry, Mapping) and isinstance(geometry.get("depth"), Mapping) and \
        geometry["depth"].get("source") == "calibration"
    if from_calibration and depth is not None:
        raise GeometryConflict("the matches were computed on events rectified by a calibration, whose depth model "
                               "they carry: leave out --depth (or give --no-metres).")
    if depth is not None and not from_calibration:
        return depth
    for meta, where in zip((matches_meta, recording_meta), names, strict=True):
        model = stored_depth(meta, where)
        if model is not None:
            return model
    return None


def stored_depth(meta: Mapping, where: str) -> DepthModel | None:
    """The depth model a file's meta holds (:func:`~cvstereo.geometry.depth.depth_from_meta`), or None; a broken one is
    refused naming ``where`` it is and how to do without it."""
    try:
        return depth_from_meta(meta)
    except (ValueError, TypeError) as exc:
        raise ValueError(f"{where}: its meta holds no valid depth model ({exc}); give --depth A C or "
                         "--no-metres.") from None


def as_matched(recording: Recording, matches_meta: Mapping) -> Recording:
    """The recording with its cameras in the order the matches used (exchanged where the rig check swapped
    them: :func:`cvstereo.model.matches.cameras_swapped`), so that scoring and pictures put each match on the
    camera it was anchored on."""
    return recording.swapped() if cameras_swapped(matches_meta) else recording
