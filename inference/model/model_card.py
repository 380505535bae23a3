"""What a checkpoint is, in one line for the screen: `model_card.json` beside a bundled checkpoint.

The card names the model, the data it was trained on and its held-out accuracy (official metrics, all views,
causal newest-frame predictions, per test split), and whether it was trained on black frames (pose only).
`scripts/bundle_model.py` writes it from `touchanything eval` results; the dashboard's model line, the replay
summary and the comparison video show `ModelCard.summary()`. A checkpoint without a card is named by its path.
"""
from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path

from touchanything.core.output_safety import write_text

CARD_FILE = "model_card.json"
SPLIT_NAMES = {"test_seen": "seen", "test_unseen": "unseen"}


@dataclass(frozen=True)
class ModelCard:
    """name: e.g. "nano"; trained_on: where the training data came from ("simulated EgoTouch world, 162
    episodes"); held_out: {split: {metric: value}} (volumetric_iou, contact_iou, …); pose_only: trained on
    black frames."""

    name: str
    trained_on: str
    held_out: dict[str, dict[str, float]] = field(default_factory=dict)
    pose_only: bool = False

    @property
    def simulated(self) -> bool:
        return "simulated" in self.trained_on

    def summary(self) -> str:
        """"nano — trained on simulated data; held-out V-IoU 0.55 seen / 0.53 unseen objects"."""
        where = "simulated data" if self.simulated else self.trained_on
        scores = [f"{values['volumetric_iou']:.2f} {SPLIT_NAMES.get(split, split)}"
                  for split, values in self.held_out.items()
                  if isinstance(values.get("volumetric_iou"), float) and math.isfinite(values["volumetric_iou"])]
        held = f"; held-out V-IoU {' / '.join(scores)}{' objects' if scores else ''}" if scores else ""
        return f"{self.name}{' (pose only)' if self.pose_only else ''} — trained on {where}{held}"


def read_card(checkpoint: Path) -> ModelCard | None:
    """The card beside `checkpoint`, or None when there is none or it cannot be read (a card only labels the
    model; a broken one is ignored rather than stopping a replay)."""
    path = Path(checkpoint).parent / CARD_FILE
    try:
        data = json.loads(path.read_text())
        return ModelCard(name=str(data["name"]), trained_on=str(data["trained_on"]),
                         held_out={str(k): {str(m): float(v) for m, v in d.items()} for k, d in data.get("held_out", {}).items()},
                         pose_only=bool(data.get("pose_only", False)))
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return None


def write_card(folder: Path, card: ModelCard) -> Path:
    """Write `card` as the folder's model card (through the output rule: a temporary file renamed into place)."""
    path = Path(folder) / CARD_FILE
    write_text(path, json.dumps(asdict(card), indent=1) + "\n")
    return path
