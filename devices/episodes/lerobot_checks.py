"""What a LeRobot dataset's metadata says wrongly, as one line per problem (`info` lists them): the counts of
`meta/info.json`, its `splits`, every feature's `names` (the forms Rerun's LeRobot importer accepts) and
`meta/stats.json` (the shapes LeRobot computes: (3, 1, 1) per video feature, the feature's last axis otherwise;
every value finite; min, max, mean, std and count always, the quantiles since LeRobot 0.4)."""
from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np

from touchanything.core.errors import describe
from touchanything.devices.episodes import lerobot_format as fmt
from touchanything.devices.episodes.lerobot_episode import read_info
from touchanything.devices.episodes.lerobot_stats import QUANTILE_KEYS

COUNT_KEYS = ("total_episodes", "total_frames", "total_tasks")
STAT_KEYS = ("min", "max", "mean", "std", "count", *QUANTILE_KEYS)
SPLIT_RANGE = re.compile(r"(\d+):(\d+)")


def _is_count(value: object) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and value >= 0


def count_problems(info: dict, path: Path, episodes: int, frames: int) -> list[str]:
    """A count that is not a whole number ≥ 0, or an episode or frame total other than the `episodes` found and
    the `frames` read."""
    problems = [describe(path, key, f"{info[key]!r} is not a count (a whole number ≥ 0)")
                for key in COUNT_KEYS if info.get(key) is not None and not _is_count(info[key])]
    for key, found in (("total_episodes", episodes), ("total_frames", frames)):
        if _is_count(info.get(key)) and info[key] != found:
            problems.append(describe(path, key, f"says {info[key]}; the dataset holds {found}"))
    return problems


def split_problems(info: dict, path: Path, episodes: int) -> list[str]:
    """`splits` not a map of names to episode ranges "first:end" within the `episodes` found."""
    splits = info.get("splits", {})
    if not isinstance(splits, dict):
        return [describe(path, "splits", "not a map of split names to episode ranges \"first:end\"")]
    problems = []
    for name, value in splits.items():
        match = SPLIT_RANGE.fullmatch(value) if isinstance(value, str) else None
        if match is None or not int(match[1]) <= int(match[2]) <= episodes:
            problems.append(describe(path, f"splits.{name}", f"{value!r} is not an episode range \"first:end\" within 0:{episodes}"))
    return problems


def names_problems(info: dict, path: Path) -> list[str]:
    """`names` other than None, a string, a list or a map with one entry (Rerun's importer rejects the whole
    dataset then), or a list of another length than a 1-D feature's values."""
    problems = []
    for key, feature in info["features"].items():
        names = feature.get("names") if isinstance(feature, dict) else None
        shape = feature.get("shape") if isinstance(feature, dict) else None
        if not (names is None or isinstance(names, (str, list)) or (isinstance(names, dict) and len(names) == 1)):
            problems.append(describe(path, f"{key} names", "not None, a list or a map with one entry"))
        elif isinstance(names, list) and isinstance(shape, list) and len(shape) == 1 and shape != [1] and len(names) != shape[0]:
            problems.append(describe(path, f"{key} names", f"{len(names)} names for {shape[0]} values"))
    return problems


def _expected_shape(feature: dict) -> tuple[int, ...] | None:
    shape = feature.get("shape")
    if feature.get("dtype") in ("video", "image"):
        return (3, 1, 1)
    return (int(shape[-1]),) if isinstance(shape, list) and shape and isinstance(shape[-1], int) else None


def stats_problems(root: Path, info: dict) -> list[str]:
    """`meta/stats.json` missing, unreadable, or a feature's statistics not as LeRobot computes them."""
    path = Path(root) / fmt.STATS_PATH
    try:
        stats = json.loads(path.read_text())
    except FileNotFoundError:
        return [describe(path, None, "missing (LeRobot's normalisation needs it)")]
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        return [describe(path, None, f"not a readable JSON file ({exc})")]
    if not isinstance(stats, dict):
        return [describe(path, None, "not a map of features to their statistics")]
    problems = []
    for key, feature in info["features"].items():
        values, shape = stats.get(key), _expected_shape(feature) if isinstance(feature, dict) else None
        if shape is None or feature.get("dtype") == "string":
            continue
        if not isinstance(values, dict) or not set(STAT_KEYS[:5]) <= set(values):
            problems.append(describe(path, key, f"missing, or without one of {', '.join(STAT_KEYS[:5])}"))
            continue
        for stat, value in ((stat, values[stat]) for stat in STAT_KEYS if stat in values):
            try:
                array = np.asarray(value, np.float64)
            except (TypeError, ValueError):
                array = np.full(1, math.nan)
            wanted = (1,) if stat == "count" else shape
            if array.shape != wanted or not np.isfinite(array).all():
                problems.append(describe(path, f"{key}.{stat}", f"not {wanted} finite numbers"))
    return problems


def metadata_problems(root: Path, episodes: int, frames: int) -> list[str]:
    """Every problem of the metadata of the dataset at `root` whose episodes were found (`episodes`) and read
    (`frames` in all)."""
    info, path = read_info(root), Path(root) / fmt.INFO_PATH
    return (count_problems(info, path, episodes, frames) + split_problems(info, path, episodes)
            + names_problems(info, path) + stats_problems(root, info))
