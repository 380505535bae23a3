"""The CPU presets' project extensions — the conv backbone (`vision_encoder.type: conv`), the hand pose input
(`pose_encoder.input: hand`) and the single-frame baseline (`model.baseline`): their config keys and errors,
numerics at the extremes, and that the streaming engine, ONNX export (fp32 and int8) and checkpoints take them."""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
import torch
import yaml

from touchanything.core.errors import UserError
from touchanything.core.snapshot import VIEW_NAMES, Snapshot
from touchanything.inference.engine.engine_setting import EngineSetting
from touchanything.inference.engine.onnx_export import export_onnx
from touchanything.inference.engine.streaming_engine import StreamingEngine
from touchanything.inference.model.checkpoint import load_model, save_checkpoint
from touchanything.inference.model.model_config import (
    PRESETS,
    BaselineConfig,
    ModelConfig,
    config_from_dict,
    config_to_dict,
)
from touchanything.inference.model.models import create_model
from touchanything.inference.model.pose_encoder import FEATURE_LIMIT, hand_features, prepare_poses
from touchanything.inference.model.single_frame_baseline import SingleFrameBaseline
from touchanything.inference.training.train_config import train_config_from_file

CONV_NANO = dataclasses.replace(PRESETS["nano"], image_size=64)
BASELINE = dataclasses.replace(CONV_NANO, baseline=BaselineConfig(hidden=64, layers=1))
POSE_SKIP = dataclasses.replace(CONV_NANO, tactile_decoder=dataclasses.replace(CONV_NANO.tactile_decoder, type="mlp_skip"))
MODELS = {"conv nano": CONV_NANO, "baseline": BASELINE, "pose skip only": POSE_SKIP}


def make(config: ModelConfig, seed: int = 0):
    torch.manual_seed(seed)
    model = create_model(config)
    poses = prepare_poses(np.random.default_rng(seed).normal([0, 0, 12], 0.2, (50, 42, 3)), np.ones((50, 2), bool))
    model.set_pose_statistics(poses)
    return model.eval()


def snapshots(size: int, frames: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    for i in range(frames):
        joints = rng.normal([0, 0, 12], 0.2, (42, 3)).astype(np.float32)
        yield Snapshot(i, i * 33_333, {v: rng.integers(0, 256, (size, size, 3), dtype=np.uint8) for v in VIEW_NAMES},
                       joints, np.array([True, i % 5 != 4]))


@pytest.mark.parametrize("raw, message", [
    ({"vision_encoder": {"type": "resnet"}}, r"model.vision_encoder.type: 'resnet' is not supported; choose from dinov2, conv"),
    ({"vision_encoder": {"type": "conv", "model_name": "vit_n14", "freeze": False}}, r"unknown backbone 'vit_n14' for type conv"),
    ({"vision_encoder": {"type": "conv", "model_name": "conv_n16"}}, r"model.vision_encoder.freeze: .* set freeze: false"),
    ({"vision_encoder": {"type": "conv", "model_name": "conv_n16", "freeze": False, "pretrained_path": "w.pth"}},
     r"pretrained_path: a conv backbone is trained from scratch"),
    ({"vision_encoder": {"type": "conv", "model_name": "conv_n16", "freeze": False, "patch_size": 14}},
     r"patch_size: is 14 but must be 16"),
    ({"pose_encoder": {"input": "world"}}, r"model.pose_encoder.input: 'world' is not supported; choose from camera, hand"),
    ({"baseline": {"hidden": 0}}, r"model.baseline.hidden: must be ≥ 1"),
    ({"baseline": [1, 2]}, r"model.baseline: expected a mapping"),
])
def test_extension_keys_are_checked_with_one_line(raw, message):
    with pytest.raises(UserError, match=message):
        config_from_dict({"model": raw, "data": {"image_size": [96, 96]}}, "x.yaml")


def test_an_image_size_that_is_not_a_multiple_of_the_conv_stride_is_refused():
    raw = {"model": {"vision_encoder": {"type": "conv", "model_name": "conv_n16", "freeze": False}}, "data": {"image_size": [100, 100]}}
    with pytest.raises(UserError, match=r"data.image_size: 100 is not a positive multiple of the patch size 16"):
        config_from_dict(raw, "x.yaml")


@pytest.mark.parametrize("name", MODELS)
def test_configs_round_trip_and_official_configs_gain_no_baseline_key(name):
    config = MODELS[name]
    assert config_from_dict(yaml.safe_load(yaml.safe_dump(config_to_dict(config)))) == config
    assert "baseline" not in config_to_dict(PRESETS["paper"])["model"]
    assert config_to_dict(CONV_NANO)["model"]["vision_encoder"]["patch_size"] == 16


def test_conv_backbone_gives_one_token_per_cell():
    model = make(CONV_NANO)
    tokens = model.vision_encoder.encoder.forward_features(torch.zeros(3, 3, 64, 64))["x_norm_patchtokens"]
    assert tokens.shape == (3, 16, 128) and CONV_NANO.patches == 16


def test_hand_features_are_wrist_relative_and_bounded_for_invalid_hands():
    joints = np.random.default_rng(0).normal([0.1, 0.0, 12.0], 0.05, (2, 42, 3))
    features = hand_features(torch.from_numpy(prepare_poses(joints, np.array([[True, False], [True, True]]))))
    assert torch.allclose(features[0, :21, :3], torch.from_numpy(joints[0, :21] - joints[0, :1]).float(), atol=1e-5)
    assert torch.equal(features[0, 21:], torch.tensor([0, 0, 0, -10, -10, -10.0]).expand(21, 6))
    model = make(CONV_NANO)
    x = model.pose_encoder.normalised(torch.from_numpy(prepare_poses(joints, np.array([[True, False], [True, True]]))))
    assert x.abs().max() <= FEATURE_LIMIT and torch.isfinite(x).all()


def test_pose_statistics_come_from_valid_hands_and_survive_a_checkpoint(tmp_path):
    model = make(CONV_NANO)
    scale = model.pose_encoder.pose_scale.clone()
    assert torch.all(scale > 0) and not torch.equal(scale, torch.ones(6))
    assert model.set_pose_statistics(np.full((4, 42, 3), -10.0, np.float32)) == 0  # no valid hand: unchanged
    assert torch.equal(model.pose_encoder.pose_scale, scale)
    save_checkpoint(tmp_path / "m.pth", model)
    assert torch.equal(load_model(tmp_path / "m.pth").pose_encoder.pose_scale, scale)


@pytest.mark.parametrize("name", MODELS)
@pytest.mark.parametrize("views", [("ego",), VIEW_NAMES])
def test_streaming_newest_frame_equals_the_batch_forward(name, views):
    model = make(MODELS[name])
    frames = list(snapshots(64, 16, seed=2))
    engine = StreamingEngine(model, EngineSetting(views=views))
    predictions = [p for s in frames for p in engine.step(s)]
    clip = [frames[i] for i in range(1, 16, 2)]
    batch = {v: torch.stack([torch.from_numpy(s.images[v]) for s in clip]).float().div(255).movedim(-1, 1) for v in views}
    mean, std = torch.tensor([0.485, 0.456, 0.406]).view(3, 1, 1), torch.tensor([0.229, 0.224, 0.225]).view(3, 1, 1)
    batch = {v: ((x - mean) / std)[None] for v, x in batch.items()}
    poses = torch.from_numpy(np.stack([prepare_poses(s.joints, s.joints_valid) for s in clip]))[None]
    with torch.no_grad():
        expected = model(poses=poses, views=batch)["tactile"][0, -1].numpy()
    last = predictions[-1]
    hands = [h for h in (0, 1) if clip[-1].joints_valid[h]]
    assert last.window_exact and last.hands_predicted == tuple(bool(clip[-1].joints_valid[h]) for h in (0, 1))
    assert np.nanmax(np.abs(last.pressure[hands] - expected[hands])) < 1e-4


@pytest.mark.parametrize("name", MODELS)
def test_onnx_export_fp32_and_int8_agree_with_torch(name, tmp_path):
    model = make(MODELS[name])
    export_onnx(model, tmp_path, int8=True)
    frames = list(snapshots(64, 14, seed=5))
    torch_engine = StreamingEngine(model, EngineSetting())
    reference = [p.pressure for s in frames for p in torch_engine.step(s)]
    for precision, tolerance in (("fp32", 1e-4), ("int8", 0.1)):
        engine = StreamingEngine(model, EngineSetting(runtime="onnx", precision=precision), onnx_dir=tmp_path)
        got = [p.pressure for s in frames for p in engine.step(s)]
        assert max(float(np.nanmax(np.abs(a - b))) for a, b in zip(got, reference)) < tolerance


@pytest.mark.parametrize("name", MODELS)
def test_extreme_frames_and_poses_give_finite_maps_in_range(name):
    model = make(MODELS[name])
    views = {v: torch.full((1, 8, 3, 64, 64), value) for v, value in zip(VIEW_NAMES, (-3.0, 3.0, 0.0))}
    poses = torch.from_numpy(prepare_poses(np.full((1, 8, 42, 3), 1e6), np.ones((1, 8, 2), bool)))
    with torch.no_grad():
        out = model(poses=poses, views=views)["tactile"]
    assert torch.isfinite(out).all() and out.min() >= 0 and out.max() <= 1


def test_the_baseline_is_its_own_class_and_ignores_time():
    model = make(BASELINE)
    assert isinstance(model, SingleFrameBaseline)
    views = {v: torch.randn(1, 8, 3, 64, 64) for v in VIEW_NAMES}
    poses = torch.from_numpy(prepare_poses(np.random.default_rng(1).normal([0, 0, 12], 0.2, (1, 8, 42, 3)),
                                           np.ones((1, 8, 2), bool)))
    with torch.no_grad():
        whole = model(poses=poses, views=views)["tactile"]
        last = model(poses=poses[:, -1:], views={v: x[:, -1:] for v, x in views.items()})["tactile"]
    assert torch.allclose(whole[:, -1:], last, atol=1e-6)


@pytest.mark.parametrize("name", ["nano", "tiny", "nano_vit"])
def test_the_bundled_configs_are_the_presets(name):
    """configs/NAME.yaml (what the bundled models were trained with) builds exactly PRESETS[NAME]."""
    assert train_config_from_file(Path(f"configs/{name}.yaml")).model == PRESETS[name]


def test_the_pose_skip_is_a_direct_path_from_the_pose_to_the_cells():
    """With the fused tokens (and view slots) fixed, the mlp_skip and mlp_skip_views decoders' maps still change
    with the hand pose."""
    poses = torch.from_numpy(prepare_poses(np.random.default_rng(1).normal([0, 0, 12], 0.2, (42, 3)), np.ones(2, bool)))
    for config in (PRESETS["nano"], POSE_SKIP):
        model = make(config)
        fused, slots = torch.zeros(1, 1, 42, model.config.embed_dim), torch.ones(1, 1, 3, model.config.embed_dim)
        with torch.no_grad():
            a = model.decoder(fused, model.pose_encoder.normalised(poses[None, None]), slots)
            b = model.decoder(fused, model.pose_encoder.normalised(poses[None, None] * 1.2), slots)
        assert a.shape == (1, 1, 2, 21, 21) and not torch.allclose(a, b)


def test_the_view_skip_reads_each_hand_s_own_wrist_camera_directly():
    """mlp_skip_views (the CPU presets): with the fused tokens and the pose fixed, the maps change with the pooled
    view slots; the left hand reads the left wrist slot where the right hand reads the right one (and vice
    versa); mlp_skip has no such input."""
    poses = torch.from_numpy(prepare_poses(np.random.default_rng(1).normal([0, 0, 12], 0.2, (42, 3)), np.ones(2, bool)))
    model = make(CONV_NANO)
    d = model.config.embed_dim
    fused, pose = torch.zeros(1, 1, 42, d), model.pose_encoder.normalised(poses[None, None])
    slots = torch.randn(1, 1, 3, d)
    swapped = slots[:, :, [0, 2, 1]]
    with torch.no_grad():
        a, b = model.decoder(fused, pose, slots), model.decoder(fused, pose, torch.zeros(1, 1, 3, d))
        feats = model.decoder.joint_proj(torch.zeros(1, 21, d))
        own_first = slots[0, :, [0, 1, 2]].flatten(1)  # chest, left wrist, right wrist: the left hand's order
        left = model.decoder.hand(feats, pose[0, :, :21], own_first)
        right_given_swapped = model.decoder(fused, pose, swapped)[0, 0, 1]
        right_as_if_left = model.decoder.hand(feats, pose[0, :, 21:], own_first)
    assert not torch.allclose(a, b) and torch.allclose(a[0, 0, 0], left[0, 0])
    assert torch.allclose(right_given_swapped, right_as_if_left[0, 0])
    assert make(POSE_SKIP).decoder.views == 0 and model.frame_token_shape == (model.config.patches + 3, d)
