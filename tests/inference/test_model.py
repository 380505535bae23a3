"""TouchAnything model: official state_dict names, strict official-format loading, numerics at the extremes."""
from __future__ import annotations

import shutil

import numpy as np
import pytest
import torch
import torch.nn.functional as F
import yaml

from touchanything.core.errors import UserError
from touchanything.inference.model.checkpoint import build_model, load_model, save_checkpoint
from touchanything.inference.model.model_config import PRESETS, ModelConfig, with_backbone
from touchanything.inference.model.pose_encoder import prepare_poses
from touchanything.inference.model.preprocess import to_model_input
from touchanything.inference.model.touch_model import TouchAnything
from touchanything.inference.model.vit import BACKBONES, DinoVisionTransformer, interpolate_pos_embed, load_dinov2_weights

VIEWS = ("ego", "wrist_left", "wrist_right")


@pytest.fixture(scope="module")
def paper_model():
    torch.manual_seed(0)
    return TouchAnything(PRESETS["paper"]).eval()


@pytest.fixture(scope="module")
def tiny_model():
    torch.manual_seed(1)
    model = TouchAnything(PRESETS["tiny"]).eval()
    with torch.no_grad():  # non-trivial BatchNorm statistics so the decoder does not sit at 0.5
        for module in model.modules():
            if isinstance(module, torch.nn.BatchNorm2d):
                module.running_mean.normal_(0, 0.5)
                module.running_var.uniform_(0.5, 2.0)
    return model


def _inputs(config: ModelConfig, batch: int = 1, views=VIEWS, seed: int = 0, size: int | None = None):
    g = torch.Generator().manual_seed(seed)
    size = size or config.image_size
    frames = {v: torch.randn(batch, 8, 3, size, size, generator=g) for v in views}
    poses = torch.from_numpy(prepare_poses(np.random.default_rng(seed).normal(0, 2, (batch, 8, 42, 3)) + [0, 0, 40],
                                           np.ones((batch, 8, 2), bool)))
    return frames, poses


def test_paper_state_dict_has_the_official_names_and_counts(paper_model):
    state = paper_model.state_dict()
    assert len(state) == 539
    assert sum(p.numel() for p in paper_model.parameters()) == 163_621_890
    assert sum(p.numel() for p in paper_model.parameters() if p.requires_grad) == 77_041_410
    for prefix in ("vision_encoder.encoder.", "multi_view_encoder.vision_encoder.encoder."):
        assert sum(k.startswith(prefix) for k in state) == 175
    expected = {
        "vision_encoder.encoder.pos_embed": (1, 1370, 768), "vision_encoder.encoder.mask_token": (1, 768),
        "vision_encoder.encoder.blocks.11.ls2.gamma": (768,), "vision_encoder.encoder.blocks.0.attn.qkv.weight": (2304, 768),
        "multi_view_encoder.view_embeddings.wrist_left": (1, 1, 1, 768), "multi_view_encoder.view_gate.0.weight": (192, 768),
        "multi_view_encoder.cross_view_transformer.layers.1.self_attn.in_proj_weight": (2304, 768),
        "multi_view_encoder.output_norm.weight": (768,),
        "temporal_transformer.temporal_pos_encoding.pe": (1, 16, 768),
        "temporal_transformer.layers.2.mlp.3.weight": (768, 3072), "temporal_transformer.layers.0.spatial_attn.out_proj.bias": (768,),
        "pose_encoder.pose_scale": (3,), "pose_encoder.joint_embed.0.weight": (384, 3), "pose_encoder.joint_pos_embed": (1, 42, 768),
        "pose_encoder.transformer.layers.1.linear1.weight": (3072, 768),
        "fusion.layers.1.ffn.3.weight": (768, 3072), "fusion.layers.0.cross_attn.in_proj_bias": (2304,), "fusion.norm.bias": (768,),
        "decoder.joint_grid_weights": (21, 64), "decoder.refine.3.weight": (64, 128, 3, 3),
        "decoder.upsample.0.weight": (64, 32, 4, 4), "decoder.refine.1.num_batches_tracked": (), "decoder.head.0.weight": (1, 32, 3, 3),
    }
    for key, shape in expected.items():
        assert tuple(state[key].shape) == shape, key
    assert torch.equal(state["pose_encoder.pose_offset"], torch.tensor([0.0, 0.0, 50.0]))


def test_official_checkpoint_with_the_config_official_train_writes_loads_and_reproduces(paper_model, official_dir, tmp_path):
    """An official `best_model.pth` (DDP `module.` prefixes) with the `config.yaml` the official train.py
    writes beside it (`_base_` still in it, no base.yaml there) loads strictly and gives the same outputs."""
    folder = tmp_path / "20250101_000000_dinov2_vitb14_tactile_prediction_touchanything_with_glove_aug_wilor"
    folder.mkdir()
    torch.save({"epoch": 12, "model_state_dict": {f"module.{k}": v for k, v in paper_model.state_dict().items()},
                "optimizer_state_dict": {}, "scheduler_state_dict": {}, "loss": 0.1, "metrics": {"val_loss": 0.1}},
               folder / "best_model.pth")
    shutil.copy(official_dir / "configs" / "config_saved_by_official_train.yaml", folder / "config.yaml")
    loaded = load_model(folder / "best_model.pth")
    expected = with_backbone(PRESETS["paper"], pretrained_path="models/dinov2/dinov2_vitb14_pretrain.pth")
    assert not loaded.training and loaded.config == expected
    for views in (("ego",), ("ego", "wrist_left"), ("ego", "wrist_right"), VIEWS):
        frames, poses = _inputs(PRESETS["paper"], views=views, size=112)
        with torch.no_grad():
            expected = paper_model(poses=poses, views=frames)["tactile"]
            got = loaded(poses=poses, views=frames)["tactile"]
        assert torch.equal(expected, got), views


def test_project_checkpoint_round_trip_fp16(tiny_model, tmp_path):
    save_checkpoint(tmp_path / "m.pth", tiny_model, epoch=3, half=True)
    assert (tmp_path / "config.yaml").is_file()
    loaded = load_model(tmp_path / "m.pth")
    frames, poses = _inputs(PRESETS["tiny"])
    with torch.no_grad():
        a, b = tiny_model(poses=poses, views=frames)["tactile"], loaded(poses=poses, views=frames)["tactile"]
    assert (a - b).abs().max() < 2e-2


def test_checkpoint_for_another_preset_is_named(tiny_model, tmp_path):
    save_checkpoint(tmp_path / "tiny" / "m.pth", tiny_model)
    (tmp_path / "small").mkdir()
    (tmp_path / "small" / "config.yaml").write_text(yaml.safe_dump({"model": {"vision_encoder": {"model_name": "dinov2_vits14"}}}))
    with pytest.raises(UserError, match="another preset"):
        load_model(tmp_path / "tiny" / "m.pth", tmp_path / "small" / "config.yaml")
    state = torch.load(tmp_path / "tiny" / "m.pth", weights_only=True)
    del state["model_state_dict"]["decoder.joint_proj.0.bias"]
    torch.save(state, tmp_path / "tiny" / "broken.pth")
    with pytest.raises(UserError, match="missing 1 key.*decoder.joint_proj.0.bias"):
        load_model(tmp_path / "tiny" / "broken.pth")


@pytest.mark.parametrize("make, message", [
    (lambda p: None, "checkpoint not found"),
    (lambda p: p.write_bytes(b"not a checkpoint"), "not a readable PyTorch checkpoint"),
])
def test_bad_checkpoint_files(tmp_path, make, message):
    make(tmp_path / "x.pth")
    (tmp_path / "config.yaml").write_text("model: {}\n")
    with pytest.raises(UserError, match=message):
        load_model(tmp_path / "x.pth")


def test_missing_config_and_bad_config(tmp_path, tiny_model):
    torch.save({"model_state_dict": tiny_model.state_dict()}, tmp_path / "m.pth")
    with pytest.raises(UserError, match="no config.yaml beside"):
        load_model(tmp_path / "m.pth")
    (tmp_path / "config.yaml").write_text("model: [unclosed\n")
    with pytest.raises(UserError, match="not a readable YAML"):
        load_model(tmp_path / "m.pth")


def _official_dinov2_state(spec) -> dict:
    """A hand-made state dict with the official DINOv2 key names and shapes."""
    w = spec.width
    state = {"cls_token": torch.randn(1, 1, w), "pos_embed": torch.randn(1, 1370, w), "mask_token": torch.zeros(1, w),
             "patch_embed.proj.weight": torch.randn(w, 3, 14, 14), "patch_embed.proj.bias": torch.randn(w),
             "norm.weight": torch.ones(w), "norm.bias": torch.zeros(w)}
    for i in range(spec.depth):
        p = f"blocks.{i}."
        state.update({p + "norm1.weight": torch.ones(w), p + "norm1.bias": torch.zeros(w),
                      p + "attn.qkv.weight": torch.randn(3 * w, w) * 0.02, p + "attn.qkv.bias": torch.zeros(3 * w),
                      p + "attn.proj.weight": torch.randn(w, w) * 0.02, p + "attn.proj.bias": torch.zeros(w),
                      p + "ls1.gamma": torch.full((w,), 0.1), p + "norm2.weight": torch.ones(w), p + "norm2.bias": torch.zeros(w),
                      p + "mlp.fc1.weight": torch.randn(4 * w, w) * 0.02, p + "mlp.fc1.bias": torch.zeros(4 * w),
                      p + "mlp.fc2.weight": torch.randn(w, 4 * w) * 0.02, p + "mlp.fc2.bias": torch.zeros(w),
                      p + "ls2.gamma": torch.full((w,), 0.1)})
    return state


def test_dinov2_weights_load_strictly_from_official_names(tmp_path):
    state = _official_dinov2_state(BACKBONES["dinov2_vits14"])
    torch.save(state, tmp_path / "dinov2_vits14_pretrain.pth")
    config = with_backbone(PRESETS["small"], pretrained_path=str(tmp_path / "dinov2_vits14_pretrain.pth"))
    model = build_model(config)
    assert torch.equal(model.vision_encoder.encoder.pos_embed, state["pos_embed"])
    assert model.multi_view_encoder.vision_encoder.encoder is model.vision_encoder.encoder
    vit = DinoVisionTransformer(BACKBONES["dinov2_vitb14"])
    with pytest.raises(UserError, match="do not match"):
        load_dinov2_weights(vit, tmp_path / "dinov2_vits14_pretrain.pth")
    with pytest.raises(UserError, match="not found"):
        build_model(with_backbone(ModelConfig(), pretrained_path=str(tmp_path / "absent.pth")))


def test_position_embedding_interpolation_matches_dinov2():
    pos = torch.randn(1, 1370, 32)
    out = interpolate_pos_embed(pos, 16, 16)
    grid = pos[:, 1:].reshape(1, 37, 37, 32).permute(0, 3, 1, 2)
    reference = F.interpolate(grid, scale_factor=(16.1 / 37, 16.1 / 37), mode="bicubic", antialias=False)
    assert out.shape == (1, 257, 32)
    assert torch.equal(out[:, 0], pos[:, 0])
    assert torch.allclose(out[:, 1:], reference.permute(0, 2, 3, 1).reshape(1, 256, 32))
    by_size = F.interpolate(grid, size=(16, 16), mode="bicubic", antialias=False).permute(0, 2, 3, 1).reshape(1, 256, 32)
    assert not torch.allclose(out[:, 1:], by_size)  # the +0.1 offset matters
    assert interpolate_pos_embed(pos, 37, 37) is pos
    assert interpolate_pos_embed(pos, 8, 12).shape == (1, 97, 32)


def test_view_dict_order_does_not_matter(tiny_model):
    frames, poses = _inputs(PRESETS["tiny"])
    reordered = {k: frames[k] for k in reversed(VIEWS)}
    with torch.no_grad():
        assert torch.equal(tiny_model(poses=poses, views=frames)["tactile"], tiny_model(poses=poses, views=reordered)["tactile"])


@pytest.mark.parametrize("views", [("ego",), ("ego", "wrist_left"), ("ego", "wrist_right"), VIEWS])
def test_outputs_in_unit_range_for_extreme_frames(tiny_model, views):
    size = PRESETS["tiny"].image_size
    for value in (0, 255, (255, 0, 0)):  # black, white, one saturated channel
        images = np.empty((1, 8, size, size, 3), np.uint8)
        images[:] = value
        frames = {v: to_model_input(images) for v in views}
        joints = np.random.default_rng(0).normal(0, 1, (1, 8, 42, 3))
        joints[0, :4] = 1e6
        joints[0, 4:6] = np.nan
        joints[0, 6:, :21] = np.inf
        poses = torch.from_numpy(prepare_poses(joints, np.ones((1, 8, 2), bool)))
        with torch.no_grad():
            out = tiny_model(poses=poses, views=frames)["tactile"]
        assert torch.isfinite(out).all() and out.min() >= 0 and out.max() <= 1


def test_pose_preparation_follows_the_official_rules():
    joints = np.zeros((2, 42, 3))
    joints[0, 0] = (1e6, -1e6, 1e6)
    joints[1, 30] = np.nan
    prepared = prepare_poses(joints, np.array([[True, True], [True, True]]))
    assert tuple(prepared[0, 0]) == (10.0, -10.0, 100.0)
    assert np.all(prepared[1, 21:] == -10.0) and np.all(prepared[1, :21] == 0.0)
    invalid = prepare_poses(joints, np.array([[False, True], [True, True]]))
    assert np.all(invalid[0, :21] == -10.0)


def test_batch_one_equals_a_large_batch(tiny_model):
    frames, poses = _inputs(PRESETS["tiny"], batch=24, seed=3)
    with torch.no_grad():
        full = tiny_model(poses=poses, views=frames)["tactile"]
        single = tiny_model(poses=poses[17:18], views={k: v[17:18] for k, v in frames.items()})["tactile"]
    assert torch.allclose(full[17:18], single, atol=1e-5)


def test_bf16_autocast_is_close_to_fp32(tiny_model):
    frames, poses = _inputs(PRESETS["tiny"], seed=5)
    with torch.no_grad():
        reference = tiny_model(poses=poses, views=frames)["tactile"]
        with torch.autocast("cpu", dtype=torch.bfloat16):
            low = tiny_model(poses=poses, views=frames)["tactile"].float()
    assert torch.isfinite(low).all() and (low - reference).abs().max() < 0.05


def test_frames_path_is_the_official_ego_path(tiny_model):
    frames, poses = _inputs(PRESETS["tiny"], views=("ego",))
    with torch.no_grad():
        direct = tiny_model(frames=frames["ego"], poses=poses)["tactile"]
        via_views = tiny_model(poses=poses, views=frames)["tactile"]
        plain = tiny_model.vision_encoder(frames["ego"])
        embedded = tiny_model.multi_view_encoder(frames)
    assert direct.shape == (1, 8, 2, 21, 21) and not torch.equal(direct, via_views)
    expected = tiny_model.multi_view_encoder.output_norm(plain + tiny_model.multi_view_encoder.view_embeddings["ego"])
    assert torch.allclose(embedded, expected, atol=1e-6) and not torch.allclose(plain, embedded)


def test_view_dropout_in_training_keeps_ego():
    torch.manual_seed(0)
    encoder = TouchAnything(PRESETS["tiny"]).multi_view_encoder.train()
    kept = [tuple(encoder.kept_views(dict.fromkeys(VIEWS))) for _ in range(400)]
    assert all(k[0] == "ego" for k in kept)
    share = np.mean([("wrist_left" in k) for k in kept])
    assert 0.6 < share < 0.8
    assert encoder.eval().kept_views(dict.fromkeys(VIEWS)) == list(VIEWS)
