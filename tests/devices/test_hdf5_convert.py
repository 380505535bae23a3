"""Raw → HDF5 conversion in the official schema, reading it back, reports, and split.json."""
from __future__ import annotations

import json

import h5py
import numpy as np
import pytest

from tests.conftest import write_episode
from touchanything.core.errors import DataError, UserError
from touchanything.devices.episodes.dataset_conversion import convert_dataset, duplicate_frames
from touchanything.devices.episodes.dataset_split import SplitConfig, build_split, read_split, write_split
from touchanything.devices.episodes.episode_loader import open_episode
from touchanything.devices.episodes.hdf5_convert import convert_trajectory

OFFICIAL_DATASETS = {
    "timestamps": ((), np.int64),
    "images/chest_color": ((48, 64, 3), np.uint8), "images/left_color": ((48, 64, 3), np.uint8),
    "images/right_color": ((48, 64, 3), np.uint8),
    "poses/chest_pose": ((7,), np.float32), "poses/left_pose": ((7,), np.float32), "poses/right_pose": ((7,), np.float32),
    "hands/left_joint_xyz": ((21, 3), np.float32), "hands/right_joint_xyz": ((21, 3), np.float32),
    "hands/wilor_left_joint_xyz": ((21, 3), np.float32), "hands/wilor_right_joint_xyz": ((21, 3), np.float32),
    "hands/wilor_left_valid": ((), np.uint8), "hands/wilor_right_valid": ((), np.uint8),
    "pressure/left_pressure_grid": ((21, 21), np.float32), "pressure/right_pressure_grid": ((21, 21), np.float32),
    "masks/glove_masks": ((0, 48, 64), np.uint8), "masks/glove_obj_ids": ((0,), np.int32),
    "masks/glove_valid_frames": ((), np.bool_),
}


def test_converted_file_has_the_official_schema_and_equals_the_raw_episode(episode_dir, tmp_path):
    out = tmp_path / "out.hdf5"
    result = convert_trajectory(episode_dir, out, compression_level=4)
    assert result.status == "converted", result.error
    with h5py.File(out) as f:
        for key, (tail, dtype) in OFFICIAL_DATASETS.items():
            assert f[key].shape == (40,) + tail and f[key].dtype == dtype, key
        meta = f["metadata"].attrs
        assert meta["trajectory_id"] == "20260319_211038_740" and meta["task_name"] == "pick_up_bottle"
        assert meta["num_frames"] == 40 and meta["fps"] == 30 and list(meta["camera_resolution"]) == [48, 64]
        assert meta["right_wrist_has_issue"] and not meta["left_wrist_has_issue"]
        assert f["hands"].attrs["wilor_available"] and f["pressure"].attrs["separate_normalization"]
        assert f["pressure"].attrs["normalized"] and "tactile_max_left" in f["pressure"].attrs
        assert f["images/chest_color"].compression == "gzip"
    raw, hdf5 = open_episode(episode_dir), open_episode(out)
    with raw, hdf5:
        assert hdf5.num_frames == raw.num_frames and hdf5.problems == []
        assert np.array_equal(hdf5.timestamps_us, raw.timestamps_us)
        assert np.array_equal(hdf5.pressure.grids, raw.pressure.grids, equal_nan=True)
        assert np.array_equal(hdf5.wilor.valid, raw.wilor.valid) and np.array_equal(hdf5.wilor.joints, raw.wilor.joints)
        assert np.array_equal(hdf5.rokoko.joints, raw.rokoko.joints)
        assert np.array_equal(hdf5.trackers.poses, raw.trackers.poses)
        for view in raw.view_names:
            for i in (0, 13, 39):
                assert np.array_equal(hdf5.views[view].read(i), raw.views[view].read(i))


@pytest.mark.multiprocess
def test_dataset_conversion_with_workers_reports_and_skip_existing(tmp_path):
    raw_root = tmp_path / "raw"
    for i, name in enumerate(("Home/a/1", "Home/b/2", "Office/c/3")):
        write_episode(raw_root / name, frames=16, size=(16, 16), seed=i)
    broken = raw_root / "Office" / "c" / "4"
    write_episode(broken, frames=16, size=(16, 16))
    (broken / "wilor_hands.json").unlink()
    results = convert_dataset(raw_root, tmp_path / "h5", workers=2, compression_level=1)
    status = {r.source.name: r.status for r in results}
    assert status == {"1": "converted", "2": "converted", "3": "converted", "4": "failed"}
    failed = next(r for r in results if r.status == "failed")
    assert "wilor_hands.json" in failed.error
    assert (tmp_path / "h5" / "Home" / "a" / "1.hdf5").is_file()
    assert not list((tmp_path / "h5").rglob("*.partial*"))
    report = (tmp_path / "h5" / "conversion_report.txt").read_text()
    assert report.startswith("converted 3, skipped 0, failed 1") and "frames/s" in report
    assert "wilor valid" in (tmp_path / "h5" / "quality_report.txt").read_text()
    again = convert_dataset(raw_root, tmp_path / "h5", skip_existing=True)
    assert sorted(r.status for r in again) == ["failed", "skipped", "skipped", "skipped"]


def test_conversion_never_leaves_a_partial_file(episode_dir, tmp_path):
    (episode_dir / "left.mp4").write_bytes(b"garbage" * 50)
    result = convert_trajectory(episode_dir, tmp_path / "x.hdf5")
    assert result.status == "failed" and "unreadable left.mp4" in result.error
    assert sorted(tmp_path.iterdir()) == [tmp_path / "raw"]  # neither the trajectory nor a temporary file


def test_split_json_is_carried_over_listing_only_the_trajectories_written(tmp_path):
    raw, out = tmp_path / "raw", tmp_path / "h5"
    for seed, name in enumerate(("Home/a/1", "Home/b/2")):
        write_episode(raw / name, frames=8, size=(16, 16), seed=seed)
    listed = {"train": ["Home/a/1.hdf5", "Home/b/2.hdf5"], "val": ["Office/gone/9.hdf5"], "test_seen": [], "test_unseen": []}
    (raw / "split.json").write_text(json.dumps(listed))
    wilor = raw / "Home" / "b" / "2" / "wilor_hands.json"
    wilor.rename(tmp_path / "wilor_hands.json")  # trajectory 2 fails
    notes = []
    assert [r.status for r in convert_dataset(raw, out, on_note=notes.append)] == ["converted", "failed"]
    assert notes == [f"{raw / 'split.json'}: 2 listed trajectory(ies) not in {out} (failed or not found), the first "
                     f"Home/b/2.hdf5; {out / 'split.json'} lists the other 1"]
    assert notes[0] in (out / "conversion_report.txt").read_text()
    assert read_split(out / "split.json") == {"train": [out / "Home/a/1.hdf5"], "val": [], "test_seen": [], "test_unseen": []}
    (tmp_path / "wilor_hands.json").rename(wilor)
    assert [r.status for r in convert_dataset(raw, out, skip_existing=True)] == ["skipped", "converted"]
    assert read_split(out / "split.json")["train"] == [out / "Home/a/1.hdf5", out / "Home/b/2.hdf5"]  # its earlier copy replaced
    mine = {"train": ["Home/b/2.hdf5"], "val": ["Home/a/1.hdf5"], "test_seen": [], "test_unseen": []}
    (out / "split.json").write_text(json.dumps(mine))  # not a copy of RAW's: kept
    convert_dataset(raw, out, skip_existing=True)
    assert json.loads((out / "split.json").read_text()) == mine
    wilor.unlink()
    (raw / "Home" / "a" / "1" / "wilor_hands.json").unlink()
    notes.clear()
    assert {r.status for r in convert_dataset(raw, tmp_path / "none", on_note=notes.append)} == {"failed"}
    assert not (tmp_path / "none" / "split.json").exists() and notes[0].endswith("; split.json not written (it would list none)")


@pytest.mark.parametrize("kwargs, message", [
    ({"workers": 0}, "--workers"), ({"compression_level": 12}, "--compression-level"),
])
def test_dataset_conversion_bad_options(tmp_path, kwargs, message):
    write_episode(tmp_path / "raw" / "S" / "t" / "1", frames=3, size=(16, 16))
    with pytest.raises(UserError, match=message):
        convert_dataset(tmp_path / "raw", tmp_path / "out", **kwargs)


def test_dataset_conversion_needs_trajectories(tmp_path):
    with pytest.raises(UserError, match="no trajectories found"):
        convert_dataset(tmp_path, tmp_path / "out")
    with pytest.raises(UserError, match="not found"):
        convert_dataset(tmp_path / "nope", tmp_path / "out")


def _fake_hdf5(path, frames=40, valid_ratio=1.0):
    path.parent.mkdir(parents=True, exist_ok=True)
    with h5py.File(path, "w") as f:
        f.create_group("metadata").attrs["num_frames"] = frames
        n_valid = int(frames * valid_ratio)
        for side in ("left", "right"):
            f.create_dataset(f"hands/wilor_{side}_valid", data=(np.arange(frames) < n_valid).astype(np.uint8))


def test_split_follows_the_official_algorithm_and_is_seeded(tmp_path):
    root = tmp_path / "h5"
    for scene in ("Home", "Office"):
        for task in ("t1", "t2", "t3"):
            for k in range(5):
                _fake_hdf5(root / scene / task / f"{k}.hdf5")
    _fake_hdf5(root / "Home" / "t1" / "short.hdf5", frames=10)
    _fake_hdf5(root / "Home" / "t1" / "noisy.hdf5", valid_ratio=0.2)
    split, excluded = build_split(root)
    assert set(p.name for p in excluded) == {"short.hdf5", "noisy.hdf5"}
    unseen_tasks = {(p.parent.parent.name, p.parent.name) for p in split["test_unseen"]}
    assert len(unseen_tasks) == 2 and {s for s, _ in unseen_tasks} == {"Home", "Office"}
    assert len(split["test_unseen"]) == 10
    assert (len(split["test_seen"]), len(split["val"]), len(split["train"])) == (2, 2, 16)
    every = [p for key in split for p in split[key]]
    assert len(every) == len(set(every)) == 30
    assert build_split(root)[0] == split
    assert build_split(root, SplitConfig(seed=7))[0] != split


def test_split_file_paths_relative_or_absolute(tmp_path):
    target = tmp_path / "h5" / "S" / "t" / "1.hdf5"
    split = {"train": [target], "val": [], "test_seen": [], "test_unseen": []}
    write_split(tmp_path / "h5" / "split.json", split)
    assert json.loads((tmp_path / "h5" / "split.json").read_text())["train"] == ["S/t/1.hdf5"]
    assert read_split(tmp_path / "h5" / "split.json")["train"] == [tmp_path / "h5" / "S" / "t" / "1.hdf5"]
    write_split(tmp_path / "abs.json", split, absolute=True)
    assert read_split(tmp_path / "abs.json")["train"] == [target.resolve()]


@pytest.mark.parametrize("content, message", [
    ("[]", "expected an object"), ('{"train": "a.hdf5"}', "train: expected a list"), ("{", "not a readable JSON"),
])
def test_bad_split_files(tmp_path, content, message):
    (tmp_path / "split.json").write_text(content)
    with pytest.raises(DataError, match=message):
        read_split(tmp_path / "split.json")


def test_the_quality_report_says_what_was_not_measured():
    assert duplicate_frames(-1, -1) == "duplicate wrist frames not measured (no quality_issues.json)"
    assert duplicate_frames(0.01, -1) == "duplicate wrist frames left 1.0%, right not measured"
    assert duplicate_frames(0.0, 0.305) == "duplicate wrist frames left 0.0%, right 30.5%"
