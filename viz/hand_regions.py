"""Which cells of the 21×21 tactile grid lie under which hand joint, for drawing pressure on the skeleton.

Official grid geometry (left hand, palm view, fingers up, thumb at the right edge; the right hand is the
mirror image): fingertip pads rows 2–5 in columns 1–3 (little), 5–7 (ring), 9–11 (middle), 13–15 (index);
thumb pads rows 6–9, columns 17–19; palm rows 13–17. The bend strips (finger rows 7–11, thumb rows 11–12)
measure flexion, not pressure, so they are not drawn. Joints follow the official 21-joint order (wrist 0;
thumb 1–4, index 5–8, middle 9–12, ring 13–16, little 17–20; each finger MCP/base → tip).
"""
from __future__ import annotations

import numpy as np

FINGER_COLUMNS = {"index": (13, 16), "middle": (9, 12), "ring": (5, 8), "little": (1, 4)}
FINGER_JOINTS = {"thumb": (1, 2, 3, 4), "index": (5, 6, 7, 8), "middle": (9, 10, 11, 12), "ring": (13, 14, 15, 16),
                 "little": (17, 18, 19, 20)}
BONES = [(0, 1), (0, 5), (0, 9), (0, 13), (0, 17), (5, 9), (9, 13), (13, 17)] + [
    (j[k], j[k + 1]) for j in FINGER_JOINTS.values() for k in range(3)]
"""Skeleton edges in the official joint order."""


def _left_regions() -> list[np.ndarray]:
    """(21 joints) → (21, 21) bool masks on the left-hand grid; joints with no pressure cell are empty."""
    regions = [np.zeros((21, 21), bool) for _ in range(21)]
    for finger, (c0, c1) in FINGER_COLUMNS.items():
        base, _, distal, tip = FINGER_JOINTS[finger]
        regions[tip][2:4, c0:c1] = True
        regions[distal][4:6, c0:c1] = True
        regions[base][13:15, c0:c1] = True
    regions[4][6:8, 17:20] = True
    regions[3][8:10, 17:20] = True
    regions[1][14:18, 16:20] = True
    regions[0][15:18, 1:16] = True
    return regions


LEFT_REGIONS = np.stack(_left_regions())
REGIONS = np.stack([LEFT_REGIONS, LEFT_REGIONS[:, :, ::-1]])
"""(2, 21, 21, 21) bool: hand, joint, grid row, grid column."""


def joint_pressure(grids: np.ndarray) -> np.ndarray:
    """(2, 21, 21) pressure grids (NaN outside the layout) → (2, 21) per-joint maximum, NaN where a joint
    has no pressure cell or only NaN cells under it."""
    values = np.where(REGIONS, np.nan_to_num(grids, nan=-np.inf)[:, None], -np.inf).max(axis=(2, 3))
    return np.where(np.isfinite(values), values, np.nan).astype(np.float32)
