"""The scene families of the generalization suite: each draws a scene of textured planes from a seed.

A family is a function ``plan(rng, view, seconds, photos) -> Plan``: the planes (:class:`LayerSpec`: pattern,
size, position, velocity), the rig's turn rate and the fastest image motion, all plain numbers, so that a
recording's meta says what it shows. :class:`FamilyScene` builds the planes' textures from the plan and
renders them (:class:`~cvstereo.simulate.scenes.LayeredScene`). A moving rig is a world moving the other way:
the depth of what each pixel sees, hence the truth, is the same.

- ``objects``: textured objects moving sideways before a still wall (suite v1's case).
- ``translate``: the rig moving sideways past textured planes at several depths (parallax, occlusions).
- ``turn``: the rig turning about its vertical axis among planes at several depths (motion from the turn,
  disparity from the depth alone).
- ``ground``: the rig moving forward over a ground plane (the driving case: disparity grows down the rows as
  ``B * (v - cy) / h`` for a camera at height ``h``), a wall at the far end, things standing on the ground.
- ``repetitive``: stripes, grids, checkerboards, dots and repetitive photos passing by (the ambiguous case).
- ``thin``: a plain wall with poles, wires and a plain occluder passing by (little texture, thin structures).
- ``border`` (not a suite family): one plane at disparity ``disparity_px`` filling the view (the border figure).
"""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass

import numpy as np

from cvstereo.geometry.rig import THESIS_RIG
from cvstereo.simulate import surfaces, textures
from cvstereo.simulate.motion import Motion
from cvstereo.simulate.scenes import LayeredScene, PlaneLayer
from cvstereo.simulate.surfaces import PERIODIC

__all__ = ["BASELINE_M", "FAMILIES", "GRAIN_FOCAL_PX", "TEXELS_PER_PIXEL", "Z_NEAR_M", "FamilyScene", "LayerSpec",
           "Plan", "View"]

#: Texels per sensor pixel where a plane comes nearest: fine enough that sampling never shows the texel grid.
TEXELS_PER_PIXEL = 2.0
#: Nearest plane (metres): with the rigs of the suite (10 cm, the thesis' view angle) about a fifth of the
#: width in disparity, so that roll, focal mismatch and the axis offset keep every disparity below a quarter.
Z_NEAR_M = 0.62
#: The rig's baseline the plans assume (metres): the suite's rigs all have the thesis rig's.
BASELINE_M = THESIS_RIG.baseline_m
#: Focal length (px) whose pixel is the unit of the patterns' features (:func:`~cvstereo.simulate.surfaces.pattern`'s
#: ``grain``): the thesis' DVS128. A sensor with more pixels across the same view sees the same surfaces, their
#: features over more pixels (and an event rate that grows with the pixels, not with their square).
GRAIN_FOCAL_PX = THESIS_RIG.focal_px
#: Views are widened by this much on every side: distortion and roll bring rays from beyond the nominal view.
_VIEW_MARGIN = 1.12


@dataclass(frozen=True)
class LayerSpec:
    """One plane of a plan: pattern, size, placement, motion (rig frame at t = 0; metres, m/s).

    ``range_m`` is the nearest distance from which the rig sees it (sets the texel size); ``grazing`` how much
    longer a pixel's footprint is along the texture's rows than across (a ground plane: ``Z / h``).
    """

    name: str
    kind: str
    size_m: tuple[float, float]
    center: tuple[float, float, float]
    range_m: float
    velocity: tuple[float, float, float] = (0.0, 0.0, 0.0)
    u_axis: tuple[float, float, float] = (1.0, 0.0, 0.0)
    v_axis: tuple[float, float, float] = (0.0, 1.0, 0.0)
    level: float = 0.5
    contrast: float = 0.3
    period_m: float | None = None
    angle_deg: float = 0.0
    grazing: float = 1.0
    border: bool = True
    bob: tuple[float, float, float] = (0.0, 1.0, 0.0)  # vertical sinusoid: amplitude (m), period (s), phase

    def layer(self, focal_px: float, rng: np.random.Generator) -> PlaneLayer:
        texel = self.range_m / focal_px / TEXELS_PER_PIXEL
        blur = textures.OPTICS_BLUR_PX * TEXELS_PER_PIXEL
        img, alpha = surfaces.surface(self.kind, rng, self.size_m, texel, level=self.level, contrast=self.contrast,
                                      blur_texels=blur, blur_y_texels=blur * self.grazing if self.grazing > 1 else None,
                                      period_m=self.period_m, angle_deg=self.angle_deg, border=self.border,
                                      grain=TEXELS_PER_PIXEL * max(1.0, focal_px / GRAIN_FOCAL_PX))
        terms = ((1, self.bob[0], self.bob[1], self.bob[2]),) if self.bob[0] else ()
        return PlaneLayer(self.name, img, alpha, texel, Motion(self.center, self.velocity, terms),
                          self.u_axis, self.v_axis)


@dataclass(frozen=True)
class Plan:
    """What a family drew: the planes, the rig's turn rate (rad/s, positive: to the right) and the fastest
    image motion (px/s) anywhere in the view, which sets the render rate."""

    layers: tuple[LayerSpec, ...]
    yaw_rate: float
    image_speed_px_s: float


@dataclass(frozen=True)
class View:
    """The view a plan fills: focal length, sensor size and the clip's length."""

    focal_px: float
    resolution: tuple[int, int]
    seconds: float

    @property
    def ax(self) -> float:
        """Tangent of the half-angle across, with the margin."""
        return _VIEW_MARGIN * self.resolution[0] / 2 / self.focal_px

    @property
    def ay(self) -> float:
        """Tangent of the half-angle down, with the margin."""
        return _VIEW_MARGIN * self.resolution[1] / 2 / self.focal_px

    def metres(self, px: float, z: float) -> float:
        """Metres at depth ``z`` that span ``px`` pixels."""
        return px * z / self.focal_px

    @property
    def pace(self) -> float:
        """Factor on every motion: ``(128 / width) ** 0.75``. The same motion seen by a sensor with k times the
        pixels across gives about k^2 times the events (k times the pixels per row and per column, each crossed
        k times as often): larger sensors see slower scenes, about k^1.25 times the events, so that the suite
        stays runnable (its 640x480 clips a few million events per camera)."""
        return float((128 / self.resolution[0]) ** 0.75)

    def speed_m_s(self, widths_per_s: float, z: float) -> float:
        """Sideways speed at depth ``z`` that moves the image by ``widths_per_s * pace`` widths per second."""
        return widths_per_s * self.pace * self.resolution[0] * z / self.focal_px


def _pick(rng: np.random.Generator, options):
    return options[int(rng.integers(len(options)))]


class _Patterns:
    """Hands out patterns: the recording's photos in turn where ``photo`` asks, else a procedural one."""

    def __init__(self, rng: np.random.Generator, photos: tuple[str, ...]):
        self.rng, self.photos, self.n = rng, photos, 0

    def __call__(self, procedural=("noise", "fine-noise", "blobs"), *, photo: bool = True) -> str:
        if photo and self.photos:
            self.n += 1
            return self.photos[(self.n - 1) % len(self.photos)]
        return _pick(self.rng, procedural)


def _backdrop(view: View, z: float, kind: str, *, shift_m: float = 0.0, level=0.5, contrast=0.3) -> LayerSpec:
    """A wall at depth ``z`` filling the view while the rig moves sideways by ``shift_m`` in the clip (the wall
    moves the other way): its centre where the rig is half-way."""
    width = 2 * view.ax * z + BASELINE_M + abs(shift_m) + 0.2
    height = 2 * view.ay * z + 0.2
    return LayerSpec("wall", kind, (width, height), (shift_m / 2, 0.0, z), z, level=level, contrast=contrast,
                     border=False)


def _passing(rng, view: View, patterns, z_far: float, speed: float, layer_kinds, name: str):
    """Planes at depths between the nearest and ``z_far`` spread over the strip the rig sees while it moves
    sideways at ``speed`` m/s, each with a pattern from ``layer_kinds(k, z)`` -> (kind, extra fields).

    Returns the planes (moving at ``-speed``) and how far the rig moves in the clip."""
    n = int(rng.integers(3, 6))
    depths = np.sort(np.exp(rng.uniform(np.log(Z_NEAR_M), np.log(z_far), n)))[::-1]
    depths[-1] = min(depths[-1], rng.uniform(Z_NEAR_M, 1.3))  # the nearest plane near, for a wide range
    shift = speed * view.seconds
    out = []
    for k, z in enumerate(depths):
        half = view.ax * z + abs(shift) / 2
        kind, extra = layer_kinds(k, z)
        size = (rng.uniform(0.25, 0.8) * 2 * view.ax * z, rng.uniform(0.5, 1.3) * 2 * view.ay * z)
        centre = (shift / 2 + rng.uniform(-1, 1) * half, rng.uniform(-0.4, 0.4) * view.ay * z, float(z))
        out.append(LayerSpec(f"{name}{k + 1}", kind, size, centre, float(z), (-speed, 0.0, 0.0),
                             level=rng.uniform(0.2, 0.8), contrast=rng.uniform(0.15, 0.4), **extra))
    return out, shift


def _objects(rng, view: View, photos) -> Plan:
    patterns = _Patterns(rng, photos)
    z_wall = rng.uniform(2.5, 6.0)
    layers = [_backdrop(view, z_wall, patterns(photo=len(photos) > 1), level=rng.uniform(0.3, 0.7),
                        contrast=rng.uniform(0.15, 0.4))]
    fastest = 0.0
    n = int(rng.integers(1, 4))
    for k, z in enumerate(np.sort(rng.uniform(Z_NEAR_M, min(2.0, z_wall - 0.5), n))[::-1]):
        widths_per_s = rng.uniform(0.2, 0.8) * _pick(rng, (-1, 1))
        v = view.speed_m_s(widths_per_s, z)
        size = (rng.uniform(0.2, 0.5) * 2 * view.ax * z, rng.uniform(0.3, 0.9) * 2 * view.ay * z)
        centre = (-v * view.seconds / 2 + rng.uniform(-0.25, 0.25) * view.ax * z,
                  rng.uniform(-0.3, 0.3) * view.ay * z, float(z))
        bob = (rng.uniform(0, 0.05) * view.ay * z, rng.uniform(0.7, 2.0), rng.uniform(0, 2 * np.pi))
        layers.append(LayerSpec(f"object{k + 1}", patterns(), size, centre, float(z), (v, 0.0, 0.0),
                                level=rng.uniform(0.2, 0.8), contrast=rng.uniform(0.15, 0.4), bob=bob))
        fastest = max(fastest, (abs(v) + 2 * np.pi * bob[0] / bob[1]) * view.focal_px / z)
    return Plan(tuple(layers), 0.0, fastest)


def _translate(rng, view: View, photos) -> Plan:
    patterns = _Patterns(rng, photos)
    z_wall = rng.uniform(4.0, 10.0)
    speed = view.speed_m_s(rng.uniform(0.2, 0.7), Z_NEAR_M) * _pick(rng, (-1, 1))  # the rig's (the world: -speed)
    planes, shift = _passing(rng, view, patterns, 0.7 * z_wall, speed, lambda k, z: (patterns(), {}), "plane")
    wall = dataclasses.replace(_backdrop(view, z_wall, patterns(photo=False), shift_m=shift,
                                         level=rng.uniform(0.3, 0.7), contrast=rng.uniform(0.15, 0.35)),
                               velocity=(-speed, 0.0, 0.0))
    return Plan((wall, *planes), 0.0, abs(speed) * view.focal_px / min(p.center[2] for p in planes))


def _turn(rng, view: View, photos) -> Plan:
    patterns = _Patterns(rng, photos)
    yaw_rate = rng.uniform(0.2, 0.7) * view.pace * view.resolution[0] / view.focal_px * _pick(rng, (-1, 1))
    swept = yaw_rate * view.seconds
    half_angle = np.arctan(view.ax)
    r_wall = rng.uniform(3.0, 8.0)
    lo, hi = min(0.0, swept) - half_angle, max(0.0, swept) + half_angle
    left, right = r_wall * np.tan(lo - 0.05), r_wall * np.tan(hi + 0.05)  # the wall spans every bearing seen
    size = (right - left + BASELINE_M + 0.2, 2 * view.ay * r_wall / np.cos(max(-lo, hi) + 0.05) + 0.2)
    wall = LayerSpec("wall", patterns(photo=len(photos) > 1), size, ((left + right) / 2, 0.0, r_wall), r_wall,
                     level=rng.uniform(0.3, 0.7), contrast=rng.uniform(0.15, 0.4), border=False)
    layers = [wall]
    n = int(rng.integers(2, 5))
    ranges = np.sort(np.exp(rng.uniform(np.log(Z_NEAR_M + 0.05), np.log(0.6 * r_wall), n)))[::-1]
    for k, r in enumerate(ranges):
        bearing = rng.uniform(lo, hi)
        size = (rng.uniform(0.3, 0.8) * 2 * view.ax * r, rng.uniform(0.5, 1.2) * 2 * view.ay * r)
        centre = (r * np.sin(bearing), rng.uniform(-0.3, 0.3) * view.ay * r, r * np.cos(bearing))
        layers.append(LayerSpec(f"panel{k + 1}", patterns(), size, tuple(map(float, centre)), float(r),
                                u_axis=(float(np.cos(bearing)), 0.0, float(-np.sin(bearing))),
                                level=rng.uniform(0.2, 0.8), contrast=rng.uniform(0.15, 0.4)))
    return Plan(tuple(layers), float(yaw_rate), abs(yaw_rate) * view.focal_px * (1 + view.ax**2))


#: Ground strips: each reaches this factor further than it starts, with texels for its near end.
_STRIP_RATIO = 1.3


def _ground(rng, view: View, photos) -> Plan:
    patterns = _Patterns(rng, photos)
    height = rng.uniform(0.25, 0.6)  # the cameras above the ground: the bottom row's disparity below W/4
    speed = rng.uniform(0.5, 2.0) * view.pace  # forward
    travel = speed * view.seconds
    h_px = view.resolution[1] / 2
    z0 = height / view.ay  # the ground seen at the bottom row, nearer by the margin (offsets, roll, distortion)
    z_wall = rng.uniform(8.0, 14.0) + travel
    ground_kind = patterns(("noise", "fine-noise", "blobs"))
    level, contrast = rng.uniform(0.25, 0.5), rng.uniform(0.25, 0.5)
    layers, z = [], z0
    while z < z_wall:
        z_end = min(z * _STRIP_RATIO, z_wall)
        near = max(z0, z - travel / 2)  # where it comes closest in the clip (half-way, for both ends' sake)
        width = 2 * view.ax * (z_end + travel) + BASELINE_M + 0.2
        # two texels more at either end: a texture spans one texel less than its texels, and no ray may pass
        # between two strips
        overlap = 2 * near / view.focal_px / TEXELS_PER_PIXEL
        layers.append(LayerSpec(f"ground{len(layers) + 1}", ground_kind, (width, z_end - z + 2 * overlap),
                                (0.0, height, (z + z_end) / 2), near, (0.0, 0.0, -speed), v_axis=(0.0, 0.0, 1.0),
                                level=level, contrast=contrast, grazing=z_end / height, border=False))
        z = z_end
    # the wall reaches below the ground, where the ground hides it: no ray passes between the two
    below = 0.05 * z_wall
    wall_h = view.ay * z_wall * 1.2 + height + below
    layers.append(LayerSpec("wall", patterns(photo=len(photos) > 1), (2 * view.ax * z_wall + 1.0, wall_h),
                            (0.0, height + below - wall_h / 2, z_wall), z_wall - travel, (0.0, 0.0, -speed),
                            level=rng.uniform(0.3, 0.7), contrast=rng.uniform(0.15, 0.4), border=False))
    for k in range(int(rng.integers(1, 4))):
        zk = rng.uniform(2.0, 0.7 * z_wall)
        tall, wide = rng.uniform(0.3, 1.5), rng.uniform(0.08, 0.6)
        layers.append(LayerSpec(f"thing{k + 1}", patterns(), (wide, tall),
                                (rng.uniform(-0.8, 0.8) * view.ax * zk, height - tall / 2, zk), zk - travel,
                                (0.0, 0.0, -speed), level=rng.uniform(0.2, 0.8), contrast=rng.uniform(0.15, 0.4)))
    bottom = h_px**2 * speed / (view.focal_px * height)  # rows per second at the bottom of the view
    return Plan(tuple(layers), 0.0, float(bottom * (1 + view.ax)))


def _repetitive(rng, view: View, photos) -> Plan:
    patterns = _Patterns(rng, photos)
    z_wall = rng.uniform(4.0, 10.0)
    speed = view.speed_m_s(rng.uniform(0.2, 0.7), Z_NEAR_M) * _pick(rng, (-1, 1))

    def periodic(k, z):
        use_photo = photos and k % 2 == 1
        kind = patterns() if use_photo else _pick(rng, PERIODIC)
        period_px = rng.uniform(0.04, 0.12) * view.resolution[0]
        angle = 0.0 if rng.uniform() < 0.6 else rng.uniform(-30.0, 30.0)
        return kind, {} if use_photo else {"period_m": view.metres(period_px, z), "angle_deg": angle}

    planes, shift = _passing(rng, view, patterns, 0.7 * z_wall, speed, periodic, "repeat")
    wall = dataclasses.replace(_backdrop(view, z_wall, "noise", shift_m=shift, level=rng.uniform(0.3, 0.7),
                                         contrast=rng.uniform(0.1, 0.2)), velocity=(-speed, 0.0, 0.0))
    return Plan((wall, *planes), 0.0, abs(speed) * view.focal_px / min(p.center[2] for p in planes))


def _thin(rng, view: View, photos) -> Plan:
    z_wall = rng.uniform(3.0, 8.0)
    speed = view.speed_m_s(rng.uniform(0.2, 0.7), Z_NEAR_M) * _pick(rng, (-1, 1))  # the rig's
    shift = speed * view.seconds
    ground = rng.uniform(0.3, 0.7)
    wall = dataclasses.replace(_backdrop(view, z_wall, "plain", shift_m=shift, level=ground,
                                         contrast=rng.uniform(0.02, 0.06)), velocity=(-speed, 0.0, 0.0))
    layers = [wall]

    def against_wall():  # a thin thing darker or brighter than the wall by 0.5-1.2 in log intensity
        return ground * float(np.exp(rng.uniform(0.5, 1.2) * _pick(rng, (-1, 1))))

    nearest = 2.0
    for k in range(int(rng.integers(3, 9))):
        z = rng.uniform(Z_NEAR_M, 0.8 * z_wall)
        nearest = min(nearest, z)
        tall = 2 * view.ay * z + 0.2
        x = shift / 2 + rng.uniform(-1, 1) * (view.ax * z + abs(shift) / 2)
        layers.append(LayerSpec(f"pole{k + 1}", "plain", (view.metres(rng.uniform(1.0, 4.0), z), tall),
                                (x, 0.0, z), z, (-speed, 0.0, 0.0), level=against_wall(), contrast=0.03))
    for k in range(int(rng.integers(1, 4))):
        z = rng.uniform(0.8, 0.6 * z_wall)
        a = np.deg2rad(rng.uniform(5.0, 60.0) * _pick(rng, (-1, 1)))
        length = 2 * view.ax * z * 1.5 + abs(shift)
        layers.append(LayerSpec(f"wire{k + 1}", "plain", (length, view.metres(rng.uniform(0.8, 2.0), z)),
                                (shift / 2, rng.uniform(-0.6, 0.6) * view.ay * z, z), z, (-speed, 0.0, 0.0),
                                u_axis=(float(np.cos(a)), float(np.sin(a)), 0.0),
                                v_axis=(float(-np.sin(a)), float(np.cos(a)), 0.0), level=against_wall(),
                                contrast=0.03))
    if rng.uniform() < 0.75:
        z = rng.uniform(Z_NEAR_M, 1.2)
        nearest = min(nearest, z)
        size = (rng.uniform(0.3, 0.6) * 2 * view.ax * z, 2 * view.ay * z + 0.2)
        x = shift / 2 + rng.uniform(-0.5, 0.5) * (view.ax * z + abs(shift) / 2)
        layers.append(LayerSpec("occluder", "plain", size, (x, 0.0, z), z, (-speed, 0.0, 0.0),
                                level=against_wall(), contrast=0.04))
    return Plan(tuple(layers), 0.0, abs(speed) * view.focal_px / nearest)


def _border(rng, view: View, photos, disparity_px: float) -> Plan:
    z = view.focal_px * BASELINE_M / disparity_px
    speed = view.speed_m_s(0.2, z)
    wall = _backdrop(view, z, photos[0] if photos else "noise", shift_m=speed * view.seconds, contrast=0.35)
    return Plan((dataclasses.replace(wall, velocity=(-speed, 0.0, 0.0)),), 0.0, speed * view.focal_px / z)


#: Family name -> plan function (the suite's six, in the suite file's order).
FAMILIES = {"objects": _objects, "translate": _translate, "turn": _turn, "ground": _ground,
            "repetitive": _repetitive, "thin": _thin}


@dataclass(frozen=True)
class FamilyScene:
    """One recording's scene: a family's plan drawn from ``seed`` for a sensor, built and rendered.

    Parameters
    ----------
    family : str
        One of :data:`FAMILIES`, or ``border`` (then ``disparity_px`` is the plane's disparity on an ideal rig).
    seed : int
    resolution : (width, height)
    focal_px : float
        The left camera's focal length (the plan is drawn for its view; texels for its pixels).
    seconds : float
        The clip's length (planes must cover what the moving rig sees until then).
    photos : tuple of str
        Photos (:data:`~cvstereo.simulate.surfaces.PHOTOS`) the family may use; the others are procedural.
    disparity_px : float or None
    """

    family: str
    seed: int
    resolution: tuple[int, int]
    focal_px: float
    seconds: float
    photos: tuple[str, ...] = ()
    disparity_px: float | None = None
    kind = "family"

    def __post_init__(self):
        if self.family not in FAMILIES and self.family != "border":
            raise ValueError(f"unknown scene family {self.family!r}; choose one of {', '.join(FAMILIES)}.")
        if (self.family == "border") != (self.disparity_px is not None):
            raise ValueError("disparity_px is the border scene's plane disparity, and only that scene's.")
        bad = [p for p in self.photos if p not in surfaces.PHOTOS]
        if bad:
            raise ValueError(f"unknown photo(s) {', '.join(bad)}; choose from {', '.join(surfaces.PHOTOS)}.")

    @functools.cached_property
    def plan(self) -> Plan:
        """The family's drawing for this seed and sensor (the same every time)."""
        rng = np.random.default_rng([self.seed, 0x24, sorted(FAMILIES).index(self.family) + 1
                                     if self.family in FAMILIES else 0])
        view = View(self.focal_px, tuple(self.resolution), self.seconds)
        if self.family == "border":
            return _border(rng, view, self.photos, self.disparity_px)
        return FAMILIES[self.family](rng, view, self.photos)

    @functools.cached_property
    def scene(self) -> LayeredScene:
        """The planes with their textures (each layer's texture from its own seeded stream)."""
        plan = self.plan
        layers = tuple(spec.layer(self.focal_px, np.random.default_rng([self.seed, 0x7E, k]))
                       for k, spec in enumerate(plan.layers))
        yaw = Motion((0.0,), (plan.yaw_rate,)) if plan.yaw_rate else None
        return LayeredScene(layers, background=0.5, rig_yaw=yaw, name=f"family:{self.family}")

    def render(self, rig, index: int, times_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Intensity and depth, each (T, H, W) float32, of camera ``index`` of ``rig`` at ``times_s`` (T,)."""
        if tuple(rig.resolution) != tuple(self.resolution) or not np.isclose(rig.focal_px, self.focal_px):
            raise ValueError(f"this {self.family} scene was drawn for {self.resolution[0]}x{self.resolution[1]} at "
                             f"f={self.focal_px:g} px; the rig has {rig.resolution[0]}x{rig.resolution[1]} at "
                             f"f={rig.focal_px:g}: draw the scene for the rig.")
        return self.scene.render(rig, index, times_s)

    def describe(self) -> dict:
        plan = self.plan
        return {"type": self.kind, "family": self.family, "seed": self.seed, "photos": list(self.photos),
                "resolution": list(self.resolution), "focal_px": self.focal_px, "seconds": self.seconds,
                "disparity_px": self.disparity_px, "yaw_rate": plan.yaw_rate,
                "image_speed_px_s": plan.image_speed_px_s,
                "layers": [dataclasses.asdict(spec) for spec in plan.layers]}
