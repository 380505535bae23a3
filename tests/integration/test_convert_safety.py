"""`convert` under the output rule: what sits at a trajectory's path is replaced only when it is this
command's complete conversion of that episode, `--skip-existing` trusts only those, and a full disk (a real tmpfs)
is one line per trajectory naming the cause, never a crash, with nothing half-written left."""
from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import h5py
import pytest

from tests.conftest import write_episode
from tests.integration.test_input_links import digest
from tests.integration.test_refused_inputs import refused
from touchanything.app.cli import main
from touchanything.app.sessions.bundled import SAMPLE_DIR
from touchanything.core.temporary_files import PARTIAL
from touchanything.devices.episodes.dataset_split import read_split
from touchanything.devices.episodes.hdf5_output import SOURCE_MARK, WRITTEN_MARK, written_from

REPO = Path(__file__).resolve().parents[2]


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
        split = disk / "out" / "split.json"  # the sample's, carried over: only what was written
        assert not split.exists() or all(p.is_file() for paths in read_split(split).values() for p in paths)
    finally:
        subprocess.run(["umount", str(disk)], check=True)


def rewrite_line(path: Path, number: int, change) -> None:
    """Replace line `number` (1-based) of a JSON-lines file with `change(text)`, in place."""
    lines = path.read_text().splitlines(keepends=True)
    lines[number - 1] = change(lines[number - 1].rstrip("\n")) + "\n"
    path.write_text("".join(lines))


def with_nan(text: str, *keys: str | int) -> str:
    """A JSON line with the number at `keys` replaced by NaN (written as Python's json writes it)."""
    row = json.loads(text)
    place = row
    for key in keys[:-1]:
        place = place[key]
    place[keys[-1]] = float("nan")
    return json.dumps(row)


def test_a_damaged_trajectory_is_converted_faithfully_counted_and_named(raw, tmp_path, capsys):
    copy = tmp_path / "raw"
    shutil.copytree(raw, copy)
    chest = copy / EPISODES[0] / "chest.mp4"
    chest.write_bytes(chest.read_bytes()[: chest.stat().st_size * 4 // 5])  # a video cut short
    poses = copy / EPISODES[1]
    rewrite_line(poses / "wilor_hands.json", 5, lambda text: text[:40])  # malformed lines
    rewrite_line(poses / "wilor_hands.json", 9, lambda text: "garbage")
    rewrite_line(poses / "wilor_hands.json", 7, lambda text: with_nan(text, "left_pos", 0, 0))  # NaN poses
    rewrite_line(poses / "vive_poses.json", 3, lambda text: with_nan(text, "poses", "chest", "trans", 0))
    before = digest(copy)
    out = tmp_path / "out"
    assert main(["convert", str(copy), str(out)]) == 0  # what could be read, with validity flags: faithful
    printed = capsys.readouterr().out
    assert "converted 3 (2 damaged), skipped 0, failed 0; " in printed
    damaged = [line for line in printed.splitlines() if line.startswith("damaged: ")]
    first, second = out / f"{EPISODES[0]}.hdf5", out / f"{EPISODES[1]}.hdf5"
    assert len(damaged) == 2 and damaged[0].startswith(f"damaged: {first}: ") and damaged[1].startswith(f"damaged: {second}: ")
    kept, held, decode = re.fullmatch(r"(\d+) of 20 frames \(chest\.mp4: (\d+) frames(?:, (\d+) decode)?\)",
                                      damaged[0].removeprefix(f"damaged: {first}: ")).groups()
    assert 0 < int(kept) == int(decode or held) < 20
    assert re.fullmatch(
        re.escape(f"damaged: {second}: wilor_hands.json (3 problems): line 5: invalid JSON (") + r"[^)]+" + re.escape(
            "); frame left empty / line 9: invalid JSON (Expecting value); frame left empty / left_pos: not 21 finite "
            "joints within the official bounds; hand marked invalid (line 7) | vive_poses.json: poses.chest: expected "
            "trans[3] and rot[4] finite numbers, rot of non-zero length; pose dropped (line 3)"), damaged[1]), damaged[1]
    assert (out / "conversion_report.txt").read_text().count("damaged: ") == 2
    with h5py.File(first) as file:
        assert file["metadata"].attrs["num_frames"] == int(kept) == file["images/chest_color"].shape[0]
    with h5py.File(second) as file:
        assert file["metadata"].attrs["num_frames"] == 20
        assert not file["hands/wilor_left_valid"][4] and not file["hands/wilor_right_valid"][4]  # line 5
        assert not file["hands/wilor_left_valid"][6] and file["hands/wilor_left_valid"][5]  # line 7's NaN
        assert not file["poses/chest_pose"][2].any()  # dropped: zeros, as the official reader marks it missing
    assert digest(copy) == before


@pytest.mark.parametrize("name", ["conversion_report.txt", "quality_report.txt"])
def test_a_report_of_the_users_is_replaced_only_with_overwrite(raw, tmp_path, capsys, name):
    out = tmp_path / "out"
    out.mkdir()
    mine = out / name
    mine.write_text("converted 3, skipped 0, failed 0; my own notes on this conversion\n")
    before = digest(out)
    refused(capsys, ["convert", str(raw), str(out)], f"{mine}: exists; pass --overwrite to replace it")
    assert digest(out) == before  # before any work: no trajectory either
    assert main(["convert", str(raw), str(out), "--overwrite"]) == 0
    assert "my own notes" not in mine.read_text()
    assert main(["convert", str(raw), str(out)]) == 0  # its own report now (it carries the tag): replaced without asking
    copy = out / "copy.txt"
    shutil.copyfile(mine, copy)  # a copy without the tag, put back at the report's name, is not the project's
    os.replace(copy, mine)
    capsys.readouterr()
    refused(capsys, ["convert", str(raw), str(out)], f"{mine}: exists; pass --overwrite to replace it")


def test_a_legal_250_byte_output_root_is_converted_into(raw, tmp_path, capsys):
    """`convert` writes no temporary copy of OUT itself: a 250-byte name (legal; only its temporary name would not
    be) is no reason to refuse it."""
    out = tmp_path / ("o" * 250)
    assert main(["convert", str(raw), str(out)]) == 0, capsys.readouterr().err
    assert [written_from(p) for p in trajectories(out)] == list(EPISODES)
    assert (out / "conversion_report.txt").is_file()


@pytest.mark.skipif(os.geteuid() != 0, reason="mounting a tmpfs needs root")
def test_split_json_lists_only_the_trajectories_a_full_disk_let_through(tmp_path):
    raw = tmp_path / "raw"
    write_episode(raw / EPISODES[0], frames=30, size=(240, 320))  # 20 MB uncompressed: more than the disk
    for seed, name in enumerate(EPISODES[1:], start=1):
        write_episode(raw / name, frames=10, size=(16, 16), seed=seed)
    listed = {"train": [f"{EPISODES[0]}.hdf5", f"{EPISODES[1]}.hdf5"], "val": [f"{EPISODES[2]}.hdf5"], "test_seen": [],
              "test_unseen": []}
    (raw / "split.json").write_text(json.dumps(listed))
    before = digest(raw)
    disk = tmpfs(tmp_path / "disk", "3m")
    out = disk / "out"
    try:
        run = subprocess.run([sys.executable, "-m", "touchanything.app.cli", "convert", str(raw), str(out),
                              "--compression-level", "0"], capture_output=True, text=True, timeout=600)
        assert run.returncode == 1, run.stderr[-2000:]
        printed = run.stdout.replace("\r", "\n")
        assert f"failed: {out / EPISODES[0]}.hdf5: not written (No space left on device)" in printed
        assert (f"{raw / 'split.json'}: 1 listed trajectory(ies) not in {out} (failed or not found), the first "
                f"{EPISODES[0]}.hdf5; {out / 'split.json'} lists the other 2") in printed
        assert read_split(out / "split.json") == {"train": [out / f"{EPISODES[1]}.hdf5"], "val": [out / f"{EPISODES[2]}.hdf5"],
                                                  "test_seen": [], "test_unseen": []}
        assert [written_from(p) for p in trajectories(out)] == list(EPISODES[1:])
        assert digest(raw) == before
    finally:
        subprocess.run(["umount", str(disk)], check=True)
