"""The settings `bench` measures for a model (`EngineSetting`s: the one record and name every part shares) and
the reference each is compared with."""
from __future__ import annotations

import dataclasses

from touchanything.core.view_sets import VIEW_SETS
from touchanything.inference.engine.engine_setting import OUTPUTS, EngineSetting

PARTIAL_VIEWS = (VIEW_SETS["ego"], VIEW_SETS["ego+left"], VIEW_SETS["ego+right"])
RATES = (2, 3)
"""The prediction rates (every k-th frame) the full grid measures besides every frame."""


ENSEMBLE_SIZES = (2, 4, 8)
"""The ensemble sizes (members) the grid measures, those a model's ensemble has enough members for."""


def settings_for(model: str, quick: bool, pose_only: bool = False, members: int = 1) -> list[EngineSetting]:
    """The reference (torch fp32, all views, newest frame, on the CPU) first, then one knob at a time around it:
    precision and runtime, the partial view sets (torch fp32 and ONNX int8), the prediction rates (ONNX int8)
    and the look-ahead output positions (torch fp32); `quick`: the reference and ONNX int8 only. A model whose
    ensemble has `members` > 1 adds torch fp32 and ONNX int8 at each of `ENSEMBLE_SIZES` up to `members` (and
    all of them). With `pose_only`, each followed by its pose-only twin (`blank`)."""
    base = EngineSetting(model, device="cpu")
    int8 = base.with_tier("onnx-int8")
    settings = [base, int8] if quick else (
        [base, base.with_tier("torch-bf16"), base.with_tier("onnx-fp32"), int8]
        + [dataclasses.replace(s, views=v) for s in (base, int8) for v in PARTIAL_VIEWS]
        + [dataclasses.replace(int8, every=k) for k in RATES]
        + [dataclasses.replace(base, output=o) for o in OUTPUTS[1:]])
    sizes = sorted({k for k in ENSEMBLE_SIZES if k <= members} | ({members} if members > 1 else set()))
    settings += [dataclasses.replace(s, members=k) for k in sizes for s in (base, int8)]
    return [t for s in settings for t in ((s, dataclasses.replace(s, blank=True)) if pose_only else (s,))]


def reference_of(setting: EngineSetting) -> EngineSetting:
    """The setting its accuracy is compared with: the same model's torch fp32, all views, newest frame."""
    return EngineSetting(setting.model, device=setting.device, blank=setting.blank)
