"""How much of a data set's contact the hand pose alone cannot decide, and how noisy that pose is.

Definition (per data set, per hand side): a hand-frame is one hand in one frame whose WiLoR pose is valid;
its pose is the hand's 21 true joints in the head-camera frame (metres). The pose tolerance τ is the median,
over all hand-frames, of the RMS joint distance between the pose the model reads (`wilor_hands.json`, depth
scaling undone) and the truth. A contact hand-frame (a tactile cell above 0.1), taken every fifth frame, is
**pose-ambiguous** when some no-contact hand-frame of the same side has a true pose within τ of it (RMS joint
distance ≤ τ) — in another episode, or in the same one at least 15 frames (0.5 s, the span of the model's
clip) away: the pose the model gets cannot tell the two apart, and its clip cannot hold both. (Frames
closer than that, such as the moment before a touch, are left out.)
"""
from __future__ import annotations

import numpy as np

from touchanything.core.snapshot import HANDS
from touchanything.devices.sim.episode_stats import EpisodeStats

SAMPLE_EVERY = 5
APART = 15
CHUNK = 256
OCCLUDED = 0.25
"""A hand-frame with more than this share of its joints hidden from the head camera counts as occluded."""


def nearest_rms(queries: np.ndarray, pool: np.ndarray, query_keys: np.ndarray, pool_keys: np.ndarray) -> np.ndarray:
    """(Q,) the smallest RMS joint distance (metres) from each (Q, 21, 3) query pose to a (P, 21, 3) pool pose,
    leaving out the pool poses of the same episode fewer than `APART` frames away; keys (N, 2) are (episode,
    frame). inf where no pool pose is left."""
    if len(pool) == 0 or len(queries) == 0:
        return np.full(len(queries), np.inf)
    q = queries.reshape(len(queries), 63).astype(np.float64)
    p = pool.reshape(len(pool), 63).astype(np.float64)
    p_norm = np.einsum("ij,ij->i", p, p)
    out = np.empty(len(q))
    for start in range(0, len(q), CHUNK):
        block, keys = q[start:start + CHUNK], query_keys[start:start + CHUNK]
        squared = np.einsum("ij,ij->i", block, block)[:, None] + p_norm[None] - 2.0 * block @ p.T
        near = (keys[:, :1] == pool_keys[None, :, 0]) & (np.abs(keys[:, 1:] - pool_keys[None, :, 1]) < APART)
        squared[near] = np.inf
        out[start:start + CHUNK] = np.sqrt(np.maximum(squared.min(axis=1), 0.0) / 21.0)
    return out


def _share(hit: int, count: int) -> float | None:
    return hit / count if count else None


def pose_statistics(results: list[EpisodeStats]) -> dict:
    """The card's `pose_error` (mm: median, 90th percentile, visible and occluded hands' medians) and
    `pose_ambiguity` (tolerance in mm, sampled contact hand-frames, ambiguous share, and per hand and task)."""
    valid = np.concatenate([s.pose_valid for s in results])
    error = np.concatenate([s.pose_error for s in results])[valid]
    hidden = np.concatenate([s.hidden for s in results])[valid]
    if error.size == 0:
        return {"pose_error_mm": None, "pose_ambiguity": None}
    tolerance = float(np.median(error))
    per_task: dict[str, list[int]] = {}
    total = [0, 0]
    for h, side in enumerate(HANDS):
        free, free_keys, queries, query_keys, labels = [], [], [], [], []
        for e, stats in enumerate(results):
            frames = np.arange(stats.frames)
            free_mask = stats.pose_valid[:, h] & ~stats.touching[:, h]
            chosen = (frames % SAMPLE_EVERY == 0) & stats.pose_valid[:, h] & stats.touching[:, h]
            free.append(stats.poses[free_mask, h])
            free_keys.append(np.stack([np.full(free_mask.sum(), e), frames[free_mask]], axis=1))
            queries.append(stats.poses[chosen, h])
            query_keys.append(np.stack([np.full(chosen.sum(), e), frames[chosen]], axis=1))
            labels += [f"{side}/{label}" for label in stats.labels[chosen, h]]
        nearest = nearest_rms(*(np.concatenate(a) for a in (queries, free, query_keys, free_keys)))
        ambiguous = nearest <= tolerance
        for label, hit in zip(labels, ambiguous):
            entry = per_task.setdefault(label, [0, 0])
            entry[0] += int(hit)
            entry[1] += 1
        total[0] += int(ambiguous.sum())
        total[1] += len(ambiguous)
    mm = 1000.0
    return {
        "pose_error_mm": {
            "median": round(tolerance * mm, 1), "p90": round(float(np.percentile(error, 90)) * mm, 1),
            "visible_hand_median": _median_mm(error[hidden <= OCCLUDED]),
            "occluded_hand_median": _median_mm(error[hidden > OCCLUDED]),
        },
        "pose_ambiguity": {
            "tolerance_mm": round(tolerance * mm, 1), "contact_frames": total[1], "ambiguous_share": _share(*total),
            "by_hand_and_task": {k: {"contact_frames": n, "ambiguous_share": _share(hit, n)} for k, (hit, n) in sorted(per_task.items())},
        },
    }


def _median_mm(values: np.ndarray) -> float | None:
    return round(float(np.median(values)) * 1000.0, 1) if values.size else None
