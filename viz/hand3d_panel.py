"""Pressure painted on 3D hands, drawn on the CPU for the comparison video (`--hand3d`): each hand's surface
(`viz.hand_surface`) seen from its palm side with the fingers up (so the thumbs point inwards: the mirror image
of the 2D maps), flat-shaded under a light from the viewer, painted on the fixed 0–1 pressure scale; the back
of the hand and cells outside the layout are grey. Measured | predicted, each left hand then right hand.

Orthographic projection, back faces culled, painter's order (far triangles first) with OpenCV's polygon fill;
`benchmarks/rerun_costs.py` measures the time per frame.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass

import cv2
import numpy as np

from touchanything.core.snapshot import HANDS
from touchanything.viz.colormap import PRESSURE_LUT, apply
from touchanything.viz.hand_surface import cross, hand_topology, hand_vertices, palm_frame, vertex_values
from touchanything.viz.pressure_panel import BACKGROUND, put_text

HAND3D_HEIGHT = 300
"""Height of the panel in the comparison video (its width is the video's, 1440)."""
UNPAINTED = (150, 150, 162)
"""Colour of the back of the hand and of cells outside the layout."""
AMBIENT = 0.35
LIGHT = np.array([-0.35, -0.45, -1.0]) / np.linalg.norm([-0.35, -0.45, -1.0])
"""Direction towards the light in view coordinates (right, down, into the screen): from the viewer, upper left."""
TITLE_HEIGHT = 24


def vertex_colours(grid: np.ndarray | None, side: int) -> np.ndarray:
    """(V, 3) uint8 RGB per vertex of hand `side`: its cell of the (21, 21) `grid` on the pressure scale, grey
    where it has none (also for a grid that is None)."""
    return apply(vertex_values(grid, hand_topology(side)), PRESSURE_LUT, 0.0, 1.0, UNPAINTED)


def palm_view(joints: np.ndarray, side: int) -> tuple[np.ndarray, np.ndarray, float]:
    """(rotation (3, 3) whose rows are screen right, screen down and into the screen; the point shown at the
    centre; the hand's length) for hand `side`'s (21, 3) joints seen from the palm side, fingers up."""
    normal, _, fingerward, _ = palm_frame(joints, side)
    down, into = -fingerward, -normal
    rotation = np.stack([cross(down, into), down, into])
    knuckles = joints[[5, 9, 13, 17]].mean(axis=0)
    length = 2.1 * float(np.linalg.norm(knuckles - joints[0]))
    return rotation, joints[0] + 0.5 * length * fingerward, length


@dataclass(frozen=True)
class HandDrawing:
    """One hand projected into a (height, width) view: the triangles facing the viewer, far to near
    (`order`), their pixel corners (N, 3, 2) int32 and their shade (N,) in [AMBIENT, 1]."""

    side: int
    order: np.ndarray
    pixels: list[np.ndarray]
    shade: np.ndarray

    def paint(self, canvas: np.ndarray, grid: np.ndarray | None) -> None:
        """Fill the triangles into `canvas` (contiguous (H, W, 3) uint8) in place, painted with `grid`."""
        triangles = hand_topology(self.side).triangles[self.order]
        colours = vertex_colours(grid, self.side)[triangles].mean(axis=1) * self.shade[:, None]
        for polygon, colour in zip(self.pixels, colours.round().astype(int).tolist()):
            cv2.fillConvexPoly(canvas, polygon, colour)


def draw_hand(joints: np.ndarray, side: int, width: int, height: int) -> HandDrawing | None:
    """Hand `side` ((21, 3) joints) fitted into a (height, width) view; None when the joints are not finite
    or the hand has no extent."""
    vertices = hand_vertices(joints, side)
    if vertices is None:
        return None
    rotation, centre, length = palm_view(np.asarray(joints, np.float64), side)
    if not length > 1e-9:
        return None
    scale = 0.85 * min(height, 1.25 * width) / length
    points = (vertices - centre) @ rotation.T
    xy = points[:, :2] * scale + np.array([width / 2, height / 2])
    triangles = hand_topology(side).triangles
    corners, space = xy[triangles], points[triangles]
    e1, e2 = corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]
    facing = np.flatnonzero(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0] < 0)
    order = facing[np.argsort(-space[facing, :, 2].mean(axis=1), kind="stable")]
    normals = cross(space[order, 1] - space[order, 0], space[order, 2] - space[order, 0])
    light = normals @ LIGHT / np.maximum(np.linalg.norm(normals, axis=1), 1e-12)
    shade = AMBIENT + (1 - AMBIENT) * np.clip(light, 0.0, 1.0)
    pixels = np.clip(np.round(corners[order]), -4 * width, 4 * width).astype(np.int32)
    return HandDrawing(side, order, list(pixels), shade)


@functools.lru_cache(maxsize=32)
def _background(titles: tuple[str, ...], width: int, height: int) -> np.ndarray:
    """The panel without hands: the background and the four titles (text is the slow part; cached)."""
    panel = np.empty((height, width, 3), np.uint8)
    panel[:] = BACKGROUND
    for k, title in enumerate(titles):
        put_text(panel, title, (k * (width // 4) + 8, 18), 0.45)
    panel.flags.writeable = False
    return panel


def hand3d_panel(joints: np.ndarray, valid: np.ndarray, measured: np.ndarray | None, predicted: np.ndarray | None,
                 width: int = 1440, height: int = HAND3D_HEIGHT) -> np.ndarray:
    """(height, width, 3) uint8: four hand views — measured left, measured right, predicted left, predicted
    right. joints (42, 3) (left 0–20, right 21–41), valid (2,) bool; measured / predicted (2, 21, 21) or None
    (then "n/a")."""
    cell = width // 4
    hands = np.asarray(joints, np.float64).reshape(2, 21, 3)
    drawings = [draw_hand(hands[side], side, cell, height - TITLE_HEIGHT) if valid[side] else None for side in range(2)]
    titles, views = [], []
    for grids, label in ((measured, "Measured"), (predicted, "Predicted")):
        for side, hand in enumerate(HANDS):
            if grids is None:
                titles.append(f"{label}: n/a")
            elif drawings[side] is None:
                titles.append(f"{label}, {hand} hand: no pose")
            else:
                titles.append(f"{label}, {hand} hand (palm side)")
                views.append((len(titles) - 1, drawings[side], grids[side]))
    panel = _background(tuple(titles), width, height).copy()
    for k, drawing, grid in views:
        view = np.ascontiguousarray(panel[TITLE_HEIGHT:, k * cell:(k + 1) * cell])
        drawing.paint(view, grid)
        panel[TITLE_HEIGHT:, k * cell:(k + 1) * cell] = view
    return panel
