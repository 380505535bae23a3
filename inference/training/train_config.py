"""Training settings in the official structure: `training`, `system` and the training part of `data`.

Read strictly (every key of the official configs is known; a misspelt one is an error naming it), with the
official names: `training.{batch_size, num_epochs, save_interval, val_interval, num_workers}`,
`training.optimizer.{type: adamw, lr, weight_decay, betas}`, `training.scheduler.{type: cosine, warmup_epochs,
min_lr}`, `training.loss.{mse_weight, l1_weight, tv_weight, contact_weight, pressure_threshold}`,
`system.{seed, mixed_precision}`, `data.{pose_source, fallback_pose_source}`. Defaults are the official
recipe (`touchanything_with_glove_aug_wilor.yaml`). Official keys that do not change this trainer are
accepted and listed by `TrainConfig.unused` (the `train` command prints them). Two project extensions, not in
the official structure: `data.blank_images` (default false), which trains the pose-only baseline, and
`data.colour_augmentation` (default 0: none; `colour_augmentation.py`).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import ClassVar

from touchanything.core.errors import UserError, describe
from touchanything.inference.model.config_files import read_config_file
from touchanything.inference.model.config_sections import SectionReader, check_section, limits, section_to_dict
from touchanything.inference.model.model_config import (
    CLIP_LENGTH,
    FRAME_INTERVAL,
    ModelConfig,
    ModelInputConfig,
    config_to_dict,
    read_model_config,
)
from touchanything.inference.training.tactile_loss import TactileLossConfig

POSE_SOURCES = ("wilor", "rokoko")
GRAD_CLIP = 1.0  # the official trainer clips the gradient norm at 1.0 (not a config key)


@dataclass(frozen=True)
class OptimizerConfig:
    FIXED: ClassVar = {"type": "adamw"}
    lr: float = field(default=5e-5, metadata=limits(0.0))
    weight_decay: float = field(default=0.05, metadata=limits(0.0))
    betas: tuple[float, float] = field(default=(0.9, 0.999), metadata=limits(0.0, 1.0, high_open=True))


@dataclass(frozen=True)
class SchedulerConfig:
    """Linear warm-up from 1 % of `lr` over `warmup_epochs`, then cosine to `min_lr`; stepped per epoch."""

    FIXED: ClassVar = {"type": "cosine"}
    warmup_epochs: int = field(default=10, metadata=limits(0))
    min_lr: float = field(default=1e-6, metadata=limits(0.0))


@dataclass(frozen=True)
class TrainingConfig:
    """`num_workers`: DataLoader worker processes per training process (0: load in the main process)."""

    FIXED: ClassVar = {"invalid_pose_policy": "keep"}
    UNUSED: ClassVar = ("gradient_accumulation_steps", "keep_last_n", "log_interval", "pose_valid_joint_ratio_threshold")
    batch_size: int = field(default=16, metadata=limits(1))
    num_epochs: int = field(default=100, metadata=limits(1))
    save_interval: int = field(default=5, metadata=limits(1))
    val_interval: int = field(default=1, metadata=limits(1))
    num_workers: int = field(default=4, metadata=limits(0))
    optimizer: OptimizerConfig = OptimizerConfig()
    scheduler: SchedulerConfig = SchedulerConfig()
    loss: TactileLossConfig = TactileLossConfig()


@dataclass(frozen=True)
class SystemConfig:
    UNUSED: ClassVar = ("device", "gpu_ids", "cudnn_benchmark")
    seed: int = 42
    mixed_precision: bool = False


@dataclass(frozen=True)
class TrainingDataConfig:
    """The training part of `data`; the model's input keys (`image_size`, `blank_images`) are read by
    `ModelInputConfig`."""

    FIXED: ClassVar = {"use_augmentation": False, "random_crop": False, "random_flip": False}
    UNUSED: ClassVar = ("dataset", "data_root", "split_file", "mapping_left", "mapping_right", "train_split",
                        "val_split", "test_split", "use_camera_frame", "joint_set", "color_jitter", "glove_augmentation")
    ELSEWHERE: ClassVar = ("image_size", "blank_images", *ModelInputConfig.FIXED)
    pose_source: str = "wilor"
    fallback_pose_source: str | None = None
    colour_augmentation: float = field(default=0.0, metadata=limits(0.0, 1.0))


@dataclass(frozen=True)
class TrainConfig:
    """A whole training run: the model, `training`, `system`, the training part of `data`."""

    model: ModelConfig = ModelConfig()
    training: TrainingConfig = TrainingConfig()
    system: SystemConfig = SystemConfig()
    data: TrainingDataConfig = TrainingDataConfig()
    unused: tuple[str, ...] = field(default=(), compare=False)

    def check(self, source: str = "config") -> TrainConfig:
        self.model.check(source)
        check_section(self.training, "training", source)
        check_section(self.data, "data", source)
        warmup, epochs = self.training.scheduler.warmup_epochs, self.training.num_epochs
        if warmup > epochs:
            raise UserError(describe(source, "training.scheduler.warmup_epochs", f"{warmup} exceeds num_epochs {epochs}"))
        primary, fallback = self.data.pose_source, self.data.fallback_pose_source
        if primary not in POSE_SOURCES:
            raise UserError(describe(source, "data.pose_source", f"must be wilor or rokoko, got {primary!r}"))
        if self.data.colour_augmentation and self.model.vision_encoder.freeze:
            raise UserError(describe(source, "data.colour_augmentation",
                                     "needs a trained backbone: a frozen one's features are cached unaugmented"))
        if fallback not in (None, *POSE_SOURCES) or fallback == primary:
            raise UserError(describe(source, "data.fallback_pose_source",
                                     f"must be null or the other pose source, got {fallback!r}"))
        return self


def with_epochs(config: TrainConfig, epochs: int) -> tuple[TrainConfig, str | None]:
    """`config` training `epochs` epochs (≥ 1) and a note when its warm-up had to be shortened: a warm-up longer
    than the run becomes round(warm-up × epochs / configured epochs), at most epochs − 1."""
    if isinstance(epochs, bool) or not isinstance(epochs, int) or epochs < 1:
        raise UserError(f"--epochs must be a whole number ≥ 1, got {epochs!r}")
    t = config.training
    warmup, note = t.scheduler.warmup_epochs, None
    if warmup > epochs:
        shorter = min(epochs - 1, round(warmup * epochs / t.num_epochs))
        note = (f"note: warm-up shortened from {warmup} to {shorter} epoch(s) for a run of {epochs} "
                f"(in proportion to the config's {t.num_epochs} epochs)")
        warmup = shorter
    training = replace(t, num_epochs=epochs, scheduler=replace(t.scheduler, warmup_epochs=warmup))
    return replace(config, training=training).check(), note


SECTIONS = {"training": TrainingConfig, "system": SystemConfig, "data": TrainingDataConfig}
OTHER_SECTIONS = {"model", "evaluation"}  # read by the model reader / not used by training


def train_config_from_dict(data: dict, source: str = "config") -> TrainConfig:
    reader = SectionReader(source)
    for key in data:
        if key not in SECTIONS and key not in OTHER_SECTIONS:
            raise reader.error(key, "unknown section (the official structure has model, data, training, evaluation, system)")
    if "evaluation" in data:
        reader.unused.append("evaluation")
    model = read_model_config(data, reader)
    sections = {name: reader.read(cls, data.get(name), name) for name, cls in SECTIONS.items()}
    return TrainConfig(model=model, **sections, unused=tuple(reader.unused)).check(source)


def train_config_from_file(path: Path) -> TrainConfig:
    """Read a training config (its `_base_` chain merged underneath, as the official loader does)."""
    return train_config_from_dict(read_config_file(path), str(path))


def train_config_to_dict(config: TrainConfig) -> dict:
    """The whole config in the official structure, as written beside checkpoints (`config.yaml`)."""
    out = config_to_dict(config.model)
    out["data"].update(section_to_dict(config.data))
    return {**out, "training": section_to_dict(config.training), "system": section_to_dict(config.system)}


def _augmentation_note(config: TrainConfig) -> str:
    """"; colour augmentation S" when the run changes its frames' colours (never on black frames)."""
    strength = config.data.colour_augmentation
    return f"; colour augmentation {strength:g}" if strength and not config.model.blank_images else ""


def describe_settings(config: TrainConfig) -> list[str]:
    """The effective settings, a few lines, printed at the start of a run."""
    m, t, o, s, loss = config.model, config.training, config.training.optimizer, config.training.scheduler, config.training.loss
    loading = f"{t.num_workers} data-loader worker(s)" if t.num_workers else "data loaded in the main process"
    lines = [
        f"model: {m.backbone} at {m.image_size} px (backbone {'frozen' if m.vision_encoder.freeze else 'trained'}"
        f"{', weights ' + m.vision_encoder.pretrained_path if m.vision_encoder.pretrained_path else ''}), "
        f"temporal {m.temporal_transformer.num_layers}×{m.temporal_transformer.num_heads} heads, "
        f"cross-view {m.multi_view.num_cross_layers}, pose {m.pose_encoder.num_layers}, fusion {m.fusion.num_layers}, "
        f"decoder {m.tactile_decoder.conv_channels} channels; view dropout {m.multi_view.view_dropout_prob}",
        f"training: {t.num_epochs} epochs, batch {t.batch_size}, AdamW lr {o.lr:g} weight decay {o.weight_decay:g} "
        f"betas ({o.betas[0]:g}, {o.betas[1]:g}), {s.warmup_epochs} warm-up epochs then cosine to {s.min_lr:g}, "
        f"gradient clip {GRAD_CLIP:g}, {'mixed precision' if config.system.mixed_precision else 'fp32'}, seed {config.system.seed}, "
        f"{loading}",
        f"loss: mse {loss.mse_weight:g} + l1 {loss.l1_weight:g} (×{loss.contact_weight:g} above {loss.pressure_threshold:g}) "
        f"+ tv {loss.tv_weight:g}; clips of {CLIP_LENGTH} frames at interval {FRAME_INTERVAL}; poses {config.data.pose_source}"
        f"{' falling back to ' + config.data.fallback_pose_source if config.data.fallback_pose_source else ''}"
        f"{'; images blanked (pose-only baseline)' if config.model.blank_images else ''}"
        f"{_augmentation_note(config)}; "
        f"validation every {t.val_interval} epoch(s), a checkpoint every {t.save_interval}",
    ]
    if config.unused:
        lines.append("accepted, not used by this trainer: " + ", ".join(config.unused))
    return lines
