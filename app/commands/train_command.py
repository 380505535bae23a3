"""`touchanything train --config CFG --data ROOT`: train (one process, or several under torchrun)."""
from __future__ import annotations

import argparse
import os
import time
from dataclasses import replace
from pathlib import Path

from touchanything.core.output_safety import add_overwrite_argument, check_output


def add_parser(commands: argparse._SubParsersAction) -> None:
    parser = commands.add_parser("train", help="train a model on HDF5 trajectories or raw episode folders (torchrun for several GPUs)")
    parser.add_argument("--config", type=Path, required=True, help="training config (official structure)")
    parser.add_argument("--data", type=Path, required=True,
                        help="dataset root holding split.json; its .frame_cache keeps the decoded frames")
    parser.add_argument("--split-file", type=Path, help="split file (default: DATA/split.json)")
    parser.add_argument("--out", type=Path, help="checkpoint folder (default: checkpoints/<time>_<backbone>_<config>)")
    parser.add_argument("--resume", type=Path, help="continue from a checkpoint of the same run (e.g. OUT/last.pth)")
    parser.add_argument("--epochs", type=int, metavar="N",
                        help="train N epochs instead of the config's training.num_epochs (a quick run); a warm-up longer "
                             "than that is shortened in proportion, with a note")
    parser.add_argument("--blank-images", action="store_true",
                        help="train the pose-only baseline: every frame black (sets data.blank_images: true)")
    add_overwrite_argument(parser, "--out's checkpoints and config.yaml (replaced anyway when resuming from --out)")
    parser.set_defaults(run=run)


def check_run_folder(out: Path, args: argparse.Namespace, names: tuple[str, ...]) -> None:
    """`out` and the files of `names` in it, before any work: an earlier run's are replaced only with --overwrite or
    when resuming from a checkpoint in `out` (which is read whole before anything is written)."""
    inputs = (args.config, args.data, args.split_file)
    check_output(out, (*inputs, args.resume), folder=True)
    resuming_here = args.resume is not None and args.resume.resolve().parent == out.resolve()
    for name in names:
        check_output(out / name, inputs if resuming_here else (*inputs, args.resume), args.overwrite or resuming_here)


def run(args: argparse.Namespace) -> int:
    from touchanything.inference.model.checkpoint import CONFIG_FILE
    from touchanything.inference.training.train_config import describe_settings, train_config_from_file, with_epochs
    from touchanything.inference.training.trainer import BEST, LAST, Trainer

    config = train_config_from_file(args.config)
    if args.epochs is not None:
        config, note = with_epochs(config, args.epochs)
        if note and os.environ.get("RANK", "0") == "0":
            print(note, flush=True)
    if args.blank_images:
        config = replace(config, model=replace(config.model, blank_images=True))
    run_name = f"{time.strftime('%Y%m%d_%H%M%S')}_{config.model.backbone}_tactile_prediction_{args.config.stem}"
    out = args.out or Path("checkpoints") / run_name
    check_run_folder(out, args, (BEST, LAST, CONFIG_FILE))
    if os.environ.get("RANK", "0") == "0":
        print("\n".join([f"config {args.config}", *describe_settings(config)]), flush=True)
    trainer = Trainer(config, args.data, out, args.split_file)
    if args.resume:
        trainer.resume(args.resume)
    result = trainer.fit()
    if trainer.rank == 0:
        print(f"best validation loss {result.best_val_loss:.4f}; skipped {result.skipped_batches} empty-mask batch(es); "
              f"checkpoints: {out / BEST}, {out / LAST}")
        print("view sets seen by the encoder: " + ", ".join(f"{k} {v}" for k, v in sorted(result.view_sets.items())))
    return 0
