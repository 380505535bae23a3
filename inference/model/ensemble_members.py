"""The ensemble format: an `ensemble.json` beside a checkpoint lists the other members of its ensemble,
`{"members": ["members/2/best_model.pth", "members/3/best_model.pth", …]}` (paths relative to that folder).
The folder's own checkpoint is member 1; each member is a complete checkpoint with its config.yaml beside it,
of the same model config as member 1. `member_checkpoints` reads and checks it; it never loads weights."""
from __future__ import annotations

import json
from pathlib import Path

from touchanything.core.errors import UserError
from touchanything.inference.model.checkpoint import find_config
from touchanything.inference.model.config_files import read_config_file
from touchanything.inference.model.model_config import ModelConfig, config_from_dict

ENSEMBLE_FILE = "ensemble.json"


def listed_members(checkpoint: Path) -> list[Path]:
    """Members 2… named by the `ensemble.json` beside `checkpoint`, resolved against its folder; UserError for
    a missing or damaged file."""
    path = Path(checkpoint).parent / ENSEMBLE_FILE
    if not path.is_file():
        raise UserError(f"{path}: no ensemble file beside the checkpoint (an ensemble of more than one member needs one)")
    try:
        members = json.loads(path.read_text(encoding="utf-8")).get("members")
    except (OSError, UnicodeDecodeError, ValueError, AttributeError) as exc:
        raise UserError(f"{path}: not a readable ensemble file ({exc.__class__.__name__})") from None
    if not isinstance(members, list) or not all(isinstance(m, str) and m for m in members):
        raise UserError(f'{path}: expected {{"members": ["members/2/best_model.pth", …]}} (a list of checkpoint paths)')
    return [path.parent / m for m in members]


def member_count(checkpoint: Path) -> int:
    """How many members `checkpoint`'s ensemble has (1 without an ensemble file beside it)."""
    return 1 + len(listed_members(checkpoint)) if (Path(checkpoint).parent / ENSEMBLE_FILE).is_file() else 1


def _config(checkpoint: Path, config: Path | None = None) -> ModelConfig:
    source = find_config(checkpoint, config)
    return config_from_dict(read_config_file(source), str(source))


def member_checkpoints(checkpoint: Path, k: int, config: Path | None = None) -> list[Path]:
    """The first `k` members' checkpoints, `checkpoint` first (k = 1: `checkpoint` alone, no ensemble file
    read). `config`: member 1's config (None: the config.yaml beside it). UserError for a missing or damaged
    ensemble.json, a listed member missing, `k` above the members there are, a member whose config differs."""
    checkpoint = Path(checkpoint)
    if k == 1:
        return [checkpoint]
    listed = listed_members(checkpoint)
    if k > len(listed) + 1:
        raise UserError(f"{checkpoint.parent / ENSEMBLE_FILE}: {k} members asked for, the ensemble has {len(listed) + 1}")
    members = listed[:k - 1]
    if missing := next((m for m in members if not m.is_file()), None):
        raise UserError(f"{missing}: ensemble member listed in {checkpoint.parent / ENSEMBLE_FILE} not found")
    first = _config(checkpoint, config)
    if other := next((m for m in members if _config(m) != first), None):
        raise UserError(f"{other}: ensemble member has another model config than {checkpoint} (members must share it)")
    return [checkpoint, *members]
