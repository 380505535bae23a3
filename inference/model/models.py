"""The model a config describes: TouchAnything (official architecture, and the CPU presets' extensions) or the
single-frame baseline (`model.baseline`)."""
from __future__ import annotations

from touchanything.inference.model.model_config import ModelConfig
from touchanything.inference.model.single_frame_baseline import SingleFrameBaseline
from touchanything.inference.model.touch_model import TouchAnything
from touchanything.inference.model.vision_encoder import backbone

TactileModel = TouchAnything | SingleFrameBaseline
"""Both take `forward(poses=, views=)`, `encode_frames`, `head`, `last_kept`, `set_pose_statistics` and
`frame_token_shape`."""


def create_model(config: ModelConfig) -> TactileModel:
    """A new, randomly initialised model for `config` (checked)."""
    config = config.check()
    if config.baseline is not None:
        return SingleFrameBaseline(config, backbone(config))
    return TouchAnything(config)
