"""The user cache of simulated episodes, `~/.cache/touchanything/simulated/<simulator digest>/<episode key>/`: a
`simulate` that is stopped (a session that ends kills it) loses nothing it finished — run again, it copies
those episodes from the cache and simulates only the rest.

An episode is a pure function of its `EpisodeSpec` (scene, length, seed, unseen object, trajectory id; episode i of a
seed is the same whatever the number of episodes) and of the code that makes and writes it, so the key is the
spec and the digest is the SHA-256 of the sources of the devices layer and of `core` below it: a
change there never serves an episode that code would now make differently. Each entry holds the episode's
folder (its files copied with their metadata) and its statistics (`stats.pkl`), written under a marked temporary
name (`core.temporary_files`) and renamed, so a killed writer leaves no entry that looks complete, and what it left
is removed by the next store into that folder.
"""
from __future__ import annotations

import dataclasses
import functools
import hashlib
import os
import pickle
import shutil
from pathlib import Path

from touchanything.core.temporary_files import mark, remove_left_behind, unmark
from touchanything.devices.sim.episode_generator import EpisodeSpec
from touchanything.devices.sim.episode_stats import EpisodeStats

STATS_FILE, EPISODE_DIR = "stats.pkl", "episode"


@functools.cache
def simulator_digest() -> str:
    """SHA-256 of the code an episode comes from: every source and layout file of the devices layer (the simulator,
    and the episode writers and tactile pipeline it writes through) and of the shared records below it (snapshot,
    tactile layout, output rule), by relative path and content."""
    digest = hashlib.sha256()
    package = Path(__file__).resolve().parents[2]
    for layer in (package / "core", package / "devices"):
        for path in sorted(p for p in layer.rglob("*") if p.suffix in (".py", ".json") and "__pycache__" not in p.parts):
            digest.update(path.relative_to(package).as_posix().encode() + b"\0" + path.read_bytes() + b"\0")
    return digest.hexdigest()


def entry_for(spec: EpisodeSpec) -> Path:
    """The cache folder of the episode `spec` describes (it may not exist)."""
    root = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "touchanything" / "simulated"
    key = hashlib.sha256(repr(dataclasses.astuple(spec)).encode()).hexdigest()[:16]
    return root / simulator_digest()[:16] / f"{spec.trajectory_id}-{key}"


def restore(spec: EpisodeSpec, root: Path) -> EpisodeStats | None:
    """The cached episode of `spec` copied under `root` (its folder where the simulator would write it) and its
    statistics, or None when the cache has none."""
    entry = entry_for(spec)
    try:
        stats: EpisodeStats = pickle.loads((entry / STATS_FILE).read_bytes())
    except (OSError, pickle.UnpicklingError, EOFError, AttributeError):
        return None
    folder = Path(root) / stats.folder
    _copy_files(entry / EPISODE_DIR, folder)
    return dataclasses.replace(stats, folder=folder)


def _copy_files(source: Path, target: Path) -> None:
    """Copy the tree `source` to `target`, file by file with metadata; the first OSError (a full disk) is raised
    as it is."""
    for path in sorted(source.rglob("*")):
        if path.is_file():
            destination = target / path.relative_to(source)
            destination.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(path, destination)


def store(spec: EpisodeSpec, stats: EpisodeStats, root: Path) -> None:
    """Copy the episode just written under `root` into the cache with its statistics (folder kept relative to
    `root`); a cache that cannot be written is skipped (the episode is already where it belongs). What a writer killed
    mid-copy left in that folder is removed first (named on stderr)."""
    entry = entry_for(spec)
    partial = entry.with_name(f".{entry.name}.partial-{os.getpid()}")
    try:
        entry.parent.mkdir(parents=True, exist_ok=True)
        remove_left_behind(entry.parent)
        mark(partial, "folder")
    except OSError:
        return
    try:
        _copy_files(Path(stats.folder), partial / EPISODE_DIR)
        relative = dataclasses.replace(stats, folder=Path(stats.folder).relative_to(root))
        (partial / STATS_FILE).write_bytes(pickle.dumps(relative))
        partial.rename(entry)
    except OSError:
        shutil.rmtree(partial, ignore_errors=True)
    finally:
        unmark(partial)
