"""Training settings from the `training`, `data` and `system` sections of an official-structure config.

Defaults are the official ones (100 epochs, batch 16, AdamW lr 5e-5 and weight decay 0.05 on every
parameter, 10 warm-up epochs from 1 % of the rate then cosine to 1e-6, gradient clipping at 1.0, fp32,
a periodic checkpoint every 5 epochs, seed 42, view dropout 0.3 from the model section).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from devices.errors import UserError
from inference.model_config import ModelConfig, config_from_dict, config_to_dict, deep_merge, read_config_file


@dataclass(frozen=True)
class TrainConfig:
    model: ModelConfig
    epochs: int = 100
    batch_size: int = 16
    learning_rate: float = 5e-5
    weight_decay: float = 0.05
    warmup_epochs: int = 10
    min_lr: float = 1e-6
    grad_clip: float = 1.0
    save_every: int = 5
    seed: int = 42
    mixed_precision: bool = False
    pose_source: str = "wilor"
    clip_length: int = 8
    frame_interval: int = 2

    def check(self) -> "TrainConfig":
        positive = {"epochs": self.epochs, "batch_size": self.batch_size, "learning_rate": self.learning_rate,
                    "save_every": self.save_every, "clip_length": self.clip_length, "frame_interval": self.frame_interval}
        for name, value in positive.items():
            if not value > 0:
                raise UserError(f"training setting {name} must be positive, got {value}")
        if not 0 <= self.warmup_epochs <= self.epochs:
            raise UserError(f"warmup_epochs must be within 0–epochs, got {self.warmup_epochs}")
        if self.pose_source not in ("wilor", "rokoko"):
            raise UserError(f"pose_source must be wilor or rokoko, got {self.pose_source!r}")
        if self.clip_length > self.model.window_size:
            raise UserError(f"clip_length {self.clip_length} exceeds the temporal window {self.model.window_size}")
        return self

    @property
    def span(self) -> int:
        return (self.clip_length - 1) * self.frame_interval + 1


def train_config_from_file(path: Path) -> TrainConfig:
    """Read a training config (a `base.yaml` beside it is merged underneath)."""
    data = read_config_file(path)
    training, system, data_section = data.get("training") or {}, data.get("system") or {}, data.get("data") or {}
    d = TrainConfig(ModelConfig())
    try:
        config = TrainConfig(
            model=config_from_dict(data, str(path)),
            epochs=int(training.get("epochs", d.epochs)),
            batch_size=int(training.get("batch_size", d.batch_size)),
            learning_rate=float(training.get("learning_rate", training.get("lr", d.learning_rate))),
            weight_decay=float(training.get("weight_decay", d.weight_decay)),
            warmup_epochs=int(training.get("warmup_epochs", d.warmup_epochs)),
            min_lr=float(training.get("min_lr", d.min_lr)),
            grad_clip=float(training.get("grad_clip", d.grad_clip)),
            save_every=int(training.get("save_every", d.save_every)),
            seed=int(training.get("seed", d.seed)),
            mixed_precision=bool(system.get("mixed_precision", d.mixed_precision)),
            pose_source=str(data_section.get("pose_source", d.pose_source)),
            clip_length=int(data_section.get("clip_length", d.clip_length)),
            frame_interval=int(data_section.get("frame_interval", d.frame_interval)),
        )
    except (TypeError, ValueError) as exc:
        raise UserError(f"{path}: a training setting has the wrong type ({exc})") from None
    return config.check()


def train_config_to_dict(config: TrainConfig) -> dict:
    """The full config (model, data, training, system) as written beside checkpoints."""
    c = config
    return deep_merge(config_to_dict(c.model), {
        "data": {"clip_length": c.clip_length, "frame_interval": c.frame_interval, "pose_source": c.pose_source},
        "training": {"epochs": c.epochs, "batch_size": c.batch_size, "learning_rate": c.learning_rate,
                     "weight_decay": c.weight_decay, "warmup_epochs": c.warmup_epochs, "min_lr": c.min_lr,
                     "grad_clip": c.grad_clip, "save_every": c.save_every, "seed": c.seed},
        "system": {"mixed_precision": c.mixed_precision},
    })
