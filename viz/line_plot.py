"""Line plots of recent history (metrics, latency) as images: fixed y range, newest sample at the right."""
from __future__ import annotations

import cv2
import numpy as np

from touchanything.viz.pressure_panel import AXES, BACKGROUND, put_text

PLOT_SAMPLES = 300
"""History shown by the plots: 10 s at 30 fps."""
LATENCY_PLOT_MS = 200.0
"""Top of the latency plots' scale."""
SERIES_COLOURS = ((90, 200, 255), (255, 170, 90), (140, 230, 140), (230, 120, 200))


def line_plot(series: dict[str, np.ndarray], width: int, height: int, y_max: float, title: str,
              capacity: int, unit: str = "") -> np.ndarray:
    """(height, width, 3) uint8. series: label → 1-D values, the last `capacity` shown left to right with
    the newest at the right edge; NaN leaves a gap; values are clipped to [0, y_max]. The legend shows
    each series' latest value ("n/a" when it is NaN or there is none): the value of the frame shown."""
    image = np.empty((height, width, 3), np.uint8)
    image[:] = BACKGROUND
    left, top, right, bottom = 34, 24, width - 6, height - 8
    image[top:bottom, left:right] = AXES
    put_text(image, title, (6, 16), 0.45)
    put_text(image, f"{y_max:g}", (2, top + 10), 0.32)
    put_text(image, "0", (20, bottom), 0.32)
    span = max(capacity - 1, 1)
    legend_x = left + 8 + 7 * len(title)
    for k, (label, values) in enumerate(series.items()):
        colour = SERIES_COLOURS[k % len(SERIES_COLOURS)]
        values = np.asarray(values, np.float64)[-capacity:]
        x = right - (len(values) - 1 - np.arange(len(values))) * (right - left) / span
        y = bottom - np.clip(values, 0, y_max) / y_max * (bottom - top)
        for segment in _finite_runs(np.isfinite(values)):
            points = np.stack([x[segment], y[segment]], axis=1).round().astype(np.int32)
            cv2.polylines(image, [points], False, colour, 1, cv2.LINE_AA)
        latest = values[-1] if values.size else np.nan
        text = f"{label} {latest:.{0 if unit else 2}f}{unit}" if np.isfinite(latest) else f"{label} n/a"
        put_text(image, text, (legend_x, 16), 0.4, colour)
        legend_x += 9 * len(text) + 12
    return image


def _finite_runs(finite: np.ndarray) -> list[slice]:
    """Slices of consecutive True values (each at least one sample long)."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], finite.astype(np.int8), [0]])))
    return [slice(a, b) for a, b in zip(edges[::2], edges[1::2])]
