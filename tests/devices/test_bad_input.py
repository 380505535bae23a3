"""Every bad input gives a clear line naming the file and field, and the other streams are still read."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

from tests.conftest import frame_image
from touchanything.devices.episodes.episode_files import read_pressure_grids
from touchanything.devices.episodes.episode_loader import open_episode
from touchanything.devices.episodes.hdf5_convert import convert_trajectory
from touchanything.devices.episodes.raw_episode import open_raw_episode
from touchanything.devices.episodes.video_io import VideoWriter

ROOT = Path(__file__).resolve().parents[2]


def _lines(path):
    return path.read_text().splitlines()


@pytest.mark.parametrize("name", ["chest.mp4", "pressure_grids.npz", "wilor_hands.json", "jq_pressure.json"])
def test_missing_required_file_is_named_and_the_rest_is_read(episode_dir, name):
    (episode_dir / name).unlink()
    with open_raw_episode(episode_dir) as ep:
        assert any(name in p and "missing required file" in p for p in ep.problems)
        assert ep.num_frames == 40
        assert ep.wilor is not None or name == "wilor_hands.json"
        assert "wrist_left" in ep.views


def test_unreadable_video(episode_dir):
    (episode_dir / "left.mp4").write_bytes(b"\x00\x01garbage" * 100)
    with open_raw_episode(episode_dir) as ep:
        assert any(p.startswith(str(episode_dir / "left.mp4")) and "unreadable video" in p for p in ep.problems)
        assert ep.view_names == ("ego", "wrist_right") and ep.pressure is not None


def test_truncated_fragmented_video_keeps_its_complete_seconds(tmp_path, episode_dir):
    path = episode_dir / "chest.mp4"
    path.unlink()  # a writer never opens an existing file
    with VideoWriter(path) as writer:
        for i in range(120):
            writer.write(frame_image(0, i, (48, 64)))
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with open_raw_episode(episode_dir) as ep:
        reader = ep.views["ego"]
        frames = list(reader.frames())
        assert 30 <= len(frames) < 120
        assert ep.num_frames <= 40


def test_truncated_plain_mp4_is_unreadable(episode_dir):
    import av

    path = episode_dir / "right.mp4"
    with av.open(str(path), "w") as container:  # moov atom at the end, as ordinary writers do
        stream = container.add_stream("libx264", rate=30)
        stream.width, stream.height, stream.pix_fmt = 64, 48, "yuv420p"
        for i in range(40):
            for packet in stream.encode(av.VideoFrame.from_ndarray(frame_image(2, i, (48, 64)), format="rgb24")):
                container.mux(packet)
        for packet in stream.encode():
            container.mux(packet)
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with open_raw_episode(episode_dir) as ep:
        assert any("right.mp4" in p and "unreadable video" in p for p in ep.problems)


def test_broken_jsonl_line_is_named_and_later_frames_do_not_shift(episode_dir):
    path = episode_dir / "wilor_hands.json"
    lines = _lines(path)
    original = json.loads(lines[5])
    lines[4] = lines[4][:40]  # line 5 cut in the middle
    path.write_text("\n".join(lines) + "\n")
    with open_raw_episode(episode_dir) as ep:
        assert any("wilor_hands.json: line 5: invalid JSON" in p for p in ep.problems)
        assert not ep.wilor.valid[4].any()
        assert np.allclose(ep.wilor.joints[5, 0], np.array(original["left_pos"], np.float32))


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), 5000.0])
def test_absurd_poses_mark_the_hand_invalid(episode_dir, bad):
    path = episode_dir / "wilor_hands.json"
    lines = _lines(path)
    row = json.loads(lines[2])
    row["left_pos"][3][0] = bad
    lines[2] = json.dumps(row)
    path.write_text("\n".join(lines) + "\n")
    with open_raw_episode(episode_dir) as ep:
        assert not ep.wilor.valid[2, 0] and np.all(ep.wilor.joints[2, 0] == 0)
        assert any("left_pos" in p and "line 3" in p for p in ep.problems)


def test_pose_rows_with_wrong_joint_count(episode_dir):
    path = episode_dir / "wilor_hands.json"
    lines = _lines(path)
    row = json.loads(lines[0])
    row["right_pos"] = row["right_pos"][:20]
    lines[0] = json.dumps(row)
    path.write_text("\n".join(lines) + "\n")
    with open_raw_episode(episode_dir) as ep:
        assert not ep.wilor.valid[0, 1] and ep.wilor.valid[0, 0]


def _grids(left: tuple, right: tuple | None, left_dtype=np.float32) -> dict[str, np.ndarray]:
    arrays = {"left_pressure_grid": np.zeros(left, left_dtype)}
    return arrays | ({"right_pressure_grid": np.zeros(right, np.float32)} if right else {})


@pytest.mark.parametrize("arrays, field", [
    (_grids((40, 21, 20), (40, 21, 21)), "left_pressure_grid"),
    (_grids((40, 21, 21), (40, 21, 21), np.int32), "left_pressure_grid"),
    (_grids((40, 21, 21), None), "right_pressure_grid"),
    (_grids((40, 21, 21), (39, 21, 21)), "right_pressure_grid"),
])
def test_pressure_npz_of_wrong_shape_or_dtype(episode_dir, arrays, field):
    np.savez(episode_dir / "pressure_grids.npz", **arrays)
    with open_raw_episode(episode_dir) as ep:
        assert ep.pressure is None
        assert any(f"pressure_grids.npz: {field}:" in p for p in ep.problems)
        assert ep.wilor is not None and len(ep.views) == 3


def test_corrupt_npz(episode_dir):
    (episode_dir / "pressure_grids.npz").write_bytes(b"PK\x03\x04 not really")
    with pytest.raises(Exception) as err:
        read_pressure_grids(episode_dir / "pressure_grids.npz")
    assert "not a readable .npz file" in str(err.value)


def test_frame_count_mismatch_aligns_to_the_shortest_and_reports(episode_dir):
    with np.load(episode_dir / "pressure_grids.npz") as data:
        arrays = {k: data[k] for k in data.files}
    arrays["left_pressure_grid"] = arrays["left_pressure_grid"][:30]
    arrays["right_pressure_grid"] = arrays["right_pressure_grid"][:30]
    np.savez(episode_dir / "pressure_grids.npz", **arrays)
    path = episode_dir / "rokoko_hands.json"
    path.write_text("\n".join(_lines(path)[:12]) + "\n")
    with open_raw_episode(episode_dir) as ep:
        assert ep.num_frames == 30
        note = next(p for p in ep.problems if "frame counts differ" in p)
        assert "pressure_grids.npz 30" in note and "rokoko_hands.json 12" in note and "aligned to 30" in note
        assert ep.rokoko.valid[:12].all() and not ep.rokoko.valid[12:].any() and len(ep.rokoko.valid) == 30
        assert len(ep.wilor.valid) == 30


def test_hdf5_with_wrong_dataset_shape(episode_dir, tmp_path):
    out = tmp_path / "e.hdf5"
    assert convert_trajectory(episode_dir, out).status == "converted"
    with h5py.File(out, "a") as f:
        del f["pressure/left_pressure_grid"]
        f.create_dataset("pressure/left_pressure_grid", data=np.zeros((40, 16, 16), np.float32))
        del f["hands/wilor_right_valid"]
    with open_episode(out) as ep:
        assert ep.pressure is None and ep.wilor is None and len(ep.views) == 3
        assert any("pressure/left_pressure_grid: has shape (40, 16, 16)" in p for p in ep.problems)
        assert any("hands/wilor_right_valid: missing dataset" in p for p in ep.problems)


def test_not_an_hdf5_file(tmp_path):
    (tmp_path / "x.hdf5").write_text("hello")
    from touchanything.core.errors import DataError

    with pytest.raises(DataError, match="not a readable HDF5 file"):
        open_episode(tmp_path / "x.hdf5")


@pytest.mark.parametrize("make", ["missing", "garbage_hdf5", "not_episode"])
def test_cli_prints_one_line_without_traceback(tmp_path, make):
    path = {"missing": tmp_path / "nope", "garbage_hdf5": tmp_path / "x.hdf5", "not_episode": tmp_path / "t.txt"}[make]
    if make != "missing":
        path.write_text("junk")
    proc = subprocess.run([sys.executable, "-m", "touchanything.app.cli", "info", str(path)], capture_output=True, text=True)
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr and len(proc.stderr.strip().splitlines()) == 1
    assert str(path) in proc.stderr


def test_a_checkpoint_in_another_pickle_protocol_is_one_line_without_library_warnings(tmp_path, episode_dir):
    import pickle

    checkpoint = tmp_path / "best_model.pth"
    checkpoint.write_bytes(pickle.dumps({"model_state_dict": {"w": 1}}, protocol=5))
    proc = subprocess.run([sys.executable, "-m", "touchanything.app.cli", "replay", str(episode_dir), "--headless",
                           "--checkpoint", str(checkpoint), "--config", str(ROOT / "models" / "nano" / "config.yaml")],
                          capture_output=True, text=True)
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [f"touchanything replay: error: {checkpoint}: not a readable PyTorch "
                                                "checkpoint (UnpicklingError)"]


def test_a_data_error_crosses_a_process_boundary_whole():
    """A worker process of a batch (simulate, convert with --workers) raises DataError to its parent by pickle."""
    import pickle

    from touchanything.core.errors import DataError

    again = pickle.loads(pickle.dumps(DataError("episode/left.h5", "pressure", "holds NaN")))
    assert isinstance(again, DataError) and str(again) == "episode/left.h5: pressure: holds NaN"
    assert (again.path, again.field, again.problem) == (Path("episode/left.h5"), "pressure", "holds NaN")
