"""Colour maps as 256-entry RGB lookup tables: the official pressure map and a diverging error map."""
from __future__ import annotations

import numpy as np

PRESSURE_STOPS = ((0.0, (0, 0, 255)), (1 / 3, (0, 255, 255)), (2 / 3, (255, 255, 0)), (1.0, (255, 0, 0)))
"""The official PRESSURE_CMAP: blue → cyan → yellow → red over [0, 1]."""
ERROR_STOPS = ((0.0, (33, 102, 172)), (0.5, (247, 247, 247)), (1.0, (178, 24, 43)))
"""Diverging: blue (prediction below ground truth) → white (equal) → red (above), over [−1, 1]."""


def lookup_table(stops) -> np.ndarray:
    """(256, 3) uint8 from (position, colour) stops, linear in between."""
    positions = np.array([p for p, _ in stops])
    colours = np.array([c for _, c in stops], float)
    x = np.linspace(0.0, 1.0, 256)
    return np.stack([np.interp(x, positions, colours[:, k]) for k in range(3)], axis=1).round().astype(np.uint8)


PRESSURE_LUT = lookup_table(PRESSURE_STOPS)
ERROR_LUT = lookup_table(ERROR_STOPS)


def apply(values: np.ndarray, lut: np.ndarray, low: float, high: float, background: tuple[int, int, int]) -> np.ndarray:
    """(...,) values → (..., 3) uint8 on a fixed scale [low, high]; NaN (and ±inf) become `background`."""
    values = np.asarray(values, np.float64)
    finite = np.isfinite(values)
    index = np.clip((np.where(finite, values, low) - low) / (high - low) * 255.0, 0, 255).round().astype(np.intp)
    out = lut[index]
    out[~finite] = background
    return out
