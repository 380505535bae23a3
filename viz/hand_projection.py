"""2D hand skeletons with pressure drawn onto the joints, in the head-camera image, and the line saying where
the pose comes from.

WiLoR joints live in the head-camera frame with WiLoR's camera (`core.hand_pose.project_wilor`), so they
project with a pinhole.
"""
from __future__ import annotations

import cv2
import numpy as np

from touchanything.core.hand_pose import project_wilor
from touchanything.core.snapshot import HANDS, POSE_FROM_CAMERA, Snapshot
from touchanything.viz.colormap import PRESSURE_LUT, apply
from touchanything.viz.hand_regions import BONES, joint_pressure

HAND_COLOURS = ((90, 200, 255), (255, 170, 90))
"""Skeleton colour per hand (left, right)."""


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


def pose_label(snapshot: Snapshot | None) -> str:
    """Where the snapshot's hand pose comes from and each hand's state, e.g. "pose: camera estimate (left
    0.94, right not found)", "pose: WiLoR file (left ok, right invalid)", "pose: none"."""
    if snapshot is None or not snapshot.pose_source:
        return "pose: none"
    missing = "not found" if snapshot.pose_source == POSE_FROM_CAMERA else "invalid"
    confidence = snapshot.joints_confidence
    hands = [f"{hand} {missing}" if not snapshot.joints_valid[h] else
             f"{hand} {'ok' if confidence is None else f'{float(confidence[h]):.2f}'}" for h, hand in enumerate(HANDS)]
    return f"pose: {snapshot.pose_source} ({', '.join(hands)})"
