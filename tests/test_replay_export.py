"""`touchanything replay`: headless export through the engine, with and without ground truth, and its errors."""
from __future__ import annotations

import numpy as np

from touchanything.app.cli import main
from touchanything.app.sessions.replay_export import ReplaySummary
from touchanything.devices.episodes.episode_loader import open_episode
from touchanything.devices.episodes.video_io import VideoReader
from touchanything.devices.tactile_layout import TactileLayout
from touchanything.inference.evaluation.running_metrics import RunningMetrics
from touchanything.viz.frame_facts import FrameFacts, HandFacts
from touchanything.viz.pressure_panel import BACKGROUND


def test_replay_exports_a_playable_video_with_metrics(episode_dir, tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))  # the ONNX graphs are exported there
    out = tmp_path / "video" / "replay.mp4"
    assert main(["replay", str(episode_dir), "--views", "ego", "wrist_left", "--runtime", "onnx", "--precision", "int8",
                 "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "frames    40 written, 40 with a prediction" in printed and "contact_iou" in printed
    assert "contact   lamps agree on " in printed and "where a hand was predicted and measured)" in printed
    with VideoReader(out) as video:
        assert video.num_frames == 40
        frame = video.read(39)
    assert frame.shape == (806, 1440, 3) and frame[:270].std() > 5  # the camera row is not blank
    strip = frame[630:780].astype(int)
    assert (np.abs(strip - BACKGROUND).sum(axis=-1) > 20).mean() > 0.3  # plot axes, lines and contact lamps


def test_an_episode_without_ground_truth_shows_the_prediction_only(episode_dir, tmp_path, capsys):
    (episode_dir / "pressure_grids.npz").unlink()
    (episode_dir / "jq_pressure.json").unlink()
    with open_episode(episode_dir) as episode:
        assert episode.pressure is None
    assert main(["replay", str(episode_dir), "--headless", "--out", str(tmp_path / "r.mp4")]) == 0
    printed = capsys.readouterr().out
    assert "metrics   n/a" in printed and "40 with a prediction" in printed and "lamps" not in printed


def test_the_lamp_agreement_counts_each_hand_where_both_lamps_are_known():
    summary = ReplaySummary()
    known = lambda p, m: HandFacts(True, True, p, m)  # noqa: E731 - a posed and measured hand
    summary.add_lamps(FrameFacts(True, True, (known(True, True), known(False, True))))
    summary.add_lamps(FrameFacts(True, True, (known(False, True), known(False, False))))
    summary.add_lamps(FrameFacts(True, True, (known(True, True), HandFacts(False, True, None, True))))  # right: no pose
    summary.add_lamps(FrameFacts(False, True, (HandFacts(False, True, None, True), HandFacts(False, True, None, False))))
    assert summary.lamps_agree == [2, 1] and summary.lamps_judged == [3, 2]
    assert summary.lamp_line() == ("contact   lamps agree on 60.0 % (left 66.7 % of 3 frames, right 50.0 % of 2; "
                                   "where a hand was predicted and measured)")


def test_replay_errors_are_one_clear_line(episode_dir, tmp_path, capsys):
    cases = [(["replay", str(tmp_path / "none"), "--out", str(tmp_path / "a.mp4")], "not found"),
             (["replay", str(episode_dir), "--out", str(tmp_path / "a.avi")], ".mp4"),
             (["replay", str(episode_dir), "--precision", "int4", "--out", str(tmp_path / "a.mp4")], "no precision"),
             (["replay", str(episode_dir), "--views", "wrist_left", "--out", str(tmp_path / "a.mp4")], "include ego"),
             (["replay", str(episode_dir), "--checkpoint", str(tmp_path / "x.pth"), "--out", str(tmp_path / "a.mp4")],
              "x.pth")]
    for argv, message in cases:
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert message in err and "Traceback" not in err


def test_running_metrics_roll_and_accumulate():
    layout = TactileLayout.default()
    metrics = RunningMetrics(layout.bend, window=3)
    assert np.isnan(metrics.cumulative()["volumetric_iou"]) and np.isnan(metrics.rolling()["contact_iou"])
    full = np.where(layout.valid, 1.0, np.nan)
    for value in (1.0, 1.0, 0.0, 0.0, 0.0):
        metrics.add(full * value, full)
    assert metrics.rolling()["volumetric_iou"] == 0.0
    assert abs(metrics.cumulative()["volumetric_iou"] - 0.4) < 1e-9
    metrics.reset()
    assert metrics.frames == 0


def test_running_metrics_equal_the_batch_metrics_of_their_frames():
    """The per-frame sum vectors give exactly the official metrics of the window / of every frame."""
    from touchanything.inference.evaluation.metrics import METRICS, compute_tactile_metrics

    layout = TactileLayout.default()
    rng = np.random.default_rng(3)
    mask = np.where(layout.valid, 1.0, np.nan)
    preds = rng.uniform(0, 0.4, (50, 2, 21, 21)) * mask
    gts = rng.uniform(0, 0.4, (50, 2, 21, 21)) * mask
    gts[10:20] = np.nan  # frames without ground truth are not judged
    metrics = RunningMetrics(layout.bend, window=7, threshold=0.2)
    for p, g in zip(preds, gts):
        metrics.add(p, g)
    for got, frames in ((metrics.rolling(), slice(43, 50)), (metrics.cumulative(), slice(0, 50))):
        want = compute_tactile_metrics(preds[frames], gts[frames], layout.bend, threshold=0.2)
        assert tuple(got) == METRICS
        for key in METRICS:
            assert np.isclose(got[key], want[key], rtol=1e-12, equal_nan=True), key
