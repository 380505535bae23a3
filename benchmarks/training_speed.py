"""Where a training step's time goes on this machine, and training clips/s of the ViT nano decoding its frames
per clip against the conv nano reading the frame cache.

    python benchmarks/training_speed.py --data HDF5_ROOT [--split-file F] [--trajectories 12] [--steps 30]
                                        [--rounds 2] [--out docs/bench]

Settings, interleaved round by round (this machine's speed drifts), each a fresh model trained for `--steps`
steps after 3 warm-up steps on the first `--trajectories` training trajectories of the split, batch 8,
loading in the main process (the bundled configs' `num_workers: 0`):
- `nano_vit, decoded per clip` — the ViT nano (configs/nano_vit.yaml: the official
  architecture at nano size, ViT at 112 px) with frames decoded from the HDF5 file and resized every clip;
- `nano_vit, frame cache` — the same model with frames from the frame cache;
- `nano, frame cache` — the bundled nano's recipe (configs/nano.yaml: conv backbone at 96 px, hand pose input);
- `nano, decoded per clip` — the same without the cache.
Each step is timed in four parts: loading the batch, the forward pass, loss and backward, the optimiser
step (with gradient clipping). Writes `training_speed.md` and `.json` into `--out`.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

import numpy as np
import torch

from touchanything.devices.episodes.dataset_split import read_split
from touchanything.inference.model.checkpoint import build_model
from touchanything.inference.training.clip_dataset import ClipDataset, clip_loader
from touchanything.inference.training.frame_cache import FrameCache
from touchanything.inference.training.tactile_loss import tactile_loss
from touchanything.inference.training.train_config import GRAD_CLIP, TrainConfig, train_config_from_file

CONFIGS = Path(__file__).resolve().parents[1] / "configs"
SETTINGS = (("nano_vit", False), ("nano_vit", True), ("nano", True), ("nano", False))
PARTS = ("load", "forward", "backward", "optimiser")


def timed_steps(config: TrainConfig, dataset: ClipDataset, steps: int, warmup: int = 3) -> dict[str, float]:
    """Train a fresh model for warmup + steps steps; seconds per clip of each part over the last `steps`."""
    torch.manual_seed(0)
    model = build_model(config.model).train()
    model.set_pose_statistics(np.concatenate([e.poses for e in dataset.episodes]))
    optimizer = torch.optim.AdamW(model.parameters(), lr=config.training.optimizer.lr)
    loader = clip_loader(dataset, config.training.batch_size, 0, seed=0, shuffle=True)
    loader.sampler.set_epoch(0)
    batches, totals, clips = iter(loader), dict.fromkeys(PARTS, 0.0), 0
    for step in range(warmup + steps):
        marks = [time.perf_counter()]
        batch = next(batches, None)
        if batch is None:  # fewer clips than steps: another pass over the trajectories
            batches = iter(loader)
            batch = next(batches)
        marks.append(time.perf_counter())
        pred = model(poses=batch["poses"], views=batch["views"])["tactile"]
        marks.append(time.perf_counter())
        loss = tactile_loss(pred, batch["target"], batch["mask"], config.training.loss)
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        marks.append(time.perf_counter())
        torch.nn.utils.clip_grad_norm_(model.parameters(), GRAD_CLIP)
        optimizer.step()
        marks.append(time.perf_counter())
        if step >= warmup:
            clips += len(batch["poses"])
            for part, start, stop in zip(PARTS, marks, marks[1:]):
                totals[part] += stop - start
    return {part: seconds / clips for part, seconds in totals.items()}


def run(args: argparse.Namespace) -> dict:
    files = read_split(args.split_file or args.data / "split.json")["train"][:args.trajectories]
    configs = {name: train_config_from_file(CONFIGS / f"{name}.yaml") for name in ("nano_vit", "nano")}
    datasets = {}
    for name, cached in SETTINGS:
        size = configs[name].model.image_size
        cache = FrameCache.beside(args.data, size) if cached else None
        datasets[name, cached] = ClipDataset(files, size, cache=cache)
    rows = []
    for round_ in range(1, args.rounds + 1):
        for name, cached in SETTINGS:
            load = os.getloadavg()[0]
            parts = timed_steps(configs[name], datasets[name, cached], args.steps)
            total = sum(parts.values())
            rows.append({"round": round_, "model": name, "frames": "frame cache" if cached else "decoded per clip",
                         "clips_per_s": 1.0 / total, **{f"{p}_ms_per_clip": 1000 * parts[p] for p in PARTS},
                         "load_avg": load})
            print(f"round {round_} {name:9s} {rows[-1]['frames']:17s} {1 / total:6.1f} clips/s  "
                  + "  ".join(f"{p} {1000 * parts[p]:6.1f}" for p in PARTS) + f" ms/clip  (load {load:.2f})", flush=True)
    return {"host": platform.node(), "cores": os.cpu_count(), "torch": torch.__version__,
            "threads": torch.get_num_threads(), "trajectories": len(files), "steps": args.steps, "rows": rows}


def markdown(result: dict) -> str:
    rows = result["rows"]

    def median(model: str, frames: str) -> float:
        return float(np.median([r["clips_per_s"] for r in rows if r["model"] == model and r["frames"] == frames]))

    before, after = median("nano_vit", "decoded per clip"), median("nano", "frame cache")
    lines = [f"# Training speed ({result['cores']} CPU cores, torch {result['torch']}, {result['threads']} threads)", "",
             f"`python benchmarks/training_speed.py`: {result['trajectories']} training trajectories, batch 8, "
             f"{result['steps']} timed steps per setting after 3 warm-up steps, settings interleaved round by round.", "",
             f"**clips/s: {before:.1f} for the ViT nano decoding its frames per clip (nano_vit, decoded per clip), "
             f"{after:.1f} for the conv nano reading the frame cache (nano, frame cache): {after / before:.1f}×** "
             "(medians over rounds).", "",
             "| round | model | frames | clips/s | load ms/clip | forward ms/clip | backward ms/clip | optimiser ms/clip | load avg |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['round']} | {r['model']} | {r['frames']} | {r['clips_per_s']:.1f} | " + " | ".join(
            f"{r[f'{p}_ms_per_clip']:.1f}" for p in PARTS) + f" | {r['load_avg']:.2f} |")
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--data", type=Path, required=True, help="HDF5 root (the frame cache goes beside it)")
    parser.add_argument("--split-file", type=Path, help="split file (default DATA/split.json)")
    parser.add_argument("--trajectories", type=int, default=12, help="training trajectories used (default 12)")
    parser.add_argument("--steps", type=int, default=30, help="timed steps per setting (default 30)")
    parser.add_argument("--rounds", type=int, default=2, help="interleaved rounds (default 2)")
    parser.add_argument("--out", type=Path, default=Path("recordings/bench"), help="report folder (default recordings/bench)")
    args = parser.parse_args()
    result = run(args)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "training_speed.json").write_text(json.dumps(result, indent=1) + "\n")
    (args.out / "training_speed.md").write_text(markdown(result))
    print(f"report: {args.out / 'training_speed.md'}")


if __name__ == "__main__":
    main()
