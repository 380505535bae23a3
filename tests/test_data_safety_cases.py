"""The smaller cases of issue 31, each with its real command: seeds and durations, an output inside an input
episode, unreadable videos named, replays that predicted nothing or met damage, a LeRobot count that is wrong,
and a recording on a full disk (a real tmpfs)."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import h5py
import pytest

from tests.conftest import write_episode
from tests.test_input_links import digest
from tests.test_refused_inputs import refused
from touchanything.app.cli import main
from touchanything.devices.episodes.hdf5_convert import convert_trajectory
from touchanything.devices.episodes.hdf5_episode import IMAGE_KEYS, WILOR_VALID_KEYS

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def small(tmp_path_factory) -> tuple[Path, Path]:
    """A short raw episode and its HDF5 trajectory."""
    root = tmp_path_factory.mktemp("small")
    raw = write_episode(root / "raw" / "Home" / "press" / "001", frames=40, size=(32, 32))
    h5 = root / "h5" / "Home" / "press" / "001.hdf5"
    assert convert_trajectory(raw, h5, 1).status == "converted"
    return raw, h5


def test_seeds_and_durations_are_refused_alike(tmp_path, capsys, small):
    refused(capsys, ["split", str(small[1].parents[2]), "--seed", "-1", "--out", str(tmp_path / "s.json")],
            "--seed must be an integer 0–4294967295, got -1")
    refused(capsys, ["simulate", str(tmp_path / "sim"), "--episodes", "1", "--seconds", "1e9"],
            "--seconds must be 1–3600", "got 1000000000.0")
    assert not (tmp_path / "sim").exists() and not (tmp_path / "s.json").exists()


def test_convert_into_an_input_episode_is_refused(tmp_path, capsys, small):
    raw = tmp_path / "raw"
    shutil.copytree(small[0].parents[2], raw)
    episode = raw / "Home" / "press" / "001"
    before = digest(raw)
    refused(capsys, ["convert", str(raw), str(episode / "conv2")], "the output would lie inside the input",
            str(episode))
    assert digest(raw) == before and not (episode / "conv2").exists()


def test_convert_names_the_video_that_does_not_read(tmp_path, capsys, small):
    raw = tmp_path / "raw"
    shutil.copytree(small[0].parents[2], raw)
    (raw / "Home" / "press" / "001" / "left.mp4").write_bytes(b"not a video at all" * 100)
    assert main(["convert", str(raw), str(tmp_path / "h5")]) == 1
    assert "cannot convert: unreadable left.mp4" in capsys.readouterr().out


def h5_copy(small, tmp_path: Path) -> Path:
    path = tmp_path / "Home" / "press" / "001.hdf5"
    path.parent.mkdir(parents=True)
    shutil.copyfile(small[1], path)
    return path


def test_a_replay_that_predicted_nothing_claims_no_metrics(tmp_path, capsys, small):
    path = h5_copy(small, tmp_path)
    with h5py.File(path, "a") as file:
        for key in WILOR_VALID_KEYS:
            file[key][...] = 0
    assert main(["replay", str(path), "--out", str(tmp_path / "r.mp4")]) == 0
    out = capsys.readouterr().out
    assert "metrics   n/a (no frame had a hand pose to predict from)" in out and "lamps agree" not in out


def test_a_replay_names_the_damage_it_met_while_reading(tmp_path, capsys, small):
    path = h5_copy(small, tmp_path)
    with h5py.File(path, "r") as file:
        chunk = file[IMAGE_KEYS["ego"]].id.get_chunk_info(20)
    with open(path, "r+b") as handle:
        handle.seek(chunk.byte_offset + 2)
        handle.write(b"\xff" * max(chunk.size - 4, 1))
    assert main(["replay", str(path), "--out", str(tmp_path / "r.mp4")]) == 0
    out = capsys.readouterr().out
    assert "problems  none" in out  # before the frames were read
    assert "problems  1 more found while replaying" in out and "images/chest_color" in out


def test_info_names_a_lerobot_count_that_is_wrong(tmp_path, capsys, small):
    out = tmp_path / "lerobot"
    assert main(["export-lerobot", str(small[0]), str(out)]) == 0
    info = out / "meta" / "info.json"
    data = json.loads(info.read_text())
    info.write_text(json.dumps({**data, "total_frames": -5, "total_episodes": 3}))
    capsys.readouterr()
    assert main(["info", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "meta/info.json: total_frames: -5 is not a count (a whole number ≥ 0)" in printed
    assert "meta/info.json: total_episodes: says 3; the dataset holds 1" in printed


@pytest.mark.skipif(os.geteuid() != 0, reason="mounting a tmpfs needs root")
def test_a_recording_on_a_full_disk_says_how_many_frames_replay(tmp_path):
    disk = tmp_path / "disk"
    disk.mkdir()
    subprocess.run(["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", str(disk)], check=True)
    try:
        run = subprocess.run([sys.executable, "-m", "touchanything.app.cli", "record", "--scene", str(REPO / "scenes" / "sim.toml"),
                              "--out", str(disk / "ep"), "--seconds", "4"], capture_output=True, text=True, timeout=300)
        err = run.stderr.strip().splitlines()
        assert run.returncode == 2 and len(err) == 1 and "No space left on device" in err[0], run.stderr[-2000:]
        assert "can be replayed (no frame of the head camera's video decodes)" in err[0] or " frames written before replay" in err[0]
    finally:
        subprocess.run(["umount", str(disk)], check=True)


def test_record_into_the_episode_the_simulated_rig_replays_is_refused(capsys):
    episode = REPO / "recordings" / "sample" / "Home" / "slide_box_cardboard" / "sim0007_00000"
    refused(capsys, ["record", "--scene", str(REPO / "scenes" / "sim.toml"), "--out", str(episode / "rec"), "--seconds", "1"],
            "the output would lie inside the input", "sim0007_00000")
    assert not (episode / "rec").exists()
