"""Visibility of contact points from a camera: inside the image and in line of sight.

The line of sight is sphere traced through the world's signed distance: both hands (palms and bones), the
table and the objects. The surfaces a point touches (within 2 mm) do not count as occluders — they are
at the contact by definition — and hits within 5 mm of the point are ignored, so a palm-side point seen
through the back of its own hand (a palm or finger is thicker than that) is hidden.
"""
from __future__ import annotations

import numpy as np

from touchanything.devices.sim.cameras import Camera
from touchanything.devices.sim.hand_model import HandState
from touchanything.devices.sim.shapes import Shape, capsule_sdf

MARGIN = 0.005
TOUCHING = 0.002
STEPS = 64
HIT = 1e-4


def _surfaces(points: np.ndarray, shapes: list[Shape]) -> np.ndarray:
    """(N, S + 1) signed distances to each object and to the table top (last column)."""
    return np.stack([s.sdf(points) for s in shapes] + [points[:, 2]], axis=1)


def _hands(points: np.ndarray, hands: list[HandState]) -> np.ndarray:
    distance = np.full(len(points), np.inf)
    for hand in hands:
        distance = np.minimum(distance, hand.palm.sdf(points))
        distance = np.minimum(distance, capsule_sdf(points, hand.bone_a, hand.bone_b, hand.bone_radius).min(axis=1))
    return distance


def visible(camera: Camera, points: np.ndarray, shapes: list[Shape], hands: list[HandState]) -> np.ndarray:
    """(N,) bool for (N, 3) contact points."""
    if len(points) == 0:
        return np.zeros(0, bool)
    uv, distance, ok = camera.project(points)
    candidate = ok & camera.in_image(uv)
    ignored = _surfaces(points, shapes) < TOUCHING
    direction = (points - camera.centre) / np.maximum(distance, 1e-9)[:, None]
    end = distance - MARGIN
    t = np.zeros(len(points))
    blocked = np.zeros(len(points), bool)
    active = candidate & (end > 0)
    for _ in range(STEPS):
        idx = np.flatnonzero(active)
        if idx.size == 0:
            break
        probe = camera.centre + t[idx, None] * direction[idx]
        surfaces = np.where(ignored[idx], np.inf, _surfaces(probe, shapes)).min(axis=1)
        step = np.minimum(surfaces, _hands(probe, hands))
        hit = step < HIT
        blocked[idx[hit]] = True
        t[idx] += np.maximum(step, HIT)
        active[idx[hit | (t[idx] >= end[idx])]] = False
    return candidate & ~blocked
