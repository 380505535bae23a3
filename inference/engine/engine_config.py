"""Streaming-engine settings and the runtime they select (ONNX graphs exported on first use and cached)."""
from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass
from pathlib import Path

from touchanything.devices.errors import UserError
from touchanything.devices.snapshot import VIEW_NAMES
from touchanything.inference.engine.engine_runtime import MANIFEST, OnnxRuntime, TorchRuntime, check_runtime, read_manifest
from touchanything.inference.model.model_config import config_to_dict
from touchanything.inference.model.touch_model import TouchAnything

OUTPUTS = ("newest", "centre", "stitched")
INVALID_HANDS = ("skip", "official")


@dataclass(frozen=True)
class EngineConfig:
    """runtime/precision: torch fp32|bf16|fp16 (fp16 on GPU only), onnx fp32|int8. device: torch device.
    onnx_dir: graphs from `touchanything export-onnx` (None: exported on first use into the user cache).
    views: the views the engine may use (a subset of the present ones is used per frame).
    output: newest (no look-ahead), centre (window position 4: 6 frames = 200 ms look-ahead) or
        stitched (official offline average over the 8 clips covering a frame: 14 frames = 467 ms).
    every: predict every k-th frame and hold the last prediction in between (newest output only).
    invalid_hands: skip (a hand without a valid pose is not predicted) or official (fed as −10 joints
        and predicted anyway).
    threads: CPU threads for the model (see `compute_threads`)."""

    runtime: str = "torch"
    precision: str = "fp32"
    device: str = "cpu"
    onnx_dir: Path | None = None
    views: tuple[str, ...] = VIEW_NAMES
    output: str = "newest"
    every: int = 1
    invalid_hands: str = "skip"
    threads: int | None = None

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


def model_digest(model: TouchAnything) -> str:
    """A short hash of the model's weights and config (names the cached ONNX export)."""
    digest = hashlib.sha256(repr(config_to_dict(model.config)).encode())
    for name, tensor in sorted(model.state_dict().items()):
        digest.update(name.encode())
        digest.update(tensor.detach().float().cpu().numpy().tobytes())
    return digest.hexdigest()[:16]


def onnx_cache_dir(model: TouchAnything) -> Path:
    root = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return root / "touchanything" / "onnx" / model_digest(model)


def onnx_folder(model: TouchAnything, folder: Path | None, precision: str) -> Path:
    """The folder holding graphs for `model` at `precision`; exported there first when missing (cache)."""
    from touchanything.inference.engine.onnx_export import export_onnx

    if folder is None:
        folder = onnx_cache_dir(model)
        has = (folder / MANIFEST).is_file() and precision in read_manifest(folder)["files"]
        if not has:
            export_onnx(model, folder, int8=True, source="cache")
        return folder
    manifest = read_manifest(folder)
    if manifest["config"] != config_to_dict(model.config):
        raise UserError(f"{folder}: the ONNX graphs were exported from a different model architecture")
    if precision not in manifest["files"]:
        raise UserError(f"{folder}: no {precision} graphs; export with `touchanything export-onnx --int8`")
    return folder


def make_runtime(model: TouchAnything, config: EngineConfig) -> TorchRuntime | OnnxRuntime:
    config.check()
    if config.runtime == "torch":
        return TorchRuntime(model, config.precision, config.device, config.compute_threads())
    return OnnxRuntime(onnx_folder(model, config.onnx_dir, config.precision), config.precision, config.compute_threads())
