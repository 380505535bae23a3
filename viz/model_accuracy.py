"""The one held-out accuracy every view shows for the running model, and where it comes from.

Once the model is in the speed/accuracy atlas, the atlas says it: the V-IoU with its 95 % interval and the number
of held-out trajectories of the running setting's row, else (a setting the atlas did not measure) of the model's
reference setting's row (`bench_setting.reference_of`), said as such. Without atlas rows for the model, its
`model_card.json` says it ("model card: …", with the trajectory count where the card has one per split). So the
dashboard's header and its atlas line never show two numbers for one model.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from touchanything.inference.engine.engine_setting import EngineSetting
from touchanything.inference.evaluation.atlas import AtlasRow
from touchanything.inference.evaluation.bench_setting import reference_of
from touchanything.inference.model.model_card import SPLIT_NAMES, ModelCard


@dataclass(frozen=True)
class ModelAccuracy:
    """line: the accuracy with its source, for the model's line ("" when nothing is known); caption: the same
    number as the atlas panel's line ends ("V-IoU 0.595 in the atlas", "not in the atlas; …")."""

    line: str = ""
    caption: str = "not in the atlas"


def model_accuracy(setting: EngineSetting, rows: Sequence[AtlasRow], card: ModelCard | None) -> ModelAccuracy:
    """The accuracy of `setting` from `rows` (the atlas rows of this model's weights: none when the atlas did not
    measure them), else from `card` (see the module)."""
    own = _row(rows, setting)
    if own is not None:
        return ModelAccuracy(f"held-out {_atlas_viou(own)} (atlas)", f"V-IoU {own.volumetric_iou:.3f} in the atlas")
    reference = _row(rows, reference_of(setting))
    if reference is not None:
        name = reference.name
        return ModelAccuracy(f"held-out {_atlas_viou(reference)} (atlas, reference setting {name}: "
                             f"{setting.name()} is not in the atlas)",
                             f"not in the atlas; reference {name} V-IoU {reference.volumetric_iou:.3f}")
    scores = card_scores(card)
    if not scores:
        return ModelAccuracy()
    return ModelAccuracy(f"model card: held-out V-IoU {scores} objects{_card_count(card)}",
                         f"not in the atlas (model card: V-IoU {scores})")


def card_scores(card: ModelCard | None) -> str:
    """"0.65 seen / 0.55 unseen": the card's held-out V-IoU per split ("" without a card or a V-IoU)."""
    return " / ".join(f"{values['volumetric_iou']:.2f} {SPLIT_NAMES.get(split, split)}"
                      for split, values in _scored(card).items())


def _card_count(card: ModelCard) -> str:
    """" on N held-out trajectories" when every scored split of the card gives its count (`trajectories`), else ""."""
    counts = [values.get("trajectories") for values in _scored(card).values()]
    return f" on {sum(int(c) for c in counts)} held-out trajectories" if all(counts) else ""


def _scored(card: ModelCard | None) -> dict[str, dict[str, float]]:
    """The card's held-out splits that give a finite V-IoU."""
    return {split: values for split, values in (card.held_out if card else {}).items()
            if math.isfinite(values.get("volumetric_iou", math.nan))}


def _row(rows: Sequence[AtlasRow], setting: EngineSetting) -> AtlasRow | None:
    """The row of `setting` (by name: the device is not part of it), or None."""
    return next((row for row in rows if row.name == setting.name()), None)


def _atlas_viou(row: AtlasRow) -> str:
    """"V-IoU 0.595 [0.571, 0.619] on 108 held-out trajectories"."""
    low, high = row.volumetric_iou_ci95
    return f"V-IoU {row.volumetric_iou:.3f} [{low:.3f}, {high:.3f}] on {row.trajectories} held-out trajectories"
