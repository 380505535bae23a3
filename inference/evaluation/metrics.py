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
Also computed per trajectory by the official module but not reported (`EXTRA_METRICS`; its docstring calls
temporal accuracy "may be inflated" and recommends F1). "Kept frames" are the frames whose ground truth is not
all NaN, in order (an all-NaN frame is removed from the sequence); the contact flags are temporal accuracy's:
- temporal precision TP/(TP+FP), recall TP/(TP+FN), F1 2PR/(P+R) over kept frames, each 0.0 when its
  denominator is 0; support = TP+FN (ground-truth contact frames). Only a trajectory with no kept frame gives
  NaN precision, recall and F1 (support 0); kept frames without any contact give recall 0.0, F1 0.0 and
  precision 0.0 (FP / FP has TP = 0; nothing predicted has denominator 0), as the official
  `temporal_f1_score` does.
- onsets (no contact at t−1 → contact at t) and offsets (contact → no contact), t counted in the kept-frame
  sequence. Taking predicted events in time order, each matches the first not-yet-matched ground-truth event
  of its kind within ±2 positions. Precision = matched / predicted events, recall = matched / ground-truth
  events (each 0.0 when its denominator is 0); `num_gt_onsets`, `num_gt_offsets` count the ground truth's.
  Fewer than two kept frames → the four ratios NaN, both counts 0.
Across trajectories: nanmean per metric (counts included). Sums are int64 / float64 and the accumulator keeps
the kept frames' two contact flags, so streaming accumulation over any number of frames gives the same value
as one batch call.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from touchanything.core.snapshot import HANDS

CONTACT_THRESHOLD = 0.1
MIN_CONTACT_RATIO = 0.05
EVENT_TOLERANCE = 2
METRICS = ("temporal_accuracy", "contact_iou", "volumetric_iou", "mae", "mae_left", "mae_right")
"""The six metrics the official evaluation reports."""
DETECTION_METRICS = ("temporal_precision", "temporal_recall", "temporal_f1", "temporal_support")
EVENT_METRICS = ("onset_precision", "onset_recall", "offset_precision", "offset_recall", "num_gt_onsets", "num_gt_offsets")
EXTRA_METRICS = DETECTION_METRICS + EVENT_METRICS
"""Computed per trajectory by the official metric module, not reported by its evaluation."""
ALL_METRICS = METRICS + EXTRA_METRICS
ERROR_METRICS = ("mae", "mae_left", "mae_right")
"""Lower is better; every other metric but the counts is a score in [0, 1], higher is better."""
COUNT_METRICS = ("temporal_support", "num_gt_onsets", "num_gt_offsets")
"""Ground-truth counts: the same whatever the prediction."""


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


def _fraction(num: float, den: float) -> float:
    """num / den, 0.0 when den is 0 (the official precision / recall convention)."""
    return float(num / den) if den > 0 else 0.0


def reported_metrics(s: dict) -> dict[str, float]:
    """The six reported metrics (`METRICS`) from an accumulator's sums `s`."""
    return {
        "temporal_accuracy": _ratio(s["agree"], s["judged"]),
        "contact_iou": _ratio(s["intersection"], s["union"]),
        "volumetric_iou": _ratio(s["vol_min"], s["vol_max"]),
        "mae": _ratio(s["abs_left"] + s["abs_right"], s["cells_left"] + s["cells_right"]),
        "mae_left": _ratio(s["abs_left"], s["cells_left"]),
        "mae_right": _ratio(s["abs_right"], s["cells_right"]),
    }


def detection_metrics(sums: dict) -> dict[str, float]:
    """Per-frame contact precision, recall, F1 and support from an accumulator's sums; with no kept frame
    (every ground-truth frame all NaN) the three ratios are NaN and the support 0."""
    tp, fp, support = sums["tp"], sums["fp"], int(sums["tp"] + sums["fn"])
    if sums["judged"] == 0:
        return dict.fromkeys(DETECTION_METRICS[:3], float("nan")) | {"temporal_support": 0}
    precision, recall = _fraction(tp, tp + fp), _fraction(tp, support)
    return {"temporal_precision": precision, "temporal_recall": recall,
            "temporal_f1": _fraction(2 * precision * recall, precision + recall), "temporal_support": support}


def contact_events(flags: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(onsets, offsets): the positions t ≥ 1 of a bool sequence where it turns on / off at t."""
    change = np.flatnonzero(flags[1:] != flags[:-1]) + 1
    return change[flags[change]], change[~flags[change]]


def matched_events(predicted: np.ndarray, truth: np.ndarray, tolerance: int = EVENT_TOLERANCE) -> int:
    """How many predicted events (ascending positions) match: each, in order, takes the first not-yet-matched
    ground-truth event (ascending positions) within ±tolerance."""
    taken = np.zeros(len(truth), bool)
    for t in predicted:
        free = np.flatnonzero(~taken & (np.abs(truth - t) <= tolerance))
        if free.size:
            taken[free[0]] = True
    return int(np.count_nonzero(taken))


def event_metrics(pred_flags: np.ndarray, gt_flags: np.ndarray, tolerance: int = EVENT_TOLERANCE) -> dict[str, float]:
    """Onset / offset precision and recall, and the ground truth's event counts, from the contact flags of the
    kept frames in order; fewer than two frames → the ratios NaN and the counts 0."""
    if len(gt_flags) < 2:
        return dict.fromkeys(EVENT_METRICS[:4], float("nan")) | {"num_gt_onsets": 0, "num_gt_offsets": 0}
    out = {}
    for kind, predicted, truth in zip(("onset", "offset"), contact_events(pred_flags), contact_events(gt_flags)):
        matched = matched_events(predicted, truth, tolerance)
        out[f"{kind}_precision"] = _fraction(matched, len(predicted))
        out[f"{kind}_recall"] = _fraction(matched, len(truth))
        out[f"num_gt_{kind}s"] = len(truth)
    return {key: out[key] for key in EVENT_METRICS}


@dataclass
class MetricAccumulator:
    """Streaming sums of one trajectory's metrics, plus the contact flags of its kept frames (for the onset /
    offset metrics); `add` chunks of frames in order, then `result()`."""

    bend: np.ndarray
    threshold: float = CONTACT_THRESHOLD
    min_ratio: float = MIN_CONTACT_RATIO
    sums: dict = field(default_factory=lambda: {k: 0 for k in (
        "agree", "judged", "tp", "fp", "fn", "intersection", "union", "vol_min", "vol_max", "abs_left", "abs_right",
        "cells_left", "cells_right")})
    kept_flags: list[np.ndarray] = field(default_factory=list, repr=False)
    """One (2, K) bool array per chunk: [prediction, ground truth] contact flags of its K kept frames."""

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
        flags = self._contact_flags(valid, p_on, g_on)
        self.kept_flags.append(flags)
        p_flag, g_flag = flags
        s["agree"] += int(np.count_nonzero(p_flag == g_flag))
        s["judged"] += len(g_flag)
        s["tp"] += int(np.count_nonzero(p_flag & g_flag))
        s["fp"] += int(np.count_nonzero(p_flag & ~g_flag))
        s["fn"] += int(np.count_nonzero(~p_flag & g_flag))
        s["vol_min"] += float(np.minimum(p, g).sum(dtype=np.float64))
        s["vol_max"] += float(np.maximum(p, g).sum(dtype=np.float64))
        error = np.abs(p - g)
        for h, hand in enumerate(HANDS):
            s[f"abs_{hand}"] += float(error[:, h].sum(dtype=np.float64))
            s[f"cells_{hand}"] += int(np.count_nonzero(valid[:, h]))

    def _contact_flags(self, valid: np.ndarray, p_on: np.ndarray, g_on: np.ndarray) -> np.ndarray:
        """(2, K) bool: the prediction's and the ground truth's contact flags of the K kept frames (ground truth
        not all NaN), in order."""
        kept = valid.any(axis=(1, 2, 3))
        tactile = valid[kept] & ~self.bend[None]
        cells = tactile.sum(axis=(1, 2, 3))
        above = np.stack([(on[kept] & tactile).sum(axis=(1, 2, 3)) for on in (p_on, g_on)])
        return (cells > 0) & (above / np.maximum(cells, 1) >= self.min_ratio)

    def result(self) -> dict[str, float]:
        """Every metric of `ALL_METRICS`, in that order."""
        p_flags, g_flags = np.concatenate(self.kept_flags, axis=1) if self.kept_flags else np.zeros((2, 0), bool)
        return reported_metrics(self.sums) | detection_metrics(self.sums) | event_metrics(p_flags, g_flags)


def compute_tactile_metrics(pred: np.ndarray, gt: np.ndarray, bend: np.ndarray, threshold: float = CONTACT_THRESHOLD,
                            min_contact_ratio: float = MIN_CONTACT_RATIO) -> dict[str, float]:
    """Every metric of `ALL_METRICS` for one trajectory (all frames given have a prediction)."""
    accumulator = MetricAccumulator(bend, threshold, min_contact_ratio)
    accumulator.add(pred, gt)
    return accumulator.result()


def aggregate(rows: list[dict[str, float]]) -> dict[str, float]:
    """nanmean over trajectories, metric by metric for every key of `ALL_METRICS`, counts included (NaN when
    every trajectory is NaN)."""
    out = {}
    for key in ALL_METRICS:
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
