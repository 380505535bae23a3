"""The simulated rig: determinism, touch physics, visibility direction, and valid EgoTouch output."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from touchanything.app.cli import main
from touchanything.core.errors import UserError
from touchanything.core.tactile_layout import TactileLayout
from touchanything.devices.episodes.episode_loader import find_raw_episodes, open_episode
from touchanything.devices.episodes.hdf5_convert import convert_trajectory
from touchanything.devices.sim.dataset_generator import SimulationConfig, simulate_dataset
from touchanything.devices.sim.episode_generator import EpisodeSpec, generate_episode
from touchanything.devices.sim.hand_model import FINGER_COLUMNS, hand_state
from touchanything.devices.sim.script_base import PALM_DOWN
from touchanything.devices.sim.shapes import Shape, pose_at
from touchanything.devices.sim.touch import DEPTH_SCALE, cell_pressure

JSONL = ("wilor_hands.json", "rokoko_hands.json", "vive_poses.json", "jq_pressure.json")


@pytest.fixture(scope="module")
def small_dataset(tmp_path_factory):
    out = tmp_path_factory.mktemp("sim")  # seed 8: two of the three 4 s episodes touch
    card = simulate_dataset(out, SimulationConfig(episodes=3, seconds=4.0, seed=8, workers=2))
    return out, card


def test_same_seed_gives_byte_identical_streams(tmp_path):
    spec = EpisodeSpec("Office", 2.0, 1234, False, "ep")
    a, b = generate_episode(tmp_path / "a", spec), generate_episode(tmp_path / "b", spec)
    for name in JSONL + ("pressure_grids.npz",):
        assert (a.folder / name).read_bytes() == (b.folder / name).read_bytes(), name
    other = generate_episode(tmp_path / "c", EpisodeSpec("Office", 2.0, 99, False, "ep"))
    assert (other.folder / "jq_pressure.json").read_bytes() != (a.folder / "jq_pressure.json").read_bytes()


def test_no_pressure_when_the_hand_is_far_from_everything():
    box = Shape("box", (0.05, 0.05, 0.05), (100, 100, 100), pose_at([0.0, 0.3, 0.05]))
    for side in ("left", "right"):
        hand = hand_state(side, pose_at([0.3, -0.2, 0.4], PALM_DOWN), np.full(5, 0.3))
        pressure = cell_pressure(hand, [box])
        tactile = ~np.isnan(hand.cell_points[..., 0])
        assert np.all(pressure[tactile] == 0.0)
        assert np.allclose(pressure[~np.isnan(hand.bend)], 0.3)  # bend cells follow flexion


def test_pressure_where_a_fingertip_penetrates_a_surface():
    flex = np.array([0.6, 0.0, 0.9, 0.9, 0.9])
    hand = hand_state("right", pose_at([0, 0, 0.3], PALM_DOWN), flex)  # well above the table (z = 0)
    col = 20 - (FINGER_COLUMNS["index"] + 1)  # right hand: display column mirrored
    tip = hand.cell_points[2, col]
    depth = 0.003
    box = Shape("box", (0.05, 0.05, 0.05), (100, 100, 100), pose_at(tip + [0, 0, depth - 0.05]))  # pad 3 mm inside
    pressure = cell_pressure(hand, [box])
    assert pressure[2, col] == pytest.approx(1 - np.exp(-depth / DEPTH_SCALE), rel=0.05)
    palm = ~np.isnan(hand.cell_points[..., 0])
    palm[:13] = False
    assert np.all(pressure[palm] == 0.0)


def test_generated_episodes_read_cleanly_and_convert(small_dataset, tmp_path):
    out, _ = small_dataset
    episodes = find_raw_episodes(out)
    assert len(episodes) == 3
    layout = TactileLayout.default()
    for folder in episodes:
        with open_episode(folder) as ep:
            assert ep.problems == [] and ep.num_frames == 120
            assert ep.view_names == ("ego", "wrist_left", "wrist_right")
            assert (ep.views["ego"].width, ep.views["ego"].height) == (640, 480)
            wilor = ep.wilor.joints[ep.wilor.valid]
            assert wilor.size and np.abs(wilor[..., :2]).max() < 5 and 0 < wilor[..., 2].min() and wilor[..., 2].max() < 100
            assert ep.wilor.valid.mean() > 0.8
            grids = ep.pressure.grids
            assert np.all(np.isnan(grids[:, ~layout.valid])) and np.all(np.isfinite(grids[:, layout.valid]))
            assert ep.pressure.attrs["baseline_corrected_left"] and ep.pressure.attrs["baseline_corrected_right"]
            assert np.nanmax(grids) > 0.5  # something was touched
        assert convert_trajectory(folder, tmp_path / f"{folder.name}.hdf5").status == "converted"


def test_contact_visibility_is_lower_from_the_head_camera(small_dataset):
    _, card = small_dataset
    shares = {camera: v["share"] for camera, v in card["contact_visibility"].items()}
    assert card["contact_visibility"]["chest"]["contact_points"] > 100
    assert shares["chest"] < shares["left"] - 0.15 and shares["chest"] < shares["right"] - 0.15


def test_split_and_card(small_dataset):
    out, card = small_dataset
    split = json.loads((out / "split.json").read_text())
    listed = [p for key in split for p in split[key]]
    assert len(listed) == 3 and all(p.endswith(".hdf5") for p in listed)
    unseen = {e["path"] for e in card["episodes_list"] if set(e["objects"]) & set(card["unseen_objects"])}
    assert len(split["test_unseen"]) == len(unseen)
    assert (out / "dataset_card.md").read_text().startswith("# Simulated EgoTouch dataset")
    assert card["frames"] == 360 and sum(card["scenes"].values()) == 3
    written = json.loads((out / "dataset_card.json").read_text())
    for entry in written["episodes_list"]:  # relative to the dataset root: no machine paths
        assert not Path(entry["path"]).is_absolute() and (out / entry["path"] / "chest.mp4").is_file()
    assert str(out) not in (out / "dataset_card.json").read_text()


def test_convert_moves_the_split_into_the_hdf5_root(small_dataset, tmp_path, capsys):
    out, _ = small_dataset
    assert main(["convert", str(out), str(tmp_path / "h5"), "--compression-level", "1"]) == 0
    from touchanything.devices.episodes.dataset_split import read_split

    split = read_split(tmp_path / "h5" / "split.json")
    assert all(p.is_file() for key in split for p in split[key])


def test_dead_column_is_repaired_in_the_ground_truth(tmp_path):
    seed = next(s for s in range(100, 200) if _has_dead_column(s))
    stats = generate_episode(tmp_path, EpisodeSpec("Home", 1.0, seed, False, "dead"))
    with open_episode(stats.folder) as ep:
        layout = TactileLayout.default()
        dead = layout.sensor_index[1, :, stats.dead_column]
        assert np.all(ep.glove.raw[:, 1, dead[dead >= 0]] == 0)


def _has_dead_column(seed: int) -> bool:
    from touchanything.devices.sim.episode_generator import DEAD_COLUMN_PROBABILITY, plan

    rng = np.random.default_rng(seed)
    plan(EpisodeSpec("Home", 1.0, seed, False, "x"), rng)
    return rng.random() < DEAD_COLUMN_PROBABILITY


@pytest.mark.parametrize("argv, message", [
    (["--episodes", "0"], "--episodes must be at least 1"),
    (["--episodes", "2", "--seconds", "-3"], "--seconds must be 1–3600"),
    (["--episodes", "2", "--workers", "0"], "--workers must be at least 1"),
])
def test_simulate_bad_arguments(tmp_path, capsys, argv, message):
    assert main(["simulate", str(tmp_path / "out"), *argv]) == 2
    assert message in capsys.readouterr().err


def test_simulate_refuses_a_non_empty_output_and_an_unwritable_one(tmp_path, capsys):
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "keep.txt").write_text("precious")
    assert main(["simulate", str(tmp_path / "out"), "--episodes", "1"]) == 2
    assert "not empty" in capsys.readouterr().err and (tmp_path / "out" / "keep.txt").exists()
    (tmp_path / "file").write_text("x")
    assert main(["simulate", str(tmp_path / "file"), "--episodes", "1"]) == 2
    assert "not a folder" in capsys.readouterr().err
    assert main(["simulate", str(tmp_path / "file" / "sub"), "--episodes", "1"]) == 2  # parent is a file
    assert "cannot be created" in capsys.readouterr().err


def test_simulation_config_is_checked():
    with pytest.raises(UserError):
        simulate_dataset("unused", SimulationConfig(episodes=1, seconds=float("nan")))


def test_simulate_prints_its_final_progress_line_once(tmp_path, capsys):
    """In a log (stderr not a terminal) every bar update is one line: 100 % must appear once, not three times."""
    assert main(["simulate", str(tmp_path / "out"), "--episodes", "2", "--seconds", "1"]) == 0
    lines = capsys.readouterr().err.replace("\r", "\n").splitlines()
    assert sum("100%" in line for line in lines) == 1 and sum("2/2" in line for line in lines) == 1
