"""2D hand skeletons with pressure drawn onto the joints, in the head-camera image.

WiLoR joints live in the head-camera frame with WiLoR's camera: focal length 5000/256 · max(W, H) pixels
and the principal point at the image centre (the official convention), so they project with a pinhole.
"""
from __future__ import annotations

import cv2
import numpy as np

from touchanything.viz.colormap import PRESSURE_LUT, apply
from touchanything.viz.hand_regions import BONES, joint_pressure

WILOR_FOCAL_PER_PIXEL = 5000.0 / 256.0
HAND_COLOURS = ((90, 200, 255), (255, 170, 90))
"""Skeleton colour per hand (left, right)."""


def project_wilor(joints: np.ndarray, width: int, height: int) -> np.ndarray:
    """(..., 3) head-camera joints → (..., 2) pixel coordinates; NaN where z ≤ 0 or not finite."""
    joints = np.asarray(joints, np.float64)
    focal = WILOR_FOCAL_PER_PIXEL * max(width, height)
    z = joints[..., 2]
    ok = np.isfinite(joints).all(axis=-1) & (z > 1e-6)
    safe = np.where(ok, z, 1.0)
    uv = np.stack([focal * joints[..., 0] / safe + width / 2, focal * joints[..., 1] / safe + height / 2], axis=-1)
    return np.where(ok[..., None], uv, np.nan)


def draw_hands(image: np.ndarray, joints: np.ndarray, valid: np.ndarray, pressure: np.ndarray | None) -> np.ndarray:
    """A copy of the RGB head-camera `image` with each valid hand's skeleton; joints over a pressure cell
    are filled with the colour of their predicted pressure (fixed [0, 1] scale) and sized by it.
    joints (42, 3) WiLoR head-camera frame; valid (2,); pressure (2, 21, 21) or None."""
    out = image.copy()
    h, w = out.shape[:2]
    points = project_wilor(np.asarray(joints).reshape(2, 21, 3), w, h)
    values = joint_pressure(pressure) if pressure is not None else np.full((2, 21), np.nan)
    colours = apply(values, PRESSURE_LUT, 0.0, 1.0, (255, 255, 255)).tolist()
    radii = (3 + np.round(6 * np.nan_to_num(values, nan=0.0))).astype(int).tolist()
    finite = np.isfinite(points).all(axis=-1)
    pixels = np.clip(np.round(np.nan_to_num(points)), -10_000, 10_000).astype(int).tolist()
    for hand in range(2):
        if not valid[hand] or not finite[hand].any():
            continue
        pts, ok = pixels[hand], finite[hand]
        for a, b in BONES:
            if ok[a] and ok[b]:
                cv2.line(out, pts[a], pts[b], HAND_COLOURS[hand], 2, cv2.LINE_AA)
        for j in np.flatnonzero(ok):
            cv2.circle(out, pts[j], radii[hand][j], colours[hand][j], -1, cv2.LINE_AA)
            cv2.circle(out, pts[j], radii[hand][j], (0, 0, 0), 1, cv2.LINE_AA)
    return out
