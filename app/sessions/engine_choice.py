"""Which model and runtime the engine runs: a bundled model (the default one, see `bundled`) or a user's
checkpoint, and the runtime tiers offered by the command line and the dashboard's switch."""
from __future__ import annotations

import argparse
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import TYPE_CHECKING

from touchanything.app.sessions.bundled import MODELS_DIR, bundled_models
from touchanything.core.errors import UserError
from touchanything.core.view_sets import parse_view_set
from touchanything.inference.engine.engine_setting import EngineSetting
from touchanything.inference.engine.onnx_manifest import export_source
from touchanything.inference.model.model_card import read_card
from touchanything.inference.model.torch_device import DEVICE_HELP, check_precision_early, device_label

if TYPE_CHECKING:
    import torch

    from touchanything.inference.engine.ensemble_engine import EnsembleEngine
    from touchanything.inference.engine.streaming_engine import StreamingEngine

DEFAULT_MODEL = "pico"
CPU_TIERS = ("torch-fp32", "torch-bf16", "onnx-fp32", "onnx-int8")
"""Runtime-precision pairs that run on a CPU (fp16 and tf32 need a GPU), spelled as in a setting's name."""
GPU_TIERS = ("torch-fp32", "torch-tf32", "torch-bf16", "torch-fp16")
"""Runtime-precision pairs that run on a CUDA GPU (ONNX Runtime here is the CPU build)."""


@dataclass(frozen=True)
class ModelChoice:
    """Where the model's files are — the checkpoint (config.yaml beside it unless `config` is given) and the
    export folder an ONNX setting runs (`onnx_dir`, checked against the checkpoint's weights; None: the user
    cache's export of the checkpoint) — and the engine `setting` it runs at, whose `model` is the checkpoint's
    short name (`model_key`). Make one with `choose`."""

    checkpoint: Path
    setting: EngineSetting
    config: Path | None = None
    onnx_dir: Path | None = None

    def __post_init__(self) -> None:
        if self.setting.runtime == "torch":  # what runs here: a GPU precision without a GPU, before torch loads
            check_precision_early(self.setting.precision, self.setting.device)

    def with_setting(self, **changes) -> ModelChoice:
        """The same files at a setting with `changes` (`runtime=`, `every=`, `views=`, …)."""
        return replace(self, setting=replace(self.setting, **changes))

    def with_tier(self, tier: str) -> ModelChoice:
        """The same files at another tier (`onnx-int8`)."""
        return replace(self, setting=self.setting.with_tier(tier))

    def with_checkpoint(self, checkpoint: Path) -> ModelChoice:
        """Another checkpoint (its own config.yaml, and for ONNX the user cache's export of it) at the same
        setting; the same checkpoint keeps its config and export folder."""
        if Path(checkpoint).resolve() == self.checkpoint.resolve():
            return self
        return choose(checkpoint, **_knobs(self.setting))

    @property
    def runs_export(self) -> bool:
        """Whether the engine runs the graphs of the export folder `onnx_dir`."""
        return self.setting.runtime == "onnx" and self.onnx_dir is not None


def _knobs(setting: EngineSetting) -> dict:
    return {f.name: getattr(setting, f.name) for f in fields(setting) if f.name != "model"}


def choose(checkpoint: Path, config: Path | None = None, onnx_dir: Path | None = None, **knobs) -> ModelChoice:
    """The checkpoint's files at the setting of `knobs` (EngineSetting's fields but `model`, which is the
    checkpoint's `model_key`); UserError for a bad knob."""
    return ModelChoice(Path(checkpoint), EngineSetting(model_key(Path(checkpoint)), **knobs), config, onnx_dir)


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
                  runtime: str | None = None, precision: str | None = None, **knobs) -> ModelChoice:
    """`--onnx DIR`: the export in `folder` on ONNX Runtime (`precision`, default fp32), with `checkpoint`, else
    the checkpoint the export was made from (else the bundled default), at the setting's other `knobs`; the
    weights are checked against the export when the engine is built. UserError when `runtime` is not onnx, or
    `folder` is no export."""
    if runtime not in (None, "onnx"):
        raise UserError(f"{folder}: an ONNX export runs on the onnx runtime, not {runtime}")
    source = checkpoint or export_source(folder) or default_checkpoint()
    return choose(source, config, folder, runtime="onnx", precision=precision or "fp32", device=device, **knobs)


def choice_inputs(choice: ModelChoice) -> tuple[Path, ...]:
    """The files the choice reads (a command's inputs, never written): checkpoint, config, export folder."""
    return tuple(p for p in (choice.checkpoint, choice.config, choice.onnx_dir if choice.runs_export else None) if p)


def tiers_for(device: torch.device) -> tuple[str, ...]:
    """The tiers the dashboard offers for an engine on `device`."""
    return GPU_TIERS if device.type == "cuda" else CPU_TIERS


def model_name(choice: ModelChoice) -> str:
    """What the model is: its card's name and training data ("pico — trained on simulated data"; its accuracy is
    said once, by `setting_choice.running_accuracy`), else the bundled model's folder name, else the checkpoint's
    path."""
    if card := read_card(choice.checkpoint):
        return replace(card, held_out={}).summary()
    bundled = {path.resolve(): name for name, path in bundled_models().items()}
    return bundled.get(choice.checkpoint.resolve(), str(choice.checkpoint))


def is_bundled(checkpoint: Path) -> bool:
    """Whether `checkpoint` is a bundled model's (the atlas measured those weights only)."""
    return Path(checkpoint).resolve() in {path.resolve() for path in bundled_models().values()}


def model_key(checkpoint: Path) -> str:
    """The model's short name: the bundled model's folder name, else the checkpoint's folder name."""
    bundled = {path.resolve(): name for name, path in bundled_models().items()}
    return bundled.get(checkpoint.resolve(), checkpoint.resolve().parent.name)


def model_label(choice: ModelChoice, engine: StreamingEngine | None = None) -> str:
    """The model's name with the tier, the export folder it runs, and for a built engine the device it runs on
    ("nano — trained on simulated data (onnx-int8 from exports/nano on cpu)")."""
    export = f" from {choice.onnx_dir}" if choice.runs_export else ""
    where = f" on {device_label(engine.runtime.device)}" if engine is not None else ""
    return f"{model_name(choice)} ({choice.setting.tier}{export}{where})"


def illustrative_note(choice: ModelChoice, camera_pose: bool) -> str:
    """"" unless the poses come from the camera (`camera_pose`: bare hands) and the model's card says it was
    trained on simulated (gloved) hands: then its prediction only illustrates what the model does, and this
    says so."""
    card = read_card(choice.checkpoint)
    if not camera_pose or card is None or not card.simulated:
        return ""
    return "illustrative only: bare-hand poses from the camera, model trained on simulated gloved hands"


def build_engine(choice: ModelChoice) -> StreamingEngine | EnsembleEngine:
    """Load the checkpoint and build its engine at the choice's setting (an ONNX tier runs `onnx_dir`'s graphs,
    checked against the checkpoint, else exports its graphs into the user cache on first use); with
    `members` > 1 the engine of the checkpoint's ensemble (`ensemble_engine`, `onnx_dir` for member 1 only). A
    bad checkpoint, config, tier, export or ensemble raises UserError."""
    # imported where used: --help loads this module
    from touchanything.inference.engine.ensemble_engine import load_ensemble
    from touchanything.inference.engine.streaming_engine import StreamingEngine
    from touchanything.inference.model.checkpoint import load_model

    choice.setting.resolved_device()  # an absent device is named before the model loads
    if choice.setting.members > 1:
        return load_ensemble(choice.checkpoint, choice.setting, choice.config, choice.onnx_dir)
    return StreamingEngine(load_model(choice.checkpoint, choice.config), choice.setting, onnx_dir=choice.onnx_dir)
