"""Copy a trained checkpoint into models/<name>/ as fp16 (official dict format, weights only) + config.yaml, with
its model card (what it is, what it was trained on, its held-out accuracy from `touchanything eval` results).

    .venv/bin/python scripts/bundle_model.py CHECKPOINT models/NAME --trained-on "simulated EgoTouch world, 162 episodes" \
        --eval test_seen=EVAL_SEEN/results.json test_unseen=EVAL_UNSEEN/results.json

With CHECKPOINT = models/NAME/best_model.pth (a model bundled already) only its card is written: the weights, which
the atlas knows by their sha256, stay as they are.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import yaml

from touchanything.inference.model.checkpoint import CONFIG_FILE, find_config, load_model, read_checkpoint, save_checkpoint
from touchanything.inference.model.model_card import ModelCard, write_card

CARD_METRICS = ("volumetric_iou", "contact_iou", "temporal_accuracy", "mae")


def held_out(results_json: Path, pose_only: bool) -> dict[str, float]:
    """The causal all-views metrics in an eval results.json of the evaluated model, or with `pose_only` of its
    pose-only rows (`eval --pose-only-baseline CHECKPOINT`: the black-frame model evaluated beside it)."""
    payload = json.loads(results_json.read_text())
    record = next(r for r in payload["results"] if r["views"] == "all" and not r["baseline"]
                  and (r["pose_only"] or model_is_blank(payload)) == pose_only)
    overall = record["causal"]["overall"]
    return {key: float(overall[key]) for key in CARD_METRICS if key in overall}


def model_is_blank(payload: dict) -> bool:
    """Whether the evaluated checkpoint itself is a pose-only (black-frame) model."""
    return bool(load_model(Path(payload["checkpoint"])).config.blank_images)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("checkpoint", type=Path)
    parser.add_argument("out", type=Path)
    parser.add_argument("--trained-on", required=True, help="where the training data came from (the card says it)")
    parser.add_argument("--eval", nargs="+", default=[], metavar="SPLIT=RESULTS_JSON",
                        help="held-out eval results per test split (their causal, all-views metrics go on the card; "
                             "for a pose-only model, its own evaluation or the pose-only rows of the model it was "
                             "evaluated beside)")
    args = parser.parse_args()
    model = load_model(args.checkpoint)
    source = read_checkpoint(args.checkpoint)
    config = yaml.safe_load(find_config(args.checkpoint, None).read_text())
    target = args.out / "best_model.pth"
    if target.resolve() != args.checkpoint.resolve():
        save_checkpoint(target, model, epoch=int(source.get("epoch", 0)), loss=source.get("loss"),
                        metrics=source.get("metrics"), half=True, config=config)
    splits = dict(item.split("=", 1) for item in args.eval)
    pose_only = bool(model.config.blank_images)
    card = ModelCard(name=args.out.name, trained_on=args.trained_on,
                     held_out={split: held_out(Path(path), pose_only) for split, path in splits.items()},
                     pose_only=pose_only)
    write_card(args.out, card)
    print(f"{target}: {target.stat().st_size / 2**20:.1f} MB (+ {args.out / CONFIG_FILE}); card: {card.summary()}")


if __name__ == "__main__":
    main()
