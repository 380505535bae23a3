"""Whether an ensemble's spread means something: does it rank the cells as the error does?

Per frame, the Spearman rank correlation (ties ranked by their mean rank) between the members' spread and the
absolute error |prediction − measured| over the cells of the predicted hands inside the hand layout (cells
where prediction, spread and measurement are all finite). A frame whose spread or error is constant over
those cells (or that has fewer than two) has no correlation and is skipped. Per trajectory: the mean over
its frames that have one; NaN when none has.
"""
from __future__ import annotations

import numpy as np
from scipy.stats import spearmanr


def frame_correlation(pressure: np.ndarray, spread: np.ndarray, measured: np.ndarray,
                      hands_predicted: np.ndarray) -> float:
    """(2, 21, 21) prediction, spread and measurement in the same units, `hands_predicted` (2,) bool → the
    frame's Spearman correlation in [-1, 1], NaN when it has none (module docstring)."""
    cells = np.isfinite(pressure) & np.isfinite(spread) & np.isfinite(measured)
    cells &= np.asarray(hands_predicted, bool)[:, None, None]
    spread_cells, error = spread[cells], np.abs(pressure[cells] - measured[cells])
    if error.size < 2 or np.ptp(spread_cells) == 0 or np.ptp(error) == 0:
        return float("nan")
    return float(spearmanr(spread_cells, error).statistic)


def trajectory_correlation(pressure: np.ndarray, spread: np.ndarray, measured: np.ndarray,
                           hands_predicted: np.ndarray) -> float:
    """(N, 2, 21, 21) predictions, spreads and measurements of one trajectory, `hands_predicted` (N, 2) → the
    mean of its frames' correlations (`frame_correlation`), NaN when no frame has one."""
    values = [frame_correlation(*frame) for frame in zip(pressure, spread, measured, hands_predicted, strict=True)]
    kept = [v for v in values if not np.isnan(v)]
    return float(np.mean(kept)) if kept else float("nan")
