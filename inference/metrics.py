"""Official TouchAnything tactile metrics (the protocol of `src/utils/metrics.py`), importable on their own.

Grids are (N, 2, 21, 21) [left, right] in normalised units with NaN outside the layout; `bend` is the
(2, 21, 21) bend-cell mask (left on hand 0, right on hand 1). Per trajectory:
- temporal accuracy: a frame is "contact" when, over its non-NaN non-bend cells of both hands (302 in the
  official layout), the share strictly above 0.1 is ≥ 5 % (≥ 16 cells); accuracy = mean agreement of the
  prediction's and the ground truth's flags over frames whose ground truth is not all NaN (NaN if none);
- contact IoU: cells > 0.1 (bend cells included, NaN ground-truth cells zeroed in both), intersection and
  union summed over all frames and both hands; 0/0 → NaN;
- volumetric IoU: Σ min(P, G) / Σ max(P, G) over non-NaN ground-truth cells; 0/0 → NaN;
- MAE (and per hand): mean |P − G| over non-NaN ground-truth cells; no cells → NaN.
Across trajectories: nanmean per metric. Sums are int64 / float64, so streaming accumulation over any
number of frames gives the same value as one batch call.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

CONTACT_THRESHOLD = 0.1
MIN_CONTACT_RATIO = 0.05
METRICS = ("temporal_accuracy", "contact_iou", "volumetric_iou", "mae", "mae_left", "mae_right")


def contact_frames(grids: np.ndarray, bend: np.ndarray, threshold: float = CONTACT_THRESHOLD,
                   min_ratio: float = MIN_CONTACT_RATIO) -> np.ndarray:
    """(N,) bool: the official per-frame contact flag (a frame with no valid cell is "no contact")."""
    valid = ~np.isnan(grids) & ~bend[None]
    flat = (grids.shape[0], valid[0].size if grids.shape[0] else 0)
    cells = valid.reshape(flat).sum(axis=1)
    above = (valid & (np.nan_to_num(grids, nan=0.0) > threshold)).reshape(flat).sum(axis=1)
    return (cells > 0) & (above / np.maximum(cells, 1) >= min_ratio)


def _ratio(num: float, den: float) -> float:
    return float(num / den) if den > 0 else float("nan")


@dataclass
class MetricAccumulator:
    """Streaming sums of one trajectory's metrics; `add` chunks of frames, then `result()`."""

    bend: np.ndarray
    threshold: float = CONTACT_THRESHOLD
    min_ratio: float = MIN_CONTACT_RATIO
    sums: dict = field(default_factory=lambda: {k: 0 for k in (
        "agree", "judged", "intersection", "union", "vol_min", "vol_max", "abs_left", "abs_right", "cells_left", "cells_right")})

    def add(self, pred: np.ndarray, gt: np.ndarray) -> None:
        """pred, gt: (N, 2, 21, 21) (float32 or float64; sums are float64); pred is masked with the ground
        truth's NaN."""
        gt, pred = np.asarray(gt), np.asarray(pred)
        if gt.shape[0] == 0:
            return
        valid = ~np.isnan(gt)
        g = np.where(valid, gt, 0.0)
        p = np.where(valid, pred, 0.0)
        p_on, g_on = p > self.threshold, g > self.threshold
        s = self.sums
        s["intersection"] += int(np.count_nonzero(p_on & g_on))
        s["union"] += int(np.count_nonzero(p_on | g_on))
        tactile = valid & ~self.bend[None]
        cells = tactile.sum(axis=(1, 2, 3))
        judged = cells > 0
        flags = [judged & ((on & tactile).sum(axis=(1, 2, 3)) / np.maximum(cells, 1) >= self.min_ratio) for on in (p_on, g_on)]
        s["agree"] += int(np.count_nonzero((flags[0] == flags[1]) & valid.any(axis=(1, 2, 3))))
        s["judged"] += int(np.count_nonzero(valid.any(axis=(1, 2, 3))))
        s["vol_min"] += float(np.minimum(p, g).sum(dtype=np.float64))
        s["vol_max"] += float(np.maximum(p, g).sum(dtype=np.float64))
        error = np.abs(p - g)
        for h, hand in enumerate(("left", "right")):
            s[f"abs_{hand}"] += float(error[:, h].sum(dtype=np.float64))
            s[f"cells_{hand}"] += int(np.count_nonzero(valid[:, h]))

    def result(self) -> dict[str, float]:
        s = self.sums
        return {
            "temporal_accuracy": _ratio(s["agree"], s["judged"]),
            "contact_iou": _ratio(s["intersection"], s["union"]),
            "volumetric_iou": _ratio(s["vol_min"], s["vol_max"]),
            "mae": _ratio(s["abs_left"] + s["abs_right"], s["cells_left"] + s["cells_right"]),
            "mae_left": _ratio(s["abs_left"], s["cells_left"]),
            "mae_right": _ratio(s["abs_right"], s["cells_right"]),
        }


def compute_tactile_metrics(pred: np.ndarray, gt: np.ndarray, bend: np.ndarray, threshold: float = CONTACT_THRESHOLD,
                            min_contact_ratio: float = MIN_CONTACT_RATIO) -> dict[str, float]:
    """The six official metrics of one trajectory (all frames given have a prediction)."""
    accumulator = MetricAccumulator(bend, threshold, min_contact_ratio)
    accumulator.add(pred, gt)
    return accumulator.result()


def aggregate(rows: list[dict[str, float]]) -> dict[str, float]:
    """nanmean over trajectories, metric by metric (NaN when every trajectory is NaN)."""
    out = {}
    for key in METRICS:
        values = np.array([r[key] for r in rows], np.float64)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            out[key] = float(np.nanmean(values)) if values.size else float("nan")
    return out


def ground_truth_for_metrics(grids: np.ndarray, normalized: bool) -> np.ndarray:
    """The official vmax fallback: data flagged `normalized` are used as they are; otherwise divided by
    max(nanmax(left), nanmax(right), 1) of the trajectory; then clipped to [0, 1] (NaN kept)."""
    grids = np.asarray(grids, np.float64)
    finite = grids[np.isfinite(grids)]
    vmax = 1.0 if normalized or finite.size == 0 else max(float(finite.max()), 1.0)
    return np.clip(grids / vmax, 0.0, 1.0)
