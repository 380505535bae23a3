"""The one record every panel of a drawn dashboard frame comes from (`ShownFrame`): the dashboard replaces it in
one step, so the maps, titles, lamps, metrics and the head camera's discs never mix two predictions."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from touchanything.core.snapshot import Snapshot
from touchanything.inference.engine.prediction import Prediction
from touchanything.viz.frame_facts import FrameFacts


@dataclass(frozen=True)
class ShownFrame:
    """What every panel of a drawn frame comes from: the session's published snapshot and prediction (with the
    prediction's truth and facts), the views the model uses, the running engine's ensemble members and the
    display settings the maps are drawn with (contact threshold, outline, spread). The dashboard replaces it in
    one step."""

    snapshot: Snapshot | None = None
    prediction: Prediction | None = None
    truth: np.ndarray | None = None
    facts: FrameFacts | None = None
    views_used: tuple[str, ...] = ()
    members: int = 1
    settings: tuple[float, bool, bool] = (0.0, False, False)

    def new_cameras(self, shown: ShownFrame) -> bool:
        """The camera images differ from `shown`'s: another snapshot or other views used."""
        return self.snapshot is not shown.snapshot or self.views_used != shown.views_used

    def new_maps(self, shown: ShownFrame) -> bool:
        """What the prediction decides (maps, titles, lamps, metrics, legends, the head camera's discs) differs
        from `shown`'s: another prediction, truth or facts, or other settings."""
        return (self.prediction is not shown.prediction or self.truth is not shown.truth
                or self.facts is not shown.facts or (self.members, self.settings) != (shown.members, shown.settings))
