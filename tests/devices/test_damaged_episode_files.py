"""The episode readers on damaged files, one example each: JSON-lines lines merged, split or lost move no other
frame, a corrupted frame index moves nothing, out-of-range numbers are invalid values, damaged npz members, HDF5
chunks and video headers are named problems, an absurd frame rate in a video header reads at 30 fps, and a split
entry that is no path is one line."""
from __future__ import annotations

import json

import h5py
import numpy as np
import pytest

from touchanything.devices.episodes.episode_files import save_npz
from touchanything.devices.episodes.episode_loader import open_episode
from touchanything.devices.episodes.hdf5_convert import convert_trajectory
from touchanything.devices.episodes.raw_episode import GLOVE_FILE, GRIDS_FILE, ROKOKO_FILE, VIVE_FILE, WILOR_FILE


@pytest.mark.parametrize("how", ["join", "split", "drop", "drop_first", "join_last"])
def test_lines_merged_split_or_lost_keep_every_other_frame_in_place(episode_dir, how):
    from touchanything.devices.episodes.raw_episode import open_raw_episode

    path = episode_dir / ROKOKO_FILE
    with open_raw_episode(episode_dir) as ep:
        before = ep.rokoko.joints.copy()
    lines = path.read_text().splitlines(keepends=True)
    k = {"join": 10, "split": 10, "drop": 10, "drop_first": 0, "join_last": len(lines) - 2}[how]
    if how.startswith("join"):
        lines[k] = lines[k].rstrip("\n")
    elif how == "split":
        lines[k] = lines[k][:50] + "\n" + lines[k][50:]
    else:
        del lines[k]
    path.write_text("".join(lines))
    with open_raw_episode(episode_dir) as ep:
        touched = {k, k + 1}
        keep = [i for i in range(ep.num_frames) if i not in touched]
        np.testing.assert_array_equal(ep.rokoko.joints[keep], before[keep])
        assert any(f"{ROKOKO_FILE}: line" in p for p in ep.problems), ep.problems


def test_one_corrupted_frame_index_moves_nothing(episode_dir):
    from touchanything.devices.episodes.raw_episode import open_raw_episode

    path = episode_dir / WILOR_FILE
    with open_raw_episode(episode_dir) as ep:
        before = ep.wilor.joints.copy()
    lines = path.read_text().splitlines()
    for k, index in ((5, 9), (len(lines) - 1, 3)):
        row = json.loads(lines[k])
        row["frame_index"] = index
        lines[k] = json.dumps(row)
    path.write_text("\n".join(lines) + "\n")
    with open_raw_episode(episode_dir) as ep:
        np.testing.assert_array_equal(ep.wilor.joints, before)
        assert any("line 6: frame_index 9 disagrees with the line order (5); kept in line order" in p for p in ep.problems)


def test_numbers_beyond_float_range_are_invalid_values_not_a_crash(episode_dir):
    from touchanything.devices.episodes.raw_episode import open_raw_episode

    for name, edit in ((WILOR_FILE, lambda r: r["left_pos"][0].__setitem__(0, 10**400)),
                       (VIVE_FILE, lambda r: r["poses"]["chest"]["trans"].__setitem__(0, 10**400)),
                       (GLOVE_FILE, lambda r: r.__setitem__("timestamp_us", 2**70))):
        lines = (episode_dir / name).read_text().splitlines()
        row = json.loads(lines[2])
        edit(row)
        lines[2] = json.dumps(row)
        (episode_dir / name).write_text("\n".join(lines) + "\n")
    with open_raw_episode(episode_dir) as ep:
        assert not ep.wilor.valid[2, 0] and not ep.trackers.valid[2, 0] and ep.glove.timestamps_us is None
        for field in ("left_pos", "poses.chest", "timestamp_us"):
            assert any(f": {field}: " in p and "(line 3)" in p for p in ep.problems), (field, ep.problems)


def test_damaged_npz_members_and_scalars(episode_dir, tmp_path):
    from touchanything.core.errors import DataError
    from touchanything.devices.episodes.episode_files import read_pressure_grids

    path = episode_dir / GRIDS_FILE
    data = bytearray(path.read_bytes())
    directory = data.find(b"PK\x01\x02")  # the first member's compression method: 264, which zipfile does not know
    data[directory + 11] = 0x01
    (tmp_path / "bad.npz").write_bytes(bytes(data))
    with pytest.raises(DataError, match="not a readable .npz file"):
        read_pressure_grids(tmp_path / "bad.npz")
    with np.load(path) as npz:
        arrays = {k: npz[k] for k in npz.files}
    save_npz(path, {**arrays, "tactile_max_left": np.complex64(3 + 1j), "bend_max_right": np.zeros(3)})
    grids = read_pressure_grids(path)
    assert "tactile_max_left" not in grids.attrs and grids.attrs["tactile_max_right"] == arrays["tactile_max_right"]
    assert [p.split(": ")[1] for p in grids.problems] == ["tactile_max_left", "bend_max_right"]
    out = tmp_path / "e.hdf5"
    assert convert_trajectory(episode_dir, out).status == "converted"


def test_a_damaged_hdf5_chunk_is_a_named_problem_and_a_missing_frame(episode_dir, tmp_path):
    out = tmp_path / "e.hdf5"
    assert convert_trajectory(episode_dir, out).status == "converted"
    with h5py.File(out) as file:
        spans = {key: (file[key].id.get_chunk_info(3).byte_offset, file[key].id.get_chunk_info(3).size)
                 for key in ("pressure/left_pressure_grid", "images/left_color")}
    data = bytearray(out.read_bytes())
    for start, size in spans.values():
        data[start + size // 2: start + size // 2 + 8] = bytes(8)
    out.write_bytes(bytes(data))
    with open_episode(out) as ep:
        assert ep.pressure is None and any("pressure/left_pressure_grid: unreadable" in p for p in ep.problems)
        reader = ep.views["wrist_left"]
        assert reader.read(2) is not None and reader.read(3) is None and reader.read(4) is not None
        assert any("images/left_color: frame 3: unreadable" in p for p in ep.problems)


def test_a_video_with_a_damaged_header_is_unreadable_not_a_crash(episode_dir):
    from touchanything.devices.episodes.raw_episode import open_raw_episode

    path = episode_dir / "left.mp4"
    data = path.read_bytes()
    for eighth in range(1, 8):  # some cuts leave a stream without a picture size, which used to crash
        path.write_bytes(data[:len(data) * eighth // 64])
        with open_raw_episode(episode_dir) as ep:
            assert "wrist_left" not in ep.views
            assert any(p.startswith(f"{path}: ") and ("unreadable video" in p or "no video stream" in p) for p in ep.problems)


def test_a_video_whose_header_gives_an_absurd_frame_rate_reads_at_30_fps(episode_dir):
    """Found by the fuzzer: one flipped bit in the fragment header's default sample duration (512 → 33554944
    ticks of 1/15360 s) left an average rate of 30/65537 fps, and seeking divided by zero."""
    from touchanything.devices.episodes.video_io import VideoReader

    path = episode_dir / "left.mp4"
    with VideoReader(path) as reader:
        frames = list(reader.frames())
    data = bytearray(path.read_bytes())
    duration = data.find(b"tfhd") + 12  # "tfhd", version and flags, track id, then the default sample duration
    assert data[duration:duration + 4] == (512).to_bytes(4, "big")
    data[duration] ^= 2
    path.write_bytes(bytes(data))
    with VideoReader(path) as reader:
        assert reader._stream.average_rate < 1 and reader.fps == 30.0
        assert reader.read(0) is not None and len(list(reader.frames())) == len(frames)

@pytest.mark.parametrize("entry", ["", "x" * 300 + ".hdf5", "a\x00b.hdf5"])
def test_a_split_entry_that_is_no_path_is_one_line(tmp_path, entry):
    from touchanything.core.errors import DataError
    from touchanything.devices.episodes.dataset_split import read_split

    (tmp_path / "split.json").write_text(json.dumps({"train": ["a.hdf5"], "val": [], "test_seen": [entry]}))
    with pytest.raises(DataError, match=r"split.json: test_seen: entry 1 is not a usable file path"):
        read_split(tmp_path / "split.json")
