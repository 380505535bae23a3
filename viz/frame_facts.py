"""The facts every view of one frame shows, derived once: built per prediction (and per frame of a headless
replay) and read by the dashboard's panels, the comparison video, the replay summary and the Rerun recording,
so that no two of them decide differently.

Per hand: posed (the model predicted it: it had a valid pose), measured (the glove map has it), whether the
prediction and the measurement are "in contact" — the official per-frame contact rule applied to the hand on
its own: at least 5 % of its non-NaN, non-bend cells strictly above the contact threshold (official 0.1) —
None where that map is not there, and whether the two agree (None unless both are known). And the running
official metrics, each a number or None where undefined ("n/a").
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from touchanything.core.snapshot import HANDS
from touchanything.inference.evaluation.metrics import CONTACT_THRESHOLD, contact_frames
from touchanything.inference.evaluation.running_metrics import RunningMetrics

Metrics = dict[str, float | None]
"""Official metric → its value, None where undefined."""


def hand_contact(grids: np.ndarray, bend: np.ndarray, threshold: float = CONTACT_THRESHOLD) -> np.ndarray:
    """(2, 21, 21) grid (NaN outside the layout) → (2,) bool: the contact rule per hand (a hand without any
    valid cell is "no contact"; `FrameFacts` says "unknown" for it instead)."""
    return np.array([contact_frames(np.asarray(grids[h])[None, None], bend[h][None], threshold)[0] for h in range(2)])


def _defined(metrics: dict[str, float]) -> Metrics:
    """Metric values with NaN (undefined) as None."""
    return {key: None if value is None or math.isnan(value) else float(value) for key, value in metrics.items()}


def metric_text(value: float | None) -> str:
    """A metric with three decimals, or "n/a" when undefined (None or NaN)."""
    return "n/a" if value is None or math.isnan(value) else f"{value:.3f}"


@dataclass(frozen=True)
class HandFacts:
    """One hand at one frame (see the module)."""

    posed: bool
    measured: bool
    contact_predicted: bool | None
    contact_measured: bool | None

    @property
    def agree(self) -> bool | None:
        """Whether the predicted and the measured contact agree; None unless both are known."""
        if self.contact_predicted is None or self.contact_measured is None:
            return None
        return self.contact_predicted == self.contact_measured


@dataclass(frozen=True)
class FrameFacts:
    """predicted: there is a prediction (maps) of this frame; measured: there is ground truth for it; hands:
    [left, right]; rolling / cumulative: the running official metrics after this frame (None: no ground truth
    to measure against)."""

    predicted: bool
    measured: bool
    hands: tuple[HandFacts, HandFacts]
    rolling: Metrics | None = None
    cumulative: Metrics | None = None

    @property
    def posed(self) -> tuple[bool, bool]:
        """Per hand: the model predicted it."""
        return self.hands[0].posed, self.hands[1].posed

    @property
    def unposed(self) -> list[str]:
        """The names of the hands a prediction left out (no pose); empty without a prediction."""
        return [name for name, hand in zip(HANDS, self.hands) if self.predicted and not hand.posed]

    def contact(self, kind: str) -> np.ndarray:
        """(2,) float64 per hand, kind "predicted" or "measured": 1 in contact, 0 not, NaN unknown."""
        values = [getattr(hand, f"contact_{kind}") for hand in self.hands]
        return np.array([np.nan if value is None else float(value) for value in values])


def frame_facts(predicted: np.ndarray | None, hands_predicted: Sequence[bool] | None, measured: np.ndarray | None,
                bend: np.ndarray, threshold: float = CONTACT_THRESHOLD, metrics: RunningMetrics | None = None) -> FrameFacts:
    """The facts of one frame: `predicted` (2, 21, 21) or None (no prediction of this frame) with
    `hands_predicted` (None: each hand that has a value), `measured` (2, 21, 21) or None (no ground truth; an
    all-NaN hand is not measured), the `bend` mask, the contact `threshold`, and `metrics` as they stand after
    this frame (None: no ground truth to measure against)."""
    posed = [False, False] if predicted is None else _has_values(predicted) if hands_predicted is None else list(hands_predicted)
    present = [False, False] if measured is None else _has_values(measured)
    contact_p = hand_contact(predicted, bend, threshold) if predicted is not None else None
    contact_m = hand_contact(measured, bend, threshold) if measured is not None else None
    hands = tuple(HandFacts(posed=bool(posed[h]), measured=present[h],
                            contact_predicted=bool(contact_p[h]) if posed[h] else None,
                            contact_measured=bool(contact_m[h]) if present[h] else None) for h in range(2))
    return FrameFacts(predicted=predicted is not None, measured=measured is not None, hands=hands,
                      rolling=None if metrics is None else _defined(metrics.rolling()),
                      cumulative=None if metrics is None else _defined(metrics.cumulative()))


def _has_values(grids: np.ndarray) -> list[bool]:
    """Per hand of a (2, 21, 21) map: any cell is a number (not all NaN)."""
    return [not bool(np.isnan(grids[h]).all()) for h in range(2)]
