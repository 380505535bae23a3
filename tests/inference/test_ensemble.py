"""Ensembles: the ensemble.json format, the `/membersK` knob, the ensemble engine's mean and spread (torch and
ONNX), and the spread/error rank correlation."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import torch

from touchanything.app.sessions.bundled import MODELS_DIR
from touchanything.app.sessions.engine_choice import build_engine, choose
from touchanything.core.errors import UserError
from touchanything.core.snapshot import VIEW_NAMES, Snapshot
from touchanything.inference.engine.engine_setting import EngineSetting, parse_setting
from touchanything.inference.engine.ensemble_engine import EnsembleEngine, load_ensemble, member_mean
from touchanything.inference.engine.streaming_engine import StreamingEngine
from touchanything.inference.evaluation.spread_error import frame_correlation, trajectory_correlation
from touchanything.inference.model.checkpoint import load_model, read_checkpoint
from touchanything.inference.model.ensemble_members import member_checkpoints

PICO = MODELS_DIR / "pico"
FRAMES = 10


def ensemble_folder(tmp_path: Path, members: list[Path]) -> Path:
    """A copy of pico whose ensemble.json lists copies of `members` (folders with best_model.pth and config.yaml)
    as members/2, members/3, … → the copy's checkpoint."""
    root = tmp_path / "pico"
    shutil.copytree(PICO, root)
    for number, folder in enumerate(members, start=2):
        shutil.copytree(folder, root / "members" / str(number))
    listed = [f"members/{n}/best_model.pth" for n in range(2, len(members) + 2)]
    (root / "ensemble.json").write_text(json.dumps({"members": listed}))
    return root / "best_model.pth"


def perturbed_pico(folder: Path, seed: int = 1, scale: float = 0.02) -> Path:
    """pico with every floating weight nudged by N(0, scale) noise, saved as a complete checkpoint in `folder`."""
    folder.mkdir(parents=True)
    shutil.copy(PICO / "config.yaml", folder / "config.yaml")
    data = read_checkpoint(PICO / "best_model.pth")
    generator = torch.Generator().manual_seed(seed)
    data["model_state_dict"] = {k: v + scale * torch.randn(v.shape, generator=generator, dtype=v.dtype)
                                if v.is_floating_point() else v for k, v in data["model_state_dict"].items()}
    torch.save(data, folder / "best_model.pth")
    return folder


def snapshots(frames: int = FRAMES) -> list[Snapshot]:
    """A random 64 px stream; the right hand has no valid pose on frames 3 and 7."""
    rng = np.random.default_rng(0)
    out = []
    for i in range(frames):
        images = {v: rng.integers(0, 256, (64, 64, 3), dtype=np.uint8) for v in VIEW_NAMES}
        joints = (rng.normal(0, 2, (42, 3)) + [0, 0, 40]).astype(np.float32)
        out.append(Snapshot(i, i * 33_333, images, joints, np.array([True, i % 4 != 3])))
    return out


def run(engine) -> list:
    return [p for s in snapshots() for p in engine.step(s)] + engine.drain()


def test_identical_members_give_the_single_model_and_zero_spread(tmp_path):
    checkpoint = ensemble_folder(tmp_path, [PICO, PICO])
    single = run(StreamingEngine(load_model(PICO / "best_model.pth"), EngineSetting("pico")))
    ensemble = run(build_engine(choose(checkpoint, members=3, device="cpu")))
    assert len(single) == len(ensemble) == FRAMES
    for one, three in zip(single, ensemble, strict=True):
        np.testing.assert_array_equal(three.pressure, one.pressure)
        assert one.spread is None
        np.testing.assert_array_equal(np.isnan(three.spread), np.isnan(one.pressure))
        assert np.nanmax(three.spread) == 0.0
        assert three.hands_predicted == one.hands_predicted and set(three.timings_ms) == set(one.timings_ms)


def hand_computed(checkpoint: Path, member: Path) -> tuple[np.ndarray, np.ndarray]:
    """The two single-model torch engines' outputs → their mean and |a − b| / 2, (N, 2, 21, 21)."""
    a, b = (np.stack([p.pressure for p in run(StreamingEngine(load_model(path), EngineSetting("pico")))])
            for path in (checkpoint, member))
    assert np.nanmax(np.abs(a - b)) > 1e-3  # the members differ
    return (a.astype(np.float64) + b) / 2, np.abs(a.astype(np.float64) - b) / 2


@pytest.mark.parametrize("runtime, tolerance", [("torch", 1e-6), ("onnx", 1e-4)])
def test_two_members_give_their_mean_and_half_difference(tmp_path, monkeypatch, runtime, tolerance):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))  # each ONNX member's export lands there
    checkpoint = ensemble_folder(tmp_path, [perturbed_pico(tmp_path / "perturbed")])
    mean, spread = hand_computed(checkpoint, checkpoint.parent / "members/2/best_model.pth")
    engine = load_ensemble(checkpoint, EngineSetting("pico", runtime=runtime, members=2))
    predictions = run(engine)
    assert engine.runtime.name == runtime
    got_mean, got_spread = (np.stack([getattr(p, f) for p in predictions]) for f in ("pressure", "spread"))
    np.testing.assert_allclose(got_mean, mean, atol=tolerance, rtol=0)
    np.testing.assert_allclose(got_spread, spread, atol=tolerance, rtol=0)


def test_nan_cells_stay_nan_and_a_hand_not_predicted_stays_zero(tmp_path):
    checkpoint = ensemble_folder(tmp_path, [perturbed_pico(tmp_path / "perturbed")])
    predictions = run(load_ensemble(checkpoint, EngineSetting("pico", members=2)))
    outside = np.isnan(predictions[0].pressure)
    assert outside.any()
    for p in predictions:
        np.testing.assert_array_equal(np.isnan(p.pressure), outside)
        np.testing.assert_array_equal(np.isnan(p.spread), outside)
    unposed = predictions[3]
    assert unposed.hands_predicted == (True, False)
    assert np.nanmax(unposed.pressure[1]) == 0.0 and np.nanmax(unposed.spread[1]) == 0.0
    assert np.nanmax(unposed.spread[0]) > 0.0


def test_member_mean_is_safe_with_broken_members_and_zero_maps():
    zeros = np.zeros((3, 2, 21, 21), np.float32)
    zeros[:, 0, 0, 0] = np.nan  # outside the layout in every member
    mean, spread = member_mean(zeros)
    assert np.isnan(mean[0, 0, 0]) and np.isnan(spread[0, 0, 0])
    assert np.nansum(mean) == 0.0 and np.nansum(spread) == 0.0
    broken = np.full((3, 2, 21, 21), 0.5, np.float32)
    broken[0, 1, 2, 3], broken[1, 1, 2, 3], broken[2, 1, 2, 3] = np.inf, np.nan, 0.25
    mean, spread = member_mean(broken)
    assert mean[1, 2, 3] == 0.25 and spread[1, 2, 3] == 0.0  # the one finite member holds the cell
    assert np.all(mean[0] == 0.5) and np.all(spread[0] == 0.0)


def test_the_members_knob_round_trips_and_refuses_bad_values():
    setting = parse_setting("pico/onnx-int8/all/members4")
    assert setting.members == 4 and setting.runtime == "onnx"
    assert setting.name() == "pico/onnx-int8/all/members4"
    assert EngineSetting("pico", every=2, members=3).name() == "pico/torch-fp32/all/every2/members3"
    assert EngineSetting("pico").name() == "pico/torch-fp32/all"
    with pytest.raises(UserError, match="canonical"):
        parse_setting("pico/torch-fp32/all/members1")
    with pytest.raises(UserError, match="unknown part 'members0'"):
        parse_setting("pico/torch-fp32/all/members0")
    for bad in (0, -2, 1.5, True, "2"):
        with pytest.raises(UserError, match="ensemble members must be a whole number") as caught:
            EngineSetting("pico", members=bad)
        assert "\n" not in str(caught.value)


def refusal(checkpoint: Path, k: int) -> str:
    with pytest.raises(UserError) as caught:
        member_checkpoints(checkpoint, k)
    assert "\n" not in str(caught.value)
    return str(caught.value)


def test_bad_ensembles_are_one_clear_line(tmp_path):
    checkpoint = ensemble_folder(tmp_path, [PICO, MODELS_DIR / "nano"])
    assert member_checkpoints(checkpoint, 1) == [checkpoint]
    assert member_checkpoints(checkpoint, 2)[1] == checkpoint.parent / "members/2/best_model.pth"
    assert "another model config" in refusal(checkpoint, 3) and "members/3" in refusal(checkpoint, 3)
    assert "5 members asked for, the ensemble has 3" in refusal(checkpoint, 5)
    (checkpoint.parent / "members/2/best_model.pth").unlink()
    assert "members/2/best_model.pth: ensemble member listed" in refusal(checkpoint, 2)
    ensemble = checkpoint.parent / "ensemble.json"
    for text in ("{not json", '["members/2/best_model.pth"]', '{"members": "members/2"}', '{"members": [2]}', "\xff"):
        ensemble.write_bytes(text.encode("latin-1"))
        assert refusal(checkpoint, 2).startswith(f"{ensemble}: ")
    ensemble.unlink()
    assert "no ensemble file" in refusal(checkpoint, 2)
    with pytest.raises(UserError, match="no ensemble file"):
        build_engine(choose(checkpoint, members=2, device="cpu"))


def test_the_engine_needs_as_many_models_as_members():
    with pytest.raises(UserError, match="asks for 3 members, 2 models given"):
        EnsembleEngine([load_model(PICO / "best_model.pth")] * 2, EngineSetting("pico", members=3))


def test_spread_error_correlation_on_a_hand_worked_example():
    pressure = np.full((2, 21, 21), np.nan)
    measured, spread = pressure.copy(), pressure.copy()
    cells = [(0, 0, 0), (0, 0, 1), (0, 0, 2), (0, 0, 3)]
    for cell, p, m, s in zip(cells, [0.5, 0.2, 0.9, 0.1], [0.4, 0.5, 0.3, 0.1], [0.2, 0.1, 0.4, 0.3], strict=True):
        pressure[cell], measured[cell], spread[cell] = p, m, s
    pressure[1], measured[1], spread[1] = 0.0, 1.0, 0.0  # the right hand: not predicted, not counted
    # errors 0.1, 0.3, 0.6, 0.0 rank 2, 3, 4, 1; spreads 0.2, 0.1, 0.4, 0.3 rank 2, 1, 4, 3:
    # d = 0, 2, 0, -2, rho = 1 - 6 * 8 / (4 * 15) = 0.2
    both = np.array([True, False])
    assert frame_correlation(pressure, spread, measured, both) == pytest.approx(0.2)
    flat = np.where(np.isnan(spread), np.nan, 0.1)
    assert np.isnan(frame_correlation(pressure, flat, measured, both))  # constant spread: skipped
    assert np.isnan(frame_correlation(pressure, spread, pressure, both))  # constant (zero) error: skipped
    perfect = np.where(np.isnan(spread), np.nan, np.abs(pressure - measured))
    frames = [np.stack(x) for x in ((pressure,) * 3, (spread, flat, perfect), (measured,) * 3, (both,) * 3)]
    assert trajectory_correlation(*frames) == pytest.approx((0.2 + 1.0) / 2)
    assert np.isnan(trajectory_correlation(*(f[1:2] for f in frames)))


def test_bench_measures_an_ensemble_beside_its_single_member(tmp_path):
    """The atlas's grid adds each ensemble size the model has (torch fp32 and ONNX int8); bench builds the members
    from beside the checkpoint and replays them like any setting: the K = 2 row of identical members has the
    single model's accuracy."""
    from touchanything.app.sessions.bundled import sample_episodes
    from touchanything.inference.evaluation.bench import BenchPlan, bench_model
    from touchanything.inference.evaluation.bench_accuracy import HeldOut
    from touchanything.inference.evaluation.bench_data import latency_clip
    from touchanything.inference.evaluation.bench_setting import settings_for

    names = [s.name() for s in settings_for("pico", quick=True, members=3)]
    assert names == ["pico/torch-fp32/all", "pico/onnx-int8/all", "pico/torch-fp32/all/members2",
                     "pico/onnx-int8/all/members2", "pico/torch-fp32/all/members3", "pico/onnx-int8/all/members3"]
    assert len(settings_for("pico", quick=False, members=8)) == 14 + 2 * 2 + 2  # 2, 4 and 8
    checkpoint = ensemble_folder(tmp_path, [PICO])
    path = sample_episodes()[0]
    rows = bench_model("pico", load_model(checkpoint), HeldOut([(path, "episodes")], frames=30), latency_clip(path, 12),
                       BenchPlan(True, rounds=1, per_round=3, naive_steps=2), lambda message: None, checkpoint).rows
    by_name = {row["setting"]: row for row in rows}
    assert by_name["pico/torch-fp32/all/members2"]["volumetric_iou"] == by_name["pico/torch-fp32/all"]["volumetric_iou"]
    assert by_name["pico/torch-fp32/all/members2"]["p99_ms"] > 0


def test_bench_measures_whether_an_ensembles_spread_ranks_its_error(tmp_path):
    """An ensemble setting's replay carries, per trajectory, the spread–error rank correlation of the two members'
    mean and half difference (worked out here from two single-model replays), its row the mean and interval, and
    the report a line for it; a single model's row carries none."""
    from touchanything.app.sessions.bundled import sample_episodes
    from touchanything.inference.evaluation.bench import accuracy_fields
    from touchanything.inference.evaluation.bench_accuracy import replay_outputs, settings_accuracy
    from touchanything.inference.evaluation.bench_data import load_episode
    from touchanything.inference.evaluation.bench_intervals import SPREAD_ERROR, add_intervals
    from touchanything.inference.evaluation.bench_report import spread_error_lines

    checkpoint = ensemble_folder(tmp_path, [perturbed_pico(tmp_path / "perturbed")])
    single, pair = EngineSetting("pico"), EngineSetting("pico", members=2)
    engines = {single: StreamingEngine(load_model(checkpoint), single), pair: load_ensemble(checkpoint, pair)}
    episode = load_episode(sample_episodes()[2], 64, 60)  # the Workbench episode: both hands press
    results = settings_accuracy([single, pair], engines, [episode], progress=lambda message: None)

    other = StreamingEngine(load_model(checkpoint.parent / "members/2/best_model.pth"), single)
    a, b = replay_outputs(engines[single], episode, [0.0]), replay_outputs(other, episode, [0.0])
    expected = trajectory_correlation((a.pressure + b.pressure) / 2, np.abs(a.pressure - b.pressure) / 2, episode.gt,
                                      a.hands)
    assert np.isfinite(expected)
    assert results[pair].per_trajectory[0][SPREAD_ERROR] == pytest.approx(expected, abs=1e-3)
    assert SPREAD_ERROR not in results[single].per_trajectory[0]

    rows = [{"setting": s.name(), **accuracy_fields(results[s])} for s in (single, pair)]
    add_intervals(rows, [{"name": episode.name, "split": episode.split}])
    assert "spread_error_rho" not in rows[0] and rows[1]["spread_error_rho"] == pytest.approx(expected, abs=1e-3)
    assert rows[1]["spread_error_rho_ci95"] == pytest.approx([expected] * 2, abs=1e-3)  # one trajectory: no spread
    assert spread_error_lines(rows)[-1].startswith("| pico/torch-fp32/all/members2 | ") and \
        spread_error_lines(rows)[-1].endswith(" | 1 |")
    assert spread_error_lines(rows[:1]) == []
