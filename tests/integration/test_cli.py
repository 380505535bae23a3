"""The command line on real episode folders and HDF5 files."""
from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import write_episode
from touchanything.app.cli import main
from touchanything.devices.episodes.episode_loader import open_episode
from touchanything.devices.episodes.video_io import VideoReader


@pytest.fixture
def raw_root(tmp_path):
    for i, name in enumerate(("Home/a/1", "Home/b/2", "Office/c/3")):
        write_episode(tmp_path / "raw" / name, frames=20, size=(16, 16), seed=i)
    return tmp_path / "raw"


def test_info_on_an_episode(episode_dir, capsys):
    assert main(["info", str(episode_dir)]) == 0
    out = capsys.readouterr().out
    assert "Home/pick_up_bottle/20260319_211038_740" in out and "40 at 30 fps" in out
    assert "views     all: head camera 64×48 (40 frames); left wrist camera 64×48" in out and "wilor: left valid 100%" in out
    assert "contact" in out and "problems  none" in out


def break_lines(path: Path, numbers: list[int]) -> None:
    """Cut the given 1-based lines of a JSON-lines file short, so they no longer parse."""
    lines = path.read_text().splitlines()
    for number in numbers:
        lines[number - 1] = lines[number - 1][:10]
    path.write_text("\n".join(lines) + "\n")


def test_info_on_a_dataset_root_lists_each_trajectory_s_problems(tmp_path, capsys):
    one = write_episode(tmp_path / "Home" / "a" / "1", frames=8, size=(16, 16))
    many = write_episode(tmp_path / "Home" / "b" / "2", frames=8, size=(16, 16), seed=1)
    break_lines(one / "wilor_hands.json", [3])
    break_lines(many / "wilor_hands.json", [2, 3, 4, 5, 6])
    assert main(["info", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "problems 1\n      - Home/a/1/wilor_hands.json: line 3: invalid JSON" in out
    assert out.count("Home/b/2/wilor_hands.json: line") == 3 and "      … and 2 more" in out


@pytest.mark.multiprocess
def test_convert_info_and_split_on_a_dataset(raw_root, tmp_path, capsys):
    out_root = tmp_path / "h5"
    assert main(["convert", str(raw_root), str(out_root), "--workers", "2", "--compression-level", "1"]) == 0
    printed = capsys.readouterr().out
    assert "converted 3, skipped 0, failed 0" in printed and "frames/s" in printed
    assert main(["convert", str(raw_root), str(out_root), "--skip-existing"]) == 0
    assert "converted 0, skipped 3" in capsys.readouterr().out
    assert main(["split", str(out_root), "--min-frames", "10", "--unseen-ratio", "0.5", "--allow-empty"]) == 0
    assert "test_unseen 1" in capsys.readouterr().out
    assert main(["info", str(out_root)]) == 0
    out = capsys.readouterr().out
    assert "0 raw episode(s), 3 HDF5 file(s)" in out and "split     train" in out
    assert main(["info", str(out_root / "Home" / "a" / "1.hdf5")]) == 0
    assert "Home/a/1" in capsys.readouterr().out


def test_split_keeps_the_simulator_s_split_copied_by_convert(sim_hdf5_root, tmp_path, capsys):
    split = sim_hdf5_root / "split.json"
    before = split.read_text()
    assert main(["split", str(sim_hdf5_root), "--min-frames", "10"]) == 0
    out = capsys.readouterr().out
    assert f"{split}: a split is already there (train " in out and "kept (--overwrite" in out and "test_unseen" in out
    assert split.read_text() == before
    other = tmp_path / "other.json"
    assert main(["split", str(sim_hdf5_root), "--min-frames", "10", "--out", str(other)]) == 0
    assert main(["split", str(sim_hdf5_root), "--min-frames", "10", "--out", str(other), "--overwrite"]) == 0
    assert other.read_text() != before and split.read_text() == before


def test_info_on_a_raw_root_counts_split_files_to_convert_apart_from_missing_ones(raw_root, tmp_path, capsys):
    """A simulated root's split.json names the .hdf5 files `convert` will write beside the raw folders."""
    listed = {"train": ["Home/a/1.hdf5", "Home/b/2.hdf5"], "val": [], "test_seen": ["Office/c/3.hdf5"],
              "test_unseen": ["Office/gone/9.hdf5"]}
    (raw_root / "split.json").write_text(json.dumps(listed))
    assert main(["info", str(raw_root)]) == 0
    out = capsys.readouterr().out
    assert "train 2, val 0, test_seen 1, test_unseen 1; 3 listed HDF5 file(s) to be written by `touchanything " \
           "convert`; 1 listed file(s) missing" in out
    (raw_root / "split.json").write_text(json.dumps(listed | {"test_unseen": []}))
    assert main(["info", str(raw_root)]) == 0
    assert "missing" not in capsys.readouterr().out
    out_root = tmp_path / "h5"
    assert main(["convert", str(raw_root), str(out_root), "--compression-level", "1"]) == 0
    capsys.readouterr()
    assert main(["info", str(out_root)]) == 0
    out = capsys.readouterr().out
    assert "split     train 2, val 0, test_seen 1, test_unseen 0\n" in out


def test_convert_labels_wall_and_work_time_and_unmeasured_quality(raw_root, tmp_path, capsys):
    (raw_root / "Home" / "a" / "1" / "quality_issues.json").unlink()
    out_root = tmp_path / "h5"
    assert main(["convert", str(raw_root), str(out_root), "--compression-level", "1"]) == 0
    captured = capsys.readouterr()
    printed = captured.out.splitlines()
    assert captured.err.replace("\r", "\n").count("100%") == 1  # the final progress line once in a log
    assert "failed=0" in captured.err and "failed=None" not in captured.err
    report = (out_root / "conversion_report.txt").read_text().splitlines()
    assert printed[0] == report[0]
    assert re.fullmatch(r"converted 3, skipped 0, failed 0; 60 frames in [\d.]+ s wall time \([\d.]+ frames/s\), "
                        r"[\d.]+ s of work summed over trajectories \([\d.]+ frames/s per worker\)", report[0])
    quality = (out_root / "quality_report.txt").read_text()
    assert "-1.00" not in quality
    assert "1.hdf5: wilor valid 100.0%, duplicate wrist frames not measured (no quality_issues.json)" in quality
    assert "2.hdf5: wilor valid 100.0%, duplicate wrist frames left 1.0%, right 30.0%" in quality


def test_convert_failure_exit_status(raw_root, tmp_path, capsys):
    (raw_root / "Home" / "a" / "1" / "chest.mp4").unlink()
    assert main(["convert", str(raw_root), str(tmp_path / "h5")]) == 1
    captured = capsys.readouterr()
    assert "failed 1" in captured.out


def test_grids_command_with_the_official_layout_and_a_repaired_column(episode_dir, official_dir, capsys):
    before = open_episode(episode_dir).pressure.grids
    assert main(["grids", str(episode_dir), "--layout", str(official_dir), "--repair-column", "right:14"]) == 0
    assert "baseline corrected left True" in capsys.readouterr().out
    after = open_episode(episode_dir).pressure.grids
    assert after.shape == before.shape and not np.array_equal(after, before, equal_nan=True)


@pytest.mark.parametrize("argv, message", [
    (["grids", "EP", "--repair-column", "middle:3"], "HAND:COLUMN"),
    (["grids", "EP", "--min-scale", "0"], "--min-scale must be a finite number > 0"),
    (["convert", "RAW", "OUT", "--workers", "0"], "--workers must be at least 1"),
    (["split", "NOWHERE"], "no .hdf5 trajectories"),
    (["demo", "NOWHERE"], "not found"),
])
def test_bad_options_give_one_clear_line(episode_dir, tmp_path, capsys, argv, message):
    argv = [str(episode_dir) if a == "EP" else str(tmp_path / a) if a in ("RAW", "OUT", "NOWHERE") else a for a in argv]
    if "RAW" in " ".join(argv) or argv[0] == "convert":
        write_episode(tmp_path / "RAW" / "S" / "t" / "1", frames=3, size=(16, 16))
    try:
        code = main(argv)
    except SystemExit as exit:  # argparse rejects option syntax itself
        code = exit.code
    err = capsys.readouterr().err
    assert code == 2 and message in err and "Traceback" not in err


def test_demo_replays_an_episode_into_a_video(episode_dir, tmp_path, capsys):
    assert main(["demo", str(episode_dir), "--headless", "--out", str(tmp_path / "demo.mp4")]) == 0
    out = capsys.readouterr().out
    assert "frames    40 written, 40 with a prediction" in out and "engine    " in out
    with VideoReader(tmp_path / "demo.mp4") as video:
        assert video.num_frames == 40


def test_demo_without_a_display_falls_back_to_the_video(tmp_path, capsys, monkeypatch):
    """No X display: the bundled sample's three episodes through the bundled model into one video, in the tour's
    order (where the model is right first), a summary per episode and overall; saying why and where."""
    import av

    from touchanything.app.sessions.bundled import sample_episodes

    monkeypatch.delenv("DISPLAY", raising=False)
    assert len(sample_episodes()) == 3
    assert main(["demo", "--out", str(tmp_path / "demo.mp4")]) == 0
    out = capsys.readouterr().out
    assert "no dashboard: no X display: DISPLAY is not set" in out and f"video     {tmp_path / 'demo.mp4'}" in out
    headers = re.findall(r"--- episode (\d) of 3: (\w+)/", out)
    assert headers == [("1", "Workbench"), ("2", "Office"), ("3", "Home")] * 2  # before the replay, and with the summaries
    assert out.count("frames    300 written, 300 with a prediction") == 3 and out.count("problems  none") == 3
    per_episode = [float(v) for v in re.findall(r"^metrics   (?!mean over).*?volumetric_iou (\d\.\d+)", out, re.M)]
    overall = re.search(r"--- all episodes\noverall   3 episodes, 900 frames\nmetrics   mean over the 3 episodes .*?"
                        r"volumetric_iou (\d\.\d+)", out)
    assert len(per_episode) == 3 and overall is not None  # the official overall: the mean over trajectories
    assert abs(float(overall[1]) - sum(per_episode) / 3) <= 0.0015  # each printed to 3 places
    with av.open(str(tmp_path / "demo.mp4")) as video:
        assert sum(1 for _ in video.demux(video.streams.video[0]) if _.size) == 900


def test_info_of_a_dataset_names_the_pose_source_per_hand(tmp_path, capsys):
    write_episode(tmp_path / "raw" / "Home" / "a" / "001", frames=14, seed=1)  # conftest: right hand gone every 7th frame
    assert main(["info", str(tmp_path / "raw")]) == 0
    assert "wilor poses left 100%, right 86%, contact" in capsys.readouterr().out  # 12 of 14 frames
