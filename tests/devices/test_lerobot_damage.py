"""`export-lerobot` says the damage it exports, one line per episode, and the dataset records which
pictures stand in for frames the source did not decode (`observation.views_valid`). Real episode folders, a real
video damaged on disk, real JSON-lines streams with broken lines and NaN poses, the real command line."""
from __future__ import annotations

import json
from pathlib import Path

import av
import numpy as np
import pyarrow.parquet as pq
import pytest

from conftest import write_episode
from touchanything.app.cli import main
from touchanything.core.errors import DataError
from touchanything.devices.episodes import lerobot_format as fmt
from touchanything.devices.episodes.episode_loader import open_episode
from touchanything.devices.episodes.lerobot_export import export_lerobot


def zero_packets_from(video: Path, first: int) -> int:
    """Overwrite the coded bytes of every packet from `first` on with zeros, in place (the container's index stays
    whole, so the file still holds all its packets, but they no longer decode); the frames that still decode."""
    data = bytearray(video.read_bytes())
    with av.open(str(video)) as container:
        packets = [(p.pos, p.size) for p in container.demux(container.streams.video[0]) if p.size]
    for pos, size in packets[first:]:
        data[pos:pos + size] = bytes(size)
    video.write_bytes(bytes(data))
    decoded = 0
    with av.open(str(video)) as container:
        try:
            for _ in container.decode(video=0):
                decoded += 1
        except av.error.FFmpegError:
            pass
    return decoded


def views_valid(out: Path, episode: int) -> np.ndarray:
    """(frames, views) of `observation.views_valid` for `episode`, read with pyarrow."""
    table = pq.read_table(out / "data" / "chunk-000" / "file-000.parquet")
    rows = np.array(table["episode_index"].to_pylist()) == episode
    return np.array(table[fmt.VIEWS_VALID].to_pylist())[rows]


def test_a_left_video_that_stops_decoding_is_named_and_its_filled_frames_marked(tmp_path, capsys):
    root = tmp_path / "raw"
    episode = write_episode(root / "Home" / "pick_up_bottle" / "001", frames=60, seed=1)
    decoded = zero_packets_from(episode / "left.mp4", 12)
    assert 0 < decoded <= 12
    out = tmp_path / "lerobot"
    assert main(["export-lerobot", str(root), str(out)]) == 0
    printed = capsys.readouterr().out
    filled = 60 - decoded
    assert f"damaged   {episode}: wrist_left: {filled} of 60 frames do not decode (written black, 0.0 in " \
           f"observation.views_valid)" in printed
    assert "exported  1 episodes, 60 frames" in printed and "skipped" not in printed
    info = json.loads((out / "meta" / "info.json").read_text())
    assert info["features"][fmt.VIEWS_VALID] | {"info": None} == {
        "dtype": "float32", "shape": [3], "names": ["ego", "wrist_left", "wrist_right"], "info": None}
    valid = views_valid(out, 0)
    assert valid.shape == (60, 3) and valid[:, [0, 2]].all()
    assert np.flatnonzero(valid[:, 1] == 0).tolist() == list(range(decoded, 60))  # exactly the filled frames
    stats = json.loads((out / "meta" / "stats.json").read_text())[fmt.VIEWS_VALID]
    assert stats["min"] == [1.0, 0.0, 1.0] and stats["count"] == [60]
    with open_episode(out / "episode_000000") as back:  # the project's reader: filled frames are missing frames
        assert back.views["wrist_left"].read(decoded - 1) is not None and back.views["wrist_left"].read(decoded) is None
        assert any(f"wrist_left: {filled} of 60 frames did not decode in the source" in p for p in back.problems)


def test_the_progress_counts_episode_frames_not_frames_times_views(tmp_path):
    root = tmp_path / "raw"
    write_episode(root / "Home" / "pick" / "001", frames=7, seed=1)
    write_episode(root / "Home" / "pick" / "002", frames=5, seed=2)
    calls: list[tuple[int, int]] = []
    export_lerobot(root, tmp_path / "lerobot", on_frames=lambda written, total: calls.append((written, total)))
    assert calls == [(n, 12) for n in range(1, 13)]


def test_malformed_lines_and_nan_poses_are_named_per_stream(tmp_path, capsys):
    root = tmp_path / "raw"
    episode = write_episode(root / "Home" / "pick_up_bottle" / "001", frames=20, seed=1)
    hands = (episode / "wilor_hands.json").read_text().splitlines()
    hands[4], hands[8] = hands[4][:30], "{broken"
    (episode / "wilor_hands.json").write_text("\n".join(hands) + "\n")
    poses = [json.loads(line) for line in (episode / "vive_poses.json").read_text().splitlines()]
    for row in poses[6:9]:
        row["poses"]["chest"]["trans"] = [float("nan"), 0.0, 0.0]  # written as NaN, which JSON readers take
    (episode / "vive_poses.json").write_text("".join(json.dumps(row) + "\n" for row in poses))
    out = tmp_path / "lerobot"
    assert main(["export-lerobot", str(root), str(out)]) == 0
    damaged = [line for line in capsys.readouterr().out.splitlines() if line.startswith("damaged")]
    assert len(damaged) == 1 and damaged[0].startswith(f"damaged   {episode}: wilor_hands.json (2 problems): line 5: invalid JSON")
    assert " / line 9: invalid JSON" in damaged[0]
    assert "| vive_poses.json: poses.chest: expected trans[3] and rot[4] finite numbers" in damaged[0]
    assert "(3 lines, first line 7)" in damaged[0] and "do not decode" not in damaged[0]
    table = pq.read_table(out / "data" / "chunk-000" / "file-000.parquet")  # what was dropped is flagged, not made up
    trackers_valid = np.array(table[fmt.TRACKERS_VALID].to_pylist())
    assert not trackers_valid[6:9, 0].any() and trackers_valid[[5, 9], 0].all()
    seen = np.array(table[fmt.STATE].to_pylist())[:, -2:]
    assert not seen[[4, 8]].any()


def test_an_empty_episode_folder_is_named_and_the_others_exported(tmp_path, capsys):
    root = tmp_path / "raw"
    write_episode(root / "Home" / "pick_up_bottle" / "001", frames=6, seed=1)
    (root / "Home" / "pick_up_bottle" / "002").mkdir()
    out = tmp_path / "lerobot"
    assert main(["export-lerobot", str(root), str(out)]) == 1
    printed = capsys.readouterr().out
    assert f"skipped   {root / 'Home' / 'pick_up_bottle' / '002'}: an empty folder (no episode files)" in printed
    assert "exported  1 episodes, 6 frames" in printed and "damaged" not in printed
    assert json.loads((out / "meta" / "info.json").read_text())["total_episodes"] == 1


def test_views_valid_names_that_do_not_fit_its_values_are_one_line(tmp_path):
    root = tmp_path / "raw"
    write_episode(root / "Home" / "pick" / "001", frames=4, seed=1)
    out = tmp_path / "lerobot"
    export_lerobot(root, out)
    info = json.loads((out / "meta" / "info.json").read_text())
    info["features"][fmt.VIEWS_VALID]["names"] = ["ego", "wrist_left"]
    (out / "meta" / "info.json").write_text(json.dumps(info))
    with pytest.raises(DataError, match="observation.views_valid names: 2 names for another number of values"):
        open_episode(out / "episode_000000")
