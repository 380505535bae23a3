"""Whether a setting chosen for a latency budget (`--setting auto --budget-ms MS`) keeps it while it runs: the
picker probed it for a moment on the bundled sample; the run itself can be slower (a busier machine, another
episode). Said during the run, once, when the engine's p99 step time so far goes over the budget, and after it."""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

CHECK_EVERY = 30
"""Frames between two checks of the running p99 (one second of 30 fps content)."""
MIN_STEPS = 60
"""Steps needed before a running p99 is judged (the first ones include warm-up)."""


@dataclass
class BudgetWatch:
    """`budget_ms`: the budget the setting was chosen for; `probed_ms`: its p99 when the picker probed it."""

    setting: str
    budget_ms: float
    probed_ms: float
    said: str = field(default="", init=False)
    """The overrun line once said ("" before)."""

    def during(self, step_ms: Sequence[float]) -> str | None:
        """The line to say now (once, every `CHECK_EVERY` steps from `MIN_STEPS` on) when the p99 of `step_ms`
        (the engine's step times so far, ms) is over the budget; else None."""
        if self.said or len(step_ms) < MIN_STEPS or len(step_ms) % CHECK_EVERY:
            return None
        return self.over(float(np.percentile(step_ms, 99)))

    def over(self, p99: float | None) -> str | None:
        """The line to say (once) when the running p99 step time `p99` (ms; None: not known yet) is over the budget."""
        if self.said or p99 is None or p99 <= self.budget_ms:
            return None
        self.said = (f"over budget: {self.setting} steps at p99 {p99:.2f} ms so far, over the {self.budget_ms:g} ms it "
                     f"was chosen for (probed {self.probed_ms:.2f} ms)")
        return self.said

    def after(self, p99: float | None) -> str:
        """The summary line: the run's p99 step time `p99` (ms) against the budget ("" when None: no step)."""
        if p99 is None:
            return ""
        verdict = "within" if p99 <= self.budget_ms else "OVER"
        return (f"budget    p99 {p99:.2f} ms per engine step in this run: {verdict} the {self.budget_ms:g} ms budget "
                f"(probed {self.probed_ms:.2f} ms before the run)")
