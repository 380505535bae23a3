"""The model's configuration in the official structure (`config.yaml` of the official release), and presets.

The `model` section is read strictly: the official sections `vision_encoder`, `temporal_transformer`,
`multi_view`, `pose_encoder`, `fusion`, `tactile_decoder` (field names as in the official YAML), plus
`num_input_joints`, `task`, `name` and the unused `pose_decoder`; anything else is an error naming the key and
the file. From `data`, the input size `image_size: [S, S]` and the settings the model's input depends on
(ImageNet normalisation, 8-frame clips at interval 2, the 21×21 grid) are read; other `data` keys belong to
training and are not looked at here. Absent keys take the official values.
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import ClassVar

import yaml

from touchanything.core.errors import UserError, describe
from touchanything.core.output_safety import write_text
from touchanything.inference.model.config_sections import SectionReader, check_section, limits, section_to_dict
from touchanything.inference.model.conv_backbone import CONV_BACKBONES
from touchanything.inference.model.vit import BACKBONES, PATCH

CLIP_LENGTH, FRAME_INTERVAL, TACTILE_SIZE, NUM_JOINTS = 8, 2, 21, 42
SPAN = (CLIP_LENGTH - 1) * FRAME_INTERVAL + 1  # frames one clip covers
IMAGENET_MEAN, IMAGENET_STD = [0.485, 0.456, 0.406], [0.229, 0.224, 0.225]
MAX_IMAGE_SIZE, MAX_WINDOW, MAX_LAYERS, MAX_HEADS, MAX_RATIO, MAX_WIDTH = 1024, 512, 64, 64, 16.0, 16384
"""Sane bounds of a config's sizes, checked before anything is built (a typo such as `image_size: 56000` would
otherwise ask for gigabytes per frame); within them, `check` also compares the estimated activation memory
with the machine's."""
LAYERS, HEADS = limits(1, MAX_LAYERS), limits(1, MAX_HEADS)
RATIO, DROPOUT = limits(0.0, MAX_RATIO), limits(0.0, 1.0, high_open=True)
ACTIVATION_SHARE = 0.5
"""A config whose estimated activation memory per frame exceeds this share of the machine's memory is refused."""


VISION_TYPES = {"dinov2": BACKBONES, "conv": CONV_BACKBONES}
"""`model.vision_encoder.type`: `dinov2` (the official ViT backbones) or `conv` (a project extension: the small
convolutional backbones of `conv_backbone`, trained from scratch, for the CPU presets)."""


def _backbone_spec(section):
    return VISION_TYPES.get(section.type, {}).get(section.model_name)


@dataclass(frozen=True)
class VisionEncoderConfig:
    DERIVED: ClassVar = {
        "patch_size": lambda s: PATCH if s.type == "dinov2" else (_backbone_spec(s).stride if _backbone_spec(s) else None),
        "embed_dim": lambda s: _backbone_spec(s).width if _backbone_spec(s) else None,
    }
    type: str = "dinov2"
    model_name: str = "dinov2_vitb14"
    pretrained_path: str | None = None
    freeze: bool = True


@dataclass(frozen=True)
class TemporalTransformerConfig:
    UNUSED: ClassVar = ("hidden_dim",)  # never read by the official code either
    num_layers: int = field(default=3, metadata=LAYERS)
    num_heads: int = field(default=8, metadata=HEADS)
    mlp_ratio: float = field(default=4.0, metadata=RATIO)
    dropout: float = field(default=0.1, metadata=DROPOUT)
    window_size: int = field(default=16, metadata=limits(CLIP_LENGTH, MAX_WINDOW))


@dataclass(frozen=True)
class MultiViewConfig:
    FIXED: ClassVar = {"enabled": True}
    num_cross_layers: int = field(default=2, metadata=LAYERS)
    num_heads: int = field(default=8, metadata=HEADS)
    mlp_ratio: float = field(default=4.0, metadata=RATIO)
    dropout: float = field(default=0.1, metadata=DROPOUT)
    view_dropout_prob: float = field(default=0.3, metadata=limits(0.0, 1.0))


POSE_INPUTS = ("camera", "hand")
"""`model.pose_encoder.input`: `camera` is the official pose input, `hand` a project extension
(`pose_encoder.TransformerPoseEncoder`)."""


@dataclass(frozen=True)
class PoseEncoderConfig:
    """`input` is a project extension (`pose_encoder.POSE_INPUTS`); `camera` is the official pose input."""

    FIXED: ClassVar = {"type": "transformer", "num_joints": NUM_JOINTS, "output_mode": "per_joint"}
    num_layers: int = field(default=2, metadata=LAYERS)
    num_heads: int = field(default=8, metadata=HEADS)
    mlp_ratio: float = field(default=4.0, metadata=RATIO)
    dropout: float = field(default=0.1, metadata=DROPOUT)
    input: str = "camera"


@dataclass(frozen=True)
class FusionConfig:
    FIXED: ClassVar = {"type": "cross_attention"}
    num_heads: int = field(default=8, metadata=HEADS)
    num_layers: int = field(default=2, metadata=LAYERS)
    mlp_ratio: float = field(default=4.0, metadata=RATIO)
    dropout: float = field(default=0.1, metadata=DROPOUT)


DECODER_TYPES = ("joint_level", "mlp_skip", "mlp_skip_views")


@dataclass(frozen=True)
class TactileDecoderConfig:
    """`type`: `joint_level` (official), or the project extensions `mlp_skip` and `mlp_skip_views`
    (`tactile_decoder.MlpTactileDecoder`; `mlp_skip_views` also reads each view's pooled backbone tokens)."""

    FIXED: ClassVar = {"num_joints": NUM_JOINTS, "tactile_size": TACTILE_SIZE}
    type: str = "joint_level"
    conv_channels: int = field(default=128, metadata=limits(1, MAX_WIDTH))
    dropout: float = field(default=0.1, metadata=DROPOUT)


@dataclass(frozen=True)
class BaselineConfig:
    """`model.baseline` (a project extension): present, the model is the single-frame baseline
    (`single_frame_baseline`) — the backbone of `vision_encoder` pooled per view, and an MLP of `layers` ×
    `hidden` units per hand; of the other sections only `multi_view.view_dropout_prob` applies."""

    hidden: int = field(default=512, metadata=limits(1, MAX_WIDTH))
    layers: int = field(default=2, metadata=LAYERS)
    dropout: float = field(default=0.1, metadata=DROPOUT)


@dataclass(frozen=True)
class ModelInputConfig:
    """The part of the `data` section the model's input depends on. `blank_images` (a project extension): the
    model was trained, and is run, with every frame black (`preprocess.blank_frames`) — a pose-only model."""

    FIXED: ClassVar = {"normalize_mean": IMAGENET_MEAN, "normalize_std": IMAGENET_STD, "clip_length": CLIP_LENGTH,
                       "frame_interval": FRAME_INTERVAL, "tactile_size": TACTILE_SIZE}
    image_size: tuple[int, int] = field(default=(224, 224), metadata=limits(1))
    blank_images: bool = False


@dataclass(frozen=True)
class ModelConfig:
    """The `model` section (official names) plus the square input size `data.image_size` and
    `data.blank_images`."""

    FIXED: ClassVar = {"task": "tactile_prediction", "num_input_joints": NUM_JOINTS}
    UNUSED: ClassVar = ("name", "pose_decoder")
    vision_encoder: VisionEncoderConfig = VisionEncoderConfig()
    temporal_transformer: TemporalTransformerConfig = TemporalTransformerConfig()
    multi_view: MultiViewConfig = MultiViewConfig()
    pose_encoder: PoseEncoderConfig = PoseEncoderConfig()
    fusion: FusionConfig = FusionConfig()
    tactile_decoder: TactileDecoderConfig = TactileDecoderConfig()
    baseline: BaselineConfig | None = field(default=None, metadata={"omit_none": True})
    image_size: int = field(default=224, metadata={"not_in_section": True})
    blank_images: bool = field(default=False, metadata={"not_in_section": True})

    @property
    def backbone(self) -> str:
        return self.vision_encoder.model_name

    @property
    def embed_dim(self) -> int:
        return _backbone_spec(self.vision_encoder).width

    @property
    def patch_size(self) -> int:
        """The backbone's output stride: one visual token per `patch_size`² pixels."""
        return VisionEncoderConfig.DERIVED["patch_size"](self.vision_encoder)

    @property
    def patches(self) -> int:
        """Backbone tokens per frame."""
        return (self.image_size // self.patch_size) ** 2

    def check(self, source: str = "config") -> ModelConfig:
        """One line naming the key for an impossible configuration."""
        def fail(key: str, problem: str) -> UserError:
            return UserError(describe(source, key, problem))

        encoder = self.vision_encoder
        if encoder.type not in VISION_TYPES:
            raise fail("model.vision_encoder.type", f"{encoder.type!r} is not supported; choose from {', '.join(VISION_TYPES)}")
        if _backbone_spec(encoder) is None:
            names = ", ".join(VISION_TYPES[encoder.type])
            raise fail("model.vision_encoder.model_name",
                       f"unknown backbone {self.backbone!r} for type {encoder.type}; choose from {names}")
        if encoder.type == "conv" and encoder.pretrained_path:
            raise fail("model.vision_encoder.pretrained_path", "a conv backbone is trained from scratch; no pretrained weights exist")
        if encoder.type == "conv" and encoder.freeze:
            raise fail("model.vision_encoder.freeze", "a conv backbone is trained from scratch; set freeze: false")
        if self.tactile_decoder.type not in DECODER_TYPES:
            raise fail("model.tactile_decoder.type",
                       f"{self.tactile_decoder.type!r} is not supported; choose from {', '.join(DECODER_TYPES)}")
        if self.pose_encoder.input not in POSE_INPUTS:
            raise fail("model.pose_encoder.input", f"{self.pose_encoder.input!r} is not supported; choose from {', '.join(POSE_INPUTS)}")
        check_section(self, "model", source)
        patch = self.patch_size
        if self.image_size < patch or self.image_size % patch:
            raise fail("data.image_size", f"{self.image_size} is not a positive multiple of the patch size {patch}")
        if self.image_size > MAX_IMAGE_SIZE:
            raise fail("data.image_size", f"must be ≤ {MAX_IMAGE_SIZE}, got {self.image_size}")
        needed, memory = activation_bytes(self), machine_memory_bytes()
        if needed > ACTIVATION_SHARE * memory:
            raise fail("data.image_size", f"{self.image_size} needs about {needed / 1e9:.1f} GB of activations per frame, "
                       f"more than {ACTIVATION_SHARE:.0%} of this machine's {memory / 1e9:.1f} GB")
        for section in ("temporal_transformer", "multi_view", "pose_encoder", "fusion"):
            heads = getattr(self, section).num_heads
            if self.embed_dim % heads:
                raise fail(f"model.{section}.num_heads", f"{heads} does not divide the width {self.embed_dim} of {self.backbone}")
        return self


def activation_bytes(config: ModelConfig, views: int = 3) -> float:
    """A rough upper estimate of the fp32 activations one frame of `views` views holds at its peak: the input
    image, the backbone's widest stage (a conv backbone's first stage; a ViT block's tokens × 8 for qkv and
    the MLP, plus every head's attention scores)."""
    pixels, tokens = config.image_size ** 2, config.patches
    spec = _backbone_spec(config.vision_encoder)
    widest = tokens * spec.width * 8
    if config.vision_encoder.type == "conv":
        widest += pixels // 4 * spec.channels[0] * 2
    else:
        widest += spec.heads * tokens ** 2
    return 4.0 * views * (pixels * 3 * 2 + widest)


def machine_memory_bytes() -> float:
    """The machine's physical memory."""
    return float(os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))


def with_backbone(config: ModelConfig, **changes) -> ModelConfig:
    """`config` with `vision_encoder` fields replaced (model_name, pretrained_path, freeze)."""
    return replace(config, vision_encoder=replace(config.vision_encoder, **changes))


def _light(backbone: str, size: int, temporal: int, heads: int, channels: int) -> ModelConfig:
    """A narrower, shallower preset: one layer of cross-view, pose and fusion attention."""
    return ModelConfig(
        vision_encoder=VisionEncoderConfig(model_name=backbone),
        temporal_transformer=TemporalTransformerConfig(num_layers=temporal, num_heads=heads),
        multi_view=MultiViewConfig(num_cross_layers=1, num_heads=heads),
        pose_encoder=PoseEncoderConfig(num_layers=1, num_heads=heads),
        fusion=FusionConfig(num_layers=1, num_heads=heads),
        tactile_decoder=TactileDecoderConfig(conv_channels=channels), image_size=size)


def _cpu(backbone: str, size: int, temporal: int, channels: int) -> ModelConfig:
    """A CPU preset (docs/findings.md): `_light` with 4 heads and the project extensions — a conv backbone
    trained from scratch, the wrist-relative hand pose input, the MLP decoder with the pose and view skips."""
    light = _light(backbone, size, temporal, 4, channels)
    return replace(light, vision_encoder=VisionEncoderConfig(type="conv", model_name=backbone, freeze=False),
                   pose_encoder=replace(light.pose_encoder, input="hand"),
                   tactile_decoder=replace(light.tactile_decoder, type="mlp_skip_views"))


PRESETS = {
    "paper": ModelConfig(),
    "small": _light("dinov2_vits14", 168, temporal=2, heads=8, channels=64),
    "tiny": _cpu("conv_t16", 112, temporal=2, channels=64),
    "nano": _cpu("conv_n16", 96, temporal=1, channels=64),
    "pico": _cpu("conv_p16", 64, temporal=1, channels=64),
    "nano_vit": with_backbone(_light("vit_n14", 112, temporal=1, heads=4, channels=32), freeze=False),
}
"""`paper` is exactly the official architecture; `small` (ViT-S/14 at 168 px, for users with the DINOv2
S/14 weights) is narrower and shallower; `tiny` (conv width 192 at 112 px), `nano` (conv width 128 at
96 px) and `pico` (conv width 64 at 64 px) are the CPU presets of configs/tiny.yaml, configs/nano.yaml and
configs/pico.yaml, trained from scratch (`_cpu`);
`nano_vit` is the nano of before them (the official structure with a ViT at 112 px, configs/nano_vit.yaml),
kept to measure against."""


def preset(name: str) -> ModelConfig:
    if name not in PRESETS:
        raise UserError(f"unknown preset {name!r}; choose from {', '.join(PRESETS)}")
    return PRESETS[name]


def read_model_config(data: dict, reader: SectionReader) -> ModelConfig:
    """The model described by an official-structure config dict (strict `model`, lenient `data`)."""
    model = reader.read(ModelConfig, data.get("model"), "model")
    inputs = reader.read(ModelInputConfig, data.get("data"), "data", strict=False)
    height, width = inputs.image_size
    if height != width:
        raise reader.error("data.image_size", f"must be square, got {list(inputs.image_size)}")
    return replace(model, image_size=height, blank_images=inputs.blank_images).check(reader.source)


def config_from_dict(data: dict, source: str = "config") -> ModelConfig:
    """`read_model_config` with a fresh reader naming `source` in its errors."""
    return read_model_config(data, SectionReader(source))


def config_to_dict(config: ModelConfig) -> dict:
    """The official structure: the `model` section and the `data` keys the model's input depends on."""
    inputs = section_to_dict(ModelInputConfig(image_size=(config.image_size, config.image_size),
                                              blank_images=config.blank_images))
    return {"model": section_to_dict(config), "data": inputs}


def write_config(path: Path, config: ModelConfig) -> None:
    write_text(Path(path), yaml.safe_dump(config_to_dict(config), sort_keys=False))
