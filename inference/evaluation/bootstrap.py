"""95 % bootstrap intervals for the official across-trajectory mean (`metrics.aggregate`: the mean of the
per-trajectory values, NaN ones left out), for one setting and for the paired difference of two settings
measured on the same trajectories.

Trajectories are drawn with replacement within each stratum (the held-out split a trajectory comes from, so
that seen and unseen objects keep their shares), `RESAMPLES` times from a fixed seed; the interval is the 2.5th
and 97.5th percentile of the resampled means (the percentile bootstrap). One `Resampler` serves every setting
of a run, so a difference is paired: each draw's mean of one setting minus the same draw's mean of the other,
which cancels what the two share (how hard the drawn trajectories are) and keeps what differs.
"""
from __future__ import annotations

import warnings
from collections.abc import Sequence

import numpy as np

RESAMPLES = 2000
SEED = 0
INTERVAL_PERCENTILES = (2.5, 97.5)
FEW_TRAJECTORIES = 20
"""Below this many trajectories (in all, or in one split) an interval is wide and unreliable; the bench says so."""


def thin_strata(strata: Sequence[str]) -> str:
    """"" when every stratum (split) has at least `FEW_TRAJECTORIES` trajectories, else one sentence naming those
    that have fewer ("only 6 test_unseen trajectories: their intervals are wide and unreliable; …")."""
    counts: dict[str, int] = {}
    for label in strata:
        counts[label] = counts.get(label, 0) + 1
    thin = [f"{n} {label}" for label, n in counts.items() if n < FEW_TRAJECTORIES]
    if not thin:
        return ""
    return (f"only {' and '.join(thin)} trajectories: their intervals are wide and unreliable (a bootstrap over fewer "
            f"than {FEW_TRAJECTORIES} trajectories understates the spread; e.g. data/heldout from "
            "scripts/make_datasets.sh has 67 and 41)")


class Resampler:
    """Fixed bootstrap draws of the trajectories 0…n−1 whose strata are `strata` (n labels)."""

    def __init__(self, strata: Sequence[str], resamples: int = RESAMPLES, seed: int = SEED) -> None:
        labels = np.asarray(list(strata), dtype=object)
        rng = np.random.default_rng(seed)
        self.size = len(labels)
        self.indices = np.empty((resamples, self.size), np.int64)
        column = 0
        for label in sorted(set(labels.tolist())):
            members = np.flatnonzero(labels == label)
            self.indices[:, column:column + members.size] = members[rng.integers(0, members.size, (resamples, members.size))]
            column += members.size

    def _means(self, values: np.ndarray) -> np.ndarray:
        """(RESAMPLES,) nanmean of every draw (NaN for a draw with no finite value)."""
        drawn = np.asarray(values, np.float64)[self.indices]
        counts = np.isfinite(drawn).sum(axis=1)
        sums = np.where(np.isfinite(drawn), drawn, 0.0).sum(axis=1)
        return np.divide(sums, counts, out=np.full(len(drawn), np.nan), where=counts > 0)

    def interval(self, values: Sequence[float]) -> tuple[float, float, float]:
        """(mean, low, high): the nanmean of `values` (one per trajectory) and its 95 % interval; all NaN when
        no value is finite."""
        values = self._checked(values)
        return _mean(values), *_percentiles(self._means(values))

    def difference(self, a: Sequence[float], b: Sequence[float]) -> tuple[float, float, float]:
        """(mean(a) − mean(b), low, high): the paired difference of two settings' per-trajectory values."""
        a, b = self._checked(a), self._checked(b)
        return _mean(a) - _mean(b), *_percentiles(self._means(a) - self._means(b))

    def _checked(self, values: Sequence[float]) -> np.ndarray:
        values = np.asarray(values, np.float64)
        if values.shape != (self.size,):
            raise ValueError(f"expected {self.size} per-trajectory values, got shape {values.shape}")
        return values


def _mean(values: np.ndarray) -> float:
    finite = values[np.isfinite(values)]
    return float(finite.mean()) if finite.size else float("nan")


def _percentiles(draws: np.ndarray) -> tuple[float, float]:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # every draw NaN: the interval is NaN
        low, high = np.nanpercentile(draws, INTERVAL_PERCENTILES)
    return float(low), float(high)
