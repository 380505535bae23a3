"""Training: end to end with resume, learning, view dropout, the NaN guard, the feature cache, loader workers, DDP."""
from __future__ import annotations

import json
import os
import shutil
import socket
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest
import torch
import yaml

from touchanything.app.cli import main
from touchanything.core.errors import UserError
from touchanything.devices.episodes.episode_loader import open_episode
from touchanything.inference.model.checkpoint import load_model, read_checkpoint
from touchanything.inference.model.model_config import PRESETS, with_backbone
from touchanything.inference.model.touch_model import TouchAnything
from touchanything.inference.training.clip_dataset import clip_starts, episode_poses, prepare_target
from touchanything.inference.training.tactile_loss import TactileLossConfig, tactile_loss
from touchanything.inference.training.train_config import (
    OptimizerConfig,
    SchedulerConfig,
    SystemConfig,
    TrainConfig,
    TrainingConfig,
    TrainingDataConfig,
    describe_settings,
    train_config_from_file,
)
from touchanything.inference.training.trainer import Trainer, TrainingError

pytestmark = pytest.mark.slow

TINY = with_backbone(PRESETS["tiny"], freeze=False)


def config(model=TINY, epochs: int = 2, batch_size: int = 4, lr: float = 1e-3, warmup_epochs: int = 1,
           val_interval: int = 1, num_workers: int = 0) -> TrainConfig:
    """A short run: periodic checkpoints every epoch, seed 3, loading in the main process unless asked."""
    training = TrainingConfig(batch_size=batch_size, num_epochs=epochs, save_interval=1, val_interval=val_interval,
                              num_workers=num_workers, optimizer=OptimizerConfig(lr=lr),
                              scheduler=SchedulerConfig(warmup_epochs=warmup_epochs))
    return TrainConfig(model=model, training=training, system=SystemConfig(seed=3))


@pytest.fixture
def data(sim_hdf5_root, tmp_path) -> Path:
    """A copy of the simulated HDF5 root whose split trains and validates on every trajectory."""
    root = tmp_path / "h5"
    shutil.copytree(sim_hdf5_root, root)
    files = sorted(str(p.relative_to(root)) for p in root.rglob("*.hdf5"))
    (root / "split.json").write_text(json.dumps({"train": files, "val": files[:1], "test_seen": [], "test_unseen": []}))
    return root


def test_official_clip_sampler_and_target_preparation():
    assert clip_starts(14, 15) == [] and clip_starts(15, 15) == [0] and clip_starts(44, 15) == [0, 15]
    pressure = np.full((2, 2, 21, 21), np.nan, np.float32)
    pressure[:, :, 5, 5] = [[4.0, 2.0], [1.0, 0.5]]
    target, mask = prepare_target(pressure, normalized=False)
    assert mask.sum() == 4 and np.isfinite(target).all() and target.max() == 1.0 and target[0, 1, 5, 5] == 0.5
    assert prepare_target(pressure, normalized=True)[0][1, 1, 5, 5] == 0.5


def test_train_checkpoint_resume_and_eval(data, tmp_path, capsys):
    def interrupt_after_epoch_2(message: str) -> None:
        if message.startswith("epoch 2:"):
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        Trainer(config(epochs=3), data, tmp_path / "run", log=interrupt_after_epoch_2).fit()
    for name in ("last.pth", "best_model.pth", "checkpoint_epoch_1.pth", "checkpoint_epoch_2.pth", "config.yaml"):
        assert (tmp_path / "run" / name).is_file(), name
    checkpoint = read_checkpoint(tmp_path / "run" / "last.pth")
    assert not (tmp_path / "run" / "checkpoint_epoch_3.pth").exists()
    assert checkpoint["epoch"] == 2
    assert set(checkpoint) >= {"model_state_dict", "optimizer_state_dict", "scheduler_state_dict", "loss", "metrics"}
    said = []
    resumed = Trainer(config(epochs=3), data, tmp_path / "run", log=said.append)
    resumed.resume(tmp_path / "run" / "last.pth")
    assert resumed.start_epoch == 2
    best = checkpoint["metrics"]["best_val_loss"]
    assert said[-1] == f"resumed from {tmp_path / 'run' / 'last.pth'}: 2 of 3 epochs done, best validation loss so far {best:.4f}"
    resumed.fit()
    # an uninterrupted run's schedule, by hand: warm-up epoch 1, then cosine over T_max = 3 − 1 = 2 epochs from
    # lr 1e-3: epoch 2 ends at 1e-6 + (1e-3 − 1e-6)(1 + cos(π/2))/2 = 5.005e-4, epoch 3 at min_lr 1e-6
    assert checkpoint["scheduler_state_dict"]["_last_lr"] == [pytest.approx(5.005e-4)]
    assert resumed.optimizer.param_groups[0]["lr"] == pytest.approx(1e-6)
    assert len(resumed.result.train_loss) == 1
    written = train_config_from_file(tmp_path / "run" / "config.yaml")
    assert written == config(epochs=3)
    model = load_model(tmp_path / "run" / "best_model.pth")
    assert isinstance(model, TouchAnything) and not model.training
    assert main(["eval", "--checkpoint", str(tmp_path / "run" / "best_model.pth"), "--data", str(data),
                 "--split", "train", "--views", "ego+left", "--num-traj", "1"]) == 0
    assert "| ego+left | overall |" in capsys.readouterr().out


def test_validation_interval_and_optimizer_settings(data, tmp_path):
    trainer = Trainer(config(epochs=3, val_interval=2), data, tmp_path / "interval", log=lambda _: None)
    assert trainer.optimizer.param_groups[0]["betas"] == (0.9, 0.999)
    result = trainer.fit()
    validated = [np.isfinite(v) for v in result.val_loss]
    assert validated == [False, True, True]  # epoch 2 by the interval, epoch 3 as the last
    assert result.best_val_loss == min(result.val_loss[1:])


def test_loss_weights_come_from_the_training_config():
    g = torch.Generator().manual_seed(0)
    pred, target = torch.rand(2, 8, 2, 21, 21, generator=g), torch.rand(2, 8, 2, 21, 21, generator=g)
    mask = (torch.rand(2, 8, 2, 21, 21, generator=g) > 0.3).float()
    plain = TactileLossConfig(l1_weight=0.0, tv_weight=0.0, contact_weight=1.0)
    assert torch.allclose(tactile_loss(pred, target, mask, plain), ((pred - target) ** 2 * mask).sum() / mask.sum())
    official = tactile_loss(pred, target, mask)
    weight = (1 + 2 * (target > 0.1).float()) * mask
    tv = (pred[..., 1:, :] - pred[..., :-1, :]).abs().mean() + (pred[..., :, 1:] - pred[..., :, :-1]).abs().mean()
    by_hand = (weight * (pred - target) ** 2).sum() / mask.sum() + 0.5 * (weight * (pred - target).abs()).sum() / mask.sum() + 0.01 * tv
    assert torch.allclose(official, by_hand)


def test_a_fallback_pose_source_fills_the_invalid_hands(episode_dir):
    with open_episode(episode_dir) as episode:
        wilor, rokoko = episode.wilor, episode.rokoko
        only = episode_poses(episode, "wilor", None)
        filled = episode_poses(episode, "wilor", "rokoko")
    missing = ~wilor.valid
    assert missing.any() and rokoko.valid[missing].all()
    hands_only, hands_filled = only.reshape(-1, 2, 21, 3), filled.reshape(-1, 2, 21, 3)
    assert np.all(hands_only[missing] == -10.0)
    assert np.allclose(hands_filled[missing], rokoko.joints[missing]) and np.array_equal(hands_filled[~missing], hands_only[~missing])


def test_loss_decreases_on_a_fixed_tiny_set(data, tmp_path):
    trainer = Trainer(config(epochs=12, warmup_epochs=0, lr=2e-3), data, tmp_path / "fit", log=lambda _: None)
    result = trainer.fit()
    assert result.train_loss[-1] < 0.7 * result.train_loss[0]


def test_colour_augmentation_changes_training_but_not_a_pose_only_run(data, tmp_path):
    """The trainer applies `data.colour_augmentation` to the frames (same seed, different losses) and leaves
    black frames alone (a pose-only run trains identically with it)."""
    import dataclasses

    def losses(model, strength: float, name: str) -> list[float]:
        run = dataclasses.replace(config(model=model, epochs=1), data=TrainingDataConfig(colour_augmentation=strength))
        return Trainer(run, data, tmp_path / name, log=lambda _: None).fit().train_loss

    assert losses(TINY, 1.0, "a") != losses(TINY, 0.0, "b")
    blank = dataclasses.replace(TINY, blank_images=True)
    assert losses(blank, 1.0, "c") == losses(blank, 0.0, "d")


def test_view_dropout_proportions_over_many_steps():
    torch.manual_seed(0)
    encoder = TouchAnything(PRESETS["tiny"]).multi_view_encoder.train()
    counts = {"all": 0, "one wrist": 0, "ego only": 0}
    steps = 3000
    for _ in range(steps):
        kept = encoder.kept_views(dict.fromkeys(("ego", "wrist_left", "wrist_right")))
        counts["all" if len(kept) == 3 else "one wrist" if len(kept) == 2 else "ego only"] += 1
    expected = {"all": 0.7 ** 2, "one wrist": 2 * 0.7 * 0.3, "ego only": 0.3 ** 2}
    for key, share in expected.items():
        assert abs(counts[key] / steps - share) < 0.03, (key, counts)


def test_trainer_records_the_view_sets_it_trained_on_with_loader_workers(data, tmp_path):
    result = Trainer(config(epochs=2, num_workers=2), data, tmp_path / "views", log=lambda _: None).fit()
    assert sum(result.view_sets.values()) > 0 and set(result.view_sets) <= {"ego", "ego+left", "ego+right", "all"}
    assert len(result.train_loss) == 2 and all(np.isfinite(result.train_loss + result.val_loss))


def _same(a, b) -> bool:
    """The same keys and exactly equal tensors, nested views included."""
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    return torch.equal(a, b)


def _open_hdf5_files() -> int:
    return h5py.h5f.get_obj_count(h5py.h5f.OBJ_ALL, h5py.h5f.OBJ_FILE)


def test_loader_workers_give_the_same_batches_as_the_main_process(data, tmp_path):
    main_process, workers = (Trainer(config(num_workers=n), data, tmp_path / str(n), log=lambda _: None) for n in (0, 2))
    open_before = _open_hdf5_files()
    orders = []
    for epoch in (0, 1):
        torch.manual_seed(11)
        expected, got = list(main_process.epoch_batches(epoch)), list(workers.epoch_batches(epoch))
        drawn = torch.rand(4)
        torch.manual_seed(11)
        assert torch.equal(drawn, torch.rand(4))  # the loaders left the global RNG (view dropout) untouched
        assert len(expected) == len(got) == 3 and all(_same(a, b) for a, b in zip(expected, got))
        orders.append(torch.cat([b["frames"][:, 0] * 100 + b["episode"] for b in expected]).tolist())
        assert all(_same(a, b) for a, b in zip(main_process.val_loader, workers.val_loader, strict=True))
    assert orders[0] != orders[1] and sorted(orders[0]) == sorted(orders[1])  # reshuffled per epoch, every clip once
    assert _open_hdf5_files() == open_before  # the main process holds no HDF5 file open when workers fork


def test_num_workers_is_read_validated_and_shown(tmp_path):
    path = tmp_path / "workers.yaml"
    path.write_text("training: {num_workers: 2}\n")
    config_read = train_config_from_file(path)
    assert config_read.training.num_workers == 2 and "training.num_workers" not in config_read.unused
    assert "2 data-loader worker(s)" in "\n".join(describe_settings(config_read))
    assert TrainingConfig().num_workers == 4  # the official default
    for value in ("-1", "2.5", "two", "true"):
        path.write_text(f"training: {{num_workers: {value}}}\n")
        with pytest.raises(UserError) as err:
            train_config_from_file(path)
        assert "training.num_workers" in str(err.value) and "\n" not in str(err.value), value
    with pytest.raises(UserError, match="training.num_workers: must be ≥ 0"):
        TrainConfig(training=TrainingConfig(num_workers=-1)).check()


def test_nan_guard_names_the_step_and_episode(data, tmp_path):
    trainer = Trainer(config(), data, tmp_path / "nan", log=lambda _: None)
    with torch.no_grad():
        trainer.model.decoder.joint_proj[0].bias.fill_(float("nan"))  # the injected NaN
    with pytest.raises(TrainingError) as err:
        trainer.fit()
    message = str(err.value)
    assert "non-finite loss" in message and "epoch 1, step 1" in message and ".hdf5" in message
    exploding = Trainer(config(lr=1e30, warmup_epochs=0), data, tmp_path / "boom", log=lambda _: None)
    with pytest.raises(TrainingError, match="non-finite"):
        exploding.fit()


def test_frozen_backbone_features_are_cached_after_the_first_epoch(data, tmp_path):
    trainer = Trainer(config(model=with_backbone(PRESETS["nano_vit"], freeze=True)), data, tmp_path / "frozen", log=lambda _: None)
    trainer.fit()
    def cached_keys(dataset) -> int:
        return sum(len(clip_starts(len(e.poses), 15)) * 8 * len(e.views) for e in dataset.episodes)

    assert trainer.cache.hits > 0 and len(trainer.cache) == cached_keys(trainer.train_set)
    assert len(trainer.val_cache) == cached_keys(trainer.val_set)  # validation never reads training tokens


def test_empty_mask_clips_are_skipped_and_zero_pressure_trains(data, tmp_path):
    files = sorted(data.rglob("*.hdf5"))
    with h5py.File(files[0], "a") as f:
        for key in ("pressure/left_pressure_grid", "pressure/right_pressure_grid"):
            f[key][...] = np.nan
    with h5py.File(files[1], "a") as f:
        for key in ("pressure/left_pressure_grid", "pressure/right_pressure_grid"):
            grid = f[key][()]
            f[key][...] = np.where(np.isnan(grid), np.nan, 0.0)
    result = Trainer(config(batch_size=1, epochs=1), data, tmp_path / "empty", log=lambda _: None).fit()
    assert result.skipped_batches > 0 and np.isfinite(result.train_loss[0])


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.multiprocess
def test_ddp_with_two_cpu_processes(data, tmp_path):
    cfg = tmp_path / "ddp.yaml"
    cfg.write_text(yaml.safe_dump({"model": {"vision_encoder": {"model_name": "vit_t14", "freeze": False},
                                             "temporal_transformer": {"num_layers": 1, "num_heads": 4},
                                             "multi_view": {"num_cross_layers": 1, "num_heads": 4},
                                             "pose_encoder": {"num_layers": 1, "num_heads": 4},
                                             "fusion": {"num_layers": 1, "num_heads": 4},
                                             "tactile_decoder": {"conv_channels": 64}},
                                   "data": {"image_size": [112, 112]},
                                   "training": {"num_epochs": 1, "batch_size": 2, "num_workers": 1,
                                                "scheduler": {"warmup_epochs": 0}}}))
    env = {**os.environ, "OMP_NUM_THREADS": "1", "MASTER_ADDR": "127.0.0.1"}
    command = [sys.executable, "-m", "torch.distributed.run", "--nproc_per_node", "2", "--master_addr", "127.0.0.1",
               "--master_port", str(_free_port()), "-m", "touchanything.app.cli", "train", "--config", str(cfg), "--data", str(data),
               "--out", str(tmp_path / "ddp")]
    proc = subprocess.run(command, capture_output=True, text=True, env=env, timeout=600, cwd=Path(__file__).parents[2])
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert (tmp_path / "ddp" / "last.pth").is_file() and "best validation loss" in proc.stdout
    load_model(tmp_path / "ddp" / "last.pth")


def test_a_split_of_raw_episode_folders_trains_from_the_frame_cache(data, sim_raw_root, tmp_path):
    """Data kept as raw episodes (too large as HDF5) train beside HDF5 ones: the split lists the folders, whose frames
    are decoded once into the frame cache of `--data`."""
    folders = sorted(str(p.parent) for p in sim_raw_root.rglob("chest.mp4"))
    split = tmp_path / "raw_split.json"
    val = sorted(str(p) for p in data.rglob("*.hdf5"))[:1]
    split.write_text(json.dumps({"train": folders, "val": val, "test_seen": [], "test_unseen": []}))
    result = Trainer(config(epochs=1), data, tmp_path / "run", split, log=lambda _: None).fit()
    assert np.isfinite(result.train_loss).all() and (tmp_path / "run" / "last.pth").is_file()
    assert len(list((data / ".frame_cache").glob("*.h5"))) == len(folders) + 1
