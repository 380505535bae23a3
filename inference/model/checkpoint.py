"""Checkpoints in the official format (`model_state_dict`, `optimizer_state_dict`, … with a `config.yaml`
beside them) and the public loader `load_model`."""
from __future__ import annotations

import warnings
from pathlib import Path

import torch
import yaml

from touchanything.core.errors import UserError
from touchanything.core.output_safety import replacing, write_text
from touchanything.inference.model.config_files import read_config_file
from touchanything.inference.model.model_config import ModelConfig, config_from_dict, write_config
from touchanything.inference.model.models import TactileModel, create_model
from touchanything.inference.model.vit import load_dinov2_weights

CONFIG_FILE = "config.yaml"
BACKBONE_PREFIXES = ("vision_encoder.encoder.", "multi_view_encoder.vision_encoder.encoder.")


def read_checkpoint(path: Path) -> dict:
    """torch.load with weights_only (nothing in the file runs); one user-facing line, and no library warning,
    for a missing or unreadable file."""
    path = Path(path)
    if not path.is_file():
        raise UserError(f"{path}: checkpoint not found")
    try:
        with warnings.catch_warnings():  # e.g. torch's "Detected pickle protocol 5" before its own error
            warnings.simplefilter("ignore")
            data = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # torch raises several types (pickle, zip, runtime) for a bad file
        raise UserError(f"{path}: not a readable PyTorch checkpoint ({exc.__class__.__name__})") from None
    if not isinstance(data, dict):
        raise UserError(f"{path}: expected a dict checkpoint")
    return data


def model_state(checkpoint: dict, path: Path) -> dict[str, torch.Tensor]:
    """The state dict inside a checkpoint (`model_state_dict`, `state_dict` or the dict itself), with
    `module.` prefixes stripped."""
    state = checkpoint.get("model_state_dict", checkpoint.get("state_dict", checkpoint))
    if not isinstance(state, dict) or not all(isinstance(v, torch.Tensor) for v in state.values()):
        raise UserError(f"{path}: no model state dict found (expected key 'model_state_dict')")
    return {k.removeprefix("module."): v for k, v in state.items()}


def load_state(model: TactileModel, state: dict[str, torch.Tensor], path: Path) -> None:
    """Strict load; mismatches are reported by name (a checkpoint for another preset is named as such). A
    TouchAnything backbone present under one official prefix only is copied to the other (the official model
    holds it twice). A tensor holding NaN or infinite values is refused, named."""
    expected = model.state_dict()
    state = dict(state)
    for have, want in (BACKBONE_PREFIXES, BACKBONE_PREFIXES[::-1]):
        if any(k.startswith(want) for k in expected) and not any(k.startswith(want) for k in state):
            state.update({want + k[len(have):]: v for k, v in list(state.items()) if k.startswith(have)})
    missing = sorted(set(expected) - set(state))
    unexpected = sorted(set(state) - set(expected))
    wrong = [(k, tuple(state[k].shape), tuple(v.shape)) for k, v in expected.items() if k in state and state[k].shape != v.shape]
    if missing or unexpected or wrong:
        parts = []
        if wrong:
            parts.append("shape mismatch " + ", ".join(f"{k} {a} vs model {b}" for k, a, b in wrong[:3]))
        if missing:
            parts.append(f"missing {len(missing)} key(s) e.g. {', '.join(missing[:3])}")
        if unexpected:
            parts.append(f"unexpected {len(unexpected)} key(s) e.g. {', '.join(unexpected[:3])}")
        raise UserError(f"{path}: checkpoint does not match the configured architecture "
                        f"({model.config.backbone}, {model.config.image_size} px; is it for another preset "
                        f"or config?): {'; '.join(parts)}")
    if damaged := next((k for k, v in state.items() if v.is_floating_point() and not bool(torch.isfinite(v).all())), None):
        raise UserError(f"{path}: tensor {damaged} holds NaN or infinite values (a damaged or diverged checkpoint)")
    model.load_state_dict(state, strict=True)


def find_config(checkpoint_path: Path, config_path: Path | None) -> Path:
    if config_path is not None:
        return Path(config_path)
    beside = Path(checkpoint_path).parent / CONFIG_FILE
    if not beside.is_file():
        raise UserError(f"{checkpoint_path}: no {CONFIG_FILE} beside the checkpoint; pass the config file")
    return beside


def load_model(checkpoint_path: Path, config_path: Path | None = None) -> TactileModel:
    """Load an official or project checkpoint with its `config.yaml` (official structure, `_base_` merged)
    → model in eval mode.

    The backbone weights come from the checkpoint, so the config's `pretrained_path` is not needed.
    """
    checkpoint = read_checkpoint(checkpoint_path)
    config = config_from_dict(read_config_file(find_config(checkpoint_path, config_path)), str(config_path or checkpoint_path))
    model = create_model(config)
    load_state(model, model_state(checkpoint, Path(checkpoint_path)), Path(checkpoint_path))
    return model.eval()


def build_model(config: ModelConfig, pretrained: bool = True) -> TactileModel:
    """A new model; with `pretrained` and a `pretrained_path` in the config, DINOv2 weights are loaded
    from that local file (a missing file is an error, never a silent random backbone)."""
    model = create_model(config)
    weights = config.vision_encoder.pretrained_path
    if pretrained and weights:
        load_dinov2_weights(model.vision_encoder.encoder, Path(weights))
    return model


def save_checkpoint(path: Path, model: TactileModel, *, epoch: int = 0, optimizer=None, scheduler=None,
                    loss: float | None = None, metrics: dict | None = None, half: bool = False,
                    config: dict | None = None) -> None:
    """Official dict format plus `config.yaml` beside (`config`, or the model's own section); `half`
    stores floating tensors as fp16. Written to a temporary name and renamed (output_safety.replacing), so a
    crash or a full disk never leaves a truncated checkpoint."""
    state = model.state_dict()
    if half:
        state = {k: v.half() if v.is_floating_point() else v for k, v in state.items()}
    path = Path(path)
    with replacing(path) as partial:
        torch.save({
            "epoch": epoch, "model_state_dict": state,
            "optimizer_state_dict": optimizer.state_dict() if optimizer is not None else {},
            "scheduler_state_dict": scheduler.state_dict() if scheduler is not None else {},
            "loss": loss, "metrics": metrics or {},
        }, partial)
    if config is None:
        write_config(path.parent / CONFIG_FILE, model.config)
    else:
        write_text(path.parent / CONFIG_FILE, yaml.safe_dump(config, sort_keys=False))
