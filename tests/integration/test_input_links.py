"""Inputs reached through links inside a dataset root are inputs: real symbolic links and hard links,
real commands; each case ends with the inputs byte-identical and one line, exit status 2."""
from __future__ import annotations

import hashlib
import os
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest

from touchanything.app.cli import main
from touchanything.app.sessions.bundled import sample_episodes
from touchanything.core.errors import UserError
from touchanything.core.input_paths import collect_inputs
from touchanything.core.output_safety import check_output


def digest(path: Path) -> dict[str, str]:
    files = [path] if path.is_file() else sorted(p for p in path.rglob("*") if p.is_file())
    return {str(f): hashlib.sha256(f.read_bytes()).hexdigest() for f in files}


def run(argv: list[str], capsys) -> tuple[int, str]:
    code = main(argv)
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) <= 1 and "Traceback" not in err, err
    return code, err


@pytest.fixture
def linked_episode(tmp_path) -> tuple[Path, Path, Path]:
    """ROOT/Home/task/001 → PAR/ep (a copy of a sample episode elsewhere)."""
    episode = tmp_path / "par" / "ep"
    shutil.copytree(sample_episodes()[0], episode)
    root = tmp_path / "root"
    (root / "Home" / "task").mkdir(parents=True)
    (root / "Home" / "task" / "001").symlink_to(episode)
    return root, tmp_path / "par", episode


def test_export_onto_the_folder_holding_a_linked_episode_is_refused(linked_episode, capsys):
    root, par, episode = linked_episode
    before = digest(episode)
    code, err = run(["export-lerobot", str(root), str(par), "--overwrite"], capsys)
    assert code == 2 and f"{par}: holds the input {episode} (reached through {root}/Home/task/001)" in err
    assert digest(episode) == before


def test_export_inside_a_linked_episode_is_refused(linked_episode, capsys):
    """OUT = PAR/ep/lr, inside the episode ROOT/Home/task/001 links to (a folder not yet there, so the
    output rule's "holds an input" does not see it): one line naming OUT, the episode and the link; nothing written."""
    root, par, episode = linked_episode
    before, listed = digest(par), sorted(par.rglob("*"))
    code, err = run(["export-lerobot", str(root), str(episode / "lr")], capsys)
    assert code == 2 and (f"{episode / 'lr'}: the output would lie inside the input {episode} (reached through "
                          f"{root}/Home/task/001)") in err
    assert digest(par) == before and sorted(par.rglob("*")) == listed  # nor a temporary file or folder


def trajectory(path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    with h5py.File(path, "w") as file:
        file.create_dataset("data", data=np.arange(1000))
    return path


def test_split_onto_a_linked_trajectory_is_refused(tmp_path, capsys):
    target = trajectory(tmp_path / "par3" / "traj.hdf5")
    root = tmp_path / "root"
    (root / "Home" / "task").mkdir(parents=True)
    (root / "Home" / "task" / "001.hdf5").symlink_to(target)
    before = digest(target)
    code, err = run(["split", str(root), "--out", str(target), "--overwrite", "--allow-empty"], capsys)
    assert code == 2 and f"is an input of this command ({target} (reached through {root}/Home/task/001.hdf5))" in err
    assert digest(target) == before


def test_an_output_that_is_a_hard_link_of_an_input_file_is_refused(tmp_path, capsys):
    source = trajectory(tmp_path / "root" / "Home" / "task" / "001.hdf5")
    alias = tmp_path / "elsewhere" / "split.json"
    alias.parent.mkdir()
    os.link(source, alias)
    before = digest(source)
    code, err = run(["split", str(tmp_path / "root"), "--out", str(alias), "--overwrite", "--allow-empty"], capsys)
    assert code == 2 and f"is the input {tmp_path / 'root'} under another name (a hard link)" in err
    assert digest(source) == before


def test_links_inside_linked_folders_are_followed_and_loops_end(tmp_path):
    deep = trajectory(tmp_path / "far" / "deep.hdf5")
    middle = tmp_path / "middle"
    middle.mkdir()
    (middle / "deep.hdf5").symlink_to(deep)
    (middle / "back").symlink_to(middle)  # a loop
    root = tmp_path / "root"
    root.mkdir()
    (root / "m").symlink_to(middle)
    found = {entry.resolved for entry in collect_inputs([root]).paths}
    assert {root, middle, deep} <= found
    with pytest.raises(UserError, match="is an input of this command"):
        check_output(deep, [root], overwrite=True)
    with pytest.raises(UserError, match="holds the input"):
        check_output(tmp_path / "far", [root], overwrite=True, whole=True)
    check_output(tmp_path / "elsewhere.json", [root])  # an unrelated output passes
