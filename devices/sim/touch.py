"""Touch: cell pressure from how far each tactile point penetrates the world, and the glove's raw bytes.

Pressure (normalised, before the glove) = 1 − exp(−depth / 5 mm) for a surface point `depth` inside an
object or below the table top; bend cells follow finger flexion. A soft object gives way first: pressed from
above by `d`, it compresses by softness · d (visibly) and the hand is left (1 − softness) · d inside it.
The glove turns it into raw uint8 slots: a static per-slot bias, per-slot gain, Gaussian noise, 8-bit
quantisation and saturation at 255, and optionally a dead display column on the right glove.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from touchanything.core.snapshot import HANDS
from touchanything.core.tactile_layout import TactileLayout
from touchanything.devices.sim.hand_model import HandState, hand_state
from touchanything.devices.sim.shapes import Shape, inverse, transform

DEPTH_SCALE = 0.005
FULL_SCALE_RAW = 235.0
BEND_RAW = 150.0
MAX_SQUASH = 0.6
"""A soft object compresses by at most this share of its height."""


def world_sdf(points: np.ndarray, shapes: list[Shape]) -> np.ndarray:
    """Signed distance of (N, 3) points to the objects and the table top (z = 0)."""
    distance = points[:, 2].copy()
    for shape in shapes:
        distance = np.minimum(distance, shape.sdf(points))
    return distance


def compress_soft(shapes: list[Shape], hands: list[HandState]) -> None:
    """Set each soft object's `squash`: softness × the deepest indentation of a tactile point from the top of the
    uncompressed object (points inside its footprint and below its top), at most `MAX_SQUASH` of its height."""
    points = np.concatenate([hand.cell_points[~np.isnan(hand.cell_points[..., 0])] for hand in hands])
    for shape in shapes:
        if not shape.softness:
            continue
        local = transform(inverse(shape.pose), points)
        half = shape.height
        if shape.kind == "box":
            footprint = np.all(np.abs(local[:, :2]) <= shape.size[:2], axis=1)
        else:
            footprint = np.linalg.norm(local[:, :2], axis=1) <= shape.size[0]
        below_top = footprint & (local[:, 2] > -half) & (local[:, 2] < half)
        indentation = float((half - local[below_top, 2]).max()) if below_top.any() else 0.0
        shape.squash = min(shape.softness * indentation, MAX_SQUASH * 2 * half)


def touch_frame(objects: list[Shape], object_poses: np.ndarray, hand_poses: np.ndarray, flexion: np.ndarray,
                sides: tuple[str, str] = HANDS) -> tuple[list[HandState], np.ndarray]:
    """One frame of the world: the objects moved to `object_poses` (S, 4, 4), the hands posed (wrists (2, 4, 4),
    `flexion` (2, 5)), soft objects compressed; returns the two hands and their (2, 21, 21) pressure."""
    for shape, pose in zip(objects, object_poses):
        shape.pose = pose
    hands = [hand_state(side, hand_poses[h], flexion[h]) for h, side in enumerate(sides)]
    compress_soft(objects, hands)
    return hands, np.stack([cell_pressure(hand, objects) for hand in hands])


def cell_pressure(hand: HandState, shapes: list[Shape]) -> np.ndarray:
    """(21, 21) pressure in [0, 1] at the hand's tactile and bend cells, NaN elsewhere (display grid)."""
    out = hand.bend.copy()
    cells = ~np.isnan(hand.cell_points[..., 0])
    depth = np.maximum(-world_sdf(hand.cell_points[cells], shapes), 0.0)
    out[cells] = 1.0 - np.exp(-depth / DEPTH_SCALE)
    return out


@dataclass
class Glove:
    """The sensor characteristics of one pair of gloves (fixed for an episode)."""

    bias: np.ndarray
    gain: np.ndarray
    noise: float
    dead_column: int | None

    @classmethod
    def draw(cls, rng: np.random.Generator, dead_column: int | None) -> Glove:
        return cls(bias=rng.uniform(0.0, 9.0, (2, 256)), gain=rng.uniform(0.85, 1.15, (2, 256)),
                   noise=float(rng.uniform(0.8, 1.6)), dead_column=dead_column)

    def raw(self, pressure: np.ndarray, layout: TactileLayout, rng: np.random.Generator) -> np.ndarray:
        """(2, 21, 21) pressure → (2, 256) uint8 raw vector through the layout."""
        scaled = np.where(layout.bend, pressure * BEND_RAW, pressure * FULL_SCALE_RAW)
        signal = layout.raw_from_grid(np.where(layout.valid, scaled, np.nan))
        values = self.bias + self.gain * signal + rng.normal(0.0, self.noise, signal.shape)
        used = np.zeros((2, 256), bool)
        for h in range(2):
            used[h, layout.used_sensors(h)] = True
        values = np.where(used, values, 0.0)
        if self.dead_column is not None:
            dead = layout.sensor_index[1, :, self.dead_column]
            values[1, dead[dead >= 0]] = 0.0
        return np.clip(np.round(values), 0, 255).astype(np.uint8)
