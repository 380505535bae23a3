"""Official TouchAnything tactile metrics (the protocol of `src/utils/metrics.py`).

Grids are (N, 2, 21, 21) [left, right] in normalised units, NaN outside the layout.
"""
from __future__ import annotations

import numpy as np

CONTACT_THRESHOLD = 0.1
MIN_CONTACT_RATIO = 0.05


def contact_frames(grids: np.ndarray, bend: np.ndarray, threshold: float = CONTACT_THRESHOLD,
                   min_ratio: float = MIN_CONTACT_RATIO) -> np.ndarray:
    """(N,) bool: the official per-frame contact flag.

    Per frame, both hands are pooled over their non-NaN, non-bend cells (302 in the official layout); the
    frame is in contact when the share of those cells strictly above `threshold` is at least `min_ratio`
    (≥ 16 of 302 cells). A frame with no valid cell is "no contact". `bend`: (2, 21, 21) bool.
    """
    valid = ~np.isnan(grids) & ~bend[None]
    cells = valid.reshape(len(grids), -1).sum(axis=1)
    above = (valid & (np.nan_to_num(grids, nan=0.0) > threshold)).reshape(len(grids), -1).sum(axis=1)
    return (cells > 0) & (above / np.maximum(cells, 1) >= min_ratio)
