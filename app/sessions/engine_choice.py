"""Which model and runtime the engine runs: the bundled models, a user's checkpoint, and the runtime tiers
offered by the command line and the dashboard's switch."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from touchanything.inference.engine.engine_config import EngineConfig
from touchanything.inference.engine.streaming_engine import StreamingEngine
from touchanything.inference.model.checkpoint import load_model

MODELS_DIR = Path(__file__).resolve().parents[2] / "models"
DEFAULT_MODEL = "nano"
CPU_TIERS = ("torch fp32", "torch bf16", "onnx fp32", "onnx int8")
"""Runtime + precision pairs that run on this machine's CPU (fp16 needs a GPU)."""


@dataclass(frozen=True)
class ModelChoice:
    """A checkpoint (config.yaml beside it unless `config` is given) and its runtime tier."""

    checkpoint: Path
    config: Path | None = None
    runtime: str = "torch"
    precision: str = "fp32"

    @property
    def tier(self) -> str:
        return f"{self.runtime} {self.precision}"

    def with_tier(self, tier: str) -> ModelChoice:
        runtime, precision = tier.split()
        return ModelChoice(self.checkpoint, self.config, runtime, precision)


def bundled_models() -> dict[str, Path]:
    """name → checkpoint of every model shipped under models/ (smallest first by file size)."""
    found = [p for p in MODELS_DIR.glob("*/best_model.pth")]
    return {p.parent.name: p for p in sorted(found, key=lambda p: p.stat().st_size)}


def default_checkpoint() -> Path:
    return MODELS_DIR / DEFAULT_MODEL / "best_model.pth"


def model_label(choice: ModelChoice) -> str:
    """A short name: the bundled model's folder name, else the checkpoint's path."""
    bundled = {path.resolve(): name for name, path in bundled_models().items()}
    return f"{bundled.get(choice.checkpoint.resolve(), str(choice.checkpoint))} ({choice.tier})"


def build_engine(choice: ModelChoice, views: tuple[str, ...]) -> StreamingEngine:
    """Load the checkpoint and build its engine (an ONNX tier exports its graphs on first use);
    a bad checkpoint, config or tier raises UserError."""
    config = EngineConfig(runtime=choice.runtime, precision=choice.precision, views=views).check()
    return StreamingEngine(load_model(choice.checkpoint, choice.config), config)
