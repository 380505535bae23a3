"""Kinematic gloved hand: 21 joints in the official order, capsule bones, and the tactile cells' surface.

Hand frame (right hand): origin at the wrist, +y toward the fingers, +z out of the palm, +x toward the
thumb. The left hand is the mirror image (thumb toward −x). `flexion` is (5,) in [0, 1] for thumb, index,
middle, ring, pinky; 0 = open, 1 = a full fist.

Tactile cells are placed on the glove surface in *anatomical* grid columns (the left hand's display
columns: pinky 1–3, ring 5–7, middle 9–11, index 13–15, thumb 17–19, palm 1–19); the right hand's display
grid is mirrored (display column c ↔ anatomical 20 − c), as in the EgoTouch data.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from touchanything.devices.sim.shapes import Shape, transform

FINGER_RADIUS = 0.0085
PALM_HALF = (0.045, 0.046, 0.013)
PALM_CENTRE = (0.0, 0.046, 0.0)
FOREARM_START, FOREARM_END, FOREARM_RADIUS = (0.0, -0.02, -0.003), (0.0, -0.24, -0.015), 0.022
FINGERS = {  # name: (MCP base in the right-hand frame, segment lengths, spread in degrees)
    "index": ((0.028, 0.088, 0.0), (0.042, 0.025, 0.020), 6.0),
    "middle": ((0.008, 0.092, 0.0), (0.046, 0.028, 0.021), 0.0),
    "ring": ((-0.012, 0.088, 0.0), (0.043, 0.026, 0.020), -6.0),
    "pinky": ((-0.031, 0.078, 0.0), (0.034, 0.020, 0.018), -12.0),
}
FINGER_ORDER = ("thumb", "index", "middle", "ring", "pinky")
JOINT_FLEX_DEG = (85.0, 100.0, 65.0)
THUMB_BASE = np.array([0.022, 0.022, 0.008])
THUMB_LENGTHS = (0.040, 0.032, 0.026)
THUMB_OPEN = np.array([0.75, 0.6, 0.25])
THUMB_CLOSED = np.array([[-0.2, 0.6, 0.75], [-0.45, 0.35, 0.8], [-0.6, 0.1, 0.75]])
FINGER_COLUMNS = {"pinky": 1, "ring": 5, "middle": 9, "index": 13, "thumb": 17}
PAD_ROWS = ((2, 2, 0.7), (3, 2, 0.25), (4, 1, 0.65), (5, 1, 0.2))  # (row, segment, position along it)
THUMB_PAD_ROWS = ((6, 2, 0.7), (7, 2, 0.25), (8, 1, 0.65), (9, 1, 0.25))
PALM_ROWS = {13: 0.082, 14: 0.066, 15: 0.050, 16: 0.034, 17: 0.018}
FINGER_BEND_ROWS = range(7, 12)
THUMB_BEND_ROWS = (11, 12)
LATERAL_DEG = 40.0


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _rot_z(deg: float) -> np.ndarray:
    a = np.radians(deg)
    return np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1.0]])


@dataclass
class HandState:
    """One hand in the world. joints (21, 3); bones a/b (M, 3) with radii (M,); palm box; cells (21, 21, 3)
    points and normals in display coordinates (NaN where no tactile surface cell); bend (21, 21) in [0, 1]
    at bend cells (NaN elsewhere); joint_flex (5, 3) in [0, 1] per finger joint."""

    side: str
    pose: np.ndarray
    joints: np.ndarray
    bone_a: np.ndarray
    bone_b: np.ndarray
    bone_radius: np.ndarray
    palm: Shape
    cell_points: np.ndarray
    cell_normals: np.ndarray
    bend: np.ndarray


def _finger_chain(name: str, flex: float) -> tuple[np.ndarray, np.ndarray]:
    """Right-hand frame joints (4, 3) MCP→tip and palm-side normals (3, 3) per segment."""
    base, lengths, spread = FINGERS[name]
    rot = _rot_z(spread * (1.0 - 0.7 * flex))
    points, normals, angle = [np.asarray(base, float)], [], 0.0
    for length, max_deg in zip(lengths, JOINT_FLEX_DEG):
        angle += np.radians(max_deg) * flex
        direction = rot @ np.array([0.0, np.cos(angle), np.sin(angle)])
        normals.append(rot @ np.array([0.0, -np.sin(angle), np.cos(angle)]))
        points.append(points[-1] + length * direction)
    return np.array(points), np.array(normals)


def _thumb_chain(flex: float) -> tuple[np.ndarray, np.ndarray]:
    points, normals = [THUMB_BASE.copy()], []
    for length, closed in zip(THUMB_LENGTHS, THUMB_CLOSED):
        direction = _unit((1.0 - flex) * _unit(THUMB_OPEN) + flex * _unit(closed))
        pad = np.array([-0.6, 0.2, 0.75])
        normals.append(_unit(pad - direction * (pad @ direction)))
        points.append(points[-1] + length * direction)
    return np.array(points), np.array(normals)


def _segment_cells(points: np.ndarray, normals: np.ndarray, rows, first_col: int,
                   cell_points: np.ndarray, cell_normals: np.ndarray) -> None:
    for row, segment, along in rows:
        axis_point = points[segment] + along * (points[segment + 1] - points[segment])
        direction = _unit(points[segment + 1] - points[segment])
        lateral = np.cross(direction, normals[segment])  # toward the thumb side (+x) for a right hand
        for k in range(3):
            beta = np.radians(LATERAL_DEG * (k - 1))
            normal = np.cos(beta) * normals[segment] + np.sin(beta) * lateral
            cell_points[row, first_col + k] = axis_point + FINGER_RADIUS * normal
            cell_normals[row, first_col + k] = normal


def _chains(flexion: np.ndarray):
    """Per finger: index, name, clipped flexion, joints (4, 3) MCP→tip and segment normals (3, 3), right-hand frame."""
    for f, name in enumerate(FINGER_ORDER):
        flex = float(np.clip(flexion[f], 0.0, 1.0))
        yield (f, name, flex, *(_thumb_chain(flex) if name == "thumb" else _finger_chain(name, flex)))


def _mirror(side: str) -> np.ndarray:
    return np.array([-1.0 if side == "left" else 1.0, 1.0, 1.0])


def hand_joints(side: str, pose: np.ndarray, flexion: np.ndarray) -> np.ndarray:
    """(21, 3) world joints of a hand posed as in `hand_state` (without its surface: cheaper)."""
    joints = np.zeros((21, 3))
    for f, _, _, points, _ in _chains(flexion):
        joints[1 + 4 * f: 5 + 4 * f] = points
    return transform(pose, joints * _mirror(side))


def hand_state(side: str, pose: np.ndarray, flexion: np.ndarray) -> HandState:
    """Pose a hand: `pose` is the 4×4 world-from-hand transform of the wrist, `flexion` (5,)."""
    mirror = _mirror(side)
    joints = np.zeros((21, 3))
    cells = np.full((21, 21, 3), np.nan)
    normals = np.full((21, 21, 3), np.nan)
    bend = np.full((21, 21), np.nan)
    bones_a, bones_b, radii = [], [], []
    for f, name, flex, points, seg_normals in _chains(flexion):
        joints[1 + 4 * f: 5 + 4 * f] = points
        rows = THUMB_PAD_ROWS if name == "thumb" else PAD_ROWS
        _segment_cells(points, seg_normals, rows, FINGER_COLUMNS[name], cells, normals)
        bones_a += list(points[:-1])
        bones_b += list(points[1:])
        radii += [FINGER_RADIUS * (1.1 if name == "thumb" else 1.0)] * 3
        for row in (THUMB_BEND_ROWS if name == "thumb" else FINGER_BEND_ROWS):
            bend[row, FINGER_COLUMNS[name]:FINGER_COLUMNS[name] + 3] = flex
    for row, y in PALM_ROWS.items():
        cols = range(1, 16) if row == 13 else range(1, 20)
        for col in cols:
            cells[row, col] = (-0.042 + (col - 1) / 18 * 0.084, y, PALM_HALF[2])
            normals[row, col] = (0.0, 0.0, 1.0)
    bones_a.append(np.array(FOREARM_START))
    bones_b.append(np.array(FOREARM_END))
    radii.append(FOREARM_RADIUS)
    rot = pose[:3, :3]

    def world(points: np.ndarray) -> np.ndarray:
        return transform(pose, points * mirror)

    palm_pose = pose.copy()
    palm_pose[:3, 3] = transform(pose, np.asarray(PALM_CENTRE) * mirror)
    display = np.arange(21) if side == "left" else 20 - np.arange(21)
    return HandState(
        side=side, pose=pose, joints=world(joints),
        bone_a=world(np.array(bones_a)), bone_b=world(np.array(bones_b)), bone_radius=np.array(radii),
        palm=Shape("box", PALM_HALF, (40, 40, 46), palm_pose),
        cell_points=world(cells)[:, display], cell_normals=((normals * mirror) @ rot.T)[:, display],
        bend=bend[:, display],
    )
