"""MediaPipe's hand landmarks → joints in WiLoR's camera frame (the model's pose input).

Per hand MediaPipe gives 21 image landmarks (pixels after scaling) and 21 world landmarks P (metres, centred
on the hand, camera axes x right, y down, z forward), in the model's joint order. WiLoR's camera has focal
length f = 5000/256 · max(W, H) px and the principal point c at the image centre. The translation t that
puts the hand where it is seen solves, for every joint, two linear equations

    f (Px + tx) − (u − cx)(Pz + tz) = 0,        f (Py + ty) − (v − cy)(Pz + tz) = 0,

in the least-squares sense (42 equations, 3 unknowns); J = P + t is then in the model's frame, its depth
stretched by WiLoR's long focal length as in the training data (a hand 40 cm from a 60° camera at 640×480
gets z ≈ 9).
"""
from __future__ import annotations

import numpy as np

from touchanything.core.hand_pose import JOINTS_PER_HAND, project_wilor, wilor_focal_px

MIN_DEPTH = 1e-3
"""A fitted hand whose nearest joint is not this far in front of the camera is refused (degenerate fit)."""


def fit_translation(world: np.ndarray, pixels: np.ndarray, width: int, height: int) -> np.ndarray | None:
    """The (3,) translation t (metres) putting the (21, 3) world landmarks where the (21, 2) pixel landmarks
    see them through WiLoR's camera for a W×H image; None when the fit is degenerate (values not finite or
    out of range, rank < 3, or the hand not in front of the camera)."""
    world, pixels = np.asarray(world, np.float64), np.asarray(pixels, np.float64)
    focal = wilor_focal_px(width, height)
    rows = world.shape[0]
    with np.errstate(all="ignore"):  # landmarks far out of range overflow to inf / NaN: refused below
        offset = pixels - np.array([width / 2, height / 2])
        a = np.zeros((2 * rows, 3))
        a[:rows, 0] = a[rows:, 1] = focal
        a[:rows, 2], a[rows:, 2] = -offset[:, 0], -offset[:, 1]
        b = np.concatenate([offset[:, 0] * world[:, 2] - focal * world[:, 0],
                            offset[:, 1] * world[:, 2] - focal * world[:, 1]])
    if not (np.isfinite(a).all() and np.isfinite(b).all()):
        return None
    t, _, rank, _ = np.linalg.lstsq(a, b, rcond=None)
    with np.errstate(all="ignore"):
        nearest = (world[:, 2] + t[2]).min()
    if rank < 3 or not np.isfinite(t).all() or not nearest >= MIN_DEPTH:
        return None
    return t


def to_camera_frame(world: np.ndarray, pixels: np.ndarray, width: int, height: int) -> np.ndarray | None:
    """(21, 3) float32 joints in WiLoR's camera frame from one hand's landmarks, or None (see
    `fit_translation`)."""
    t = fit_translation(world, pixels, width, height)
    return None if t is None else (np.asarray(world, np.float64) + t).astype(np.float32)


def reprojection_px(joints: np.ndarray, pixels: np.ndarray, width: int, height: int) -> float:
    """Mean distance in pixels between (21, 3) camera-frame joints projected through WiLoR's camera and the
    (21, 2) image landmarks they came from."""
    projected = project_wilor(np.asarray(joints).reshape(JOINTS_PER_HAND, 3), width, height)
    return float(np.linalg.norm(projected - np.asarray(pixels), axis=-1).mean())
