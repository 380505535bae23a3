"""Copy a trained checkpoint into models/<name>/ as fp16 (official dict format, weights only) + config.yaml.

    .venv/bin/python scripts/bundle_model.py CHECKPOINT models/NAME
"""
from __future__ import annotations

import argparse
from pathlib import Path

import yaml

from touchanything.inference.model.checkpoint import CONFIG_FILE, find_config, load_model, read_checkpoint, save_checkpoint


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("checkpoint", type=Path)
    parser.add_argument("out", type=Path)
    args = parser.parse_args()
    model = load_model(args.checkpoint)
    source = read_checkpoint(args.checkpoint)
    config = yaml.safe_load(find_config(args.checkpoint, None).read_text())
    target = args.out / "best_model.pth"
    save_checkpoint(target, model, epoch=int(source.get("epoch", 0)), loss=source.get("loss"),
                    metrics=source.get("metrics"), half=True, config=config)
    print(f"{target}: {target.stat().st_size / 2**20:.1f} MB (+ {args.out / CONFIG_FILE})")


if __name__ == "__main__":
    main()
