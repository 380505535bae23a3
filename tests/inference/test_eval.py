"""`touchanything eval`: the official protocol end to end on HDF5 trajectories."""
from __future__ import annotations

import json
import math
import os
import socket
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from touchanything.app.cli import main
from touchanything.core.snapshot import VIEW_NAMES
from touchanything.core.tactile_layout import TactileLayout
from touchanything.devices.episodes.dataset_split import SPLIT_KEYS, read_split, write_split
from touchanything.devices.episodes.episode_loader import open_episode
from touchanything.devices.episodes.video_io import VideoReader
from touchanything.inference.evaluation.evaluation import trajectory_metrics
from touchanything.inference.evaluation.metrics import ALL_METRICS, ground_truth_for_metrics
from touchanything.inference.evaluation.trajectory_prediction import predict_trajectory
from touchanything.inference.model.checkpoint import load_model
from touchanything.inference.model.model_config import CLIP_LENGTH, FRAME_INTERVAL, SPAN
from touchanything.inference.model.pose_encoder import prepare_poses
from touchanything.inference.model.preprocess import resize_frame, to_model_input


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def nonempty_split(root) -> str:
    split = read_split(root / "split.json")
    return next(k for k in ("train", "test_seen", "val", "test_unseen") if split[k])


def test_eval_writes_the_table_per_view_and_scene(sim_hdf5_root, tiny_checkpoint, tmp_path, capsys):
    split = read_split(sim_hdf5_root / "split.json")
    name = nonempty_split(sim_hdf5_root)
    argv = ["eval", "--checkpoint", str(tiny_checkpoint), "--data", str(sim_hdf5_root), "--split", name,
            "--views", "ego", "wrist_left+wrist_right+ego", "--batch-size", "32", "--out", str(tmp_path / "out"), "--video"]
    assert main(argv) == 0
    captured = capsys.readouterr()
    printed = captured.out
    total = 60 * len(split[name])
    final = [line for line in captured.err.replace("\r", "\n").splitlines() if f" {total}/{total} [" in line]
    assert final and all(" frames/s" in line for line in final)  # whole frames out of a total
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
        assert_means_of_the_rows(result)
    table = (tmp_path / "out" / "results.md").read_text()
    assert table.startswith("# Evaluation on") and table.count("| temporal_f1 |") == 2 and "| offset_recall |" in table
    videos = sorted((tmp_path / "out").glob("*.mp4"))
    assert len(videos) == 2 * len(split[name])
    with VideoReader(videos[0]) as reader:
        assert (reader.width, reader.height, reader.num_frames) == (1440, 656, 60)
        assert reader.read(30).std() > 10


def assert_means_of_the_rows(result: dict) -> None:
    """results.json's "overall" and per-scene figures are the official mean over its own trajectory rows: per
    metric, the plain average of the trajectories whose value is a number (NaN when none is), counts included."""
    rows = result["trajectories"]
    groups = {"overall": rows, **{scene: [r for r in rows if r["scene"] == scene] for scene in {r["scene"] for r in rows}}}
    for mode in ("stitched", "causal"):
        assert set(result[mode]) == set(groups)
        for group, members in groups.items():
            for key in ALL_METRICS:
                numbers = [r[mode][key] for r in members if not math.isnan(r[mode][key])]
                want = sum(numbers) / len(numbers) if numbers else math.nan
                assert result[mode][group][key] == pytest.approx(want, abs=1e-12, nan_ok=True), (mode, group, key)


def test_eval_video_marks_the_views_the_model_does_not_use(sim_hdf5_root, tiny_checkpoint, tmp_path, capsys):
    """`--views ego`: the wrist cameras are dimmed to 35 % under "… — not used"; the pose-only rows (black frames)
    dim every view; `all` shows the three as they are."""
    out = tmp_path / "out"
    assert main(["eval", "--checkpoint", str(tiny_checkpoint), "--data", str(sim_hdf5_root), "--split", nonempty_split(sim_hdf5_root),
                 "--num-traj", "1", "--views", "ego", "all", "--pose-only-baseline", "--out", str(out), "--video"]) == 0
    capsys.readouterr()
    frames = {}
    for video in out.glob("*.mp4"):  # <scene>_<task>_<trajectory>_<views>[_pose_only].mp4
        name = next(n for n in ("ego_pose_only", "all_pose_only", "ego", "all") if video.stem.endswith(f"_{n}"))
        with VideoReader(video) as reader:
            frames[name] = reader.read(30).astype(np.float64)
    assert sorted(frames) == ["all", "all_pose_only", "ego", "ego_pose_only"], sorted(frames)

    def tile(name: str, k: int) -> np.ndarray:  # a camera below its label
        return frames[name][40:270, 480 * k:480 * (k + 1)]

    for name, used in (("ego", (True, False, False)), ("all_pose_only", (False, False, False)),
                       ("ego_pose_only", (False, False, False))):
        for k, shown in enumerate(used):
            expected = tile("all", k) * (1.0 if shown else 0.35)
            assert np.abs(tile(name, k) - expected).mean() < 5, (name, VIEW_NAMES[k])
    assert tile("all", 1).mean() > 40  # the wrist camera is bright enough for its dimming to show


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


def test_eval_on_a_root_without_a_split_says_how_to_make_one(tiny_checkpoint, tmp_path, capsys):
    assert main(["eval", "--checkpoint", str(tiny_checkpoint), "--data", str(tmp_path)]) == 2
    assert capsys.readouterr().err.strip() == (
        f"touchanything eval: error: {tmp_path / 'split.json'}: not found; make one with `touchanything split "
        f"{tmp_path}`, or name a split file with --split-file")


def test_eval_missing_checkpoint(sim_hdf5_root, tmp_path, capsys):
    argv = ["eval", "--checkpoint", str(tmp_path / "none.pth"), "--data", str(sim_hdf5_root), "--split", nonempty_split(sim_hdf5_root)]
    assert main(argv) == 2
    assert "checkpoint not found" in capsys.readouterr().err


def clip_by_clip(model, episode, views: tuple[str, ...]) -> tuple[np.ndarray, np.ndarray]:
    """The official protocol as written: the whole model on every stride-1 clip, one clip at a time."""
    count = episode.num_frames
    frames = {v: to_model_input(np.stack([resize_frame(episode.views[v].read(i), model.config.image_size)
                                          for i in range(count)])) for v in views}
    poses = torch.from_numpy(prepare_poses(episode.wilor.joints.reshape(count, 42, 3), episode.wilor.valid))
    total, covered = np.zeros((count, 2, 21, 21)), np.zeros(count)
    causal = np.full((count, 2, 21, 21), np.nan, np.float32)
    for start in range(count - SPAN + 1):
        index = start + np.arange(CLIP_LENGTH) * FRAME_INTERVAL
        with torch.no_grad():
            out = model(poses=poses[index][None], views={v: frames[v][index][None] for v in views})["tactile"][0].numpy()
        total[index] += out
        covered[index] += 1
        causal[index[-1]] = out[-1]
    return (total / covered[:, None, None, None]).astype(np.float32), causal


def test_each_frame_encoded_once_gives_the_clip_by_clip_protocol(sim_hdf5_root, tiny_checkpoint):
    model = load_model(tiny_checkpoint)
    path = read_split(sim_hdf5_root / "split.json")[nonempty_split(sim_hdf5_root)][0]
    encoded = []
    with open_episode(path) as episode:
        stitched, causal = clip_by_clip(model, episode, VIEW_NAMES)  # the reference, once
        for batch_size in (1, 5, 64):
            prediction = predict_trajectory(model, episode, VIEW_NAMES, batch_size, "views", on_frames=encoded.append)
            np.testing.assert_allclose(prediction.stitched, stitched, atol=1e-5)
            np.testing.assert_allclose(prediction.causal, causal, atol=1e-5)
            assert sum(encoded) == episode.num_frames  # each frame once
            encoded.clear()
        gt = ground_truth_for_metrics(episode.pressure.grids, bool(episode.pressure.attrs.get("normalized", False)))
    bend = TactileLayout.default().bend
    batched, reference = trajectory_metrics(prediction.stitched, gt, bend), trajectory_metrics(stitched, gt, bend)
    for key in ALL_METRICS:
        assert batched[key] == pytest.approx(reference[key], abs=1e-6, nan_ok=True)


@pytest.mark.multiprocess
def test_eval_sharded_over_two_processes_equals_one(sim_hdf5_root, tiny_checkpoint, tmp_path):
    files = sorted(str(p) for p in sim_hdf5_root.rglob("*.hdf5"))
    assert len(files) == 3  # an odd count: the two processes get two and one
    write_split(tmp_path / "split.json", {k: [Path(f) for f in files] if k == "test_seen" else [] for k in SPLIT_KEYS},
                absolute=True)
    argv = ["eval", "--checkpoint", str(tiny_checkpoint), "--data", str(sim_hdf5_root), "--split-file",
            str(tmp_path / "split.json"), "--views", "all", "--device", "cpu", "--batch-size", "16"]
    assert main([*argv, "--out", str(tmp_path / "one")]) == 0
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    command = [sys.executable, "-m", "torch.distributed.run", "--nproc_per_node=2", "--master_port", str(free_port()),
               "-m", "touchanything.app.cli", *argv, "--out", str(tmp_path / "two")]
    proc = subprocess.run(command, capture_output=True, text=True, env=env, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert proc.stdout.count("# Evaluation on") == 1  # only the main process reports
    one, two = (json.loads((tmp_path / name / "results.json").read_text()) for name in ("one", "two"))
    assert [row["path"] for row in two["results"][0]["trajectories"]] == files
    assert_means_of_the_rows(one["results"][0])  # three trajectories: the overall is their mean, not the last one's
    assert json.dumps(one["results"], sort_keys=True) == json.dumps(two["results"], sort_keys=True)


def test_eval_keeps_earlier_results_unless_told_to_replace_them(sim_hdf5_root, tiny_checkpoint, tmp_path, capsys):
    """A run (here one where every trajectory fails) never replaces an earlier run's results without --overwrite."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "results.md").write_text("good earlier results\n")
    argv = ["eval", "--checkpoint", str(tiny_checkpoint), "--data", str(sim_hdf5_root), "--split",
            nonempty_split(sim_hdf5_root), "--views", "ego", "--out", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert f"{out / 'results.md'}: exists; pass --overwrite to replace it" in err and len(err.strip().splitlines()) == 1
    assert (out / "results.md").read_text() == "good earlier results\n" and not (out / "results.json").exists()
    assert main([*argv, "--overwrite"]) == 0
    assert "| views | scene |" in (out / "results.md").read_text()
