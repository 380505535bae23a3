"""The share of a result that vision carries: a run on the real frames against the pose-only baseline (the same
checkpoint and protocol with every camera frame black, `preprocess.blank_frames`).

For a score (higher is better): share = (real − blank) / max(real, blank); for an error (MAE, lower is
better): share = (blank − real) / max(real, blank). So the share lies in [−1, 1]:
- when the images help it is the part of the result that goes when they are blanked — (real − blank) / real
  for a score (1: the pose alone scores 0), the part of the pose-only error that the images remove for an
  error (1: no error left with them);
- 0: the images add nothing;
- when the model does better without its images it is minus the part of the pose-only result they cost
  (−1: the real run scores 0 where the pose alone does not).
All metrics are ≥ 0. Undefined (NaN, shown as n/a, never inf) when either value is missing or not finite, or
both are 0 (nothing to share). Counts of
ground-truth events (`COUNT_METRICS`) are the same in both runs and have no share.
"""
from __future__ import annotations

import math

from touchanything.inference.evaluation.metrics import ALL_METRICS, COUNT_METRICS, ERROR_METRICS

SHARE_METRICS = tuple(m for m in ALL_METRICS if m not in COUNT_METRICS)


def vision_share(real: float | None, blank: float | None, lower_is_better: bool = False) -> float:
    """The share in [−1, 1] defined above (for values ≥ 0); NaN when either value is missing or not finite, or
    both are 0."""
    if real is None or blank is None or not (math.isfinite(real) and math.isfinite(blank)):
        return math.nan
    scale = max(abs(real), abs(blank))
    if scale == 0:
        return math.nan
    gain = blank - real if lower_is_better else real - blank
    return gain / scale


def vision_shares(real: dict[str, float], blank: dict[str, float]) -> dict[str, float]:
    """{metric: share} for every metric of `SHARE_METRICS` in both (errors as lower-is-better)."""
    return {m: vision_share(real[m], blank[m], m in ERROR_METRICS) for m in SHARE_METRICS if m in real and m in blank}
