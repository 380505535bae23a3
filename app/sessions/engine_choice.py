"""Which model and runtime the engine runs: a bundled model (the default one, see `bundled`) or a user's
checkpoint, and the runtime tiers offered by the command line and the dashboard's switch."""
from __future__ import annotations

import argparse
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING

from touchanything.app.sessions.bundled import MODELS_DIR, bundled_models
from touchanything.devices.errors import UserError
from touchanything.devices.view_sets import parse_view_set
from touchanything.inference.engine.engine_config import EngineConfig
from touchanything.inference.engine.onnx_manifest import export_source
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
    (auto, cpu, cuda, cuda:N), the engine's prediction rate (every k-th frame) and output position, and the
    export folder the ONNX tiers run (`onnx_dir`, checked against the checkpoint's weights; None: the user
    cache's export of the checkpoint)."""

    checkpoint: Path
    config: Path | None = None
    runtime: str = "torch"
    precision: str = "fp32"
    device: str = "auto"
    every: int = 1
    output: str = "newest"
    onnx_dir: Path | None = None

    @property
    def tier(self) -> str:
        return f"{self.runtime} {self.precision}"

    def with_tier(self, tier: str) -> ModelChoice:
        runtime, precision = tier.split()
        return replace(self, runtime=runtime, precision=precision)

    def with_checkpoint(self, checkpoint: Path) -> ModelChoice:
        """Another checkpoint (its own config.yaml, and for ONNX the user cache's export of it) at the same tier
        and device; the same checkpoint keeps its config and export folder."""
        if Path(checkpoint).resolve() == self.checkpoint.resolve():
            return self
        return replace(self, checkpoint=checkpoint, config=None, onnx_dir=None)

    @property
    def runs_export(self) -> bool:
        """Whether the engine runs the graphs of the export folder `onnx_dir`."""
        return self.runtime == "onnx" and self.onnx_dir is not None


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


def add_onnx_argument(parser: argparse.ArgumentParser) -> None:
    """`--onnx DIR`: run an export of `touchanything export-onnx` (ONNX Runtime, its own checkpoint)."""
    parser.add_argument("--onnx", type=Path, metavar="DIR",
                        help="run the ONNX graphs of this export-onnx folder (implies the onnx runtime; the model is the "
                             "checkpoint it was exported from, whose weights must match it; default: not used)")


def export_choice(folder: Path, device: str = "auto", checkpoint: Path | None = None, config: Path | None = None,
                  runtime: str | None = None, precision: str | None = None) -> ModelChoice:
    """`--onnx DIR`: the export in `folder` on ONNX Runtime (`precision`, default fp32), with `checkpoint`, else
    the checkpoint the export was made from (else the bundled default); the weights are checked against the
    export when the engine is built. UserError when `runtime` is not onnx, or `folder` is no export."""
    if runtime not in (None, "onnx"):
        raise UserError(f"{folder}: an ONNX export runs on the onnx runtime, not {runtime}")
    source = checkpoint or export_source(folder) or default_checkpoint()
    return ModelChoice(source, config, "onnx", precision or "fp32", device, onnx_dir=folder)


def choice_inputs(choice: ModelChoice) -> tuple[Path, ...]:
    """The files the choice reads (a command's inputs, never written): checkpoint, config, export folder."""
    return tuple(p for p in (choice.checkpoint, choice.config, choice.onnx_dir if choice.runs_export else None) if p)


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
    """The model's name with the tier, the export folder it runs, and for a built engine the device it runs on
    ("nano — trained on simulated data; held-out V-IoU 0.55 seen / 0.53 unseen objects (onnx int8 from
    exports/nano on cpu)")."""
    export = f" from {choice.onnx_dir}" if choice.runs_export else ""
    where = f" on {device_label(engine.runtime.device)}" if engine is not None else ""
    return f"{model_name(choice)} ({choice.tier}{export}{where})"


def illustrative_note(choice: ModelChoice, camera_pose: bool) -> str:
    """"" unless the poses come from the camera (`camera_pose`: bare hands) and the model's card says it was
    trained on simulated (gloved) hands: then its prediction only illustrates what the model does, and this
    says so."""
    card = read_card(choice.checkpoint)
    if not camera_pose or card is None or not card.simulated:
        return ""
    return "illustrative only: bare-hand poses from the camera, model trained on simulated gloved hands"


def build_engine(choice: ModelChoice, views: tuple[str, ...]) -> StreamingEngine:
    """Load the checkpoint and build its engine (an ONNX tier runs `onnx_dir`'s graphs, checked against the
    checkpoint, else exports its graphs into the user cache on first use); a bad checkpoint, config, tier or
    export raises UserError."""
    from touchanything.inference.engine.streaming_engine import StreamingEngine  # imported where used: --help loads this module
    from touchanything.inference.model.checkpoint import load_model

    config = EngineConfig(runtime=choice.runtime, precision=choice.precision, device=choice.device,
                          onnx_dir=choice.onnx_dir, views=views, every=choice.every, output=choice.output).check()
    return StreamingEngine(load_model(choice.checkpoint, choice.config), config)
