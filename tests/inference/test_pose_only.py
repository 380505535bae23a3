"""The pose-only baseline: eval, bench and train with every frame black, and the share of a result vision carries.

The model that uses vision is trained here (nano, 6 epochs, about 30 s) on a data set where only the cameras
tell touch (`helpers/vision_task.py`): bright frames in contact, dark ones out of it, a pose drawn at random.
"""
from __future__ import annotations

import dataclasses
import json
import math
import shutil

import h5py
import numpy as np
import pytest
import torch
import yaml
from hypothesis import given
from hypothesis import strategies as st

from conftest import write_episode
from helpers.vision_task import write_vision_dataset
from touchanything.app.cli import main
from touchanything.app.commands.eval_command import markdown
from touchanything.app.sessions.bundled import MODELS_DIR, pose_only_twin, sample_episodes
from touchanything.core.errors import UserError
from touchanything.core.snapshot import VIEW_NAMES
from touchanything.devices.episodes.dataset_split import read_split
from touchanything.devices.episodes.episode_loader import open_episode
from touchanything.devices.episodes.hdf5_episode import IMAGE_KEYS
from touchanything.inference.engine.engine_setting import EngineSetting
from touchanything.inference.engine.streaming_engine import StreamingEngine
from touchanything.inference.evaluation.bench import BenchPlan, bench_model
from touchanything.inference.evaluation.bench_accuracy import HeldOut, replay_outputs
from touchanything.inference.evaluation.bench_data import latency_clip, load_episode
from touchanything.inference.evaluation.bench_report import markdown as bench_markdown
from touchanything.inference.evaluation.bench_report import target_checks, write_outputs
from touchanything.inference.evaluation.evaluation import EvaluationResult, evaluate, vision_share_summary
from touchanything.inference.evaluation.metrics import ALL_METRICS, COUNT_METRICS
from touchanything.inference.evaluation.trajectory_prediction import predict_trajectory
from touchanything.inference.evaluation.vision_share import SHARE_METRICS, vision_share, vision_shares
from touchanything.inference.model.checkpoint import load_model, read_checkpoint
from touchanything.inference.model.model_config import PRESETS, preset, with_backbone
from touchanything.inference.model.preprocess import blank_frames, to_model_input
from touchanything.inference.model.touch_model import TouchAnything
from touchanything.inference.training.clip_dataset import ClipDataset
from touchanything.inference.training.train_config import (
    OptimizerConfig,
    SchedulerConfig,
    SystemConfig,
    TrainConfig,
    TrainingConfig,
    describe_settings,
    train_config_from_file,
    train_config_to_dict,
)
from touchanything.inference.training.trainer import Trainer


def nano_config(blank: bool = False) -> TrainConfig:
    """nano with a trainable backbone, 6 epochs at lr 2e-3 without warm-up, batch 4, loading in this process."""
    training = TrainingConfig(batch_size=4, num_epochs=6, save_interval=100, num_workers=0,
                              optimizer=OptimizerConfig(lr=2e-3), scheduler=SchedulerConfig(warmup_epochs=0))
    model = dataclasses.replace(with_backbone(PRESETS["nano"], freeze=False), blank_images=blank)
    return TrainConfig(model=model, training=training, system=SystemConfig(seed=1))


@pytest.fixture(scope="module")
def vision_task(tmp_path_factory):
    """(HDF5 root, checkpoint of nano trained on the real frames, its TrainResult)."""
    root = tmp_path_factory.mktemp("vision_task")
    data = write_vision_dataset(root)
    result = Trainer(nano_config(), data, root / "real", log=lambda _: None).fit()
    return data, root / "real" / "best_model.pth", result


def overall(entry: dict, mode: str) -> dict[str, float]:
    return entry[mode]["overall"]


@pytest.mark.slow
def test_eval_pose_only_baseline_on_a_model_that_uses_vision(vision_task, tmp_path, capsys):
    data, checkpoint, _ = vision_task
    argv = ["eval", "--checkpoint", str(checkpoint), "--data", str(data), "--split", "test_seen", "--views", "all", "ego",
            "--pose-only-baseline", "--out", str(tmp_path), "--video"]
    assert main(argv) == 0
    videos = sorted(p.name for p in tmp_path.glob("*.mp4"))
    assert len(videos) == 4 and sum(name.endswith("_pose_only.mp4") for name in videos) == 2
    payload = json.loads((tmp_path / "results.json").read_text())
    assert payload["pose_only_checkpoint"] == str(checkpoint)
    results = payload["results"]
    assert [(r["views"], r["pose_only"]) for r in results] == [("all", False), ("all", True), ("ego", False), ("ego", True)]
    assert "vision_share" not in results[0] and "vision_share" not in results[2]
    real, blank = results[0], results[1]
    for mode in ("stitched", "causal"):
        r, b = overall(real, mode), overall(blank, mode)
        assert r["temporal_accuracy"] > b["temporal_accuracy"] + 0.2, (mode, r, b)
        assert r["contact_iou"] > b["contact_iou"] + 0.15, (mode, r, b)
        share = blank["vision_share"][mode]["overall"]
        assert set(share) == set(SHARE_METRICS) and not set(share) & set(COUNT_METRICS)
        assert share["contact_iou"] == pytest.approx((r["contact_iou"] - b["contact_iou"]) / r["contact_iou"])
        assert share["contact_iou"] > 0.5 and share["temporal_accuracy"] > 0.2
    table = (tmp_path / "results.md").read_text()
    assert f"Pose-only rows: `{checkpoint}` with every frame black." in table
    assert table.count("| all (pose only) | overall |") == 4 and table.count("| ego (pose only) | overall |") == 4
    assert table.count("share carried by vision") == 2 and "inf" not in table
    assert table in capsys.readouterr().out


@pytest.mark.parametrize("views, ego_path", [(VIEW_NAMES, "views"), (("ego",), "frames")])
def test_blank_eval_equals_black_frames_fed_by_hand(sim_hdf5_root, tiny_checkpoint, tmp_path, views, ego_path):
    """The pose-only run of an episode equals the real run of a copy whose every stored frame is black, and the
    backbone runs once per view (a black frame's features are the same for every frame)."""
    model = load_model(tiny_checkpoint)
    path = sorted(sim_hdf5_root.rglob("*.hdf5"))[0]
    black = shutil.copy(path, tmp_path / path.name)
    with h5py.File(black, "a") as file:
        for key in IMAGE_KEYS.values():
            shape = file[key].shape
            del file[key]
            file.create_dataset(key, data=np.zeros(shape, np.uint8))
    calls, encoded = [], []
    hook = model.vision_encoder.register_forward_hook(lambda *_: calls.append(1))
    with open_episode(path) as episode:
        blank = predict_trajectory(model, episode, views, 5, ego_path, blank=True, on_frames=encoded.append)
        assert len(calls) == len(views) and sum(encoded) == episode.num_frames
        real = predict_trajectory(model, episode, views, 5, ego_path)
    hook.remove()
    with open_episode(black) as episode:
        by_hand = predict_trajectory(model, episode, views, 5, ego_path)
    rounding = max(np.nanmax(np.abs(blank.stitched - by_hand.stitched)), np.nanmax(np.abs(blank.causal - by_hand.causal)))
    assert rounding < 1e-5  # one black frame encoded, or every frame: the same up to float rounding
    assert np.nanmax(np.abs(real.stitched - blank.stitched)) > 10 * rounding + 1e-6  # the frames reach this model


@pytest.mark.parametrize("blank", [False, True])
def test_a_view_the_episode_lacks_is_the_same_error_with_blank_frames(tmp_path, tiny_checkpoint, blank):
    folder = write_episode(tmp_path / "Lab" / "press" / "20260101_000000_000", frames=20, views=("ego",))
    with open_episode(folder) as episode, pytest.raises(UserError, match="view wrist_left is missing"):
        predict_trajectory(load_model(tiny_checkpoint), episode, ("ego", "wrist_left"), blank=blank)


def test_bench_blank_replay_equals_black_snapshots_by_hand():
    torch.manual_seed(0)
    engine = StreamingEngine(TouchAnything(preset("nano")).eval(), EngineSetting("nano"))
    episode = load_episode(sample_episodes()[0], 112, 30)
    black = dataclasses.replace(episode, images={v: np.zeros_like(frames) for v, frames in episode.images.items()})
    blank = replay_outputs(engine, episode, [0.0], blank=True).pressure
    np.testing.assert_array_equal(blank, replay_outputs(engine, black, [0.0]).pressure)
    assert np.isfinite(blank[14:]).any()
    assert np.nanmax(np.abs(replay_outputs(engine, episode, [0.0]).pressure - blank)) > 1e-5  # the frames reach this model


@pytest.mark.slow
def test_bench_pose_only_rows_beside_the_real_ones(vision_task, tmp_path):
    data, checkpoint, _ = vision_task
    path = read_split(data / "split.json")["test_seen"][0]
    plan = BenchPlan(True, rounds=1, per_round=3, naive_steps=2, pose_only=True)
    result = bench_model("vision", load_model(checkpoint), HeldOut([(path, "test_seen")]), latency_clip(path, 10),
                         plan, progress=lambda message: None)
    rows, naive = result.rows, result.naive
    assert [(r["runtime"], r["blank"]) for r in rows] == [("torch", False), ("torch", True), ("onnx", False), ("onnx", True)]
    for real, blank in (rows[0:2], rows[2:4]):
        assert blank["setting"] == real["setting"] + "/pose-only" and blank["p50_ms"] is None and blank["latency_frames"] == 0
        assert real["p50_ms"] > 0 and blank["throughput_fps"] > 0
        assert real["contact_iou"] > blank["contact_iou"] + 0.15, (real["metrics"], blank["metrics"])
        assert blank["vision_share"] == vision_shares(real["metrics"], blank["metrics"])
        assert blank["vision_share"]["contact_iou"] > 0.5
    assert rows[1]["agreement_viou"] < 0.9  # against the real fp32 outputs: blanking changed them
    record = {"machine": "test", "quick": True, "accuracy_data": str(path), "rows": rows, "naive": {"vision": naive},
              "naive_over_streaming": {"vision": naive["ratio"]}, "targets": target_checks(rows, {"vision": naive}, "vision")}
    assert not any("pose only" in check["target"] for check in record["targets"])
    written = write_outputs(record, tmp_path)
    table = bench_markdown(record)
    assert "## Share carried by vision" in table and "| vision/torch-fp32/all | " in table
    assert written[1].read_text() == table and written[2].stat().st_size > 10_000


@pytest.mark.slow
def test_train_with_blank_images_and_evaluate_it_as_the_baseline(vision_task, tmp_path, capsys):
    """`train --blank-images` trains on black frames only: on data where only the frames tell touch, its best
    validation loss stays well above the real run's. `eval --pose-only-baseline CHECKPOINT` then takes the
    pose-only rows from that checkpoint."""
    data, checkpoint, real = vision_task
    config = tmp_path / "nano.yaml"
    config.write_text(yaml.safe_dump(train_config_to_dict(nano_config())))
    assert main(["train", "--config", str(config), "--data", str(data), "--out", str(tmp_path / "blank"), "--blank-images"]) == 0
    assert "images blanked (pose-only baseline)" in capsys.readouterr().out
    assert train_config_from_file(tmp_path / "blank" / "config.yaml") == nano_config(blank=True)
    blank_loss = read_checkpoint(tmp_path / "blank" / "best_model.pth")["metrics"]["best_val_loss"]
    assert blank_loss > 1.3 * real.best_val_loss, (blank_loss, real.best_val_loss)
    pose_only = tmp_path / "blank" / "best_model.pth"
    argv = ["eval", "--checkpoint", str(checkpoint), "--data", str(data), "--split", "test_seen", "--views", "all",
            "--pose-only-baseline", str(pose_only), "--out", str(tmp_path / "eval")]
    assert main(argv) == 0
    payload = json.loads((tmp_path / "eval" / "results.json").read_text())
    real_row, blank_row = payload["results"]
    assert payload["pose_only_checkpoint"] == str(pose_only) and blank_row["pose_only"]
    expected = evaluate(load_model(pose_only), read_split(data / "split.json")["test_seen"], "all", blank=True)
    assert json.dumps(blank_row["causal"]) == json.dumps(expected.summary("causal"))
    real_overall, blank_overall = real_row["causal"]["overall"], blank_row["causal"]["overall"]
    assert real_overall["temporal_accuracy"] > blank_overall["temporal_accuracy"] + 0.2, (real_overall, blank_overall)


def test_a_missing_pose_only_checkpoint_is_one_line(sim_hdf5_root, tiny_checkpoint, tmp_path, capsys):
    split = next(key for key, files in read_split(sim_hdf5_root / "split.json").items() if files)
    argv = ["eval", "--checkpoint", str(tiny_checkpoint), "--data", str(sim_hdf5_root), "--split", split,
            "--pose-only-baseline", str(tmp_path / "none.pth")]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "none.pth" in err and "checkpoint not found" in err and len(err.strip().splitlines()) == 1


def test_blank_training_clips_keep_every_view_and_show_black(sim_hdf5_root):
    files = sorted(sim_hdf5_root.rglob("*.hdf5"))[:1]
    real, blank = ClipDataset(files, 112)[0], ClipDataset(files, 112, blank=True)[0]
    black = to_model_input(blank_frames((8, 112, 112, 3)))
    assert blank["views"].keys() == real["views"].keys() == set(VIEW_NAMES)
    assert all(torch.equal(images, black) for images in blank["views"].values())
    assert not torch.equal(real["views"]["ego"], black)
    assert all(torch.equal(real[k], blank[k]) for k in ("poses", "target", "mask", "frames"))


def test_the_blank_images_config_key(tmp_path):
    path = tmp_path / "blank.yaml"
    path.write_text("data: {blank_images: true, pose_source: wilor}\n")
    config = train_config_from_file(path)
    assert config.model.blank_images and "data.blank_images" not in config.unused
    assert "images blanked" in "\n".join(describe_settings(config))
    assert train_config_to_dict(config)["data"]["blank_images"] is True
    assert not TrainConfig().model.blank_images
    for value in ("1", "yes please", "[true]"):
        path.write_text(f"data: {{blank_images: {value}}}\n")
        with pytest.raises(UserError) as err:
            train_config_from_file(path)
        assert "data.blank_images: expected true or false" in str(err.value) and "\n" not in str(err.value)


def test_vision_share_at_the_extremes():
    assert vision_share(0.6, 0.15) == pytest.approx(0.75) and vision_share(0.15, 0.6) == pytest.approx(-0.75)
    assert vision_share(0.5, 0.0) == 1.0 and vision_share(0.0, 0.5) == -1.0 and vision_share(0.4, 0.4) == 0.0
    assert vision_share(0.1, 0.4, lower_is_better=True) == pytest.approx(0.75)  # MAE: the error vision removes
    assert vision_share(0.0, 0.3, lower_is_better=True) == 1.0
    for real, blank in ((0.0, 0.0), (math.nan, 0.5), (0.5, math.nan), (None, 0.5), (math.inf, 0.5), (0.5, -math.inf)):
        assert math.isnan(vision_share(real, blank)), (real, blank)
    assert vision_share(5e-324, 0.0) == 1.0  # the smallest positive float: no overflow


@given(st.floats(0, 1e308), st.floats(0, 1e308), st.booleans())
def test_vision_share_is_bounded(real, blank, lower_is_better):
    share = vision_share(real, blank, lower_is_better)
    assert math.isnan(share) == (real == blank == 0) and (math.isnan(share) or -1.0 <= share <= 1.0)


def test_share_tables_show_n_a_for_zero_denominators():
    """Contact IoU 0 with and without the images (a model that never predicts contact): n/a, not inf or a crash."""
    zero = dict.fromkeys(ALL_METRICS, 0.0) | {"mae": 0.2, "mae_left": math.nan}
    row = {"scene": "Lab", "stitched": zero, "causal": zero}
    real, blank = EvaluationResult("all", [row]), EvaluationResult("all", [row], blank=True)
    shares = vision_share_summary(real, blank, "stitched")["Lab"]
    assert math.isnan(shares["contact_iou"]) and math.isnan(shares["mae_left"]) and shares["mae"] == 0.0
    table = markdown([real, blank], "test")
    share_rows = [line for line in table.splitlines() if line.startswith("| all | Lab |")]
    assert len(share_rows) == 6 and "| n/a |" in share_rows[-1] and "inf" not in table  # 2 + 2 metric tables + 2 share tables


def test_the_pose_only_baseline_is_the_bundled_twin_when_there_is_one(tmp_path):
    assert pose_only_twin(MODELS_DIR / "nano" / "best_model.pth") == MODELS_DIR / "nano_pose_only" / "best_model.pth"
    assert pose_only_twin(MODELS_DIR / "pico" / "best_model.pth") is None  # no pico_pose_only bundled
    assert pose_only_twin(MODELS_DIR / "nano_pose_only" / "best_model.pth") is None
    assert pose_only_twin(tmp_path / "mine" / "best_model.pth") is None
