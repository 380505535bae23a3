"""Raw glove vectors → normalised 21×21 pressure grids (baseline, broken-column repair, normalisation).

Steps for each hand of an episode, in raw uint8 units until the last step:
1. Baseline: when the mean of the first frame over the hand's used sensors is below 15, subtract the
   first frame and clip at 0 (the official `BASELINE_NOISE_THRESHOLD` rule); otherwise leave the data.
2. Map to the display grid through the layout (NaN outside).
3. Broken-column repair: each valid cell of a configured (hand, column) is replaced by the mean of its
   valid left/right neighbours of the same kind (tactile or bend); without such neighbours it is kept.
4. Separate normalisation: tactile cells are divided by the episode's tactile maximum, bend cells by the
   bend maximum, each at least `min_scale` (so noise alone never reaches the contact threshold and a zero
   maximum never divides by zero), then clipped to [0, 1]. The divisors are stored as `tactile_max_*`/`bend_max_*`.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from touchanything.core.snapshot import HANDS
from touchanything.core.tactile_layout import TactileLayout

BASELINE_NOISE_THRESHOLD = 15.0


@dataclass(frozen=True)
class TactileConfig:
    """broken_columns: (hand name, display column) pairs to repair; min_scale in raw units (0–255): the smallest
    divisor of the normalisation. Sensor noise through the first-frame baseline reaches about 6 raw units (the
    difference of two noisy readings, σ up to 2.3), so the divisor must keep the contact threshold (0.1 of it)
    above that: at 25 an untouched glove read as contact on 70 % of its frames (docs/findings.md), at 60 on
    none."""

    baseline_threshold: float = BASELINE_NOISE_THRESHOLD
    broken_columns: tuple[tuple[str, int], ...] = ()
    min_scale: float = 60.0


@dataclass
class PressureGrids:
    """grids: (T, 2, 21, 21) float32 in [0, 1], NaN outside the layout; per-hand (2,) metadata."""

    grids: np.ndarray
    baseline_applied: np.ndarray
    tactile_max: np.ndarray
    bend_max: np.ndarray


def subtract_baseline(raw: np.ndarray, sensors: np.ndarray, threshold: float) -> tuple[np.ndarray, bool]:
    """(T, 256) one hand's raw values → (baseline-corrected float32, applied?)."""
    raw = raw.astype(np.float32)
    if raw.shape[0] == 0 or sensors.size == 0 or raw[0, sensors].mean() >= threshold:
        return raw, False
    return np.clip(raw - raw[0], 0.0, None), True


def repair_column(grid: np.ndarray, layout: TactileLayout, hand: int, column: int) -> None:
    """In place on (T, 21, 21): interpolate a broken display column of one hand from its neighbours."""
    valid, bend = layout.valid[hand], layout.bend[hand]
    for row in np.flatnonzero(valid[:, column]):
        neighbours = [
            c for c in (column - 1, column + 1)
            if 0 <= c < valid.shape[1] and valid[row, c] and bend[row, c] == bend[row, column]
        ]
        if neighbours:
            grid[:, row, column] = grid[:, row, neighbours].mean(axis=1)


def normalise(grid: np.ndarray, cells: np.ndarray, min_scale: float) -> tuple[np.ndarray, float]:
    """Divide the given cells of (T, 21, 21) by max(their maximum, min_scale); returns (grid, divisor)."""
    values = grid[:, cells]
    peak = float(values.max()) if values.size else 0.0
    scale = max(peak, min_scale, np.finfo(np.float32).tiny)
    grid[:, cells] = np.clip(values / scale, 0.0, 1.0)
    return grid, scale


def process_raw(raw: np.ndarray, layout: TactileLayout, config: TactileConfig = TactileConfig()) -> PressureGrids:
    """(T, 2, 256) uint8 raw vectors of an episode → PressureGrids."""
    raw = np.asarray(raw)
    if raw.ndim != 3 or raw.shape[1:] != (2, 256):
        raise ValueError(f"raw pressure must have shape (T, 2, 256), got {raw.shape}")
    frames = raw.shape[0]
    grids = np.empty((frames, 2, 21, 21), np.float32)
    applied, tactile_max, bend_max = np.zeros(2, bool), np.zeros(2), np.zeros(2)
    for h, name in enumerate(HANDS):
        corrected, applied[h] = subtract_baseline(raw[:, h], layout.used_sensors(h), config.baseline_threshold)
        grid = layout.hand_grid(corrected, h)
        for hand_name, column in config.broken_columns:
            if hand_name == name:
                repair_column(grid, layout, h, column)
        grid, tactile_max[h] = normalise(grid, layout.tactile[h], config.min_scale)
        grid, bend_max[h] = normalise(grid, layout.bend[h], config.min_scale)
        grids[:, h] = grid
    return PressureGrids(grids, applied, tactile_max, bend_max)
