"""LeRobot's feature statistics (`meta/stats.json` and the `stats/<feature>/<stat>` columns of the episodes
metadata), computed exactly as `lerobot` 0.6.1 computes them (`lerobot/datasets/compute_stats.py`, Apache-2.0,
ported here because LeRobot cannot share this project's Python; `benchmarks/lerobot_compat.py` compares the two).

Per episode (`compute_episode_stats`): a numeric feature's (frames, ...) values are reduced over every axis but
the last (min, max, mean, std and the 1, 10, 50, 90, 99 % quantiles, in float32 for float and bool values, float64
for integers; quantiles from a 5000-bin histogram between min and max, interpolated within the bin); count is the
number of frames. A video feature's statistics are per colour channel on [0, 1] over ~100 evenly spaced frames
(every frame of an episode under 100), each (3, 1, 1), frames over 300 pixels wide subsampled to ~150; count is
the number of frames sampled. Over episodes (`aggregate_stats`): min of mins, max of maxes, count-weighted means
(quantiles too) and the pooled standard deviation.
"""
from __future__ import annotations

import numpy as np

QUANTILES = (0.01, 0.10, 0.50, 0.90, 0.99)
QUANTILE_KEYS = tuple(f"q{int(q * 100):02d}" for q in QUANTILES)
HISTOGRAM_BINS = 5000


def _quantile(histogram: np.ndarray, edges: np.ndarray, target: float) -> float:
    """LeRobot's `_compute_single_quantile`: the value below which `target` of the counted values lie."""
    cumulative = np.cumsum(histogram)
    index = np.searchsorted(cumulative, target)
    if index == 0:
        return edges[0]
    if index >= len(cumulative):
        return edges[-1]
    before = cumulative[index - 1]
    inside = cumulative[index] - before
    if inside == 0:
        return edges[index]
    return edges[index] + (target - before) / inside * (edges[index + 1] - edges[index])


def vector_stats(rows: np.ndarray, count: int) -> dict[str, np.ndarray]:
    """Statistics of (n, d) `rows` per column (LeRobot's `RunningQuantileStats` after one update, or its
    `_compute_basic_stats` under 2 rows); `count`: the number of frames they came from."""
    if len(rows) < 2:  # LeRobot computes these in the values' own type
        mean = np.mean(rows, axis=0)
        stats = {"min": np.min(rows, axis=0), "max": np.max(rows, axis=0), "mean": mean, "std": np.std(rows, axis=0)}
        return {**stats, "count": np.array([count]), **{key: mean.copy() for key in QUANTILE_KEYS}}
    batch = rows.astype(np.result_type(rows.dtype, np.float32), copy=False)
    low, high = np.min(batch, axis=0), np.max(batch, axis=0)
    mean = np.mean(batch, axis=0)
    variance = np.mean(batch**2, axis=0) - mean**2
    stats = {"min": low, "max": high, "mean": mean, "std": np.sqrt(np.maximum(0, variance)), "count": np.array([count])}
    columns = []
    for i in range(batch.shape[1]):
        edges = np.linspace(low[i] - 1e-10, high[i] + 1e-10, HISTOGRAM_BINS + 1)
        columns.append((np.histogram(batch[:, i], bins=edges)[0].astype(np.float64), edges))
    for key, q in zip(QUANTILE_KEYS, QUANTILES):
        stats[key] = np.array([_quantile(histogram, edges, q * len(batch)) for histogram, edges in columns])
    return stats


def feature_stats(values: np.ndarray) -> dict[str, np.ndarray]:
    """A numeric feature's statistics over an episode's (frames, ...) values: each of shape (last axis,), (1,)
    for scalars."""
    values = np.asarray(values)
    rows = values.reshape(-1, 1) if values.ndim == 1 else values.reshape(-1, values.shape[-1])
    stats = vector_stats(rows, len(values))
    return stats if values.ndim > 1 else {k: v.reshape(1) if k != "count" else v for k, v in stats.items()}


def sample_indices(frames: int) -> np.ndarray:
    """The frames of an episode whose pixels go into a video feature's statistics (LeRobot's `sample_indices`)."""
    samples = max(min(frames, 100), min(int(frames**0.75), 10_000))
    return np.round(np.linspace(0, frames - 1, samples)).astype(int)


def video_stats(frames: np.ndarray) -> dict[str, np.ndarray]:
    """Per-channel statistics of sampled (N, H, W, 3) uint8 frames on [0, 1], each (3, 1, 1); count (1,) is N."""
    frames = np.asarray(frames)
    height, width = frames.shape[1:3]
    if max(width, height) >= 300:  # LeRobot's `auto_downsample_height_width`
        step = int(width / 150) if width > height else int(height / 150)
        frames = frames[:, ::step, ::step]
    stats = vector_stats(frames.reshape(-1, 3), len(frames))
    return {k: v if k == "count" else (v / 255.0).reshape(3, 1, 1) for k, v in stats.items()}


def aggregate(per_episode: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    """One feature's statistics over episodes (LeRobot's `aggregate_feature_stats`)."""
    means = np.stack([s["mean"] for s in per_episode])
    counts = np.stack([s["count"] for s in per_episode])
    total = counts.sum(axis=0)
    while counts.ndim < means.ndim:
        counts = np.expand_dims(counts, axis=-1)
    mean = (means * counts).sum(axis=0) / total
    variances = np.stack([s["std"] ** 2 for s in per_episode])
    variance = ((variances + (means - mean) ** 2) * counts).sum(axis=0) / total
    out = {"min": np.min(np.stack([s["min"] for s in per_episode]), axis=0),
           "max": np.max(np.stack([s["max"] for s in per_episode]), axis=0),
           "mean": mean, "std": np.sqrt(variance), "count": total}
    for key in QUANTILE_KEYS:
        out[key] = (np.stack([s[key] for s in per_episode]) * counts).sum(axis=0) / total
    return out


def as_json(stats: dict[str, dict[str, np.ndarray]]) -> dict:
    """{feature: {stat: nested lists}} for `meta/stats.json`."""
    return {feature: {k: np.asarray(v).tolist() for k, v in values.items()} for feature, values in stats.items()}
