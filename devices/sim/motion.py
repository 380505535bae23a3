"""Keyframed motion: hand tracks (wrist pose + finger flexion) with minimum-jerk interpolation."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation, Slerp


def min_jerk(s: np.ndarray) -> np.ndarray:
    """The minimum-jerk profile on [0, 1]: 10s³ − 15s⁴ + 6s⁵."""
    s = np.clip(s, 0.0, 1.0)
    return np.clip(s ** 3 * (10 - 15 * s + 6 * s * s), 0.0, 1.0)  # rounding can overshoot 1 by an ulp


def frame_rotation(fingers: np.ndarray, palm_normal: np.ndarray) -> np.ndarray:
    """Hand rotation (columns x, y, z) from the finger direction (y) and the palm normal (z)."""
    y = np.asarray(fingers, float) / np.linalg.norm(fingers)
    z = np.asarray(palm_normal, float)
    z = z - y * (z @ y)
    z /= np.linalg.norm(z)
    return np.stack([np.cross(y, z), y, z], axis=1)


@dataclass
class HandTrack:
    """Keyframes (time s, position (3,), rotation (3, 3), flexion (5,)) of one hand, in time order."""

    times: list[float] = field(default_factory=list)
    positions: list[np.ndarray] = field(default_factory=list)
    rotations: list[np.ndarray] = field(default_factory=list)
    flexions: list[np.ndarray] = field(default_factory=list)

    def add(self, t: float, position, rotation, flexion) -> float:
        """Append a keyframe at time t (≥ the last one); returns t."""
        if self.times and t < self.times[-1]:
            raise ValueError("keyframes must be in time order")
        self.times.append(float(t))
        self.positions.append(np.asarray(position, float))
        self.rotations.append(np.asarray(rotation, float))
        self.flexions.append(np.asarray(flexion, float))
        return t

    def hold(self, t: float) -> float:
        """Stay at the last keyframe until t."""
        return self.add(t, self.positions[-1], self.rotations[-1], self.flexions[-1])

    @property
    def last(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return self.positions[-1], self.rotations[-1], self.flexions[-1]

    def sample(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Poses at `times`: positions (T, 3), rotations (T, 3, 3), flexion (T, 5); held past the ends."""
        keys = np.asarray(self.times)
        index = np.clip(np.searchsorted(keys, times, side="right") - 1, 0, len(keys) - 1)
        nxt = np.minimum(index + 1, len(keys) - 1)
        span = np.maximum(keys[nxt] - keys[index], 1e-9)
        s = min_jerk(np.where(nxt > index, (times - keys[index]) / span, 0.0))
        pos, flex = np.stack(self.positions), np.stack(self.flexions)
        positions = pos[index] + s[:, None] * (pos[nxt] - pos[index])
        flexion = flex[index] + s[:, None] * (flex[nxt] - flex[index])
        rotations = np.empty((len(times), 3, 3))
        for k in range(len(keys) - 1):
            members = np.flatnonzero(index == k)
            if members.size:
                slerp = Slerp([0.0, 1.0], Rotation.from_matrix(np.stack([self.rotations[k], self.rotations[k + 1]])))
                rotations[members] = slerp(s[members]).as_matrix()
        last = np.flatnonzero(index == len(keys) - 1)
        rotations[last] = self.rotations[-1]
        return positions, rotations, flexion
