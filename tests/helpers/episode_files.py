"""Writers of the episode files the project only reads (`masks.npz`, `quality_issues.json`), for fixtures."""
from __future__ import annotations

import json
from pathlib import Path

from touchanything.devices.episodes.episode_files import Masks, save_npz


def write_masks(path: Path, masks: Masks) -> None:
    save_npz(path, {"masks": masks.masks, "obj_ids": masks.obj_ids, "valid_frames": masks.valid_frames})


def write_quality(path: Path, duplicate_ratio: dict[str, float]) -> None:
    data = {"duplicate_frames": {side: {"ratio": float(r)} for side, r in duplicate_ratio.items()}}
    Path(path).write_text(json.dumps(data, indent=1))
