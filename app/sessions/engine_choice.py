"""Which model and runtime the engine runs: a bundled model (the default one, see `bundled`) or a user's
checkpoint, and the runtime tiers offered by the command line and the dashboard's switch."""
from __future__ import annotations

import argparse
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING

from touchanything.app.sessions.bundled import MODELS_DIR, bundled_models
from touchanything.devices.view_sets import parse_view_set
from touchanything.inference.engine.engine_config import EngineConfig
from touchanything.inference.evaluation.bench_setting import BenchSetting
from touchanything.inference.model.model_card import read_card
from touchanything.inference.model.torch_device import DEVICE_HELP, device_label

if TYPE_CHECKING:
    import torch

    from touchanything.inference.engine.streaming_engine import StreamingEngine

DEFAULT_MODEL = "nano"
CPU_TIERS = ("torch fp32", "torch bf16", "onnx fp32", "onnx int8")
"""Runtime + precision pairs that run on a CPU (fp16 and tf32 need a GPU)."""
GPU_TIERS = ("torch fp32", "torch tf32", "torch bf16", "torch fp16")
"""Runtime + precision pairs that run on a CUDA GPU (ONNX Runtime here is the CPU build)."""


@dataclass(frozen=True)
class ModelChoice:
    """A checkpoint (config.yaml beside it unless `config` is given), its runtime tier, the `--device` setting
    (auto, cpu, cuda, cuda:N), and the engine's prediction rate (every k-th frame) and output position."""

    checkpoint: Path
    config: Path | None = None
    runtime: str = "torch"
    precision: str = "fp32"
    device: str = "auto"
    every: int = 1
    output: str = "newest"

    @property
    def tier(self) -> str:
        return f"{self.runtime} {self.precision}"

    def with_tier(self, tier: str) -> ModelChoice:
        runtime, precision = tier.split()
        return replace(self, runtime=runtime, precision=precision)

    def with_checkpoint(self, checkpoint: Path) -> ModelChoice:
        """Another checkpoint (its own config.yaml) at the same tier and device."""
        return replace(self, checkpoint=checkpoint, config=None)


def add_device_argument(parser: argparse.ArgumentParser, default: str | None = "auto") -> None:
    """`--device` for a command that runs the model (default None: the scene file's setting)."""
    where = f" (default {default})" if default else " (default: the scene's [model] device, else auto)"
    parser.add_argument("--device", default=default, help=f"where the model runs: {DEVICE_HELP}{where}")


def view_set_argument(text: str) -> tuple[str, ...]:
    """argparse type of every `--views` value: `parse_view_set`, its error as the usage message."""
    try:
        return parse_view_set(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def default_checkpoint() -> Path:
    """The bundled model every command and scene runs unless told otherwise."""
    return MODELS_DIR / DEFAULT_MODEL / "best_model.pth"


def tiers_for(device: torch.device) -> tuple[str, ...]:
    """The tiers the dashboard offers for an engine on `device`."""
    return GPU_TIERS if device.type == "cuda" else CPU_TIERS


def model_name(choice: ModelChoice) -> str:
    """What the model is: its card's summary (name, training data, held-out V-IoU; `model_card`), else the
    bundled model's folder name, else the checkpoint's path."""
    if card := read_card(choice.checkpoint):
        return card.summary()
    bundled = {path.resolve(): name for name, path in bundled_models().items()}
    return bundled.get(choice.checkpoint.resolve(), str(choice.checkpoint))


def model_key(choice: ModelChoice) -> str:
    """The model's short name: the bundled model's folder name, else the checkpoint's folder name."""
    bundled = {path.resolve(): name for name, path in bundled_models().items()}
    return bundled.get(choice.checkpoint.resolve(), choice.checkpoint.resolve().parent.name)


def setting_name(choice: ModelChoice, views: tuple[str, ...]) -> str:
    """The engine setting's name in the atlas's spelling (`nano/onnx-int8/all`), whatever chose it."""
    return BenchSetting(model_key(choice), choice.runtime, choice.precision, views, choice.every, choice.output).name()


def model_label(choice: ModelChoice, engine: StreamingEngine | None = None) -> str:
    """The model's name with the tier and, for a built engine, the device it runs on
    ("nano — trained on simulated data; held-out V-IoU 0.55 seen / 0.53 unseen objects (torch fp32 on cpu)")."""
    where = f" on {device_label(engine.runtime.device)}" if engine is not None else ""
    return f"{model_name(choice)} ({choice.tier}{where})"


def illustrative_note(choice: ModelChoice, camera_pose: bool) -> str:
    """"" unless the poses come from the camera (`camera_pose`: bare hands) and the model's card says it was
    trained on simulated (gloved) hands: then its prediction only illustrates what the model does, and this
    says so."""
    card = read_card(choice.checkpoint)
    if not camera_pose or card is None or not card.simulated:
        return ""
    return "illustrative only: bare-hand poses from the camera, model trained on simulated gloved hands"


def build_engine(choice: ModelChoice, views: tuple[str, ...]) -> StreamingEngine:
    """Load the checkpoint and build its engine (an ONNX tier exports its graphs on first use);
    a bad checkpoint, config or tier raises UserError."""
    from touchanything.inference.engine.streaming_engine import StreamingEngine  # imported where used: --help loads this module
    from touchanything.inference.model.checkpoint import load_model

    config = EngineConfig(runtime=choice.runtime, precision=choice.precision, device=choice.device, views=views,
                          every=choice.every, output=choice.output).check()
    return StreamingEngine(load_model(choice.checkpoint, choice.config), config)
