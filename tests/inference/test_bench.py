"""The benchmark machinery on a random nano model and the bundled sample (the full run is `touchanything bench`)."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch

from touchanything.app.cli import build_parser, main
from touchanything.app.sessions.bundled import sample_episodes
from touchanything.core.errors import UserError
from touchanything.inference.evaluation.bench import BenchPlan, bench_model, naive_latency
from touchanything.inference.evaluation.bench_accuracy import HeldOut, agreement_sums
from touchanything.inference.evaluation.bench_data import latency_clip
from touchanything.inference.evaluation.bench_gpu import bench_presets_on, gpu_markdown, gpu_settings
from touchanything.inference.evaluation.bench_plot import MIN_ACCURACY_SPAN, frontier_steps, named_front, pareto_figure, pareto_front
from touchanything.inference.evaluation.bench_report import _signed, markdown, target_checks, write_outputs
from touchanything.inference.evaluation.bench_setting import settings_for
from touchanything.inference.model.model_config import preset
from touchanything.inference.model.touch_model import TouchAnything

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def nano_rows():
    torch.manual_seed(0)
    model = TouchAnything(preset("nano")).eval()
    path = sample_episodes()[0]
    clip = latency_clip(path, 20)
    result = bench_model("nano", model, HeldOut([(path, "episodes")], frames=40), clip,
                         BenchPlan(True, rounds=2, per_round=5, naive_steps=3), progress=lambda message: None)
    return result.rows, result.naive


def test_rows_have_the_documented_fields(nano_rows):
    rows, naive = nano_rows
    assert [row["setting"] for row in rows] == ["nano/torch-fp32/all", "nano/onnx-int8/all"]
    for row in rows:
        for key in ("model", "checkpoint_sha256", "setting", "trajectories", "p50_ms", "p99_ms", "volumetric_iou",
                    "contact_iou", "runtime", "precision", "views", "every", "output", "agreement_viou", "peak_rss_mb",
                    "device", "gpu_name", "capture", "per_trajectory"):
            assert key in row
        assert row["model"] == "nano" and row["trajectories"] == 1 and len(row["per_trajectory"]["volumetric_iou"]) == 1
        assert row["device"] == "cpu" and row["gpu_name"] is None
        assert row["views"] == "all" and row["latency_frames"] == 10
        assert 0 < row["p50_ms"] <= row["p99_ms"] and row["peak_rss_mb"] > 0
        assert 0 <= row["volumetric_iou"] <= 1 and row["throughput_fps"] > 0
    assert rows[0]["agreement_viou"] == 1.0 and rows[0]["agreement_max_abs"] == 0.0
    assert 0.8 < rows[1]["agreement_viou"] <= 1.0
    assert naive["naive_p50_ms"] > naive["streaming_p50_ms"] and naive["ratio"] > 1


def test_the_accuracy_columns_are_the_official_metrics_of_an_independent_replay(nano_rows):
    """The reference row's V-IoU and C-IoU, worked out by hand from a fresh engine's replay of the same 40 frames
    (the fixture's model built again from its seed): Σ min / Σ max and cells above 0.1 in both / in either, over
    the measured cells (the official vmax fallback: divided by max(episode maximum, 1))."""
    from itertools import islice

    from touchanything.devices.episodes.episode_loader import open_episode
    from touchanything.devices.rig.replay import ReplayConfig, ReplaySource
    from touchanything.inference.engine.engine_setting import EngineSetting
    from touchanything.inference.engine.streaming_engine import StreamingEngine

    rows, _ = nano_rows
    torch.manual_seed(0)
    engine = StreamingEngine(TouchAnything(preset("nano")).eval(), EngineSetting(device="cpu"))
    with open_episode(sample_episodes()[0]) as episode:
        predictions = [p for s in islice(ReplaySource(episode, ReplayConfig(speed=None)), 40) for p in engine.step(s)]
        grids = np.asarray(episode.pressure.grids, np.float64)
    assert [p.frame_index for p in predictions] == list(range(40))
    measured = np.clip(grids / max(np.nanmax(grids), 1.0), 0.0, 1.0)[:40]
    inside = ~np.isnan(measured)
    predicted = np.stack([p.pressure for p in predictions])[inside]
    p, m = predicted.astype(np.float64), measured[inside]
    viou = np.minimum(p, m).sum() / np.maximum(p, m).sum()
    ciou = ((predicted > 0.1) & (m > 0.1)).sum() / ((predicted > 0.1) | (m > 0.1)).sum()
    assert rows[0]["volumetric_iou"] == pytest.approx(viou, abs=1e-5)
    assert rows[0]["per_trajectory"]["volumetric_iou"] == [pytest.approx(viou, abs=1e-5)]
    assert rows[0]["contact_iou"] == pytest.approx(ciou, abs=1e-5)


def test_report_files_and_targets(nano_rows, tmp_path):
    rows, naive = nano_rows
    record = {"machine": "test", "quick": True, "accuracy_data": "sample", "rows": rows,
              "naive_over_streaming": {"nano": naive["ratio"]}, "naive": {"nano": naive},
              "targets": target_checks(rows, {"nano": naive}, "nano")}
    paths = write_outputs(record, tmp_path)
    assert json.loads(paths[0].read_text())["rows"][1]["runtime"] == "onnx"  # valid JSON (NaN written as null)
    assert "| target |" in paths[1].read_text() and paths[2].stat().st_size > 10_000
    checks = {c["target"].split(":")[0]: c for c in record["targets"]}
    assert checks["nano ONNX int8, all views"]["met"] in (True, False)
    assert checks["paper preset"]["met"] is None  # not measured here


def test_full_grid_turns_one_knob_at_a_time():
    grid = settings_for("nano", quick=False)
    assert grid[0] == settings_for("nano", quick=True)[0] and len(set(grid)) == len(grid) == 14
    assert {s.output for s in grid} == {"newest", "centre", "stitched"} and {s.every for s in grid} == {1, 2, 3}
    assert {(s.runtime, s.precision) for s in grid} == {("torch", "fp32"), ("torch", "bf16"), ("onnx", "fp32"), ("onnx", "int8")}
    assert len({s.views for s in grid}) == 4


def test_pareto_front_and_agreement_helpers():
    assert pareto_front([(10, 0.5), (20, 0.6), (30, 0.55), (5, 0.1)]) == [0, 1, 3]
    a = np.array([[0.2, np.nan], [0.4, 0.0]])
    assert agreement_sums(a, a) == (pytest.approx(0.6), pytest.approx(0.6), 0.0)
    assert agreement_sums(np.array([0.2, 0.5]), np.array([0.4, np.nan])) == (pytest.approx(0.2), pytest.approx(0.4),
                                                                             pytest.approx(0.2))


def plot_rows(points: list[tuple[float, float]]) -> list[dict]:
    return [{"p99_ms": x, "volumetric_iou": y, "contact_iou": y, "model": "nano", "setting": f"nano/setting{i}"}
            for i, (x, y) in enumerate(points)]


def test_pareto_plot_reads_plainly_when_settings_are_nearly_equal():
    """Two settings 7e-7 apart (the --quick run): plain tick labels, an axis at least 0.02 wide, the frontier."""
    import matplotlib.pyplot as plt

    fig = pareto_figure(plot_rows([(12.0, 0.1459300), (30.0, 0.1459307)]))
    ax = fig.axes[0]
    fig.canvas.draw()
    labels = [t.get_text() for t in ax.get_yticklabels()]
    assert ax.yaxis.get_offset_text().get_text() == "" and all("e" not in t for t in labels)
    low, high = ax.get_ylim()
    assert high - low >= MIN_ACCURACY_SPAN
    frontier = next(line for line in ax.get_lines() if line.get_label() == "Pareto frontier")
    assert list(zip(*frontier.get_data())) == [(12.0, 0.1459300), (30.0, 0.1459300), (30.0, 0.1459307)]
    plt.close(fig)


def test_frontier_labels_skip_equal_and_crowded_settings():
    # 0 and 1 are 0.0005 apart (one label: the faster, 0); 3 is beaten by 4; 0's label would sit 0.02 under 2's at
    # latencies 1.2× apart (crowded with a 0.05 gap, apart with a 0.01 gap)
    points = [(1.0, 0.50), (1.1, 0.5005), (1.2, 0.52), (5.0, 0.521), (1.5, 0.60)]
    assert named_front(points, gap=0.05) == [4, 2]
    assert named_front(points, gap=0.01) == [4, 2, 0]
    assert named_front([(1.0, 0.5), (2.0, 0.51)], gap=0.05) == [1, 0]  # 2× apart in latency: both named


def test_frontier_is_a_staircase_run_on_to_the_slowest_setting():
    assert frontier_steps([(10, 0.5), (20, 0.6), (30, 0.55), (5, 0.1)]) == [
        (5, 0.1), (10, 0.1), (10, 0.5), (20, 0.5), (20, 0.6), (30, 0.6)]
    assert frontier_steps([(10, 0.5), (20, 0.4)]) == [(10, 0.5), (20, 0.5)]  # one front point: a flat line
    assert frontier_steps([]) == []


def test_bench_writes_under_recordings_by_default_and_says_so(capsys):
    args = build_parser().parse_args(["bench"])
    assert args.out == Path("recordings") / "bench" and not args.out.is_absolute()
    with pytest.raises(SystemExit):
        main(["bench", "--help"])
    assert "default recordings/bench in the working directory" in " ".join(capsys.readouterr().out.split())


def test_naive_recompute_is_timed_per_frame():
    torch.manual_seed(0)
    times = naive_latency(TouchAnything(preset("nano")).eval(), latency_clip(sample_episodes()[0], 3), steps=4)
    assert times.shape == (4,) and np.all(times > 0)


def test_bench_command_errors_are_clear(tmp_path, capsys):
    assert main(["bench", "--quick", "--frames", "5", "--out", str(tmp_path)]) == 2
    assert "--frames" in capsys.readouterr().err
    assert main(["bench", "--quick", "--data", str(tmp_path / "none"), "--out", str(tmp_path)]) == 2
    assert "none: not found" in capsys.readouterr().err


def test_the_gpu_bench_runs_its_settings_on_the_cpu_eagerly():
    clip = latency_clip(sample_episodes()[0], 16)
    rows, naive = bench_presets_on(torch.device("cpu"), clip, rounds=1, per_round=2, naive_steps=1, presets=("nano",),
                                   progress=lambda message: None)
    assert len(rows) == len(gpu_settings("nano", torch.device("cpu"))) == 8  # fp32/bf16 × 3 views/ego × graphs/eager
    assert {r["precision"] for r in rows} == {"fp32", "bf16"}  # fp16 needs a GPU
    assert {r["capture"] for r in rows} == {"eager (CUDA graphs need a CUDA GPU)"}
    assert all(r["device"] == "cpu" and r["gpu_name"] is None and r["peak_gpu_mb"] is None and r["p50_ms"] > 0 for r in rows)
    assert set(naive) == {"nano fp32", "nano bf16"} and all(v > 0 for v in naive.values())
    table = gpu_markdown({"machine": "test", "device": "cpu", "rows": rows, "naive": naive})
    assert table.count("| nano/torch-") == 8 and "| nano fp32 |" in table and "eager |" in table


def test_held_out_trajectories_come_from_a_dataset_roots_split_lists(tmp_path):
    from conftest import write_episode
    from touchanything.inference.evaluation.bench_data import held_out_paths

    for name in ("a", "b", "c"):
        write_episode(tmp_path / "Lab" / "press" / name, frames=16)
    split = {"train": ["Lab/press/c"], "val": [], "test_seen": ["Lab/press/a"], "test_unseen": ["Lab/press/b"]}
    (tmp_path / "split.json").write_text(json.dumps(split))
    assert held_out_paths(tmp_path) == [(tmp_path / "Lab/press/a", "test_seen"), (tmp_path / "Lab/press/b", "test_unseen")]
    assert held_out_paths(tmp_path, ["train"]) == [(tmp_path / "Lab/press/c", "train")]
    with pytest.raises(UserError, match="unknown split 'test'"):
        held_out_paths(tmp_path, ["test"])
    with pytest.raises(UserError, match="the val list"):
        held_out_paths(tmp_path, ["val"])
    (tmp_path / "split.json").write_text(json.dumps({**split, "test_unseen": ["Lab/press/b", "Lab/press/gone"]}))
    with pytest.raises(UserError, match="1 listed trajectories do not exist"):
        held_out_paths(tmp_path)
    # the bundled sample's split.json names the HDF5 files `convert` would write: it is a folder of episodes
    assert {split for _, split in held_out_paths(sample_episodes()[0].parents[2])} == {"episodes"}
    with pytest.raises(UserError, match="--splits needs a dataset root"):
        held_out_paths(sample_episodes()[0].parents[2], ["test_seen"])


def test_worker_processes_measure_what_one_process_does():
    """Accuracy replays dealt out to two worker processes give the same per-trajectory metrics, in the same
    order, as one process (the bundled nano, ONNX int8 included)."""
    from touchanything.app.sessions.bundled import bundled_models
    from touchanything.inference.model.checkpoint import load_model

    checkpoint = bundled_models()["nano"]
    pairs = [(path, "episodes") for path in sample_episodes()[:3]]
    plan = BenchPlan(True, rounds=1, per_round=2, naive_steps=1)
    clip = latency_clip(pairs[0][0], 10)
    one, two = (bench_model("nano", load_model(checkpoint), HeldOut(pairs, frames=30, workers=w), clip, plan,
                            progress=lambda message: None, checkpoint=checkpoint) for w in (1, 2))
    assert one.trajectories == two.trajectories and len(one.trajectories) == 3
    for a, b in zip(one.rows, two.rows):
        assert a["setting"] == b["setting"] and a["trajectories"] == b["trajectories"] == 3
        np.testing.assert_allclose(a["per_trajectory"]["volumetric_iou"], b["per_trajectory"]["volumetric_iou"], atol=1e-6)
        np.testing.assert_allclose(a["per_trajectory"]["contact_iou"], b["per_trajectory"]["contact_iou"], atol=1e-6)
        assert a["agreement_viou"] == pytest.approx(b["agreement_viou"], abs=1e-6)


def test_the_model_axis_targets_judge_faster_and_more_accurate_models_against_the_base():
    from touchanything.inference.evaluation.bench_report import model_axis_checks

    def row(setting: str, p99: float | None, unseen: float, ci: tuple[float, float]) -> dict:
        return {"setting": setting, "model": setting.split("/")[0], "p99_ms": p99, "volumetric_iou": unseen,
                "per_split": {"test_unseen": {"volumetric_iou": unseen, "volumetric_iou_ci95": list(ci)}}}

    rows = [row("nano/torch-fp32/all", 8.0, 0.49, (0.46, 0.52)), row("nano/onnx-int8/all", 3.0, 0.49, (0.46, 0.52)),
            row("pico/torch-fp32/all", 4.0, 0.47, (0.44, 0.50)), row("pico/onnx-int8/all", 1.2, 0.47, (0.44, 0.50)),
            row("big/torch-fp32/all", 20.0, 0.53, (0.505, 0.55)), row("big/onnx-int8/all", 9.0, 0.53, (0.505, 0.55)),
            row("baseline_pose/torch-fp32/all", 2.0, 0.5, (0.47, 0.53))]
    comparisons = [{"setting": "pico/torch-fp32/all", "against": "baseline_pose/torch-fp32/all",
                    "delta_contact_iou": [0.03, 0.012, 0.05]},
                   {"setting": "big/torch-fp32/all", "against": "nano/torch-fp32/all",
                    "per_split": {"test_unseen": {"delta_volumetric_iou": [0.04, 0.02, 0.06]}}}]
    checks = {c["target"]: c for c in model_axis_checks(rows, "nano", comparisons)}
    assert checks["pico (faster than nano): ONNX int8 all views p99 (ms)"]["met"] is True
    assert checks["pico: contact IoU minus baseline_pose's, low end of the paired 95 % interval"]["value"] == 0.012
    assert checks["big (more accurate than nano): V-IoU on unseen objects"]["met"] is True
    low_end = checks["big: low end of its unseen V-IoU interval minus nano's unseen V-IoU"]
    assert low_end["value"] == pytest.approx(0.015) and low_end["met"] is True
    assert checks["big: low end of the paired interval of its unseen V-IoU minus nano's"]["value"] == 0.02
    assert not any(name.startswith(("nano", "baseline_pose")) for name in checks)
    rows[3]["p99_ms"] = 2.0  # faster than nano, but not within 1.5 ms
    rows[4]["per_split"]["test_unseen"]["volumetric_iou_ci95"] = [0.48, 0.55]  # its interval reaches below nano's point
    checks = {c["target"]: c for c in model_axis_checks(rows, "nano", [])}
    assert checks["pico (faster than nano): ONNX int8 all views p99 (ms)"]["met"] is False
    assert checks["pico: contact IoU minus baseline_pose's, low end of the paired 95 % interval"]["met"] is None
    assert checks["big: low end of its unseen V-IoU interval minus nano's unseen V-IoU"]["met"] is False


@pytest.mark.slow
def test_few_held_out_trajectories_are_a_warning_and_the_run_goes_on(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["bench", "--quick", "--frames", "15", "--models", str(REPO / "models" / "baseline_pose"), "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert "warning: only 3 held-out trajectories: the 95 % intervals are wide" in err
    # every phase says what it does (no long silence): reading, each setting's accuracy, each latency round
    assert "reading 3 held-out trajectories" in err and "baseline_pose/onnx-int8/all: accuracy on 3 trajectories" in err
    assert "latency round 1/" in err and "-0.000" not in (out / "engine.md").read_text()
    record = json.loads((out / "engine.json").read_text())  # the whole command: JSON, Markdown, plot
    assert [t["split"] for t in record["trajectories"]] == ["episodes"] * 3
    rows = {row["setting"]: row for row in record["rows"]}
    assert set(rows) == {"baseline_pose/torch-fp32/all", "baseline_pose/onnx-int8/all", "paper/torch-fp32/all"}
    pose = rows["baseline_pose/torch-fp32/all"]
    assert pose["trajectories"] == 3 and len(pose["checkpoint_sha256"]) == 64 and len(pose["volumetric_iou_ci95"]) == 2
    assert [c["setting"] for c in record["comparisons"]] == ["baseline_pose/onnx-int8/all"]
    assert "| baseline_pose/onnx-int8/all | baseline_pose/torch-fp32/all |" in (out / "engine.md").read_text()
    assert (out / "engine_pareto.png").stat().st_size > 10_000


def test_bench_figures_never_read_minus_zero():
    assert _signed([-0.0001, -0.0004, 0.0002]) == "+0.000 [+0.000, +0.000]"
    assert _signed([-0.0012, -0.0031, 0.0004]) == "-0.001 [-0.003, +0.000]"
    committed = (REPO / "models" / "atlas" / "engine.md").read_text()
    assert "-0.000" not in committed
    assert "-0.000" not in markdown(json.loads((REPO / "models" / "atlas" / "engine.json").read_text()))
