"""A small DSEC-style sequence made from a known scene: two event files, a cam_to_cam.yaml, true depths.

Random dots on two fronto-parallel planes (a wall at 4 m, a box at 2 m in front of its centre) blink ON and OFF
(each blink a burst of events at the dot's pixel, as a real pixel's contrast step gives); every blink is seen by
both event cameras of a calibrated 640x480 rig with lens distortion, a slightly turned
right camera and a 10 cm baseline, at the same time. The events go through the real projection
(``cv2.projectPoints``), so rectification is needed to bring a dot onto the same row of both cameras.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from cvstereo.model.events import make_events
from tests._calibration_fixtures import dsec_cam_to_cam, dump_yaml
from tests._hdf5_fixtures import write_dsec_events

RES = (640, 480)
K0 = np.array([[556.7, 0, 342.4], [0, 556.6, 215.1], [0, 0, 1]])
K3 = np.array([[555.6, 0, 321.0], [0, 555.7, 224.7], [0, 0, 1]])
D0, D3 = np.array([-0.098, 0.21, -0.00036, 6.7e-05]), np.array([-0.109, 0.268, 0.00042, -0.0081])
R = cv2.Rodrigues(np.array([0.004, -0.006, 0.009]))[0]
T = np.array([-0.10, 0.002, 0.003])
DEPTHS = (2.0, 4.0)
T_OFFSET = 52_000_000_000


def _dots(rng, n_wall: int, n_box: int) -> np.ndarray:
    wall = np.column_stack([rng.uniform(-2.6, 2.6, n_wall), rng.uniform(-2.0, 2.0, n_wall), np.full(n_wall, 4.0)])
    box = np.column_stack([rng.uniform(-0.5, 0.5, n_box), rng.uniform(-0.4, 0.4, n_box), np.full(n_box, 2.0)])
    return np.vstack([wall, box])


def _project(points, rvec, tvec, K, D) -> np.ndarray:
    return cv2.projectPoints(points.reshape(-1, 1, 3), rvec, tvec, K, D)[0].reshape(-1, 2)


#: Ground-truth maps every this many ms, named every second image index (DSEC: maps at 10 Hz, images at 20 Hz).
TRUTH_EVERY_MS = 50


def rectified_truth(dots: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each dot's pixel in the rectified left view and its true disparity x_left - x_right, from OpenCV's
    rectification of the rig (the one the scene's cam_to_cam.yaml holds), computed here without cvstereo."""
    R1, R2, P1, P2, *_ = cv2.stereoRectify(K0, D0, K3, D3, RES, R, T.reshape(3, 1), flags=cv2.CALIB_ZERO_DISPARITY,
                                           alpha=-1)
    left = (P1[:, :3] @ R1 @ dots.T).T
    right = (P2[:, :3] @ R2 @ (R @ dots.T + T.reshape(3, 1))).T
    xl, yl, xr = left[:, 0] / left[:, 2], left[:, 1] / left[:, 2], right[:, 0] / right[:, 2]
    return xl, yl, xl - xr


def _write_truth(root: Path, dots: np.ndarray, fired: list[tuple[int, np.ndarray]], seconds: float) -> None:
    """DSEC's ground truth as its public description says: ``disparity/event/NNNNNN.png`` (uint16, disparity x 256,
    0 = none) in the rectified left frame and ``disparity/timestamps.txt`` (one time in us per PNG, in order).
    A map at ts holds the dots that blinked in the 50 ms before it (the nearer where two share a pixel)."""
    xl, yl, d = rectified_truth(dots)
    folder = root / "disparity" / "event"
    folder.mkdir(parents=True, exist_ok=True)
    stamps = []
    for k in range(1, int(seconds * 1000) // TRUTH_EVERY_MS + 1):
        ts = T_OFFSET + k * TRUTH_EVERY_MS * 1000
        ids = np.unique(np.concatenate([f for t, f in fired if ts - TRUTH_EVERY_MS * 1000 < t <= ts]))
        image = np.zeros((RES[1], RES[0]), np.uint16)
        x, y = np.rint(xl[ids]).astype(int), np.rint(yl[ids]).astype(int)
        ok = (x >= 0) & (x < RES[0]) & (y >= 0) & (y < RES[1]) & (d[ids] > 0)
        order = np.argsort(d[ids][ok])  # far first: a nearer dot overwrites
        image[y[ok][order], x[ok][order]] = np.rint(d[ids][ok][order] * 256).astype(np.uint16)
        assert cv2.imwrite(str(folder / f"{2 * k:06d}.png"), image)
        stamps.append(ts)
    (root / "disparity" / "timestamps.txt").write_text("".join(f"{t}\n" for t in stamps))


def write_dsec_sequence(root, *, seconds: float = 0.2, seed: int = 0, burst: int = 3, truth: bool = False) -> Path:
    """Write ``root/events/{left,right}/events.h5`` and ``root/calibration/cam_to_cam.yaml``; return root.

    ``truth``: also DSEC's ground-truth disparity maps (:func:`_write_truth`), one every
    :data:`TRUTH_EVERY_MS`.

    ``burst``: events per blink and camera, at the dot's pixel, of the blink's polarity, 100 us apart (a real
    pixel's contrast step crosses several thresholds, one event per refractory period). With 1, every pixel
    fires alone: enough for sgbm's frames, but never for the event matchers, whose dynamic frames need a
    pixel's own recent history (event-time compares a value read before one event's update with one read after
    the other's: from one event each they differ by the whole update, 0.41 > 0.3; event-area's 1.2 needs three
    updates).
    """
    root = Path(root)
    rng = np.random.default_rng(seed)
    dots = _dots(rng, 3000, 1200)
    pix = [_project(dots, np.zeros(3), np.zeros(3), K0, D0), _project(dots, cv2.Rodrigues(R)[0], T, K3, D3)]
    steps = int(seconds * 1000)
    per_step = 60
    streams, fired = [[], []], []
    for k in range(steps):
        fire = rng.choice(dots.shape[0], per_step, replace=False)
        t = T_OFFSET + k * 1000 + np.sort(rng.integers(0, 1000, per_step))
        fired.append((T_OFFSET + k * 1000 + 999, fire))  # the blinks of this millisecond (the last event's time)
        p = rng.integers(0, 2, per_step)
        for cam in (0, 1):
            xy = np.rint(pix[cam][fire]).astype(np.int64)
            ok = (xy[:, 0] >= 0) & (xy[:, 0] < RES[0]) & (xy[:, 1] >= 0) & (xy[:, 1] < RES[1])
            for b in range(burst):
                streams[cam].append(make_events(t[ok] + 100 * b, xy[ok, 0], xy[ok, 1], p[ok]))
    for cam, name in enumerate(("left", "right")):
        (root / "events" / name).mkdir(parents=True, exist_ok=True)
        events = np.concatenate(streams[cam])
        events = events[np.argsort(events["t"], kind="stable")]
        write_dsec_events(root / "events" / name / "events.h5", events, t_offset=T_OFFSET)
    (root / "calibration").mkdir(parents=True, exist_ok=True)
    (root / "calibration" / "cam_to_cam.yaml").write_text(dump_yaml(dsec_cam_to_cam(K0, D0, K3, D3, R, T, RES)))
    if truth:
        _write_truth(root, dots, fired, seconds)
    return root
