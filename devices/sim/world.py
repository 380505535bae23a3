"""The static world of an episode (table, wall, lighting, objects) and its per-frame state."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from touchanything.devices.sim.catalogue import CATALOGUE, SceneCategory
from touchanything.devices.sim.shapes import FaceSet, Shape, pose_at

TABLE_X, TABLE_Y, TILE = (-0.6, 0.6), (-0.3, 0.8), 0.1
WALL_Y, WALL_TILE = 0.85, 0.2


def _tiles(corner: np.ndarray, u: np.ndarray, v: np.ndarray, nu: int, nv: int, normal: np.ndarray,
           colours: tuple) -> FaceSet:
    quads, tints = [], []
    for i in range(nu):
        for j in range(nv):
            origin = corner + i * u + j * v
            quads.append([origin, origin + u, origin + u + v, origin + v])
            tints.append(colours[(i + j) % 2])
    return FaceSet(np.array(quads, float), np.tile(normal, (len(quads), 1)), np.array(tints, float))


def static_faces(scene: SceneCategory) -> FaceSet:
    """Table top (z = 0, checker tiles) and a back wall."""
    nx, ny = round((TABLE_X[1] - TABLE_X[0]) / TILE), round((TABLE_Y[1] - TABLE_Y[0]) / TILE)
    table = _tiles(np.array([TABLE_X[0], TABLE_Y[0], 0.0]), np.array([TILE, 0, 0]), np.array([0, TILE, 0]),
                   nx, ny, np.array([0, 0, 1.0]), (scene.table, scene.table_accent))
    wall_colours = (scene.wall, tuple(int(c * 0.93) for c in scene.wall))
    wall = _tiles(np.array([-0.8, WALL_Y, 0.0]), np.array([WALL_TILE, 0, 0]), np.array([0, 0, WALL_TILE]),
                  8, 4, np.array([0, -1.0, 0]), wall_colours)
    return FaceSet.concat([table, wall])


def make_object(object_id: str, x: float, y: float, scale: float = 1.0) -> Shape:
    """A catalogue object, its size times `scale`, resting on the table with its centre above (x, y)."""
    spec = CATALOGUE[object_id]
    size = tuple(scale * v for v in spec.size)
    shape = Shape(spec.kind, size, spec.colour, pattern=spec.pattern, accent=spec.accent, softness=spec.softness)
    shape.pose = pose_at([x, y, shape.height])
    return shape


@dataclass
class ObjectTimeline:
    """Per-frame 4×4 poses (T, 4, 4) of each object, following the hand while attached."""

    poses: np.ndarray


def object_timeline(objects: list[Shape], attachments, hand_poses: np.ndarray, times: np.ndarray) -> ObjectTimeline:
    """hand_poses: (T, 2, 4, 4). An attached object keeps its pose relative to the hand from the grab on."""
    frames = len(times)
    poses = np.repeat(np.stack([o.pose for o in objects])[None], frames, axis=0)
    for attachment in sorted(attachments, key=lambda a: a.start):
        inside = np.flatnonzero((times >= attachment.start) & (times <= attachment.end))
        if inside.size == 0:
            continue
        first = inside[0]
        relative = np.linalg.inv(hand_poses[first, attachment.hand]) @ poses[first, attachment.obj]
        for k in inside:
            poses[k, attachment.obj] = hand_poses[k, attachment.hand] @ relative
        poses[inside[-1] + 1:, attachment.obj] = poses[inside[-1], attachment.obj]
    return ObjectTimeline(poses)
