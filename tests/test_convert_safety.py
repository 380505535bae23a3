"""`convert` under the output rule (issue 31): what sits at a trajectory's path is replaced only when it is this
command's complete conversion of that episode, `--skip-existing` trusts only those, and a full disk (a real tmpfs)
is one line per trajectory naming the cause, never a crash, with nothing half-written left."""
from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
from pathlib import Path

import h5py
import pytest

from tests.conftest import write_episode
from touchanything.app.cli import main
from touchanything.app.sessions.bundled import SAMPLE_DIR
from touchanything.devices.episodes.hdf5_output import SOURCE_MARK, WRITTEN_MARK, written_from
from touchanything.devices.temporary_files import PARTIAL

REPO = Path(__file__).resolve().parents[1]


EPISODES = ("Home/press/001", "Home/press/002", "Office/slide/003")


@pytest.fixture(scope="module")
def raw(tmp_path_factory) -> Path:
    """Three short raw episodes (small frames: the tests convert them many times)."""
    root = tmp_path_factory.mktemp("raw")
    for seed, name in enumerate(EPISODES):
        write_episode(root / name, frames=20, size=(32, 32), seed=seed)
    return root


@pytest.fixture(scope="module")
def converted(raw, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("h5") / "out"
    assert main(["convert", str(raw), str(out)]) == 0
    return out


def trajectories(root: Path) -> list[Path]:
    return sorted(p for p in root.rglob("*.hdf5"))


def test_every_converted_trajectory_carries_the_mark_of_its_episode(converted):
    assert [written_from(p) for p in trajectories(converted)] == list(EPISODES)
    for path, name in zip(trajectories(converted), EPISODES):
        with h5py.File(path, "r") as file:
            assert file.attrs[WRITTEN_MARK] == "touchanything convert" and file.attrs[SOURCE_MARK] == name


def copy_of(converted: Path, tmp_path: Path) -> Path:
    out = tmp_path / "out"
    shutil.copytree(converted, out)
    return out


def test_a_file_that_is_not_this_episodes_conversion_is_never_replaced_without_overwrite(raw, converted, tmp_path, capsys):
    out = copy_of(converted, tmp_path)
    first, second = trajectories(out)[:2]
    first.write_text("my notes, named like a trajectory\n")
    shutil.copyfile(trajectories(converted)[2], second)  # another episode's trajectory
    before = {p: hashlib.sha256(p.read_bytes()).hexdigest() for p in (first, second)}
    assert main(["convert", str(raw), str(out)]) == 2
    err = capsys.readouterr().err
    assert f"{first}: exists and is not this project's conversion of that episode (and 1 more); pass --overwrite" in err
    assert {p: hashlib.sha256(p.read_bytes()).hexdigest() for p in (first, second)} == before
    assert main(["convert", str(raw), str(out), "--overwrite"]) == 0
    assert [written_from(p) for p in trajectories(out)] == list(EPISODES)


def test_its_own_conversions_are_replaced_and_skip_existing_trusts_only_complete_ones(raw, converted, tmp_path, capsys):
    out = copy_of(converted, tmp_path)
    assert main(["convert", str(raw), str(out)]) == 0  # replaced, no question
    truncated = trajectories(out)[1]
    os.truncate(truncated, truncated.stat().st_size // 2)
    capsys.readouterr()
    assert main(["convert", str(raw), str(out), "--skip-existing"]) == 2
    assert f"{truncated}: exists and is not this project's conversion" in capsys.readouterr().err
    assert main(["convert", str(raw), str(out), "--skip-existing", "--overwrite"]) == 0
    assert "converted 1, skipped 2, failed 0" in capsys.readouterr().out
    assert written_from(truncated) == EPISODES[1]


def tmpfs(path: Path, size: str) -> Path:
    path.mkdir()
    subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(path)], check=True, capture_output=True)
    return path


@pytest.mark.skipif(os.geteuid() != 0, reason="mounting a tmpfs needs root")
@pytest.mark.parametrize("size, workers", [("2m", "1"), ("2m", "2"), ("40m", "1")])
def test_a_full_disk_is_one_line_per_trajectory_and_never_a_crash(tmp_path, size, workers):
    disk = tmpfs(tmp_path / "disk", size)
    try:
        run = subprocess.run([sys.executable, "-m", "touchanything.app.cli", "convert", str(SAMPLE_DIR), str(disk / "out"),
                              "--workers", workers, "--compression-level", "0"], capture_output=True, text=True, timeout=600)
        assert run.returncode == 1, (run.returncode, run.stderr[-2000:])
        failed = [line for line in run.stdout.replace("\r", "\n").splitlines() if line.startswith("failed: ")]
        assert failed and all(line.endswith(": not written (No space left on device)") for line in failed), failed
        assert "Traceback" not in run.stderr and "BrokenProcessPool" not in run.stdout + run.stderr
        assert not list(disk.rglob(f"*{PARTIAL}*"))
        for path in trajectories(disk):  # what was converted before the disk filled is whole
            assert written_from(path) is not None
    finally:
        subprocess.run(["umount", str(disk)], check=True)
