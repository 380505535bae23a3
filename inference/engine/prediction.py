"""The Prediction record: what the streaming engine says about one frame."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(kw_only=True)
class Prediction:
    """The engine's output for frame `frame_index` (built with keywords only).

    t_us: that frame's capture time (host monotonic µs); latency_ms = prediction time − t_us, so it
        includes any look-ahead of the output position.
    pressure: (2, 21, 21) float32 in [0, 1] [left, right], NaN outside the hand layout; a hand that was not
        predicted (no valid pose) holds 0 inside the layout ("no contact", as the metrics count it).
        None when there is no prediction (no ego view); `status` says why.
    hands_predicted: (left, right) — False shows as "no pose".
    views_used: the views whose frames built the output frame's tokens.
    timings_ms: per-stage engine time for this step (preprocess, encode, head, total); a stage that was
        skipped is absent.
    window_exact: every frame of the 8-frame window was the ideal one (no drops, no start padding).
    held: True when this frame was not computed (prediction every k-th frame) and repeats the last one.
    spread: an ensemble's (`EngineSetting.members` > 1) per-cell standard deviation of its members' pressures
        (population, ddof 0), (2, 21, 21) float32 ≥ 0, NaN where `pressure` is NaN; None for a single model
        and when `pressure` is None.
    """

    frame_index: int
    t_us: int
    pressure: np.ndarray | None
    hands_predicted: tuple[bool, bool]
    views_used: tuple[str, ...]
    latency_ms: float
    timings_ms: dict[str, float] = field(default_factory=dict)
    status: str = "ok"
    window_exact: bool = True
    held: bool = False
    spread: np.ndarray | None = None
