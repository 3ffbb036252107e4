"""Scenes: what the rig looks at, as a function of time.

A scene renders one camera of a rig at a batch of instants: ``scene.render(rig, index, times_s)`` returns
linear intensity and depth, each (T, H, W) float32 (see :mod:`cvstereo.simulate.render`), and
``scene.describe()`` a JSON-serialisable description for the recording's meta.

- :class:`LayeredScene`: textured rectangles that move (and a rig that may turn) — the building block.
- :class:`ArmsScene`: one or two arms moving through the view in front of a wall (the thesis' recordings).
- :class:`RotationScene`: the rig turning in a static room with objects at several depths (a mobile robot).
- :class:`~cvstereo.simulate.motorcycle.MotorcycleScene`: the view panning over the Middlebury motorcycle pair that
  scikit-image ships, in its own module.
- :class:`~cvstereo.simulate.fan.FanScene`: a rotating fan (the real TUM recordings), in its own module.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from cvstereo.simulate import textures
from cvstereo.simulate.fan import FanScene
from cvstereo.simulate.motion import Motion
from cvstereo.simulate.motorcycle import MotorcycleScene
from cvstereo.simulate.render import layer_hits, render_planes
from cvstereo.simulate.rig import Rig

__all__ = ["SCENES", "ArmsScene", "LayeredScene", "PlaneLayer", "RotationScene"]


@dataclass(frozen=True, eq=False)
class PlaneLayer:
    """A textured rectangle in the world: texture, texel size, orientation and motion of its centre.

    Parameters
    ----------
    name : str
    intensity, alpha : (H, W) float32 ndarray
        Linear intensity and coverage (see :mod:`cvstereo.simulate.textures`).
    texel_m : float
        Metres per texel.
    motion : Motion
        World position of the texture's centre over time.
    u_axis, v_axis : tuple of 3 float
        World directions of the texture's columns (x) and rows (y); unit, orthogonal.
    """

    name: str
    intensity: np.ndarray
    alpha: np.ndarray
    texel_m: float
    motion: Motion
    u_axis: tuple[float, float, float] = (1.0, 0.0, 0.0)
    v_axis: tuple[float, float, float] = (0.0, 1.0, 0.0)

    def __post_init__(self):
        if self.intensity.shape != self.alpha.shape or self.intensity.ndim != 2 or min(self.intensity.shape) < 2:
            raise ValueError(f"layer '{self.name}': intensity {self.intensity.shape} and alpha "
                             f"{self.alpha.shape} must be equal 2-D shapes of at least 2x2.")
        if abs(float(np.dot(self.u_axis, self.v_axis))) > 1e-9:
            raise ValueError(f"layer '{self.name}': u_axis and v_axis must be orthogonal.")

    def describe(self) -> dict:
        h, w = self.intensity.shape
        return {"name": self.name, "size_m": [w * self.texel_m, h * self.texel_m], "motion": self.motion.describe(),
                "u_axis": list(self.u_axis), "v_axis": list(self.v_axis)}


def _yaw_matrices(angles: np.ndarray) -> np.ndarray:
    """(T, 3, 3) rotations about the rig's Y axis (down) by ``angles`` (T,) radians; positive turns right."""
    c, s = np.cos(angles), np.sin(angles)
    rot = np.zeros((angles.size, 3, 3))
    rot[:, 0, 0], rot[:, 0, 2] = c, s
    rot[:, 1, 1] = 1.0
    rot[:, 2, 0], rot[:, 2, 2] = -s, c
    return rot


@dataclass(frozen=True, eq=False)
class LayeredScene:
    """Textured rectangles, a uniform background behind them, a rig that may turn, a light that may change.

    Parameters
    ----------
    layers : tuple of PlaneLayer
    background : float
        Intensity where no rectangle is hit (depth unknown there).
    rig_yaw : Motion or None
        Yaw angle of the rig (radians, axis 0 of a 1-D motion); None: the rig stands still at the origin.
    illumination : callable or None
        ``gain(times_s) -> (T,)`` multiplies the whole image (for brightness-step tests).
    name : str
    """

    layers: tuple[PlaneLayer, ...]
    background: float = 0.5
    rig_yaw: Motion | None = None
    illumination: Callable[[np.ndarray], np.ndarray] | None = None
    name: str = "layers"
    _cache: dict = field(init=False, repr=False)

    def __post_init__(self):
        if not self.layers:
            raise ValueError("LayeredScene needs at least one layer.")
        object.__setattr__(self, "_cache", {})

    def _pack(self, indices: tuple[int, ...]) -> dict:
        """Textures and axes of some layers, padded to one shape, for the renderer (cached)."""
        key = ("pack", indices)
        if key not in self._cache:
            layers = [self.layers[m] for m in indices]
            hmax = max((layer.intensity.shape[0] for layer in layers), default=2)
            wmax = max((layer.intensity.shape[1] for layer in layers), default=2)
            tex = np.zeros((len(layers), hmax, wmax), np.float32)
            alpha = np.zeros_like(tex)
            for m, layer in enumerate(layers):
                h, w = layer.intensity.shape
                tex[m, :h, :w] = layer.intensity
                alpha[m, :h, :w] = layer.alpha
            self._cache[key] = dict(
                tex=tex, alpha=alpha,
                size=np.array([[la.intensity.shape[1], la.intensity.shape[0]] for la in layers]).reshape(-1, 2),
                texel=np.array([layer.texel_m for layer in layers]),
                u_axis=np.array([layer.u_axis for layer in layers], np.float64).reshape(-1, 3),
                v_axis=np.array([layer.v_axis for layer in layers], np.float64).reshape(-1, 3),
            )
        return self._cache[key]

    def render(self, rig: Rig, index: int, times_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Intensity and depth, each (T, H, W) float32, of camera ``index`` at ``times_s`` (T,)."""
        times_s = np.asarray(times_s, np.float64)
        camera = rig.camera(index)
        yaw = np.zeros(times_s.size) if self.rig_yaw is None else self.rig_yaw.position(times_s)[:, 0]
        rot = _yaw_matrices(yaw)
        cam_pos = rot @ np.array([camera.position_x, 0.0, 0.0])
        gain = np.ones(times_s.size) if self.illumination is None else np.asarray(self.illumination(times_s))
        # With the rig at rest, layers that do not move look the same in every frame: intersect them once.
        still = tuple(m for m, layer in enumerate(self.layers) if self.rig_yaw is None and layer.motion.is_static)
        moving = tuple(m for m in range(len(self.layers)) if m not in still)
        static = None
        if still:
            key = ("static", rig, index)
            if key not in self._cache:
                fixed = dict(self._pack(still), origins=np.array([self.layers[m].motion.center for m in still]))
                self._cache[key] = layer_hits(camera.rays, cam_pos[0], rot[0], fixed)
            static = self._cache[key]
        origins = np.zeros((times_s.size, len(moving), 3))
        for j, m in enumerate(moving):
            origins[:, j] = self.layers[m].motion.position(times_s)
        layers = dict(self._pack(moving), origins=origins)
        return render_planes(camera.rays, cam_pos, rot, layers, gain=gain, background=self.background,
                             static=static)

    def describe(self) -> dict:
        return {"type": self.name, "background": self.background,
                "rig_yaw": None if self.rig_yaw is None else self.rig_yaw.describe(),
                "illumination": None if self.illumination is None else getattr(self.illumination, "__name__", "custom"),
                "layers": [layer.describe() for layer in self.layers]}


class _Built:
    """Mixin for parameter dataclasses that build a LayeredScene once per focal length and sensor size."""

    def render(self, rig: Rig, index: int, times_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Intensity and depth, each (T, H, W) float32, of camera ``index`` at ``times_s`` (T,)."""
        return self.build(rig.focal_px, rig.resolution).render(rig, index, times_s)

    def describe(self) -> dict:
        return {"type": self.kind, **dataclasses.asdict(self)}


@dataclass(frozen=True)
class ArmsScene(_Built):
    """One or two arms (sleeve and hand, fingers up) moving sideways through the view in front of a wall.

    The arms sweep to and fro (a sinusoid across ``sweep_fraction`` of the view's half-width), bob a little
    up and down, and wobble in depth by about ``wobble_m`` around ``distance_m`` (the thesis: "not assured
    that the arms stay in exactly the same distance"). A second arm moves against the first, 2 cm further.

    Parameters
    ----------
    arms : int
        1 or 2.
    distance_m : float
        Mean distance of the (first) arm from the rig.
    background_m : float
        Distance of the static wall behind.
    sweep_period_s : float
        Period of the sideways sweep; with ``sweep_fraction`` it sets the speed, hence the event rate.
    sweep_fraction : float
        Sweep amplitude as a fraction of the view's half-width at ``distance_m``.
    wobble_m : float
        Amplitude of the depth wobble.
    sleeve_contrast : float
        Contrast of the shirt's pattern (see :func:`cvstereo.simulate.textures.arm`).
    sleeve_pattern : str
        The shirt's pattern: ``checks`` (soft plaid, the presets'), ``stripes`` (vertical, one period only),
        ``checker`` (hard checkerboard) or ``natural`` (a patch of a photo from scikit-image's data).
    seed : int
        Textures and motion phases.
    """

    arms: int = 1
    distance_m: float = 0.5
    background_m: float = 2.5
    sweep_period_s: float = 3.0
    sweep_fraction: float = 0.8
    wobble_m: float = 0.02
    sleeve_contrast: float = 0.35
    sleeve_pattern: str = "checks"
    seed: int = 0
    kind = "arms"

    def __post_init__(self):
        if self.arms not in (1, 2):
            raise ValueError(f"ArmsScene.arms must be 1 or 2, got {self.arms}.")
        if not 0.1 <= self.distance_m < self.background_m:
            raise ValueError(f"ArmsScene.distance_m={self.distance_m} must be >= 0.1 m and in front of the wall "
                             f"(background_m={self.background_m}).")
        if self.sweep_period_s <= 0:
            raise ValueError(f"ArmsScene.sweep_period_s must be positive, got {self.sweep_period_s}.")
        if self.sleeve_pattern not in textures.SLEEVE_PATTERNS:
            raise ValueError(f"ArmsScene.sleeve_pattern must be one of {', '.join(textures.SLEEVE_PATTERNS)}, "
                             f"got {self.sleeve_pattern!r}.")

    @functools.lru_cache(maxsize=4)  # noqa: B019 -- frozen, hashable parameters; a handful of focal lengths
    def build(self, focal_px: float, resolution: tuple[int, int] = (128, 128)) -> LayeredScene:
        """The layers for a rig of focal length ``focal_px`` and sensor ``resolution`` (textures are sampled
        for the focal length; the motion spans the view)."""
        rng = np.random.default_rng([self.seed, 0xA5])
        half_width, half_height = resolution[0] / 2 / focal_px, resolution[1] / 2 / focal_px
        wall_texel = textures.texel_size(self.background_m, focal_px, texels_per_pixel=1.5)
        wall_size = (2.6 * half_width * self.background_m + 0.4, 2.6 * half_height * self.background_m + 0.4)
        wall_i, wall_a = textures.wall(rng, wall_size, wall_texel,
                                       blur_texels=textures.OPTICS_BLUR_PX * 1.5)
        layers = [PlaneLayer("wall", wall_i, wall_a, wall_texel, Motion((0.0, 0.0, self.background_m)))]
        for k in range(self.arms):
            z = self.distance_m + 0.02 * k
            texel = textures.texel_size(z, focal_px)
            # long enough to leave the view at the bottom (the fingertips are at -0.55 of the half-height)
            arm_i, arm_a = textures.arm(rng, texel, sleeve_contrast=self.sleeve_contrast,
                                        pattern=self.sleeve_pattern, length_m=max(1.1, 1.7 * half_height * z),
                                        blur_texels=textures.OPTICS_BLUR_PX * 2)
            if k == 1:  # the other hand: mirrored, a lighter shirt
                arm_i, arm_a = arm_i[:, ::-1].copy() * 1.3, arm_a[:, ::-1].copy()
            length = arm_i.shape[0] * texel
            view_half, view_half_y = half_width * z, half_height * z
            top = -0.55 * view_half_y  # fingertips in the upper part of the view
            amp = self.sweep_fraction * view_half
            phases = rng.uniform(0, 2 * np.pi, 4)
            start = phases[0] if k == 0 else phases[0] + np.pi  # two arms sweep against each other
            layers.append(PlaneLayer(
                f"arm{k + 1}", arm_i, arm_a, texel,
                Motion((0.0, top + length / 2, z), terms=(
                    (0, amp, self.sweep_period_s * (1 + 0.27 * k), start),
                    (1, 0.08 * view_half_y, 2.3 + 0.4 * k, phases[1]),
                    (2, 0.7 * self.wobble_m, 3.1 + 0.5 * k, phases[2]),
                    (2, 0.3 * self.wobble_m, 1.3, phases[3]),
                )),
            ))
        return LayeredScene(tuple(layers), background=0.5, name="arms")


_OBJECT_BEARINGS = (0.05, -0.3, 0.35, -0.55, 0.6, -0.8)


@dataclass(frozen=True)
class RotationScene(_Built):
    """The rig turning to and fro in a static room with objects at several depths (a mobile robot).

    Parameters
    ----------
    yaw_amplitude_deg : float
        The rig turns by up to this much either way.
    yaw_period_s : float
    object_distances_m : tuple of float
        Distances of the objects (boxes on shelves, cabinets) in the room, at the rig's height.
    seed : int
    """

    yaw_amplitude_deg: float = 35.0
    yaw_period_s: float = 8.0
    object_distances_m: tuple[float, ...] = (0.8, 1.3, 1.9, 2.6)
    seed: int = 0
    kind = "rotation"

    @functools.lru_cache(maxsize=4)  # noqa: B019 -- frozen, hashable parameters; a handful of focal lengths
    def build(self, focal_px: float, resolution: tuple[int, int] = (128, 128)) -> LayeredScene:
        """The layers for a rig of focal length ``focal_px`` (the room is larger than any view: ``resolution``
        does not change it)."""
        rng = np.random.default_rng([self.seed, 0x5A])
        blur = textures.OPTICS_BLUR_PX * 1.5
        x0, x1, z0, z1, y_floor, y_ceiling = -2.5, 2.5, -3.0, 3.5, 1.2, -1.4
        height = y_floor - y_ceiling
        room = []  # (name, size, centre, u, v, texel)
        t_room = textures.texel_size(3.0, focal_px, texels_per_pixel=1.5)
        room.append(("front", (x1 - x0, height), (0, (y_floor + y_ceiling) / 2, z1), (1, 0, 0), (0, 1, 0)))
        room.append(("back", (x1 - x0, height), (0, (y_floor + y_ceiling) / 2, z0), (-1, 0, 0), (0, 1, 0)))
        room.append(("left", (z1 - z0, height), (x0, (y_floor + y_ceiling) / 2, (z0 + z1) / 2), (0, 0, -1), (0, 1, 0)))
        room.append(("right", (z1 - z0, height), (x1, (y_floor + y_ceiling) / 2, (z0 + z1) / 2), (0, 0, 1), (0, 1, 0)))
        room.append(("floor", (x1 - x0, z1 - z0), (0, y_floor, (z0 + z1) / 2), (1, 0, 0), (0, 0, 1)))
        room.append(("ceiling", (x1 - x0, z1 - z0), (0, y_ceiling, (z0 + z1) / 2), (1, 0, 0), (0, 0, -1)))
        layers = []
        for name, size, centre, u, v in room:
            img, a = textures.wall(rng, size, t_room, blur_texels=blur)
            layers.append(PlaneLayer(name, img, a, t_room, Motion(tuple(map(float, centre))),
                                     tuple(map(float, u)), tuple(map(float, v))))
        for k, dist in enumerate(self.object_distances_m):
            # the nearest object ahead at the start, the others to both sides (the view spans +-0.37 rad)
            bearing = _OBJECT_BEARINGS[k % len(_OBJECT_BEARINGS)] + rng.uniform(-0.05, 0.05)
            size = (rng.uniform(0.25, 0.5), rng.uniform(0.4, 0.9))
            texel = textures.texel_size(dist, focal_px)
            img, a = textures.panel(rng, size, texel, level=rng.uniform(0.3, 0.8), blur_texels=blur * 1.3)
            centre = (dist * np.sin(bearing), rng.uniform(-0.2, 0.2), dist * np.cos(bearing))  # at eye height
            u = (np.cos(bearing), 0.0, -np.sin(bearing))  # facing the rig
            layers.append(PlaneLayer(f"object{k + 1}", img, a, texel, Motion(tuple(map(float, centre))),
                                     tuple(map(float, u)), (0.0, 1.0, 0.0)))
        yaw = Motion((0.0,), terms=((0, np.deg2rad(self.yaw_amplitude_deg), self.yaw_period_s, 0.0),))
        return LayeredScene(tuple(layers), background=0.3, rig_yaw=yaw, name="rotation")


#: Scene name -> parameter class, as ``cvstereo simulate --scene`` offers them.
SCENES = {"arms": ArmsScene, "rotation": RotationScene, "motorcycle": MotorcycleScene, "fan": FanScene}
