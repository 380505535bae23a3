"""`touchanything replay`: headless export through the engine, with and without ground truth, and its errors."""
from __future__ import annotations

import numpy as np
import pytest

from touchanything.app.cli import main
from touchanything.app.sessions.replay_export import ReplaySummary
from touchanything.core.tactile_layout import TactileLayout
from touchanything.devices.episodes.episode_loader import open_episode
from touchanything.devices.episodes.video_io import VideoReader
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


def test_running_metrics_by_hand_at_a_threshold_of_0_2():
    """Five frames, each uniform over the layout's cells (P predicted, G measured), contact threshold 0.2, a window
    of 3:  f0 P 0.3 G 0.3 (both contact) | f1 P 0.1 G 0.5 (measured only) | f2 G all NaN (not judged) |
    f3 P 0.25 G 0.15 (predicted only) | f4 P 0 G 0 (neither).
    cumulative: V-IoU (0.3 + 0.1 + 0.15 + 0) / (0.3 + 0.5 + 0.25 + 0) = 11/21; C-IoU: cells in both only at f0, in
    either at f0, f1, f3 → 1/3; TA: f0 and f4 agree of 4 judged → 1/2; MAE (0 + 0.4 + 0.1 + 0) / 4 = 0.125.
    rolling (f2 … f4): V-IoU 0.15/0.25 = 0.6; C-IoU 0/n = 0; TA 1/2; MAE 0.05.
    At the official 0.1 instead: f1's 0.1 is not contact and f3's 0.15 is → C-IoU 2/3, TA 3/4."""
    layout = TactileLayout.default()
    full = lambda value: np.where(layout.valid, value, np.nan)  # noqa: E731
    frames = [(0.3, 0.3), (0.1, 0.5), (0.7, np.nan), (0.25, 0.15), (0.0, 0.0)]
    metrics = RunningMetrics(layout.bend, window=3, threshold=0.2)
    official = RunningMetrics(layout.bend)
    for p, g in frames:
        for running in (metrics, official):
            running.add(full(p).astype(np.float32), np.full((2, 21, 21), np.nan) if np.isnan(g) else full(g))
    expected = {"cumulative": {"volumetric_iou": 11 / 21, "contact_iou": 1 / 3, "temporal_accuracy": 0.5, "mae": 0.125,
                               "mae_left": 0.125, "mae_right": 0.125},
                "rolling": {"volumetric_iou": 0.6, "contact_iou": 0.0, "temporal_accuracy": 0.5, "mae": 0.05,
                            "mae_left": 0.05, "mae_right": 0.05}}
    for kind, values in expected.items():
        got = getattr(metrics, kind)()
        assert tuple(got) == ("temporal_accuracy", "contact_iou", "volumetric_iou", "mae", "mae_left", "mae_right")
        for key, want in values.items():
            assert got[key] == pytest.approx(want, abs=1e-6), (kind, key)  # float32 maps: 1e-6
    assert official.cumulative()["contact_iou"] == pytest.approx(2 / 3) and official.cumulative()["temporal_accuracy"] == 0.75
    assert metrics.frames == 5


def test_no_engine_figure_without_a_prediction():
    """A plain video where no hand was found printed "engine 4.4 ms per frame" with nothing predicted."""
    nothing = ReplaySummary(frames=3, no_pose=3, step_ms=[4.0, 4.5, 5.0], latency_ms=[4.0, 4.5, 5.0])
    assert not any(line.startswith("engine") for line in nothing.lines())
    assert nothing.lines()[0] == "frames    3 replayed (no video written), 0 with a prediction, 3 without a hand pose " \
                                 "(nothing predicted)"
    some = ReplaySummary(frames=3, predicted=1, no_pose=2, step_ms=[4.0, 4.5, 5.0], latency_ms=[4.0, 4.5, 5.0], video=True)
    assert "engine    4.5 ms per frame (p99 5.0); latency p50 4.5 ms, p99 5.0 ms" in some.lines()
