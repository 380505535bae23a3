"""Painter's-algorithm renderer: faceted objects, capsule bones and spheres drawn far to near with OpenCV.

The ground (table top and wall) is drawn first, then the shadows on the table, then everything else by depth:
everything stands on the table or in front of the wall, so for a camera above the table this order is exact.
Among the rest, occlusion comes from depth ordering of small primitives (box faces are split into tiles),
which is exact for non-intersecting convex parts of this size; a shadow on an object's top is drawn right
after the top face it lies on. Lambert shading from one light; shadows darken what is under them.
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


@dataclass
class Scene:
    """What the cameras see: ground faces (table top and wall), the other faces, bones, spheres (centre (3,),
    radius, RGB colour), shadows (`shadows.Shadow`: polygon (K, 3), opacity, anchor) and the lighting."""

    ground: FaceSet
    faces: FaceSet
    capsules: Capsules
    spheres: list[tuple[np.ndarray, float, np.ndarray]]
    shadows: list
    lighting: Lighting


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


def _draw_faces(image: np.ndarray, polygons: np.ndarray, colours: np.ndarray, order: np.ndarray) -> None:
    for i in order:
        cv2.fillConvexPoly(image, polygons[i], tuple(colours[i].tolist()), cv2.LINE_AA, SHIFT)


def _darken(image: np.ndarray, camera: Camera, shadows: list) -> None:
    """Darken the image under the shadows' projected polygons (overlapping shadows darken once, by the most
    opaque)."""
    if not shadows:
        return
    sizes = np.array([len(shadow.polygon) for shadow in shadows])
    uv_all, _, ok_all = camera.project(np.concatenate([shadow.polygon for shadow in shadows]))
    splits = np.cumsum(sizes)[:-1]
    projected = [(uv, shadow.opacity) for uv, ok, shadow in zip(np.split(uv_all, splits), np.split(ok_all, splits), shadows) if ok.all()]
    if not projected:
        return
    corners = np.concatenate([uv for uv, _ in projected])
    lo = np.maximum(np.floor(corners.min(axis=0)).astype(int), 0)
    hi = np.minimum(np.ceil(corners.max(axis=0)).astype(int) + 1, [camera.width, camera.height])
    if np.any(hi <= lo):
        return
    alpha = np.zeros((hi[1] - lo[1], hi[0] - lo[0]), np.float32)
    for uv, opacity in projected:
        a = np.clip(np.floor(uv.min(axis=0)).astype(int) - lo, 0, None)
        b = np.clip(np.ceil(uv.max(axis=0)).astype(int) + 1 - lo, None, alpha.shape[::-1])
        if np.any(b <= a):
            continue
        mask = np.zeros((b[1] - a[1], b[0] - a[0]), np.uint8)
        cv2.fillPoly(mask, [np.round((uv - lo - a) * SCALE).astype(np.int32)], 255, cv2.LINE_AA, SHIFT)
        window = alpha[a[1]:b[1], a[0]:b[0]]
        np.maximum(window, mask * np.float32(opacity / 255.0), out=window)
    region = image[lo[1]:hi[1], lo[0]:hi[0]]
    keep = np.round(255.0 * (1.0 - alpha)).astype(np.uint8)
    region[:] = cv2.multiply(region, cv2.merge([keep, keep, keep]), scale=1.0 / 255.0)


def render(camera: Camera, scene: Scene) -> np.ndarray:
    """(H, W, 3) uint8 RGB image of the scene from `camera`."""
    lighting = scene.lighting
    image = _background(camera.height, camera.width, lighting.background_top, lighting.background_bottom).copy()
    ground_depth, ground_polygons, ground_colours = _faces(camera, scene.ground, lighting)
    _draw_faces(image, ground_polygons, ground_colours, np.argsort(-ground_depth, kind="stable"))
    _darken(image, camera, [s for s in scene.shadows if s.anchor is None])
    face_depth, polygons, face_colours = _faces(camera, scene.faces, lighting)
    bone_depth, ends, thickness, bone_colours = _capsules(camera, scene.capsules)
    ball_depth, balls = [], []
    for centre, radius, colour in scene.spheres:
        uv, dist, ok = camera.project(centre[None])
        if ok[0] and dist[0] > radius:
            ball_depth.append(dist[0])
            balls.append((uv[0], float(camera.pixel_radius(radius, dist)[0]), colour * lighting.gain))
    layers: dict[tuple, list] = {}
    for shadow in scene.shadows:
        if shadow.anchor is not None:
            layers.setdefault(tuple(shadow.anchor), []).append(shadow)
    layer_depth = [np.linalg.norm(np.asarray(anchor) - camera.centre) - 1e-4 for anchor in layers]
    depth = np.concatenate([face_depth, bone_depth, np.asarray(ball_depth, float), np.asarray(layer_depth, float)])
    counts = (len(face_depth), len(bone_depth), len(balls), len(layers))
    kind = np.repeat(np.arange(4), counts)
    index = np.concatenate([np.arange(n) for n in counts])
    shadow_layers = list(layers.values())
    for k in np.argsort(-depth, kind="stable"):
        i = index[k]
        if kind[k] == 0:
            cv2.fillConvexPoly(image, polygons[i], tuple(face_colours[i].tolist()), cv2.LINE_AA, SHIFT)
        elif kind[k] == 1:
            cv2.line(image, tuple(ends[i, 0].tolist()), tuple(ends[i, 1].tolist()), tuple(bone_colours[i].tolist()),
                     int(thickness[i]), cv2.LINE_AA, SHIFT)
        elif kind[k] == 2:
            _draw_sphere(image, *balls[i])
        else:
            _darken(image, camera, shadow_layers[i])
    return image
