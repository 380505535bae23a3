"""Shadows on the table and on the objects' tops, as darkened convex polygons for the renderer.

- Cast shadows from the scene's directional light: every hand bone (a capsule), palm and object is projected
  along the light onto a support below it — the table top (z = 0) or an upright object's top face. Opacity:
  the share of that surface's light that is direct (what is left is the ambient part), fading with the
  caster's height above it (× exp(−h / 15 cm), a soft light's penumbra).
- Contact shadows (ambient occlusion): straight below a bone or palm within 2.5 cm of a support, reaching
  1 cm beyond its outline and further the higher it is (+ gap / 2), darker the closer it is
  (0.55 · (1 − gap / 2.5 cm)²).
A fingertip pressing a surface meets its shadow in a dark spot; one hovering 1–3 cm above it shows a gap
between finger and shadow and a faint spot or none: a cue a wrist camera sees when the pose cannot tell.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from touchanything.devices.sim.hand_model import HandState
from touchanything.devices.sim.renderer import Lighting
from touchanything.devices.sim.shapes import Shape
from touchanything.devices.sim.world import TABLE_X, TABLE_Y

PENUMBRA = 0.15
CONTACT_RANGE = 0.025
CONTACT_DARKNESS = 0.55
CONTACT_SPREAD = 0.01
CAP_STEPS = 5
EDGE_STEPS = 4
_ANGLES = np.linspace(-np.pi / 2, np.pi / 2, CAP_STEPS)
_CAP = np.stack([np.cos(_ANGLES), np.sin(_ANGLES)], axis=1)


@dataclass
class Shadow:
    """A polygon (K, 3) lying on a support, darkening it by `opacity`; `anchor` is the centroid of the object
    top face (patch) it lies on — the renderer draws it right after that face — or None on the table."""

    polygon: np.ndarray
    opacity: float
    anchor: np.ndarray | None


@dataclass
class _Support:
    height: float
    outline: np.ndarray
    """(K, 2) convex outline in world x, y."""
    patches: list[tuple[np.ndarray, np.ndarray]]
    """An object top's faces as drawn: (outline (K, 2), centroid (3,)) each; none for the table."""


TABLE_OUTLINE = np.array([[TABLE_X[0], TABLE_Y[0]], [TABLE_X[1], TABLE_Y[0]], [TABLE_X[1], TABLE_Y[1]], [TABLE_X[0], TABLE_Y[1]]])


def _supports(objects: list[Shape]) -> list[_Support]:
    """The table and the tops of the upright boxes and cylinders."""
    out = [_Support(0.0, TABLE_OUTLINE, [])]
    for shape in objects:
        if shape.kind == "sphere" or abs(shape.pose[2, 2]) < 0.999:
            continue
        faces = shape.faces()
        top = faces.vertices[faces.normals[:, 2] > 0.999]
        if len(top) == 0:
            continue
        patches = [(np.unique(quad[:, :2], axis=0), quad.mean(axis=0)) for quad in top]
        out.append(_Support(float(top[0, 0, 2]), _hull(top[..., :2].reshape(-1, 2)), [(_hull(o), c) for o, c in patches]))
    return out


def _stadium(a: np.ndarray, b: np.ndarray, radius: float) -> np.ndarray:
    """(2 · CAP_STEPS, 2) convex outline of a 2-D segment a–b thickened by `radius`."""
    d = b - a
    length = math.hypot(d[0], d[1])
    along = d / length if length > 1e-9 else np.array([1.0, 0.0])
    frame = np.array([along, [-along[1], along[0]]])
    cap = radius * (_CAP @ frame)
    return np.concatenate([b + cap, a - cap])


def _hull(points: np.ndarray) -> np.ndarray:
    return cv2.convexHull(points.astype(np.float32)).reshape(-1, 2).astype(float)


def _clip(outline: np.ndarray, region: np.ndarray) -> np.ndarray | None:
    """The intersection of two convex (K, 2) outlines, or None if it is empty."""
    area, piece = cv2.intersectConvexConvex(outline.astype(np.float32), region.astype(np.float32))
    return None if area <= 1e-10 or piece is None else piece.reshape(-1, 2).astype(float)


def _casters(hands: list[HandState], objects: list[Shape]):
    """(points (K, 3), radius, contact) per caster: bones and palms (contact shadows too), and objects."""
    for hand in hands:
        for a, b, r in zip(hand.bone_a, hand.bone_b, hand.bone_radius):
            yield np.stack([a, b]), float(r), True
        yield np.unique(hand.palm.faces().vertices.reshape(-1, 3), axis=0), 0.0, True
    for shape in objects:
        points = shape.faces().vertices.reshape(-1, 3) if shape.kind != "sphere" else shape.pose[None, :3, 3]
        yield points, shape.size[0] if shape.kind == "sphere" else 0.0, False


def _outline(points2d: np.ndarray, radius: float) -> np.ndarray:
    """A segment's (or a point's) outline thickened by `radius`, or the convex hull of more points."""
    return _stadium(points2d[0], points2d[-1], radius) if len(points2d) <= 2 else _hull(points2d)


def cast_shadows(hands: list[HandState], objects: list[Shape], lighting: Lighting) -> list[Shadow]:
    """The hands' and objects' shadows on the table and on the objects' tops (an object casts on the table)."""
    light = np.asarray(lighting.light, float) / np.linalg.norm(lighting.light)
    direct = (1.0 - lighting.ambient) * max(-light[2], 0.0)
    strength = direct / (lighting.ambient + direct)
    shadows = []
    for support in _supports(objects):
        for points, radius, contact in _casters(hands, objects):
            if not contact and support.patches:
                continue
            heights = points[:, 2] - support.height
            if heights.max() < 0.0 or heights.min() + radius < -0.01:
                continue  # not above this support
            lifted = np.maximum(heights, 0.0)
            cast = points[:, :2] - light[:2] * (lifted / -light[2])[:, None]
            shadows += _on(support, _outline(cast, radius), strength * np.exp(-lifted.mean() / PENUMBRA))
            gap = lifted.min() - radius
            if contact and gap < CONTACT_RANGE:
                darkness = CONTACT_DARKNESS * (1.0 - max(gap, 0.0) / CONTACT_RANGE) ** 2
                shadows += _on(support, _outline(points[:, :2], radius + CONTACT_SPREAD + max(gap, 0.0) / 2), darkness)
    return shadows


def _on(support: _Support, outline: np.ndarray, opacity: float) -> list[Shadow]:
    """The shadow outline on the table, or cut into the pieces lying on each face of an object's top."""
    whole = _clip(outline, support.outline) if opacity > 0.01 else None
    if whole is None:
        return []
    if not support.patches:
        return [Shadow(_lay(whole, support.height), float(opacity), None)]
    pieces = [(_clip(outline, patch), centroid) for patch, centroid in support.patches]
    return [Shadow(_lay(piece, support.height), float(opacity), centroid) for piece, centroid in pieces if piece is not None]


def _lay(outline: np.ndarray, height: float) -> np.ndarray:
    """The (K, 2) outline at `height`, each edge split in `EDGE_STEPS` (so a fisheye bends it as it should)."""
    steps = np.arange(EDGE_STEPS)[:, None, None] / EDGE_STEPS
    dense = (outline[None] + steps * (np.roll(outline, -1, axis=0)[None] - outline[None])).transpose(1, 0, 2).reshape(-1, 2)
    return np.column_stack([dense, np.full(len(dense), height)])
