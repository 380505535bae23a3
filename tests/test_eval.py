"""`touchanything eval`: the official protocol end to end on HDF5 trajectories."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from touchanything.app.cli import main
from touchanything.devices.episodes.dataset_split import read_split
from touchanything.devices.episodes.episode_loader import open_episode
from touchanything.devices.episodes.video_io import VideoReader
from touchanything.inference.evaluation.evaluation import SPAN, predict_trajectory
from touchanything.inference.evaluation.metrics import ALL_METRICS
from touchanything.inference.model.checkpoint import load_model


def nonempty_split(root) -> str:
    split = read_split(root / "split.json")
    return next(k for k in ("train", "test_seen", "val", "test_unseen") if split[k])


def test_eval_writes_the_table_per_view_and_scene(sim_hdf5_root, tiny_checkpoint, tmp_path, capsys):
    split = read_split(sim_hdf5_root / "split.json")
    name = nonempty_split(sim_hdf5_root)
    argv = ["eval", "--checkpoint", str(tiny_checkpoint), "--data", str(sim_hdf5_root), "--split", name,
            "--views", "ego", "all", "--batch-size", "32", "--out", str(tmp_path / "out"), "--video"]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert "| views | scene |" in printed and "causal newest-frame" in printed
    payload = json.loads((tmp_path / "out" / "results.json").read_text())
    assert [r["views"] for r in payload["results"]] == ["ego", "all"]
    counts = ("temporal_support", "num_gt_onsets", "num_gt_offsets")
    for result in payload["results"]:
        assert "overall" in result["stitched"] and len(result["trajectories"]) == len(split[name])
        assert tuple(result["causal"]["overall"]) == ALL_METRICS
        for row in result["trajectories"]:
            for mode in ("stitched", "causal"):
                assert tuple(row[mode]) == ALL_METRICS
                for key in ALL_METRICS:
                    value = row[mode][key]
                    assert value >= 0 if key in counts else (math.isnan(value) or 0.0 <= value <= 1.0)
    table = (tmp_path / "out" / "results.md").read_text()
    assert table.startswith("# Evaluation on") and table.count("| temporal_f1 |") == 2 and "| offset_recall |" in table
    videos = sorted((tmp_path / "out").glob("*.mp4"))
    assert len(videos) == 2 * len(split[name])
    with VideoReader(videos[0]) as reader:
        assert (reader.width, reader.height, reader.num_frames) == (1440, 656, 60)
        assert reader.read(30).std() > 10


def test_stitching_covers_every_frame_and_causal_starts_at_frame_14(sim_hdf5_root, tiny_checkpoint):
    model = load_model(tiny_checkpoint)
    path = read_split(sim_hdf5_root / "split.json")[nonempty_split(sim_hdf5_root)][0]
    with open_episode(path) as episode:
        prediction = predict_trajectory(model, episode, ("ego", "wrist_left"), batch_size=7)
    assert np.isfinite(prediction.stitched).all()
    assert np.isnan(prediction.causal[:SPAN - 1]).all() and np.isfinite(prediction.causal[SPAN - 1:]).all()
    assert prediction.stitched.min() >= 0 and prediction.stitched.max() <= 1


@pytest.mark.parametrize("extra, message", [
    (["--split-file", "MISSING"], "file not found"),
    (["--num-traj", "0"], "--num-traj must be at least 1"),
    (["--batch-size", "0"], "--batch-size must be at least 1"),
])
def test_eval_bad_options(sim_hdf5_root, tiny_checkpoint, tmp_path, capsys, extra, message):
    extra = [str(tmp_path / e) if e == "MISSING" else e for e in extra]
    argv = ["eval", "--checkpoint", str(tiny_checkpoint), "--data", str(sim_hdf5_root), "--split", nonempty_split(sim_hdf5_root), *extra]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


def test_eval_missing_checkpoint(sim_hdf5_root, tmp_path, capsys):
    argv = ["eval", "--checkpoint", str(tmp_path / "none.pth"), "--data", str(sim_hdf5_root), "--split", nonempty_split(sim_hdf5_root)]
    assert main(argv) == 2
    assert "checkpoint not found" in capsys.readouterr().err
