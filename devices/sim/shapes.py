"""Rigid primitives of the simulated world: signed distance, pose, and a faceted surface for rendering.

Sizes are in metres in the object's own frame (z up). `pose` is a 4×4 world-from-object transform.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

CYLINDER_SIDES = 18
PATCHES = 3
"""Box faces are split into PATCHES × PATCHES tiles (texture, and finer depth ordering when rendering)."""


def transform(pose: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Apply a 4×4 pose to (..., 3) points."""
    return points @ pose[:3, :3].T + pose[:3, 3]


def inverse(pose: np.ndarray) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3] = pose[:3, :3].T
    out[:3, 3] = -pose[:3, :3].T @ pose[:3, 3]
    return out


def pose_at(position, rotation: np.ndarray | None = None) -> np.ndarray:
    out = np.eye(4)
    out[:3, 3] = position
    if rotation is not None:
        out[:3, :3] = rotation
    return out


@dataclass
class FaceSet:
    """Planar convex quads: vertices (F, 4, 3) world, outward normals (F, 3), RGB colours (F, 3) 0–255.
    Polygons with more corners are stored as fans of quads (a triangle repeats its last corner)."""

    vertices: np.ndarray
    normals: np.ndarray
    colours: np.ndarray

    def moved(self, pose: np.ndarray) -> FaceSet:
        """The same faces under a 4×4 pose."""
        return FaceSet(transform(pose, self.vertices), self.normals @ pose[:3, :3].T, self.colours)

    @staticmethod
    def concat(sets: list[FaceSet]) -> FaceSet:
        sets = [f for f in sets if len(f.vertices)]
        if not sets:
            return FaceSet(np.zeros((0, 4, 3)), np.zeros((0, 3)), np.zeros((0, 3)))
        return FaceSet(*(np.concatenate([getattr(f, k) for f in sets]) for k in ("vertices", "normals", "colours")))


@dataclass
class Shape:
    """kind: box (size = half extents x, y, z) | cylinder (radius, half height) | sphere (radius).

    pattern: plain | stripes | checker, drawn with `accent` as the second colour.
    softness: the share of an indentation from above that a box or cylinder gives way (0 = rigid); `squash` is
    its current compression (metres) along its own z axis, the bottom staying put (`touch.compress_soft`).
    """

    kind: str
    size: tuple[float, ...]
    colour: tuple[int, int, int]
    pose: np.ndarray = field(default_factory=lambda: np.eye(4))
    pattern: str = "plain"
    accent: tuple[int, int, int] = (255, 255, 255)
    softness: float = 0.0
    squash: float = 0.0
    _local: FaceSet | None = field(default=None, repr=False, compare=False)

    def sdf(self, points: np.ndarray) -> np.ndarray:
        """Signed distance (metres) of (N, 3) world points to the (compressed) shape; negative inside."""
        p = transform(inverse(self.pose), points)
        if self.kind == "sphere":
            return np.linalg.norm(p, axis=-1) - self.size[0]
        half = self.height - self.squash / 2
        p[..., 2] += self.squash / 2
        if self.kind == "box":
            q = np.abs(p) - np.array([self.size[0], self.size[1], half])
        else:
            q = np.stack([np.linalg.norm(p[..., :2], axis=-1) - self.size[0], np.abs(p[..., 2]) - half], -1)
        return np.linalg.norm(np.maximum(q, 0.0), axis=-1) + np.minimum(q.max(axis=-1), 0.0)

    @property
    def height(self) -> float:
        """Half height along the object's z axis, uncompressed."""
        return self.size[0] if self.kind == "sphere" else self.size[2] if self.kind == "box" else self.size[1]

    def faces(self) -> FaceSet:
        """The faceted surface in world coordinates (spheres are drawn as discs, so they have none)."""
        if self._local is None:
            self._local = self._local_faces()
        if not self.squash:
            return self._local.moved(self.pose)
        vertices = self._local.vertices.copy()
        vertices[..., 2] = (vertices[..., 2] + self.height) * (1.0 - self.squash / (2 * self.height)) - self.height
        return FaceSet(vertices, self._local.normals, self._local.colours).moved(self.pose)

    def _local_faces(self) -> FaceSet:
        quads, normals, colours = [], [], []
        if self.kind == "box":
            self._box_faces(quads, normals, colours)
        elif self.kind == "cylinder":
            self._cylinder_faces(quads, normals, colours)
        if not quads:
            return FaceSet.concat([])
        return FaceSet(np.array(quads, float), np.array(normals, float), np.array(colours, float))

    def _colour(self, k: int) -> tuple:
        use_accent = self.pattern != "plain" and k % 2 == 1
        return self.accent if use_accent else self.colour

    def _box_faces(self, quads: list, normals: list, colours: list) -> None:
        h = np.asarray(self.size)
        grid = np.linspace(-1.0, 1.0, PATCHES + 1)
        for axis in range(3):
            u, v = [a for a in range(3) if a != axis]
            for sign in (-1.0, 1.0):
                normal = np.zeros(3)
                normal[axis] = sign
                for i in range(PATCHES):
                    for j in range(PATCHES):
                        corners = [(grid[i], grid[j]), (grid[i + 1], grid[j]), (grid[i + 1], grid[j + 1]), (grid[i], grid[j + 1])]
                        quad = np.zeros((4, 3))
                        quad[:, axis] = sign * h[axis]
                        quad[:, u] = [c[0] * h[u] for c in corners]
                        quad[:, v] = [c[1] * h[v] for c in corners]
                        quads.append(quad)
                        normals.append(normal)
                        colours.append(self._colour(i + j if self.pattern == "checker" else i))

    def _cylinder_faces(self, quads: list, normals: list, colours: list) -> None:
        radius, half = self.size[0], self.size[1]
        angles = np.linspace(0, 2 * np.pi, CYLINDER_SIDES + 1)
        ring = np.stack([radius * np.cos(angles), radius * np.sin(angles)], -1)
        for k in range(CYLINDER_SIDES):
            a, b = ring[k], ring[k + 1]
            quads.append(np.array([[*a, -half], [*b, -half], [*b, half], [*a, half]]))
            mid = (angles[k] + angles[k + 1]) / 2
            normals.append(np.array([np.cos(mid), np.sin(mid), 0.0]))
            colours.append(self._colour(k // 3))
            for sign in (-1.0, 1.0):
                quads.append(np.array([[0, 0, sign * half], [*a, sign * half], [*b, sign * half], [*b, sign * half]]))
                normals.append(np.array([0, 0, sign]))
                colours.append(self.colour)


def capsule_sdf(points: np.ndarray, a: np.ndarray, b: np.ndarray, radius: float | np.ndarray) -> np.ndarray:
    """Signed distance of (N, 3) points to capsules with axes a→b (M, 3); returns (N, M)."""
    ab = b - a
    ap = points[:, None, :] - a[None]
    t = np.clip(np.einsum("nmk,mk->nm", ap, ab) / np.maximum(np.einsum("mk,mk->m", ab, ab), 1e-12), 0.0, 1.0)
    closest = a[None] + t[..., None] * ab[None]
    return np.linalg.norm(points[:, None, :] - closest, axis=-1) - radius
