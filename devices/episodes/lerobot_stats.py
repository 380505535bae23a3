"""LeRobot's feature statistics (`meta/stats.json` and the `stats/<feature>/<stat>` columns of the episodes
metadata), computed as `lerobot` 0.4 computes them: per element over the frames (min, max, mean, std, count and
the 1, 10, 50, 90, 99 % quantiles), per colour channel on [0, 1] for videos (a sample of frames, shape (3, 1, 1)),
and aggregated over episodes by count-weighted means and pooled variances.

The tactile maps are NaN outside the layout: statistics are taken over the finite values, and an element that
never has one (a cell outside the layout) gets 0, so that the file is plain JSON and normalising by it is a no-op.
"""
from __future__ import annotations

import numpy as np

QUANTILES = (0.01, 0.10, 0.50, 0.90, 0.99)
QUANTILE_KEYS = tuple(f"q{round(q * 100):02d}" for q in QUANTILES)
VIDEO_SAMPLES = 100
"""Frames per episode whose pixels make a video feature's statistics (evenly spaced; LeRobot samples ~100)."""


def feature_stats(values: np.ndarray) -> dict[str, np.ndarray]:
    """Statistics of (frames, ...) values per element: each (...) shaped (a (1,) vector for scalars), count (1,)."""
    data = np.asarray(values, np.float64)
    if data.ndim == 1:
        data = data[:, None]
    finite = np.isfinite(data)
    with np.errstate(invalid="ignore", divide="ignore"):
        masked = np.where(finite, data, np.nan)
        any_finite = finite.any(axis=0)
        safe = np.where(any_finite, masked, 0.0)  # all-NaN columns: zeros instead of warnings and NaN
        stats = {"min": np.nanmin(safe, axis=0), "max": np.nanmax(safe, axis=0), "mean": np.nanmean(safe, axis=0),
                 "std": np.nanstd(safe, axis=0)}
        for key, q in zip(QUANTILE_KEYS, np.nanquantile(safe, QUANTILES, axis=0)):
            stats[key] = q
    stats = {k: np.where(any_finite, v, 0.0) for k, v in stats.items()}
    stats["count"] = np.array([len(data)], np.int64)
    return stats


def video_stats(frames: np.ndarray) -> dict[str, np.ndarray]:
    """Per-channel statistics of (N, H, W, 3) uint8 frames on [0, 1], each (3, 1, 1); count (1,) is N."""
    pixels = np.asarray(frames, np.float64).reshape(-1, 3) / 255.0
    stats = {"min": pixels.min(axis=0), "max": pixels.max(axis=0), "mean": pixels.mean(axis=0), "std": pixels.std(axis=0)}
    for key, q in zip(QUANTILE_KEYS, np.quantile(pixels, QUANTILES, axis=0)):
        stats[key] = q
    stats = {k: v.reshape(3, 1, 1) for k, v in stats.items()}
    stats["count"] = np.array([len(frames)], np.int64)
    return stats


def sample_indices(frames: int) -> np.ndarray:
    """The frames of an episode whose pixels go into a video feature's statistics."""
    return np.unique(np.round(np.linspace(0, frames - 1, min(frames, VIDEO_SAMPLES))).astype(int))


def aggregate(per_episode: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    """One feature's statistics over episodes: min of mins, max of maxes, count-weighted mean and quantiles
    (as LeRobot approximates them), pooled standard deviation."""
    counts = np.array([s["count"][0] for s in per_episode], np.float64)
    total = counts.sum()
    weights = counts.reshape((-1,) + (1,) * per_episode[0]["mean"].ndim) / total
    means = np.stack([s["mean"] for s in per_episode])
    mean = (weights * means).sum(axis=0)
    variance = (weights * (np.stack([s["std"] for s in per_episode]) ** 2 + (means - mean) ** 2)).sum(axis=0)
    out = {"min": np.min([s["min"] for s in per_episode], axis=0), "max": np.max([s["max"] for s in per_episode], axis=0),
           "mean": mean, "std": np.sqrt(variance), "count": np.array([int(total)], np.int64)}
    for key in QUANTILE_KEYS:
        out[key] = (weights * np.stack([s[key] for s in per_episode])).sum(axis=0)
    return out


def as_json(stats: dict[str, dict[str, np.ndarray]]) -> dict:
    """{feature: {stat: nested lists}} for `meta/stats.json`."""
    return {feature: {k: np.asarray(v).tolist() for k, v in values.items()} for feature, values in stats.items()}
