"""The user cache of simulated episodes: a stopped `simulate` loses nothing it finished. Run again (or asked for
more episodes of the same seed), it copies the episodes an earlier run made, byte for byte, and simulates the rest;
the dataset equals one simulated without the cache."""
from __future__ import annotations

import hashlib
import json
import subprocess
import sys
from pathlib import Path

from touchanything.app.cli import main
from touchanything.devices.sim.dataset_generator import SimulationConfig, episode_specs
from touchanything.devices.sim.episode_cache import entry_for


def digests(root: Path) -> dict[str, str]:
    """sha256 of every episode file (the dataset card holds the generation time: left out)."""
    return {p.relative_to(root).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file() and not p.name.startswith("dataset_card")}


def simulate(out: Path, episodes: int, capsys) -> str:
    assert main(["simulate", str(out), "--episodes", str(episodes), "--seconds", "1", "--seed", "21"]) == 0
    return capsys.readouterr().out


def test_a_second_run_copies_what_the_first_made_and_simulates_only_the_rest(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    first = simulate(tmp_path / "a", 2, capsys)
    assert "copied from the cache" not in first
    specs = episode_specs(SimulationConfig(episodes=3, seconds=1.0, seed=21))
    assert [entry_for(s).is_dir() for s in specs] == [True, True, False]
    again = simulate(tmp_path / "b", 3, capsys)  # episode i of a seed is the same whatever the number of episodes
    assert "3 episodes, 90 frames" in again and "(2 copied from the cache of earlier runs)" in again
    assert json.loads((tmp_path / "b" / "dataset_card.json").read_text())["from_cache"] == 2
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "empty"))
    fresh = simulate(tmp_path / "c", 3, capsys)
    assert "copied" not in fresh
    assert digests(tmp_path / "b") == digests(tmp_path / "c")  # the split and every episode file
    a, b = digests(tmp_path / "a"), digests(tmp_path / "b")
    assert {k: v for k, v in b.items() if k in a and k != "split.json"} == {k: v for k, v in a.items() if k != "split.json"}


def test_a_broken_cache_entry_is_simulated_again(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    simulate(tmp_path / "a", 1, capsys)
    (spec,) = episode_specs(SimulationConfig(episodes=1, seconds=1.0, seed=21))
    (entry_for(spec) / "stats.pkl").write_bytes(b"not a pickle")
    assert "copied" not in simulate(tmp_path / "b", 1, capsys)
    assert digests(tmp_path / "a") == digests(tmp_path / "b")


def test_what_a_killed_store_left_in_the_cache_is_removed(tmp_path, monkeypatch, capsys):
    """A worker killed while copying an episode into the cache leaves its marked temporary folder; the next store
    into that folder removes it, and says so. A look-alike without the project's marker stays."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    specs = episode_specs(SimulationConfig(episodes=2, seconds=1.0, seed=21))
    folder = entry_for(specs[0]).parent
    folder.mkdir(parents=True)
    left = folder / f".{entry_for(specs[0]).name}.partial-1"
    code = ("import sys; from pathlib import Path; from touchanything.core.temporary_files import mark; "
            "p = Path(sys.argv[1]); mark(p, 'folder'); (p / 'episode').mkdir(parents=True)")
    subprocess.run([sys.executable, "-c", code, str(left)], check=True)  # its process has ended: a killed writer's
    users = folder / ".notes.partial-1"
    users.mkdir()
    assert main(["simulate", str(tmp_path / "a"), "--episodes", "2", "--seconds", "1", "--seed", "21"]) == 0
    assert f"removed {left}: left half-written by an interrupted run" in capsys.readouterr().err
    assert not left.exists() and not Path(f"{left}.owner").exists() and users.is_dir()
    assert [entry_for(s).is_dir() for s in specs] == [True, True]
    assert sorted(p.name for p in folder.iterdir()) == sorted([".notes.partial-1", *(entry_for(s).name for s in specs)])
