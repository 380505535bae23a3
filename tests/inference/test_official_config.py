"""The official config structure: the released files and the one official train.py writes, the project's own
configs round-tripping, and one line naming the key for every misspelt section or impossible value."""
from __future__ import annotations

import shutil
from dataclasses import replace
from pathlib import Path

import pytest
import yaml

from touchanything.app.cli import main
from touchanything.core.errors import UserError
from touchanything.inference.model.config_files import read_config_file
from touchanything.inference.model.model_config import PRESETS, config_from_dict, config_to_dict, with_backbone
from touchanything.inference.training.train_config import TrainConfig, describe_settings, train_config_from_file, train_config_to_dict

ROOT = Path(__file__).resolve().parents[2]
OFFICIAL_TACTILE = ("touchanything_with_glove_aug_wilor.yaml", "config_saved_by_official_train.yaml")


@pytest.mark.parametrize("name", OFFICIAL_TACTILE)
def test_official_tactile_configs_read_as_the_official_recipe(official_dir, name):
    config = train_config_from_file(official_dir / "configs" / name)
    weights = "models/dinov2/dinov2_vitb14_pretrain.pth"
    assert config.model == with_backbone(PRESETS["paper"], pretrained_path=weights)
    t, o, s, loss = config.training, config.training.optimizer, config.training.scheduler, config.training.loss
    assert (t.num_epochs, t.batch_size, t.save_interval, t.val_interval) == (100, 16, 5, 1)
    assert (o.lr, o.weight_decay, o.betas) == (5e-5, 0.05, (0.9, 0.999))
    assert (s.warmup_epochs, s.min_lr) == (10, 1e-6)
    assert (loss.mse_weight, loss.l1_weight, loss.tv_weight, loss.contact_weight, loss.pressure_threshold) == (1.0, 0.5, 0.01, 3.0, 0.1)
    assert (config.system.seed, config.system.mixed_precision) == (42, False)
    assert (config.data.pose_source, config.data.fallback_pose_source) == ("wilor", None)
    unused = set(config.unused)
    assert {"model.pose_decoder", "evaluation", "data.data_root", "data.glove_augmentation", "data.mapping_left",
            "training.gradient_accumulation_steps", "model.temporal_transformer.hidden_dim"} <= unused
    assert config_from_dict(read_config_file(official_dir / "configs" / name)) == config.model


def test_the_official_base_is_merged_underneath_and_refused_alone(official_dir, tmp_path):
    merged = read_config_file(official_dir / "configs" / "touchanything_with_glove_aug_wilor.yaml")
    assert "_base_" not in merged and merged["model"]["pose_decoder"]["type"] == "joint_query"  # from base.yaml
    assert merged["system"]["mixed_precision"] is False and merged["system"]["cudnn_benchmark"] is True
    with pytest.raises(UserError, match=r"base.yaml: model.task: 'pose_prediction' is not supported"):
        train_config_from_file(official_dir / "configs" / "base.yaml")
    alone = tmp_path / "touchanything_with_glove_aug_wilor.yaml"  # copied without its base: read as it is
    shutil.copy(official_dir / "configs" / alone.name, alone)
    assert train_config_from_file(alone).training.optimizer.lr == 5e-5


def test_base_chain_cycles_and_environment_expansion(tmp_path, monkeypatch):
    monkeypatch.setenv("WEIGHTS_DIR", "/weights")
    (tmp_path / "a.yaml").write_text("_base_: b.yaml\nmodel: {vision_encoder: {pretrained_path: $WEIGHTS_DIR/x.pth}}\n")
    (tmp_path / "b.yaml").write_text("_base_: c.yaml\ntraining: {num_epochs: 7}\n")
    (tmp_path / "c.yaml").write_text("training: {num_epochs: 9, batch_size: 3, scheduler: {warmup_epochs: 1}}\n")
    config = train_config_from_file(tmp_path / "a.yaml")
    assert (config.training.num_epochs, config.training.batch_size) == (7, 3)
    assert config.model.vision_encoder.pretrained_path == "/weights/x.pth"
    (tmp_path / "c.yaml").write_text("_base_: a.yaml\n")
    with pytest.raises(UserError, match="cycle"):
        read_config_file(tmp_path / "a.yaml")


@pytest.mark.parametrize("path", [*sorted((ROOT / "configs").glob("*.yaml")), *sorted((ROOT / "models").glob("*/config.yaml"))])
def test_project_configs_use_the_official_structure_and_round_trip(path, tmp_path):
    config = train_config_from_file(path)
    assert not config.unused
    (tmp_path / "config.yaml").write_text(yaml.safe_dump(train_config_to_dict(config)))
    assert train_config_from_file(tmp_path / "config.yaml") == config
    sections = yaml.safe_load(path.read_text()).get("model", {})  # an overlay on a `_base_` may have none
    assert set(sections) <= {"task", "num_input_joints", "vision_encoder", "temporal_transformer", "multi_view",
                             "pose_encoder", "fusion", "tactile_decoder", "baseline"}  # baseline: the project's


def test_bundled_model_configs_match_their_training_configs():
    for name in ("nano", "nano_pose_only", "baseline_pose", "baseline_frames", "pico"):
        assert train_config_from_file(ROOT / "models" / name / "config.yaml") == train_config_from_file(ROOT / "configs" / f"{name}.yaml")


@pytest.mark.parametrize("preset", sorted(PRESETS))
def test_presets_round_trip_through_the_written_structure(preset):
    written = yaml.safe_load(yaml.safe_dump(config_to_dict(PRESETS[preset])))
    assert config_from_dict(written) == PRESETS[preset]
    assert written["data"]["image_size"] == [PRESETS[preset].image_size] * 2


@pytest.mark.parametrize("config, message", [
    ({"model": {"temporal": {"num_layers": 4}}}, r"x.yaml: model.temporal: unknown setting"),
    ({"model": {"vision": {"model_name": "dinov2_vitb14"}}}, r"model.vision: unknown setting"),
    ({"model": {"temporal_transformer": {"num_layer": 4}}}, r"model.temporal_transformer.num_layer: unknown setting"),
    ({"model": {"temporal_transformer": {"num_layers": -2}}}, r"model.temporal_transformer.num_layers: must be ≥ 1, got -2"),
    ({"model": {"fusion": {"num_layers": "two"}}}, r"model.fusion.num_layers: expected a whole number, got 'two'"),
    ({"model": {"fusion": {"num_layers": 2.5}}}, r"model.fusion.num_layers: expected a whole number"),
    ({"model": {"multi_view": {"dropout": 1.5}}}, r"model.multi_view.dropout: must be < 1.0, got 1.5"),
    ({"model": {"multi_view": {"view_dropout_prob": float("nan")}}}, r"view_dropout_prob: must be a finite number"),
    ({"model": {"multi_view": {"enabled": False}}}, r"model.multi_view.enabled: False is not supported"),
    ({"model": {"vision_encoder": {"freeze": "yes"}}}, r"model.vision_encoder.freeze: expected true or false"),
    ({"model": {"vision_encoder": {"model_name": "resnet50"}}}, r"model.vision_encoder.model_name: unknown backbone 'resnet50'"),
    ({"model": {"vision_encoder": {"model_name": "vit_n14", "embed_dim": 768}}}, r"embed_dim: is 768 but must be 128"),
    ({"model": {"fusion": {"num_heads": 5}}}, r"model.fusion.num_heads: 5 does not divide the width 768"),
    ({"model": {"tactile_decoder": {"tactile_size": 16}}}, r"model.tactile_decoder.tactile_size: 16 is not supported"),
    ({"model": {"temporal_transformer": []}}, r"model.temporal_transformer: expected a mapping"),
    ({"model": {"temporal_transformer": {"window_size": 4}}}, r"window_size: must be ≥ 8"),
    ({"data": {"image_size": [224, 168]}}, r"data.image_size: must be square, got \[224, 168\]"),
    ({"data": {"image_size": [100, 100]}}, r"data.image_size: 100 is not a positive multiple of the patch size 14"),
    ({"data": {"image_size": 224}}, r"data.image_size: expected a list of 2 values, got 224"),
    ({"data": {"clip_length": 16}}, r"data.clip_length: 16 is not supported; this model supports only 8"),
    ({"data": {"normalize_mean": [0.5, 0.5, 0.5]}}, r"data.normalize_mean: \[0.5, 0.5, 0.5\] is not supported"),
])
def test_bad_model_settings_give_one_line_naming_the_key(config, message):
    with pytest.raises(UserError, match=message) as err:
        config_from_dict(config, "x.yaml")
    assert "\n" not in str(err.value)


@pytest.mark.parametrize("config, message", [
    ({"training": {"num_epoch": 5}}, r"training.num_epoch: unknown setting"),
    ({"training": {"epochs": 5}}, r"training.epochs: unknown setting"),
    ({"training": {"learning_rate": 1e-3}}, r"training.learning_rate: unknown setting"),
    ({"training": {"num_epochs": 0}}, r"training.num_epochs: must be ≥ 1, got 0"),
    ({"training": {"optimizer": {"lr": -1.0}}}, r"training.optimizer.lr: must be ≥ 0.0, got -1.0"),
    ({"training": {"optimizer": {"type": "sgd"}}}, r"training.optimizer.type: 'sgd' is not supported"),
    ({"training": {"optimizer": {"betas": [0.9]}}}, r"training.optimizer.betas: expected a list of 2 values"),
    ({"training": {"optimizer": {"betas": [0.9, 1.0]}}}, r"training.optimizer.betas: must be < 1.0"),
    ({"training": {"scheduler": {"warmup_epochs": 20}, "num_epochs": 5}}, r"training.scheduler.warmup_epochs: 20 exceeds num_epochs 5"),
    ({"training": {"loss": {"tv_weight": -0.1}}}, r"training.loss.tv_weight: must be ≥ 0.0"),
    ({"training": {"invalid_pose_policy": "skip_clip"}}, r"training.invalid_pose_policy: 'skip_clip' is not supported"),
    ({"training": {"seed": 1}}, r"training.seed: unknown setting"),
    ({"system": {"mixed_precision": 1}}, r"system.mixed_precision: expected true or false"),
    ({"data": {"pose_source": "mocap"}}, r"data.pose_source: must be wilor or rokoko, got 'mocap'"),
    ({"data": {"fallback_pose_source": "wilor"}}, r"data.fallback_pose_source: must be null or the other pose source"),
    ({"data": {"use_augmentation": True}}, r"data.use_augmentation: True is not supported"),
    ({"data": {"clip_lenght": 8}}, r"data.clip_lenght: unknown setting"),
    ({"optimizer": {"lr": 1e-3}}, r"x.yaml: optimizer: unknown section"),
])
def test_bad_training_settings_give_one_line_naming_the_key(tmp_path, config, message):
    (tmp_path / "x.yaml").write_text(yaml.safe_dump(config))
    with pytest.raises(UserError, match=message) as err:
        train_config_from_file(tmp_path / "x.yaml")
    assert "\n" not in str(err.value)


def test_yaml_exponents_without_a_dot_are_numbers(tmp_path):
    (tmp_path / "x.yaml").write_text("training: {optimizer: {lr: 1e-4}, scheduler: {min_lr: 1e-7}}\n")
    config = train_config_from_file(tmp_path / "x.yaml")
    assert (config.training.optimizer.lr, config.training.scheduler.min_lr) == (1e-4, 1e-7)


def test_effective_settings_name_what_the_run_uses():
    config = TrainConfig(model=PRESETS["nano"], unused=("training.num_workers",))
    text = "\n".join(describe_settings(config))
    for part in ("conv_n16 at 96 px", "100 epochs", "lr 5e-05", "betas (0.9, 0.999)", "10 warm-up epochs",
                 "cosine to 1e-06", "seed 42", "fp32", "×3 above 0.1", "not used by this trainer: training.num_workers"):
        assert part in text, part
    changed = replace(config, training=replace(config.training, num_epochs=7))
    assert "7 epochs" in "\n".join(describe_settings(changed))


def test_train_reads_the_official_recipe_and_names_missing_backbone_weights(official_dir, sim_hdf5_root, tmp_path, capsys):
    config = official_dir / "configs" / "touchanything_with_glove_aug_wilor.yaml"
    code = main(["train", "--config", str(config), "--data", str(sim_hdf5_root), "--out", str(tmp_path / "run")])
    out, err = capsys.readouterr()
    assert code == 2
    assert "100 epochs, batch 16, AdamW lr 5e-05 weight decay 0.05 betas (0.9, 0.999), 10 warm-up epochs" in out
    assert "mse 1 + l1 0.5 (×3 above 0.1) + tv 0.01" in out
    assert err.strip().count("\n") == 0 and "dinov2_vitb14_pretrain.pth" in err and "not found" in err
    assert not (sim_hdf5_root / ".frame_cache").exists()  # refused before any frame was decoded
