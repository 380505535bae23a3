"""Streaming-engine settings: which runtime and precision, which views, which output position and rate.

Pure configuration: checking a config builds nothing; `touchanything.inference.engine.engine_runtime.make_runtime`
turns it into a runtime. torch is imported where it is used: `touchanything --help` loads this module.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from touchanything.devices.errors import UserError
from touchanything.devices.snapshot import VIEW_NAMES
from touchanything.inference.model.torch_device import check_precision, resolve_device

if TYPE_CHECKING:
    import torch

RUNTIMES = {"torch": ("fp32", "bf16", "fp16", "tf32"), "onnx": ("fp32", "int8")}
"""Runtime → the precisions it offers (torch fp16 and tf32 on a CUDA GPU only)."""
OUTPUTS = ("newest", "centre", "stitched")
INVALID_HANDS = ("skip", "official")


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


def check_runtime(runtime: str, precision: str, device: str = "auto") -> torch.device:
    """The device the runtime will use; UserError for an unknown runtime / precision pair, a device that is
    absent, or a pair the device cannot run (fp16 on the CPU, ONNX on a GPU)."""
    if runtime not in RUNTIMES:
        raise UserError(f"unknown runtime {runtime!r}; choose from {', '.join(RUNTIMES)}")
    if precision not in RUNTIMES[runtime]:
        raise UserError(f"runtime {runtime} has no precision {precision!r}; choose from {', '.join(RUNTIMES[runtime])}")
    resolved = engine_device(runtime, device)
    if runtime == "torch":
        check_precision(precision, resolved)
    return resolved


@dataclass(frozen=True)
class EngineConfig:
    """runtime/precision: torch fp32|bf16|fp16|tf32 (fp16 and tf32 on GPU only), onnx fp32|int8. device: `auto` (the first
        CUDA GPU when there is one, else the CPU; ONNX: the CPU), `cpu`, `cuda`, `cuda:N`.
    onnx_dir: graphs from `touchanything export-onnx` (None: exported on first use into the user cache).
    views: the views the engine may use (a subset of the present ones is used per frame).
    output: newest (no look-ahead), centre (window position 4: 6 frames = 200 ms look-ahead) or
        stitched (official offline average over the 8 clips covering a frame: 14 frames = 467 ms).
    every: predict every k-th frame and hold the last prediction in between (newest output only).
    invalid_hands: skip (a hand without a valid pose is not predicted) or official (fed as −10 joints
        and predicted anyway).
    threads: CPU threads for the model (see `compute_threads`).
    capture: on a CUDA GPU, capture the torch runtime's calls as CUDA graphs (False: eager, for comparison)."""

    runtime: str = "torch"
    precision: str = "fp32"
    device: str = "auto"
    onnx_dir: Path | None = None
    views: tuple[str, ...] = VIEW_NAMES
    output: str = "newest"
    every: int = 1
    invalid_hands: str = "skip"
    threads: int | None = None
    capture: bool = True

    def compute_threads(self) -> int:
        """CPU threads for the model (None: all cores but one, so capture, decoding and display keep a core)."""
        return self.threads or max(1, (os.cpu_count() or 1) - 1)

    def check(self) -> EngineConfig:
        check_runtime(self.runtime, self.precision, self.device)
        if self.output not in OUTPUTS:
            raise UserError(f"unknown output position {self.output!r}; choose from {', '.join(OUTPUTS)}")
        if self.invalid_hands not in INVALID_HANDS:
            raise UserError(f"unknown invalid-hand mode {self.invalid_hands!r}; choose from {', '.join(INVALID_HANDS)}")
        if not isinstance(self.every, int) or self.every < 1:
            raise UserError(f"prediction rate must be a whole number ≥ 1 (every k-th frame), got {self.every!r}")
        if self.threads is not None and (not isinstance(self.threads, int) or self.threads < 1):
            raise UserError(f"threads must be a whole number ≥ 1, got {self.threads!r}")
        if self.every > 1 and self.output != "newest":
            raise UserError("predicting every k-th frame needs the newest-frame output")
        unknown = [v for v in self.views if v not in VIEW_NAMES]
        if unknown or "ego" not in self.views:
            raise UserError(f"views must include ego and come from {', '.join(VIEW_NAMES)}; got {', '.join(self.views)}")
        return self
