"""Training: one process (CPU or GPU) or several under torchrun (DDP, unused parameters allowed because of
view dropout). Official objective, optimiser and schedule; validation, best / periodic / last checkpoints
in the official format, exact resume, a NaN guard, and a backbone-feature cache when the backbone is frozen.
Clips are loaded by `training.num_workers` persistent worker processes (pinned batches on a GPU), in an
order fixed by the seed and the epoch alone.
"""
from __future__ import annotations

import math
import random
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch
import torch.distributed as dist
from torch.nn.parallel import DistributedDataParallel
from torch.utils.data import DataLoader
from tqdm import tqdm

from touchanything.core.errors import UserError
from touchanything.core.view_sets import view_set_name
from touchanything.devices.episodes.dataset_split import SPLIT_FILE, read_split
from touchanything.inference.model.checkpoint import build_model, load_state, model_state, read_checkpoint, save_checkpoint
from touchanything.inference.model.model_config import SPAN
from touchanything.inference.model.torch_device import join_process_group, resolve_device
from touchanything.inference.training.clip_dataset import ClipDataset, clip_loader
from touchanything.inference.training.colour_augmentation import augment_views
from touchanything.inference.training.feature_cache import FeatureCache
from touchanything.inference.training.frame_cache import FrameCache
from touchanything.inference.training.tactile_loss import tactile_loss
from touchanything.inference.training.train_config import GRAD_CLIP, TrainConfig, train_config_to_dict

LAST, BEST = "last.pth", "best_model.pth"


class TrainingError(UserError):
    """Training cannot go on (non-finite loss or weights); the message names the step and the episodes."""


@dataclass
class TrainResult:
    """Per-epoch mean losses, the best validation loss, skipped empty-mask batches, and how often each
    set of views (by its view-set id, `ego+left`) reached the encoder."""

    train_loss: list[float] = field(default_factory=list)
    val_loss: list[float] = field(default_factory=list)
    best_val_loss: float = math.inf
    skipped_batches: int = 0
    view_sets: Counter = field(default_factory=Counter)
    clips_per_second: float = 0.0


def _schedule(optimizer, config: TrainConfig):
    """Linear warm-up from 1 % to the full rate, then cosine to `min_lr`; stepped once per epoch."""
    epochs, s = config.training.num_epochs, config.training.scheduler
    cosine = torch.optim.lr_scheduler.CosineAnnealingLR(optimizer, T_max=max(epochs - s.warmup_epochs, 1), eta_min=s.min_lr)
    if s.warmup_epochs == 0:
        return cosine
    warmup = torch.optim.lr_scheduler.LinearLR(optimizer, 0.01, 1.0, total_iters=s.warmup_epochs)
    return torch.optim.lr_scheduler.SequentialLR(optimizer, [warmup, cosine], milestones=[s.warmup_epochs])


def _files(data: Path, split_file: Path | None, key: str) -> list[Path]:
    files = read_split(split_file or Path(data) / SPLIT_FILE)[key]
    missing = [f for f in files if not f.exists()]
    if missing:
        raise UserError(f"{missing[0]}: listed in the split but not found ({len(missing)} missing)")
    return files


class Trainer:
    def __init__(self, config: TrainConfig, data: Path, out: Path, split_file: Path | None = None,
                 log: Callable[[str], None] = print) -> None:
        self.config, self.out, self.log = config.check(), Path(out), log
        group = join_process_group()
        self.rank, self.world, self.device = group.rank, group.world, resolve_device("auto", group.local_rank)
        seed = config.system.seed + self.rank
        torch.manual_seed(seed)
        random.seed(seed)
        np.random.seed(seed)
        c = config.model
        train_files = _files(data, split_file, "train")
        if not train_files:
            raise UserError("the split's train list is empty")
        val_files = _files(data, split_file, "val")
        self.model = build_model(c).to(self.device)  # before decoding: missing backbone weights are told at once
        frame_cache = None if c.blank_images else self._frame_cache(Path(data), c.image_size)

        def dataset(files: list[Path], bar: tqdm) -> ClipDataset:
            d = config.data
            return ClipDataset(files, c.image_size, d.pose_source, d.fallback_pose_source, c.blank_images, frame_cache,
                               on_episode=lambda: bar.update(1), workers=torch.get_num_threads())

        if self.world > 1 and self.rank != 0:
            dist.barrier()  # rank 0 builds the missing frame-cache entries first; the others reuse them
        with tqdm(total=len(train_files) + len(val_files), desc="trajectories", unit="file", disable=self.rank != 0,
                  leave=False) as bar:
            self.train_set = dataset(train_files, bar)
            self.val_set = dataset(val_files, bar)
        if self.world > 1 and self.rank == 0:
            dist.barrier()
        if frame_cache is not None and self.rank == 0:
            log(f"frame cache {frame_cache.folder}: {frame_cache.reused} trajectories reused, {frame_cache.built} decoded "
                f"at {c.image_size} px")
        if len(self.train_set) == 0:
            raise UserError(f"no training clips: every train trajectory is shorter than {SPAN} frames")
        hands = self.model.set_pose_statistics(np.concatenate([e.poses for e in self.train_set.episodes]))
        if hands and self.rank == 0:
            log(f"pose input: wrist-relative joints and wrist position, standardised over {hands} training hand poses")
        self.net = DistributedDataParallel(self.model, find_unused_parameters=True) if self.world > 1 else self.model
        params = [p for p in self.model.parameters() if p.requires_grad]
        o = config.training.optimizer
        self.optimizer = torch.optim.AdamW(params, lr=o.lr, weight_decay=o.weight_decay, betas=o.betas)
        self.scheduler = _schedule(self.optimizer, config)
        self.scaler = torch.amp.GradScaler("cuda", enabled=config.system.mixed_precision and self.device.type == "cuda")
        # one cache per dataset: both number their episodes from 0, and the cache is keyed by that number
        self.cache, self.val_cache = (FeatureCache(), FeatureCache()) if c.vision_encoder.freeze else (None, None)
        self.train_loader, self.val_loader = self._loader(self.train_set, True), self._loader(self.val_set, False)
        self.result = TrainResult()
        self.start_epoch = 0

    def _frame_cache(self, root: Path, size: int) -> FrameCache | None:
        """The dataset's frame cache; None, with a note, when it cannot be written (frames are then decoded
        clip by clip)."""
        try:
            return FrameCache.beside(root, size)
        except UserError as exc:
            self.log(f"{exc}; frames are decoded clip by clip")
            return None

    def resume(self, path: Path) -> None:
        """Continue from a checkpoint of this run: weights, optimiser, schedule and epoch."""
        checkpoint = read_checkpoint(path)
        load_state(self.model, model_state(checkpoint, Path(path)), Path(path))
        if not checkpoint.get("optimizer_state_dict") or not checkpoint.get("scheduler_state_dict"):
            raise UserError(f"{path}: no optimizer/scheduler state; it cannot be resumed (use it as pretrained weights)")
        self.optimizer.load_state_dict(checkpoint["optimizer_state_dict"])
        self.scheduler.load_state_dict(checkpoint["scheduler_state_dict"])
        self.start_epoch = int(checkpoint.get("epoch", 0))
        self.result.best_val_loss = float((checkpoint.get("metrics") or {}).get("best_val_loss", math.inf))
        self.log(f"resumed from {path}: {self.start_epoch} of {self.config.training.num_epochs} epochs done, best "
                 f"validation loss so far {self.result.best_val_loss:.4f}")

    def _loader(self, dataset: ClipDataset, shuffle: bool) -> DataLoader:
        """This process's loader over `dataset` for the whole run: `training.num_workers` persistent workers,
        pinned batches on a GPU, the order seeded by `system.seed` and the epoch (this rank's share under DDP)."""
        t = self.config.training
        return clip_loader(dataset, t.batch_size, t.num_workers, self.config.system.seed, shuffle,
                           pin_memory=self.device.type == "cuda", replicas=self.world, rank=self.rank)

    def epoch_batches(self, epoch: int) -> DataLoader:
        """The training batches of `epoch` (0-based), in the order fixed by the seed and the epoch."""
        self.train_loader.sampler.set_epoch(epoch)
        return self.train_loader

    def _to_device(self, x: torch.Tensor) -> torch.Tensor:
        """Copy to the training device; asynchronous from pinned memory on a GPU."""
        return x.to(self.device, non_blocking=True)

    def _forward(self, batch: dict, cache: FeatureCache | None) -> torch.Tensor:
        """Predicted tactile maps (float32); a frozen backbone's tokens come through `cache`, the batch's dataset's."""
        poses = self._to_device(batch["poses"])
        autocast = torch.autocast(self.device.type, dtype=torch.bfloat16 if self.device.type == "cpu" else torch.float16,
                                  enabled=self.config.system.mixed_precision)
        with autocast:
            if cache is not None:
                tokens = cache.tokens(self.model.vision_encoder, batch["views"], batch["episode"], batch["frames"], self.device)
                return self.net(poses=poses, tokens=tokens)["tactile"].float()
            views = {v: self._to_device(x) for v, x in batch["views"].items()}
            if self.net.training and not self.model.config.blank_images:
                views = augment_views(views, self.config.data.colour_augmentation)
            return self.net(poses=poses, views=views)["tactile"].float()

    def _episodes(self, batch: dict, dataset: ClipDataset) -> str:
        return ", ".join(sorted({dataset.episodes[int(e)].path.name for e in batch["episode"]}))

    def _where(self, epoch: int, step: int, batch: dict) -> str:
        return (f"epoch {epoch + 1}, step {step} (episodes: {self._episodes(batch, self.train_set)}); "
                f"training stopped, the last good checkpoint is {self.out / LAST}")

    def _check_loss(self, loss: torch.Tensor, epoch: int, step: int, batch: dict) -> None:
        if not torch.isfinite(loss):
            raise TrainingError(f"non-finite loss {loss.item()} at {self._where(epoch, step, batch)}")

    def _check_weights(self, epoch: int, step: int, batch: dict) -> None:
        bad = next((n for n, p in self.model.named_parameters() if not torch.isfinite(p).all()), None)
        if bad:
            raise TrainingError(f"non-finite weights in {bad} after {self._where(epoch, step, batch)}")

    def _train_epoch(self, epoch: int) -> float:
        self.net.train()
        losses, clips, started = [], 0, time.perf_counter()
        bar = tqdm(self.epoch_batches(epoch), desc=f"epoch {epoch + 1}/{self.config.training.num_epochs}",
                   unit="batch", disable=self.rank != 0, leave=False)
        for step, batch in enumerate(bar, start=1):
            mask = self._to_device(batch["mask"])
            if mask.sum() == 0:
                self.result.skipped_batches += 1
                continue
            pred = self._forward(batch, self.cache)
            self.result.view_sets[view_set_name(tuple(self.model.last_kept))] += 1
            loss = tactile_loss(pred, self._to_device(batch["target"]), mask, self.config.training.loss)
            self._check_loss(loss, epoch, step, batch)
            self.optimizer.zero_grad(set_to_none=True)
            self.scaler.scale(loss).backward()
            self.scaler.unscale_(self.optimizer)
            torch.nn.utils.clip_grad_norm_(self.model.parameters(), GRAD_CLIP)
            self.scaler.step(self.optimizer)
            self.scaler.update()
            self._check_weights(epoch, step, batch)
            losses.append(loss.item())
            clips += len(batch["poses"])
            bar.set_postfix(loss=f"{loss.item():.4f}", clips_s=f"{clips / (time.perf_counter() - started):.1f}")
        self.result.clips_per_second = clips / max(time.perf_counter() - started, 1e-9)
        return float(np.mean(losses)) if losses else math.nan

    @torch.no_grad()
    def _validate(self) -> float:
        self.net.eval()
        total, count = 0.0, 0
        for batch in self.val_loader:
            mask = self._to_device(batch["mask"])
            if mask.sum() == 0:
                continue
            pred = self._forward(batch, self.val_cache)
            total += tactile_loss(pred, self._to_device(batch["target"]), mask, self.config.training.loss).item()
            count += 1
        if self.world > 1:
            sums = torch.tensor([total, count], dtype=torch.float64, device=self.device)
            dist.all_reduce(sums)
            total, count = sums.tolist()
        return total / count if count else math.nan

    def _save(self, name: str, epoch: int, loss: float) -> None:
        metrics = {"val_loss": self.result.val_loss[-1], "best_val_loss": self.result.best_val_loss}
        save_checkpoint(self.out / name, self.model, epoch=epoch, optimizer=self.optimizer, scheduler=self.scheduler,
                        loss=loss, metrics=metrics, config=train_config_to_dict(self.config))

    def _validates(self, done: int) -> bool:
        """Validation runs every `val_interval` epochs and after the last one."""
        return done % self.config.training.val_interval == 0 or done == self.config.training.num_epochs

    def fit(self) -> TrainResult:
        """Train from `start_epoch` to the configured number of epochs. The best checkpoint is judged on
        validated epochs only (by the training loss when there are no validation clips)."""
        for epoch in range(self.start_epoch, self.config.training.num_epochs):
            done = epoch + 1
            train_loss = self._train_epoch(epoch)
            validated = self._validates(done)
            val_loss = self._validate() if validated else math.nan
            self.result.train_loss.append(train_loss)
            self.result.val_loss.append(val_loss)
            monitored = val_loss if math.isfinite(val_loss) else train_loss
            improved = validated and math.isfinite(monitored) and monitored < self.result.best_val_loss
            if improved:
                self.result.best_val_loss = monitored
            self.scheduler.step()
            if self.rank == 0:
                self._save(LAST, done, train_loss)
                if improved:
                    self._save(BEST, done, monitored)
                if done % self.config.training.save_interval == 0:
                    self._save(f"checkpoint_epoch_{done}.pth", done, train_loss)
                self.log(f"epoch {done}: train loss {train_loss:.4f}, val loss {val_loss:.4f}, "
                         f"lr {self.optimizer.param_groups[0]['lr']:.2e}, {self.result.clips_per_second:.1f} clips/s"
                         + (", best" if improved else ""))
        if self.world > 1:
            dist.barrier()
        return self.result
