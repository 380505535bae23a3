"""Generate a simulated EgoTouch dataset: N episodes over the five scene categories, a `split.json` with
seen and unseen objects, and a dataset card (counts, contact statistics, contact visibility per camera, the
pose error and the share of contact the pose alone cannot decide).
"""
from __future__ import annotations

import contextlib
import json
import random
import signal
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from touchanything.core.errors import UserError, require_seed
from touchanything.core.snapshot import VIEW_NAMES
from touchanything.core.view_sets import VIEW_LABELS
from touchanything.devices.episodes.dataset_split import SPLIT_FILE, SPLIT_KEYS, partition_seen
from touchanything.devices.sim.catalogue import SCENES, UNSEEN_OBJECTS
from touchanything.devices.sim.episode_cache import restore, store
from touchanything.devices.sim.episode_generator import EpisodeSpec, generate_episode
from touchanything.devices.sim.episode_stats import CAMERAS, EpisodeStats
from touchanything.devices.sim.pose_ambiguity import pose_statistics

MAX_SECONDS = 3600.0
"""The longest episode (an hour: 108,000 frames of three views, tens of GB as raw video)."""
UNSEEN_SHARE = 0.2
CARD_JSON, CARD_MD = "dataset_card.json", "dataset_card.md"


@dataclass(frozen=True)
class SimulationConfig:
    episodes: int
    seconds: float = 10.0
    seed: int = 0
    workers: int = 1


def check_config(config: SimulationConfig) -> None:
    if config.episodes < 1:
        raise UserError(f"--episodes must be at least 1, got {config.episodes}")
    if not (np.isfinite(config.seconds) and 1.0 <= config.seconds <= MAX_SECONDS):
        raise UserError(f"--seconds must be 1–{MAX_SECONDS:g} (an episode of at most an hour), got {config.seconds}")
    require_seed("--seed", config.seed)
    if config.workers < 1:
        raise UserError(f"--workers must be at least 1, got {config.workers}")


def episode_specs(config: SimulationConfig) -> list[EpisodeSpec]:
    """Scenes in turn; about one episode in five uses an unseen object; every episode has its own seed."""
    scenes = list(SCENES)
    seeds = np.random.SeedSequence(config.seed).spawn(config.episodes)
    unseen = np.random.default_rng(config.seed).random(config.episodes) < UNSEEN_SHARE
    return [EpisodeSpec(scenes[i % len(scenes)], config.seconds, int(seeds[i].generate_state(1)[0]), bool(unseen[i]),
                        f"sim{config.seed:04d}_{i:05d}") for i in range(config.episodes)]


def _leave_signals_to_the_command() -> None:
    """A worker's initializer: Ctrl-C (sent to the whole foreground group) is the command's to handle, and SIGTERM
    ends the worker at once (a forked worker inherits the command's handlers, which would raise inside the episode)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


@contextlib.contextmanager
def _worker_pool(workers: int) -> Iterator[ProcessPoolExecutor]:
    """A pool that a stopped command stops at once: on an exception (Ctrl-C, SIGTERM, a failed episode) the
    episodes in progress are abandoned, their workers terminated — what Python 3.14's `terminate_workers` does —
    instead of waited for (an episode takes tens of seconds; the caller removes the half-written dataset)."""
    pool = ProcessPoolExecutor(max_workers=workers, initializer=_leave_signals_to_the_command)
    try:
        yield pool
    except BaseException:
        processes = list((pool._processes or {}).values())  # noqa: SLF001 - no public way before Python 3.14
        pool.shutdown(wait=False, cancel_futures=True)
        for process in processes:
            process.terminate()
        for process in processes:
            process.join()
        raise
    pool.shutdown(wait=True)


def _generate(args: tuple[Path, EpisodeSpec]) -> tuple[EpisodeStats, bool]:
    """The episode of `spec` written under `root`, from the user cache of episodes when an earlier run made it
    (`episode_cache`), else simulated and cached; and whether it came from the cache."""
    root, spec = args
    if (cached := restore(spec, root)) is not None:
        return cached, True
    stats = generate_episode(root, spec)
    store(spec, stats, root)
    return stats, False


def simulate_dataset(out: Path, config: SimulationConfig,
                     on_episode: Callable[[EpisodeStats], None] | None = None) -> dict:
    """Write the episodes, `split.json` and the dataset card under `out`; returns the card (`from_cache`: how many
    episodes an earlier run had made, copied from the user cache of episodes)."""
    check_config(config)
    started = time.perf_counter()
    specs = episode_specs(config)
    jobs = [(Path(out), spec) for spec in specs]
    results: list[EpisodeStats] = []
    cached = 0
    with contextlib.ExitStack() as stack:
        pool = stack.enter_context(_worker_pool(config.workers)) if config.workers > 1 else None
        for stats, from_cache in (pool.map(_generate, jobs) if pool else map(_generate, jobs)):
            results.append(stats)
            cached += from_cache
            on_episode and on_episode(stats)
    seconds = time.perf_counter() - started
    write_split(Path(out), results, config.seed)
    card = dataset_card(results, config, seconds, Path(out)) | {"from_cache": cached}
    (Path(out) / CARD_JSON).write_text(json.dumps(card, indent=1) + "\n")
    (Path(out) / CARD_MD).write_text(card_markdown(card))
    return card


def _hdf5_name(stats: EpisodeStats, out: Path) -> str:
    return (stats.folder.relative_to(out).parent / f"{stats.folder.name}.hdf5").as_posix()


def write_split(out: Path, results: list[EpisodeStats], seed: int) -> dict[str, list[str]]:
    """`split.json` naming the HDF5 files `touchanything convert` will write (relative paths; the converter
    copies this file into the HDF5 root): unseen-object episodes → test_unseen, the rest split officially."""
    seen = [_hdf5_name(s, out) for s in results if not any(o in UNSEEN_OBJECTS for o in s.objects)]
    split = partition_seen(seen, random.Random(seed))
    split["test_unseen"] = sorted(_hdf5_name(s, out) for s in results if any(o in UNSEEN_OBJECTS for o in s.objects))
    (out / SPLIT_FILE).write_text(json.dumps({k: split[k] for k in SPLIT_KEYS}, indent=1) + "\n")
    return split


def _merge(results: list[EpisodeStats], attr: str) -> dict[str, list[int]]:
    total: dict[str, list[int]] = {}
    for stats in results:
        for key, (hit, count) in getattr(stats, attr).items():
            entry = total.setdefault(key, [0, 0])
            entry[0] += hit
            entry[1] += count
    return total


def dataset_card(results: list[EpisodeStats], config: SimulationConfig, seconds: float, out: Path) -> dict:
    """The dataset card's record; episode paths relative to the dataset root `out` (no machine paths)."""
    frames = sum(s.frames for s in results)
    visible = _merge(results, "visible")
    per_camera = {}
    for camera in CAMERAS:
        hit = sum(v[0] for k, v in visible.items() if k.startswith(camera + "/"))
        count = sum(v[1] for k, v in visible.items() if k.startswith(camera + "/"))
        per_camera[camera] = {"visible": hit, "contact_points": count, "share": hit / count if count else None}
    for camera in ("left", "right"):
        own = visible.get(f"{camera}/{camera}", [0, 0])
        per_camera[camera]["own_hand_share"] = own[0] / own[1] if own[1] else None
    contact = {key: {"frames": n, "contact_share": hit / n if n else None} for key, (hit, n) in sorted(_merge(results, "contact").items())}
    return {
        "command": f"touchanything simulate OUT --episodes {config.episodes} --seconds {config.seconds:g} --seed {config.seed}",
        "episodes": len(results), "frames": frames, "seconds_per_episode": config.seconds,
        "generation_seconds": round(seconds, 1), "generation_fps": round(frames / seconds, 1) if seconds else None,
        "scenes": {scene: sum(s.scene == scene for s in results) for scene in SCENES},
        "unseen_objects": sorted(UNSEEN_OBJECTS),
        "episodes_with_unseen_objects": sum(any(o in UNSEEN_OBJECTS for o in s.objects) for s in results),
        "dead_column_episodes": sum(s.dead_column is not None for s in results),
        "contact_by_hand_and_task": contact,
        "contact_visibility": per_camera,
        **pose_statistics(results),
        "episodes_list": [{"path": s.folder.relative_to(out).as_posix(), "task": s.task, "objects": s.objects,
                           "dead_right_column": s.dead_column} for s in results],
    }


def percent(value: float | None) -> str:
    """A share as '12.3%', or 'n/a'."""
    return "n/a" if value is None else f"{100 * value:.1f}%"


def card_markdown(card: dict) -> str:
    lines = ["# Simulated EgoTouch dataset", "", f"Generated with `{card['command']}`: {card['episodes']} episodes, "
             f"{card['frames']} frames, {card['generation_fps']} frames/s.", "",
             "Scenes: " + ", ".join(f"{k} {v}" for k, v in card["scenes"].items()) + ".",
             f"Episodes with unseen objects ({', '.join(card['unseen_objects'])}): {card['episodes_with_unseen_objects']}; "
             f"with a dead right-glove column (repaired in the ground truth): {card['dead_column_episodes']}.", "",
             "## Contact share (a tactile cell above 0.1) per hand and task", "", "| hand/task | frames | contact |", "|---|---|---|"]
    lines += [f"| {k} | {v['frames']} | {percent(v['contact_share'])} |" for k, v in card["contact_by_hand_and_task"].items()]
    lines += ["", "## Contact visibility per camera", "",
              "Of the tactile points in contact, the share each camera sees (inside the image, line of sight not "
              "blocked by a hand, the table or another object).", "",
              "| camera | contact points | visible | own hand only |", "|---|---|---|---|"]
    labels = dict(zip(CAMERAS, (VIEW_LABELS[view] for view in VIEW_NAMES)))  # the JSON keeps the files' camera names
    for camera, v in card["contact_visibility"].items():
        lines.append(f"| {labels[camera]} | {v['contact_points']} | {percent(v['share'])} | {percent(v.get('own_hand_share'))} |")
    return "\n".join(lines + _pose_markdown(card)) + "\n"


def _pose_markdown(card: dict) -> list[str]:
    error, ambiguity = card["pose_error_mm"], card["pose_ambiguity"]
    if error is None:
        return []
    lines = ["", "## Pose error and pose ambiguity", "",
             f"RMS joint error of the WiLoR pose (head-camera frame, mm): median {error['median']}, 90th percentile "
             f"{error['p90']}; hands at most a quarter hidden from the head camera {error['visible_hand_median']}, more "
             f"hidden {error['occluded_hand_median']}.", "",
             f"Pose-ambiguous contact: {percent(ambiguity['ambiguous_share'])} of {ambiguity['contact_frames']} sampled contact "
             f"hand-frames have a no-contact hand-frame whose true pose is within the median pose error "
             f"({ambiguity['tolerance_mm']} mm RMS over the joints; docs/simulator.md).", "",
             "| hand/task | contact frames (sampled) | pose-ambiguous |", "|---|---|---|"]
    lines += [f"| {k} | {v['contact_frames']} | {percent(v['ambiguous_share'])} |" for k, v in ambiguity["by_hand_and_task"].items()]
    return lines
