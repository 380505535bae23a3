"""One engine setting of the speed/accuracy atlas: which model, runtime, precision, views, prediction rate and
output position, and its name — the one spelling the bench's rows, `bench --budget-ms`, and the `--setting`
option of `replay`, `live` and `demo` share.

A name is `MODEL/RUNTIME-PRECISION/VIEWS` followed by the knobs that differ from the default, each as its own
part: `/everyK` (predict every k-th frame), `/centre` or `/stitched` (output position), `/official-invalid`
(invalid hands fed as the official −10), `/eager` (no CUDA graphs), `/pose-only` (every frame black). VIEWS is
the official view configuration (`ego`, `ego+left`, `ego+right`, `all`). Examples: `nano/onnx-int8/all`,
`nano/torch-fp32/ego+left`, `nano/onnx-int8/all/every2`, `tiny/torch-fp32/all/stitched`.
"""
from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass
from pathlib import Path

from touchanything.devices.errors import UserError
from touchanything.devices.snapshot import VIEW_NAMES
from touchanything.devices.view_sets import VIEW_SETS, view_set_name
from touchanything.inference.engine.engine_config import OUTPUTS, RUNTIMES, EngineConfig

LOOKAHEAD_FRAMES = {"newest": 0, "centre": 6, "stitched": 14}
"""Frames an output position waits for after the frame it predicts (at 30 fps)."""
PARTIAL_VIEWS = (VIEW_SETS["ego"], VIEW_SETS["ego+left"], VIEW_SETS["ego+right"])
RATES = (2, 3)
"""The prediction rates (every k-th frame) the full grid measures besides every frame."""
NAME_HELP = ("MODEL/RUNTIME-PRECISION/VIEWS[/everyK][/centre|/stitched], e.g. nano/onnx-int8/all or "
             "nano/torch-fp32/ego+left")
_EVERY = re.compile(r"every([1-9][0-9]*)")


@dataclass(frozen=True)
class BenchSetting:
    model: str
    runtime: str = "torch"
    precision: str = "fp32"
    views: tuple[str, ...] = VIEW_NAMES
    rate: int = 1
    output: str = "newest"
    invalid_hands: str = "skip"
    device: str = "cpu"
    capture: bool = True
    blank: bool = False

    def name(self) -> str:
        """The setting's name (module docstring)."""
        parts = [self.model, f"{self.runtime}-{self.precision}", view_set_name(self.views)]
        parts += [f"every{self.rate}"] if self.rate > 1 else []
        parts += [self.output] if self.output != "newest" else []
        parts += ["official-invalid"] if self.invalid_hands == "official" else []
        parts += ["eager"] if not self.capture else []
        parts += ["pose-only"] if self.blank else []
        return "/".join(parts)

    def engine_config(self, onnx_dir: Path | None) -> EngineConfig:
        return EngineConfig(runtime=self.runtime, precision=self.precision, onnx_dir=onnx_dir, views=self.views,
                            output=self.output, every=self.rate, invalid_hands=self.invalid_hands, device=self.device,
                            capture=self.capture)

    @property
    def lookahead_ms(self) -> float:
        return LOOKAHEAD_FRAMES[self.output] * 1000 / 30


def parse_setting(text: str) -> BenchSetting:
    """The setting a name names; UserError saying which part is wrong."""
    parts = text.strip().split("/")
    if len(parts) < 3 or not parts[0]:
        raise UserError(f"setting {text!r} is not a setting name ({NAME_HELP})")
    model, tier, views, *knobs = parts
    runtime, _, precision = tier.partition("-")
    if precision not in RUNTIMES.get(runtime, ()):
        tiers = ", ".join(f"{r}-{p}" for r, precisions in RUNTIMES.items() for p in precisions)
        raise UserError(f"setting {text!r}: unknown runtime-precision {tier!r} ({tiers})")
    if views not in VIEW_SETS:
        raise UserError(f"setting {text!r}: unknown views {views!r}; choose from {', '.join(VIEW_SETS)}")
    setting = BenchSetting(model, runtime, precision, VIEW_SETS[views])
    for knob in knobs:
        if match := _EVERY.fullmatch(knob):
            setting = dataclasses.replace(setting, rate=int(match.group(1)))
        elif knob in OUTPUTS[1:]:
            setting = dataclasses.replace(setting, output=knob)
        elif knob == "official-invalid":
            setting = dataclasses.replace(setting, invalid_hands="official")
        elif knob == "eager":
            setting = dataclasses.replace(setting, capture=False)
        elif knob == "pose-only":
            setting = dataclasses.replace(setting, blank=True)
        else:
            raise UserError(f"setting {text!r}: unknown part {knob!r} ({NAME_HELP})")
    if setting.name() != text.strip():
        raise UserError(f"setting {text!r} is not written the canonical way; did you mean {setting.name()}?")
    return setting


def settings_for(model: str, quick: bool, pose_only: bool = False) -> list[BenchSetting]:
    """The reference (torch fp32, all views, newest frame) first, then one knob at a time around it: precision
    and runtime, the partial view sets (torch fp32 and ONNX int8), the prediction rates (ONNX int8) and the
    look-ahead output positions (torch fp32); `quick`: the reference and ONNX int8 only. With `pose_only`,
    each followed by its pose-only twin (`blank`)."""
    base = BenchSetting(model)
    int8 = dataclasses.replace(base, runtime="onnx", precision="int8")
    settings = [base, int8] if quick else (
        [base, dataclasses.replace(base, precision="bf16"), dataclasses.replace(base, runtime="onnx"), int8]
        + [dataclasses.replace(s, views=v) for s in (base, int8) for v in PARTIAL_VIEWS]
        + [dataclasses.replace(int8, rate=k) for k in RATES]
        + [dataclasses.replace(base, output=o) for o in OUTPUTS[1:]])
    return [t for s in settings for t in ((s, dataclasses.replace(s, blank=True)) if pose_only else (s,))]


def reference_of(setting: BenchSetting) -> BenchSetting:
    """The setting its accuracy is compared with: the same model's torch fp32, all views, newest frame."""
    return BenchSetting(setting.model, device=setting.device, blank=setting.blank)
