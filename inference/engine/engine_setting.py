"""One engine setting — the one record every part of the project names a streaming engine by: the CLI
(`--setting`, `--runtime`, `--precision`, `--views`), the dashboard's switches, `bench` and its atlas rows,
the budget picker, the summaries and Rerun. Adding a knob means adding it here: its field, its part of the
name, its check.

A name is `MODEL/RUNTIME-PRECISION/VIEWS` followed by the knobs that differ from the default, each as its own
part: `/everyK` (predict every k-th frame), `/centre` or `/stitched` (output position), `/official-invalid`
(invalid hands fed as the official −10), `/eager` (no CUDA graphs), `/pose-only` (every frame black),
`/membersK` (the mean of an ensemble's first K members, `ensemble_engine`). VIEWS is
the official view configuration (`ego`, `ego+left`, `ego+right`, `all`). Examples: `pico/onnx-int8/all`,
`pico/torch-fp32/ego+left`, `pico/onnx-int8/all/every2`, `nano/torch-fp32/all/stitched`, `pico/onnx-int8/all/members4`. The device is where
the setting runs, not part of its name.

Pure configuration: a setting is checked when it is made (`__post_init__`, UserError naming the bad field);
whether its device is here is `resolved_device()` (it imports torch). torch is imported where used: `--help` loads this.
"""
from __future__ import annotations

import dataclasses
import os
import re
from dataclasses import dataclass
from typing import TYPE_CHECKING

from touchanything.core.errors import UserError
from touchanything.core.snapshot import VIEW_NAMES
from touchanything.core.view_sets import VIEW_SETS, view_set_name
from touchanything.inference.model.torch_device import check_precision, resolve_device

if TYPE_CHECKING:
    import torch

RUNTIMES = {"torch": ("fp32", "bf16", "fp16", "tf32"), "onnx": ("fp32", "int8")}
"""Runtime → the precisions it offers (torch fp16 and tf32 on a CUDA GPU only)."""
TIERS = tuple(f"{runtime}-{precision}" for runtime, precisions in RUNTIMES.items() for precision in precisions)
"""Every runtime-precision pair, spelled as in a setting's name (`onnx-int8`)."""
OUTPUTS = ("newest", "centre", "stitched")
INVALID_HANDS = ("skip", "official")
LOOKAHEAD_FRAMES = {"newest": 0, "centre": 6, "stitched": 14}
"""Frames an output position waits for after the frame it predicts (at 30 fps)."""
NAME_HELP = ("MODEL/RUNTIME-PRECISION/VIEWS[/everyK][/centre|/stitched][/membersK], e.g. pico/onnx-int8/all or "
             "pico/torch-fp32/ego+left")
_EVERY = re.compile(r"every([1-9][0-9]*)")
_MEMBERS = re.compile(r"members([1-9][0-9]*)")


def engine_device(runtime: str, device: str) -> torch.device:
    """The device `runtime` runs on for the `--device` setting: torch resolves it (`resolve_device`); ONNX
    Runtime runs on the CPU here (the CPU build is installed), so `auto` means the CPU for it and a CUDA
    device is one UserError line."""
    import torch

    if runtime == "onnx":
        if device not in ("auto", "cpu"):
            resolve_device(device)  # a malformed name is named as such
            raise UserError(f"runtime onnx runs on the CPU only (onnxruntime's CPU build); use --runtime torch "
                            f"for --device {device}, or --device cpu")
        return torch.device("cpu")
    return resolve_device(device)


def compute_threads() -> int:
    """CPU threads for the model: all cores but one, so capture, decoding and display keep a core."""
    return max(1, (os.cpu_count() or 1) - 1)


@dataclass(frozen=True)
class EngineSetting:
    """model: the model's short name (a bundled model's folder name, else its checkpoint's folder name).
    runtime/precision: torch fp32|bf16|fp16|tf32 (fp16 and tf32 on GPU only), onnx fp32|int8.
    views: the views the engine may use (a subset of the present ones is used per frame; ego required).
    every: predict every k-th frame and hold the last prediction in between (newest output only).
    output: newest (no look-ahead), centre (window position 4: 6 frames = 200 ms look-ahead) or
        stitched (official offline average over the 8 clips covering a frame: 14 frames = 467 ms).
    invalid_hands: skip (a hand without a valid pose is not predicted) or official (fed as −10 joints
        and predicted anyway).
    device: `auto` (the first CUDA GPU when there is one, else the CPU; ONNX: the CPU), `cpu`, `cuda`, `cuda:N`.
    capture: on a CUDA GPU, capture the torch runtime's calls as CUDA graphs (False: eager, for comparison).
    blank: every frame black (the pose-only twin of a setting).
    members: K ≥ 1 — run the first K members of the checkpoint's ensemble (`ensemble_members`) and output
        their per-cell mean, with their spread (`Prediction.spread`); 1: the checkpoint alone."""

    model: str = ""
    runtime: str = "torch"
    precision: str = "fp32"
    views: tuple[str, ...] = VIEW_NAMES
    every: int = 1
    output: str = "newest"
    invalid_hands: str = "skip"
    device: str = "auto"
    capture: bool = True
    blank: bool = False
    members: int = 1

    def __post_init__(self) -> None:
        if self.runtime not in RUNTIMES:
            raise UserError(f"unknown runtime {self.runtime!r}; choose from {', '.join(RUNTIMES)}")
        if self.precision not in RUNTIMES[self.runtime]:
            raise UserError(f"runtime {self.runtime} has no precision {self.precision!r}; choose from "
                            f"{', '.join(RUNTIMES[self.runtime])}")
        if self.output not in OUTPUTS:
            raise UserError(f"unknown output position {self.output!r}; choose from {', '.join(OUTPUTS)}")
        if self.invalid_hands not in INVALID_HANDS:
            raise UserError(f"unknown invalid-hand mode {self.invalid_hands!r}; choose from {', '.join(INVALID_HANDS)}")
        if not isinstance(self.every, int) or isinstance(self.every, bool) or self.every < 1:
            raise UserError(f"prediction rate must be a whole number ≥ 1 (every k-th frame), got {self.every!r}")
        if not isinstance(self.members, int) or isinstance(self.members, bool) or self.members < 1:
            raise UserError(f"ensemble members must be a whole number ≥ 1, got {self.members!r}")
        if self.every > 1 and self.output != "newest":
            raise UserError("predicting every k-th frame needs the newest-frame output")
        unknown = [v for v in self.views if v not in VIEW_NAMES]
        if unknown or "ego" not in self.views:
            raise UserError(f"views must include ego and come from {', '.join(VIEW_NAMES)}; got {', '.join(self.views)}")
        object.__setattr__(self, "views", tuple(v for v in VIEW_NAMES if v in self.views))

    @property
    def tier(self) -> str:
        """Runtime and precision as the name spells them: `onnx-int8`."""
        return f"{self.runtime}-{self.precision}"

    def with_tier(self, tier: str) -> EngineSetting:
        """The same setting at another tier (`torch-bf16`)."""
        runtime, _, precision = tier.partition("-")
        return dataclasses.replace(self, runtime=runtime, precision=precision)

    def name(self) -> str:
        """The setting's name (module docstring)."""
        parts = [self.model, self.tier, view_set_name(self.views)]
        parts += [f"every{self.every}"] if self.every > 1 else []
        parts += [self.output] if self.output != "newest" else []
        parts += ["official-invalid"] if self.invalid_hands == "official" else []
        parts += ["eager"] if not self.capture else []
        parts += ["pose-only"] if self.blank else []
        parts += [f"members{self.members}"] if self.members > 1 else []
        return "/".join(parts)

    @property
    def lookahead_ms(self) -> float:
        return LOOKAHEAD_FRAMES[self.output] * 1000 / 30

    def resolved_device(self) -> torch.device:
        """The device the setting runs on here; UserError for a device that is absent or cannot run the
        precision (fp16 on the CPU, ONNX on a GPU)."""
        resolved = engine_device(self.runtime, self.device)
        if self.runtime == "torch":
            check_precision(self.precision, resolved)
        return resolved


def parse_setting(text: str) -> EngineSetting:
    """The setting a name names; UserError saying which part is wrong."""
    parts = text.strip().split("/")
    if len(parts) < 3 or not parts[0]:
        raise UserError(f"setting {text!r} is not a setting name ({NAME_HELP})")
    model, tier, views, *knobs = parts
    if tier not in TIERS:
        raise UserError(f"setting {text!r}: unknown runtime-precision {tier!r} ({', '.join(TIERS)})")
    if views not in VIEW_SETS:
        raise UserError(f"setting {text!r}: unknown views {views!r}; choose from {', '.join(VIEW_SETS)}")
    fields: dict = {}
    for knob in knobs:
        if match := _EVERY.fullmatch(knob):
            fields["every"] = int(match.group(1))
        elif match := _MEMBERS.fullmatch(knob):
            fields["members"] = int(match.group(1))
        elif knob in OUTPUTS[1:]:
            fields["output"] = knob
        elif knob == "official-invalid":
            fields["invalid_hands"] = "official"
        elif knob == "eager":
            fields["capture"] = False
        elif knob == "pose-only":
            fields["blank"] = True
        else:
            raise UserError(f"setting {text!r}: unknown part {knob!r} ({NAME_HELP})")
    try:
        setting = EngineSetting(model, views=VIEW_SETS[views], **fields).with_tier(tier)
    except UserError as exc:
        raise UserError(f"setting {text!r}: {exc}") from None
    if setting.name() != text.strip():
        raise UserError(f"setting {text!r} is not written the canonical way; did you mean {setting.name()}?")
    return setting
