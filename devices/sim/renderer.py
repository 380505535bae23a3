"""Painter's-algorithm renderer: faceted objects, capsule bones and spheres drawn far to near with OpenCV.

Occlusion comes from depth ordering of small primitives (box faces are split into tiles, the table into a
grid), which is exact for non-intersecting convex parts of this size. Lambert shading from one light.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np

from touchanything.devices.sim.cameras import Camera
from touchanything.devices.sim.shapes import FaceSet

SHIFT = 4
SCALE = 1 << SHIFT
SPHERE_RINGS = ((1.0, 0.0, 0.55), (0.8, 0.12, 0.8), (0.5, 0.25, 1.0), (0.2, 0.35, 1.25))  # scale, offset, gain


@dataclass(frozen=True)
class Lighting:
    """light: vector from the light toward the scene (world); ambient share in [0, 1]; background colours
    (top, bottom) RGB; gain: overall exposure."""

    light: tuple[float, float, float] = (0.3, 0.5, -0.8)
    ambient: float = 0.45
    background_top: tuple[int, int, int] = (200, 200, 205)
    background_bottom: tuple[int, int, int] = (120, 120, 125)
    gain: float = 1.0


@dataclass
class Capsules:
    """Bones: a, b (M, 3) world end points, radius (M,), colour (M, 3) RGB."""

    a: np.ndarray
    b: np.ndarray
    radius: np.ndarray
    colour: np.ndarray


@lru_cache(maxsize=32)
def _background(height: int, width: int, top: tuple, bottom: tuple) -> np.ndarray:
    t = np.linspace(0.0, 1.0, height)[:, None]
    column = (1 - t) * np.asarray(top) + t * np.asarray(bottom)
    return np.repeat(column[:, None, :], width, axis=1).astype(np.uint8)


def _faces(camera: Camera, faces: FaceSet, lighting: Lighting):
    """Visible faces: depth (K,), polygons (K, 4, 2) fixed-point, colours (K, 3)."""
    n = len(faces.vertices)
    if n == 0:
        return np.zeros(0), np.zeros((0, 4, 2), np.int32), np.zeros((0, 3))
    to_face = faces.vertices.mean(axis=1) - camera.centre
    front = np.einsum("fk,fk->f", faces.normals, to_face) < 0
    uv, _, ok = camera.project(faces.vertices.reshape(-1, 3))
    keep = front & ok.reshape(n, 4).all(axis=1)
    light = np.asarray(lighting.light) / np.linalg.norm(lighting.light)
    diffuse = np.clip(-faces.normals[keep] @ light, 0.0, None)
    shade = lighting.gain * (lighting.ambient + (1.0 - lighting.ambient) * diffuse)
    colours = np.clip(faces.colours[keep] * shade[:, None], 0, 255)
    polygons = np.round(uv.reshape(n, 4, 2)[keep] * SCALE).astype(np.int32)
    return np.linalg.norm(to_face[keep], axis=1), polygons, colours


def _capsules(camera: Camera, capsules: Capsules):
    """Visible bones: depth (K,), fixed-point end points (K, 2, 2), thickness (K,), colours (K, 3)."""
    m = len(capsules.radius)
    uv, _, ok = camera.project(np.concatenate([capsules.a, capsules.b]))
    keep = ok[:m] & ok[m:]
    depth = np.linalg.norm((capsules.a + capsules.b)[keep] / 2 - camera.centre, axis=1)
    thickness = np.maximum(1, np.round(2 * camera.pixel_radius(capsules.radius[keep], depth))).astype(int)
    ends = np.round(np.stack([uv[:m][keep], uv[m:][keep]], axis=1) * SCALE).astype(np.int32)
    return depth, ends, thickness, capsules.colour[keep]


def _draw_sphere(image: np.ndarray, centre: np.ndarray, radius: float, colour: np.ndarray) -> None:
    for scale, offset, gain in SPHERE_RINGS:
        c = np.round((centre - offset * radius) * SCALE).astype(int)
        cv2.circle(image, (int(c[0]), int(c[1])), max(1, int(round(radius * scale * SCALE))),
                   tuple(int(v) for v in np.clip(colour * gain, 0, 255)), -1, cv2.LINE_AA, SHIFT)


def render(camera: Camera, faces: FaceSet, capsules: Capsules,
           spheres: list[tuple[np.ndarray, float, np.ndarray]], lighting: Lighting) -> np.ndarray:
    """(H, W, 3) uint8 RGB image of the scene from `camera`."""
    image = _background(camera.height, camera.width, lighting.background_top, lighting.background_bottom).copy()
    face_depth, polygons, face_colours = _faces(camera, faces, lighting)
    bone_depth, ends, thickness, bone_colours = _capsules(camera, capsules)
    ball_depth, balls = [], []
    for centre, radius, colour in spheres:
        uv, dist, ok = camera.project(centre[None])
        if ok[0] and dist[0] > radius:
            ball_depth.append(dist[0])
            balls.append((uv[0], float(camera.pixel_radius(radius, dist)[0]), colour * lighting.gain))
    depth = np.concatenate([face_depth, bone_depth, np.asarray(ball_depth, float)])
    kind = np.concatenate([np.zeros(len(face_depth), int), np.ones(len(bone_depth), int), np.full(len(balls), 2)])
    index = np.concatenate([np.arange(len(face_depth)), np.arange(len(bone_depth)), np.arange(len(balls))])
    for k in np.argsort(-depth, kind="stable"):
        i = index[k]
        if kind[k] == 0:
            cv2.fillConvexPoly(image, polygons[i], tuple(face_colours[i].tolist()), cv2.LINE_AA, SHIFT)
        elif kind[k] == 1:
            cv2.line(image, tuple(ends[i, 0].tolist()), tuple(ends[i, 1].tolist()), tuple(bone_colours[i].tolist()),
                     int(thickness[i]), cv2.LINE_AA, SHIFT)
        else:
            _draw_sphere(image, *balls[i])
    return image
