"""Pressure panels: 21×21 hand maps on one fixed colour scale (never rescaled per frame), NaN cells as
background, nearest-neighbour upscaling, titles and a colour bar — as pure numpy/OpenCV images."""
from __future__ import annotations

import cv2
import numpy as np

from viz.colormap import ERROR_LUT, PRESSURE_LUT, apply

BACKGROUND = (26, 26, 46)
"""The official figure background #1a1a2e."""
AXES = (17, 17, 34)
FONT = cv2.FONT_HERSHEY_SIMPLEX


def hand_map(grid: np.ndarray, cell: int, error: bool = False) -> np.ndarray:
    """(21, 21) grid → (21·cell, 21·cell, 3) uint8; pressure on [0, 1] or error on [−1, 1]."""
    colours = apply(grid, ERROR_LUT, -1.0, 1.0, AXES) if error else apply(grid, PRESSURE_LUT, 0.0, 1.0, AXES)
    return np.repeat(np.repeat(colours, cell, axis=0), cell, axis=1)


def put_text(image: np.ndarray, text: str, origin: tuple[int, int], scale: float = 0.5,
             colour: tuple[int, int, int] = (255, 255, 255)) -> None:
    """White text with a black outline (readable on any background)."""
    cv2.putText(image, text, origin, FONT, scale, (0, 0, 0), 2, cv2.LINE_AA)
    cv2.putText(image, text, origin, FONT, scale, colour, 1, cv2.LINE_AA)


def colour_bar(height: int, width: int = 14, error: bool = False) -> np.ndarray:
    """A vertical colour bar, maximum at the top."""
    values = np.linspace(1.0, -1.0 if error else 0.0, height)[:, None].repeat(width, axis=1)
    return apply(values, ERROR_LUT if error else PRESSURE_LUT, -1.0 if error else 0.0, 1.0, AXES)


def pressure_panel(grids: np.ndarray, title: str, width: int, height: int, error: bool = False,
                   labels: tuple[str, str] = ("Left Hand", "Right Hand")) -> np.ndarray:
    """(2, 21, 21) → (height, width, 3) panel: title, both hands side by side, a colour bar."""
    panel = np.empty((height, width, 3), np.uint8)
    panel[:] = BACKGROUND
    put_text(panel, title, (10, 22), 0.6)
    cell = max(1, min((width - 60) // 2 // 21, (height - 60) // 21))
    size = 21 * cell
    top = 40
    for h in range(2):
        left = 10 + h * (size + 10)
        panel[top:top + size, left:left + size] = hand_map(grids[h], cell, error)
        put_text(panel, labels[h], (left, top + size + 16), 0.45)
    bar_left = 10 + 2 * (size + 10)
    if bar_left + 14 <= width:
        panel[top:top + size, bar_left:bar_left + 14] = colour_bar(size, error=error)
        put_text(panel, "+1" if error else "1", (bar_left, top - 4), 0.35)
        put_text(panel, "-1" if error else "0", (bar_left, top + size + 12), 0.35)
    return panel
