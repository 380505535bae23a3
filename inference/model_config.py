"""Model configuration: the official `config.yaml` structure (base + override merge), presets, I/O.

Official keys read (aliases in brackets, for configs written by other versions):
model.vision.{backbone [model_name, name], embed_dim, freeze [frozen], pretrained_path, image_size},
model.temporal.{num_layers, num_heads, mlp_ratio, dropout, window_size},
model.multi_view.{enabled, num_cross_layers [num_layers], num_heads, dropout, view_dropout_prob},
model.pose_encoder.{num_layers, num_heads}, model.fusion.{num_layers, num_heads},
model.tactile_decoder.{num_joints, conv_channels, tactile_size, dropout}; data.image_size (fallback for
the input size, default 224).
"""
from __future__ import annotations

import copy
import os
from dataclasses import dataclass
from pathlib import Path

import yaml

from devices.errors import UserError
from inference.vit import BACKBONES, PATCH


@dataclass(frozen=True)
class ModelConfig:
    """Everything that fixes the architecture (and the input size)."""

    backbone: str = "dinov2_vitb14"
    image_size: int = 224
    freeze_backbone: bool = True
    pretrained_path: str | None = None
    temporal_layers: int = 3
    temporal_heads: int = 8
    mlp_ratio: float = 4.0
    dropout: float = 0.1
    window_size: int = 16
    cross_view_layers: int = 2
    cross_view_heads: int = 8
    view_dropout: float = 0.3
    pose_layers: int = 2
    pose_heads: int = 8
    fusion_layers: int = 2
    fusion_heads: int = 8
    decoder_channels: int = 128
    decoder_dropout: float = 0.1
    num_joints: int = 42
    tactile_size: int = 21

    @property
    def embed_dim(self) -> int:
        return BACKBONES[self.backbone].width

    @property
    def patches(self) -> int:
        return (self.image_size // PATCH) ** 2

    def check(self) -> "ModelConfig":
        """One clear error for an impossible configuration."""
        if self.backbone not in BACKBONES:
            raise UserError(f"unknown backbone {self.backbone!r}; choose from {', '.join(BACKBONES)}")
        if self.image_size % PATCH or self.image_size < PATCH:
            raise UserError(f"image size {self.image_size} must be a positive multiple of {PATCH}")
        for name in ("temporal_heads", "cross_view_heads", "pose_heads", "fusion_heads"):
            if self.embed_dim % getattr(self, name):
                raise UserError(f"{name} = {getattr(self, name)} does not divide the width {self.embed_dim}")
        if self.num_joints != 42 or self.tactile_size != 21:
            raise UserError("only the official 42 joints and 21×21 tactile grid are supported")
        return self


PRESETS = {
    "paper": ModelConfig(),
    "small": ModelConfig(backbone="dinov2_vits14", image_size=168, temporal_layers=2, cross_view_layers=1,
                         pose_layers=1, fusion_layers=1, decoder_channels=64),
    "tiny": ModelConfig(backbone="vit_t14", image_size=112, temporal_layers=2, temporal_heads=4,
                        cross_view_layers=1, cross_view_heads=4, pose_layers=1, pose_heads=4,
                        fusion_layers=1, fusion_heads=4, decoder_channels=64),
    "nano": ModelConfig(backbone="vit_n14", image_size=112, temporal_layers=1, temporal_heads=4,
                        cross_view_layers=1, cross_view_heads=4, pose_layers=1, pose_heads=4,
                        fusion_layers=1, fusion_heads=4, decoder_channels=32),
}
"""`paper` is exactly the official architecture; `small` (ViT-S/14 at 168 px, for users with the DINOv2
S/14 weights), `tiny` (width 192, 6 blocks at 112 px) and `nano` (width 128, 4 blocks at 112 px) are
narrower and shallower for CPU real time; tiny and nano train from scratch on a CPU."""


def preset(name: str) -> ModelConfig:
    if name not in PRESETS:
        raise UserError(f"unknown preset {name!r}; choose from {', '.join(PRESETS)}")
    return PRESETS[name]


def deep_merge(base: dict, override: dict) -> dict:
    """Nested dicts merge; every other value is replaced (the official `load_config_with_base`)."""
    out = copy.deepcopy(base)
    for key, value in override.items():
        out[key] = deep_merge(out[key], value) if isinstance(value, dict) and isinstance(out.get(key), dict) else copy.deepcopy(value)
    return out


def _expand(value):
    if isinstance(value, dict):
        return {k: _expand(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_expand(v) for v in value]
    return os.path.expanduser(os.path.expandvars(value)) if isinstance(value, str) else value


def _read_yaml(path: Path) -> dict:
    try:
        data = yaml.safe_load(Path(path).read_text())
    except FileNotFoundError:
        raise UserError(f"{path}: config file not found") from None
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise UserError(f"{path}: not a readable YAML file ({exc.__class__.__name__})") from None
    if not isinstance(data, dict):
        raise UserError(f"{path}: expected a mapping at the top level")
    return data


def read_config_file(path: Path) -> dict:
    """Read a config; a `base.yaml` beside it is merged underneath, as the official loader does."""
    path = Path(path)
    data = _read_yaml(path)
    base = path.parent / "base.yaml"
    if base.is_file() and base.resolve() != path.resolve():
        data = deep_merge(_read_yaml(base), data)
    return _expand(data)


def _pick(section: dict, names: tuple[str, ...], default):
    for name in names:
        if name in section:
            return section[name]
    return default


def config_from_dict(data: dict, source: str = "config") -> ModelConfig:
    """The architecture described by an official-structure config dict."""
    model = data.get("model") or {}
    sections = {k: model.get(k) or {} for k in ("vision", "temporal", "multi_view", "pose_encoder", "fusion", "tactile_decoder")}
    vision, temporal, mv = sections["vision"], sections["temporal"], sections["multi_view"]
    pose, fusion, decoder = sections["pose_encoder"], sections["fusion"], sections["tactile_decoder"]
    d = ModelConfig()
    try:
        config = ModelConfig(
            backbone=str(_pick(vision, ("backbone", "model_name", "name"), d.backbone)),
            image_size=int(_pick(vision, ("image_size",), (data.get("data") or {}).get("image_size", d.image_size))),
            freeze_backbone=bool(_pick(vision, ("freeze", "frozen"), d.freeze_backbone)),
            pretrained_path=_pick(vision, ("pretrained_path",), None),
            temporal_layers=int(temporal.get("num_layers", d.temporal_layers)),
            temporal_heads=int(temporal.get("num_heads", d.temporal_heads)),
            mlp_ratio=float(temporal.get("mlp_ratio", d.mlp_ratio)),
            dropout=float(temporal.get("dropout", d.dropout)),
            window_size=int(temporal.get("window_size", d.window_size)),
            cross_view_layers=int(_pick(mv, ("num_cross_layers", "num_layers"), d.cross_view_layers)),
            cross_view_heads=int(mv.get("num_heads", d.cross_view_heads)),
            view_dropout=float(mv.get("view_dropout_prob", d.view_dropout)),
            pose_layers=int(pose.get("num_layers", d.pose_layers)),
            pose_heads=int(pose.get("num_heads", d.pose_heads)),
            fusion_layers=int(fusion.get("num_layers", d.fusion_layers)),
            fusion_heads=int(fusion.get("num_heads", d.fusion_heads)),
            decoder_channels=int(decoder.get("conv_channels", d.decoder_channels)),
            decoder_dropout=float(decoder.get("dropout", d.decoder_dropout)),
            num_joints=int(decoder.get("num_joints", model.get("num_input_joints", d.num_joints))),
            tactile_size=int(decoder.get("tactile_size", d.tactile_size)),
        )
    except (TypeError, ValueError) as exc:
        raise UserError(f"{source}: a model setting has the wrong type ({exc})") from None
    return config.check()


def config_to_dict(config: ModelConfig) -> dict:
    """The official structure (plus `vision.image_size`), for the `config.yaml` written beside checkpoints."""
    c = config
    return {"model": {
        "task": "tactile_prediction", "num_input_joints": c.num_joints,
        "vision": {"backbone": c.backbone, "embed_dim": c.embed_dim, "freeze": c.freeze_backbone,
                   "pretrained_path": c.pretrained_path, "image_size": c.image_size},
        "temporal": {"num_layers": c.temporal_layers, "num_heads": c.temporal_heads, "mlp_ratio": c.mlp_ratio,
                     "dropout": c.dropout, "window_size": c.window_size},
        "multi_view": {"enabled": True, "num_cross_layers": c.cross_view_layers, "num_heads": c.cross_view_heads,
                       "dropout": c.dropout, "view_dropout_prob": c.view_dropout},
        "pose_encoder": {"type": "transformer", "num_layers": c.pose_layers, "num_heads": c.pose_heads},
        "fusion": {"type": "cross_attention", "num_layers": c.fusion_layers, "num_heads": c.fusion_heads},
        "tactile_decoder": {"type": "joint_level", "num_joints": c.num_joints, "conv_channels": c.decoder_channels,
                            "tactile_size": c.tactile_size, "dropout": c.decoder_dropout},
    }, "data": {"image_size": c.image_size, "clip_length": 8, "frame_interval": 2, "pose_source": "wilor"}}


def write_config(path: Path, config: ModelConfig, extra: dict | None = None) -> None:
    data = deep_merge(config_to_dict(config), extra or {})
    Path(path).write_text(yaml.safe_dump(data, sort_keys=False))


