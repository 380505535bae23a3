"""The smaller points a new user tripped over (issue 34): the pose source and per-hand share in `info` of a dataset,
the duplicate-frame line of the quality report, the pose-only twin `eval --pose-only-baseline` takes, and bench
figures that never read "-0.000"."""
from __future__ import annotations

import json
from pathlib import Path

from conftest import write_episode
from touchanything.app.cli import main
from touchanything.app.sessions.bundled import MODELS_DIR, pose_only_twin
from touchanything.devices.episodes.dataset_conversion import duplicate_frames
from touchanything.inference.evaluation.bench_report import _signed, markdown

ROOT = Path(__file__).resolve().parents[1]


def test_info_of_a_dataset_names_the_pose_source_per_hand(tmp_path, capsys):
    write_episode(tmp_path / "raw" / "Home" / "a" / "001", frames=14, seed=1)  # conftest: right hand gone every 7th frame
    assert main(["info", str(tmp_path / "raw")]) == 0
    assert "wilor poses left 100%, right 86%, contact" in capsys.readouterr().out  # 12 of 14 frames


def test_the_quality_report_says_what_was_not_measured():
    assert duplicate_frames(-1, -1) == "duplicate wrist frames not measured (no quality_issues.json)"
    assert duplicate_frames(0.01, -1) == "duplicate wrist frames left 1.0%, right not measured"
    assert duplicate_frames(0.0, 0.305) == "duplicate wrist frames left 0.0%, right 30.5%"


def test_the_pose_only_baseline_is_the_bundled_twin_when_there_is_one(tmp_path):
    assert pose_only_twin(MODELS_DIR / "nano" / "best_model.pth") == MODELS_DIR / "nano_pose_only" / "best_model.pth"
    assert pose_only_twin(MODELS_DIR / "pico" / "best_model.pth") is None  # no pico_pose_only bundled
    assert pose_only_twin(MODELS_DIR / "nano_pose_only" / "best_model.pth") is None
    assert pose_only_twin(tmp_path / "mine" / "best_model.pth") is None


def test_bench_figures_never_read_minus_zero():
    assert _signed([-0.0001, -0.0004, 0.0002]) == "+0.000 [+0.000, +0.000]"
    assert _signed([-0.0012, -0.0031, 0.0004]) == "-0.001 [-0.003, +0.000]"
    committed = (ROOT / "models" / "atlas" / "engine.md").read_text()
    assert "-0.000" not in committed
    assert "-0.000" not in markdown(json.loads((ROOT / "models" / "atlas" / "engine.json").read_text()))
