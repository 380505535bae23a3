"""Colour augmentation of training clips (`data.colour_augmentation`): per clip and view, within the image range,
refused outside [0, 1] and with a frozen backbone, and applied by the trainer."""
from __future__ import annotations

import pytest
import torch

from touchanything.core.errors import UserError
from touchanything.inference.model.model_config import PRESETS, with_backbone
from touchanything.inference.model.preprocess import IMAGENET_MEAN, IMAGENET_STD
from touchanything.inference.training.colour_augmentation import augment_clip, augment_views
from touchanything.inference.training.train_config import (
    TrainConfig,
    TrainingDataConfig,
    describe_settings,
    train_config_from_file,
)


def normalised(images: torch.Tensor) -> torch.Tensor:
    return (images - IMAGENET_MEAN) / IMAGENET_STD


def pixels(frames: torch.Tensor) -> torch.Tensor:
    return frames * IMAGENET_STD + IMAGENET_MEAN


def test_strength_zero_leaves_the_frames_alone():
    frames = normalised(torch.rand(2, 8, 3, 16, 16))
    assert augment_clip(frames, 0.0) is frames


def test_one_draw_per_clip_within_the_image_range():
    torch.manual_seed(0)
    clip = torch.rand(6, 1, 3, 16, 16).expand(6, 8, 3, 16, 16)  # each clip: one image repeated over T
    out = pixels(augment_clip(normalised(clip), 0.8))
    assert out.min() >= -1e-5 and out.max() <= 1 + 1e-5
    assert torch.allclose(out, out[:, :1].expand_as(out), atol=1e-5)  # the same change for every frame of a clip
    per_clip = out[:, 0].flatten(1)
    assert torch.cdist(per_clip, per_clip).triu(1)[torch.ones(6, 6).triu(1).bool()].min() > 0  # clips differ


def test_full_strength_reorders_channels_and_keeps_a_black_frame_black():
    torch.manual_seed(1)
    red = torch.zeros(64, 1, 3, 8, 8)
    red[:, :, 0] = 0.5
    out = pixels(augment_clip(normalised(red), 1.0))
    brightest = out.mean(dim=(1, 3, 4)).argmax(dim=1)
    assert set(brightest.tolist()) == {0, 1, 2}  # the red moved to every channel in some clips
    black = pixels(augment_clip(normalised(torch.zeros(4, 2, 3, 8, 8)), 1.0))
    assert black.abs().max() < 1e-5


def test_saturated_and_non_finite_frames():
    white = pixels(augment_clip(normalised(torch.ones(4, 2, 3, 8, 8)), 0.5))
    assert white.min() >= 0.5 - 1e-5 and white.max() <= 1 + 1e-5  # a dimmed or clipped white, never outside
    bad = normalised(torch.rand(2, 2, 3, 8, 8))
    bad[0, 0, 0, 0, 0] = float("nan")
    assert torch.isnan(augment_clip(bad, 0.5)[0]).any()  # left for the trainer's loss check to report
    views = augment_views({"ego": normalised(torch.rand(1, 2, 3, 8, 8)), "wrist_left": normalised(torch.rand(1, 2, 3, 8, 8))}, 0.5)
    assert set(views) == {"ego", "wrist_left"}


def test_the_setting_is_read_bounded_and_shown(tmp_path):
    path = tmp_path / "aug.yaml"
    path.write_text("model: {vision_encoder: {freeze: false}}\ndata: {colour_augmentation: 0.4}\n")
    config = train_config_from_file(path)
    assert config.data.colour_augmentation == 0.4 and "data.colour_augmentation" not in config.unused
    assert "colour augmentation 0.4" in "\n".join(describe_settings(config))
    for value in ("1.5", "-0.1", ".nan"):
        path.write_text(f"data: {{colour_augmentation: {value}}}\n")
        with pytest.raises(UserError, match="data.colour_augmentation"):
            train_config_from_file(path)
    frozen = TrainConfig(model=with_backbone(PRESETS["nano_vit"], freeze=True), data=TrainingDataConfig(colour_augmentation=0.4))
    with pytest.raises(UserError, match="frozen"):
        frozen.check()
