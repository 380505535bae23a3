"""Training data loading on this machine, in clips/s over a simulated HDF5 set:
(a) the DataLoader alone (HDF5 decoding, resizing and normalising, no model) with 0, 1 and 2 worker
processes: a first pass (workers starting) and a second pass (workers warm);
(b) short training runs of the `nano` config with 0 and 2 workers: the training clips/s of the last epoch
(as the trainer reports it; validation excluded) and the wall time of the whole run.

    python benchmarks/training_loader.py [--data HDF5_ROOT] [--episodes 6] [--seconds 5] [--epochs 2] [--rounds 2]
                                         [--loading-workers 0 1 2] [--training-workers 0 2]

Without --data, simulates and converts episodes into a temporary folder (what `touchanything simulate` and
`touchanything convert --compression-level 4` write: three 640×480 views per frame, gzip). Every trajectory
is trained on, the first also validated on. Settings are interleaved round by round (this machine's speed
drifts); each row gives the load average when it started, since other processes share the cores.
"""
from __future__ import annotations

import argparse
import os
import platform
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import torch

from touchanything.devices.episodes.dataset_conversion import convert_dataset
from touchanything.devices.episodes.dataset_split import write_split
from touchanything.devices.episodes.episode_loader import find_hdf5_files
from touchanything.devices.sim.dataset_generator import SimulationConfig, simulate_dataset
from touchanything.inference.training.clip_dataset import ClipDataset, clip_loader
from touchanything.inference.training.train_config import TrainConfig, train_config_from_file
from touchanything.inference.training.trainer import Trainer

NANO = Path(__file__).resolve().parents[1] / "configs" / "nano.yaml"


def simulated_root(work: Path, episodes: int, seconds: float) -> Path:
    """Simulated raw episodes converted to HDF5 under `work` (the CLI's default compression)."""
    simulate_dataset(work / "raw", SimulationConfig(episodes=episodes, seconds=seconds, seed=1, workers=1))
    convert_dataset(work / "raw", work / "h5", compression_level=4)
    return work / "h5"


def training_split(root: Path, work: Path) -> tuple[list[Path], Path]:
    """Every trajectory under `root` for training, the first for validation; (files, split file)."""
    files = find_hdf5_files(root)
    if not files:
        raise SystemExit(f"{root}: no HDF5 trajectories")
    split = work / "bench_split.json"
    write_split(split, {"train": files, "val": files[:1]}, absolute=True)
    return files, split


def loading(dataset: ClipDataset, batch_size: int, workers: int) -> tuple[float, float]:
    """Clips/s of a first pass (workers starting) and a second pass (workers warm) over `dataset`."""
    loader = clip_loader(dataset, batch_size, workers, seed=0, shuffle=True)
    rates = []
    for epoch in (0, 1):
        loader.sampler.set_epoch(epoch)
        started = time.perf_counter()
        clips = sum(len(batch["poses"]) for batch in loader)
        rates.append(clips / (time.perf_counter() - started))
    return rates[0], rates[1]


def training(config: TrainConfig, split: Path, workers: int, out: Path) -> tuple[float, float]:
    """(training clips/s of the last epoch, wall seconds of the whole run incl. start-up and validation)."""
    config = replace(config, training=replace(config.training, num_workers=workers))
    started = time.perf_counter()
    trainer = Trainer(config, split.parent, out, split, log=lambda _: None)
    return trainer.fit().clips_per_second, time.perf_counter() - started


def row(round_: int, part: str, workers: int, values: str) -> str:
    return f"| {round_} | {part} | {workers} | {values} | {os.getloadavg()[0]:.2f} |"


def run(args: argparse.Namespace, work: Path) -> None:
    root = args.data or simulated_root(work, args.episodes, args.seconds)
    files, split = training_split(root, work)
    config = train_config_from_file(NANO)
    config = replace(config, training=replace(config.training, num_epochs=args.epochs,
                                              scheduler=replace(config.training.scheduler, warmup_epochs=0)))
    dataset = ClipDataset(files, config.model.image_size, config.data.pose_source)
    print(f"{platform.node()}: {os.cpu_count()} CPU cores, CUDA {'available' if torch.cuda.is_available() else 'absent'}, "
          f"torch {torch.__version__} with {torch.get_num_threads()} threads; {len(files)} trajectories, "
          f"{len(dataset)} clips per epoch, nano at {config.model.image_size} px, batch {config.training.batch_size}\n")
    print("| round | part | workers | clips/s | load avg (1 min) |\n|---|---|---|---|---|", flush=True)
    for round_ in range(1, args.rounds + 1):
        for workers in args.loading_workers:
            cold, warm = loading(dataset, config.training.batch_size, workers)
            print(row(round_, "loading", workers, f"{cold:.1f} first pass, {warm:.1f} warm"), flush=True)
        for workers in args.training_workers:
            rate, seconds = training(config, split, workers, work / f"run_{round_}_{workers}")
            print(row(round_, f"nano training, {args.epochs} epochs", workers,
                      f"{rate:.2f} (last epoch); run {seconds:.0f} s"), flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--data", type=Path, help="an HDF5 root (default: simulate one into a temporary folder)")
    parser.add_argument("--episodes", type=int, default=6, help="simulated episodes (default 6)")
    parser.add_argument("--seconds", type=float, default=5.0, help="length of each simulated episode (default 5)")
    parser.add_argument("--epochs", type=int, default=2, help="epochs per training run (default 2)")
    parser.add_argument("--rounds", type=int, default=2, help="interleaved rounds (default 2)")
    parser.add_argument("--loading-workers", type=int, nargs="+", default=[0, 1, 2], help="(default 0 1 2)")
    parser.add_argument("--training-workers", type=int, nargs="+", default=[0, 2], help="(default 0 2)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="training_loader_") as work:
        run(args, Path(work))


if __name__ == "__main__":
    main()
