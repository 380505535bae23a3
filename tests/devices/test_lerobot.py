"""LeRobot datasets: `export-lerobot` writes the v3.0 format, `open_episode` (and so replay, info, eval) reads it
back and the community EgoTouch layout (v2.0, [right, left], ego only); the round trip of the bundled sample."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import av
import numpy as np
import pyarrow.parquet as pq
import pytest
from rerun.chunk import RrdReader

from conftest import write_episode
from helpers.lerobot_community import write_community_dataset
from touchanything.app.cli import main
from touchanything.core.errors import DataError
from touchanything.core.tactile_layout import TactileLayout
from touchanything.devices.episodes.episode_loader import open_episode
from touchanything.devices.rig.replay import ReplayConfig, ReplaySource

SAMPLE = Path(__file__).resolve().parents[2] / "recordings" / "sample"
NANO = Path(__file__).resolve().parents[2] / "models" / "nano" / "best_model.pth"


@pytest.fixture
def two_episodes(tmp_path: Path) -> Path:
    root = tmp_path / "raw"
    write_episode(root / "Home" / "pick_up_bottle" / "001", frames=12, seed=1)
    write_episode(root / "Office" / "press_button" / "002", frames=9, seed=2)
    return root


def _same_episode(a, b, frames: list[int]) -> None:
    assert (a.num_frames, a.fps, a.scene, a.task, a.trajectory_id) == (b.num_frames, b.fps, b.scene, b.task, b.trajectory_id)
    assert np.array_equal(a.timestamps_us, b.timestamps_us) and a.view_names == b.view_names
    np.testing.assert_array_equal(a.pressure.grids, b.pressure.grids)  # NaN where NaN, float32 exact
    assert a.pressure.attrs == b.pressure.attrs
    np.testing.assert_array_equal(a.wilor.joints, b.wilor.joints)
    np.testing.assert_array_equal(a.wilor.valid, b.wilor.valid)
    np.testing.assert_array_equal(a.trackers.poses, b.trackers.poses)
    for view in a.view_names:
        for i in frames:
            diff = np.abs(a.views[view].read(i).astype(int) - b.views[view].read(i).astype(int))
            assert diff.mean() < 4 and b.views[view].read(i).shape == a.views[view].read(i).shape, (view, i)


def test_export_writes_the_v3_format(two_episodes, tmp_path, capsys):
    out = tmp_path / "lerobot"
    assert main(["export-lerobot", str(two_episodes), str(out)]) == 0
    assert "exported  2 episodes, 21 frames" in capsys.readouterr().out
    info = json.loads((out / "meta" / "info.json").read_text())
    assert info["codebase_version"] == "v3.0" and info["fps"] == 30 and info["total_frames"] == 21
    assert info["features"]["observation.tactile"]["shape"] == [434]  # 217 sensor cells per hand (official layout)
    assert info["features"]["observation.images.wrist_left"]["shape"] == [48, 64, 3]
    data = pq.read_table(out / "data" / "chunk-000" / "file-000.parquet")
    hf = json.loads(data.schema.metadata[b"huggingface"])["info"]["features"]
    assert hf["observation.tactile"] == {"feature": {"dtype": "float32", "_type": "Value"}, "length": 434, "_type": "List"}
    assert hf["observation.tactile_valid"]["_type"] == "List" and hf["timestamp"]["_type"] == "Value"
    assert data["index"].to_pylist() == list(range(21)) and data["episode_index"].to_pylist() == [0] * 12 + [1] * 9
    assert np.allclose(data["timestamp"].to_numpy()[12:], np.arange(9) / 30)
    episodes = pq.read_table(out / "meta" / "episodes" / "chunk-000" / "file-000.parquet").to_pylist()
    assert [(e["dataset_from_index"], e["dataset_to_index"]) for e in episodes] == [(0, 12), (12, 21)]
    key = "videos/observation.images.ego"
    assert [(e[f"{key}/from_timestamp"], e[f"{key}/to_timestamp"]) for e in episodes] == [(0.0, 12 / 30), (12 / 30, 21 / 30)]
    assert episodes[1]["tasks"] == ["press button"] and len(episodes[1]["stats/observation.tactile/q50"]) == 434
    assert [e["source"] for e in episodes] == ["Home/pick_up_bottle/001", "Office/press_button/002"]  # no local path
    with av.open(str(out / "videos" / "observation.images.ego" / "chunk-000" / "file-000.mp4")) as video:
        stamps = [float(frame.pts * frame.time_base) for frame in video.decode(video.streams.video[0])]
    assert np.allclose(stamps, np.arange(21) / 30, atol=1e-6)  # LeRobot finds frames by time, within 1e-4 s
    tasks = pq.read_table(out / "meta" / "tasks.parquet")
    assert tasks["task"].to_pylist() == ["pick up bottle", "press button"]
    assert json.loads(tasks.schema.metadata[b"pandas"])["index_columns"] == ["task"]  # pandas reads the text as index
    stats = json.loads((out / "meta" / "stats.json").read_text())
    assert np.array(stats["observation.images.ego"]["mean"]).shape == (3, 1, 1) and stats["index"]["count"] == [21]
    assert np.array(stats["observation.tactile"]["max"]).shape == (434,) and np.array(stats["observation.state"]["q99"]).shape == (128,)


def test_rerun_s_lerobot_importer_opens_the_export(two_episodes, tmp_path):
    """Rerun's importer (crates/store/re_lerobot) reads `names` as None, a string, a flat or nested list, or a map
    with exactly one entry, and rejects the whole dataset otherwise; the rerun CLI beside this Python imports it."""
    import socket
    import subprocess
    import sys

    out = tmp_path / "lerobot"
    assert main(["export-lerobot", str(two_episodes), str(out)]) == 0
    features = json.loads((out / "meta" / "info.json").read_text())["features"]
    for name, feature in features.items():
        names = feature["names"]
        assert names is None or isinstance(names, (str, list)) or (isinstance(names, dict) and len(names) == 1), name
    recording = tmp_path / "x.rrd"
    with socket.socket() as probe:  # its viewer server's port: one the OS has just given out (with `--port auto`, two
        probe.bind(("127.0.0.1", 0))  # runs started together both saw 9876 free, and one failed to bind it)
        port = probe.getsockname()[1]
    proc = subprocess.run([str(Path(sys.executable).parent / "rerun"), str(out), "--save", str(recording), "--port", str(port)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0 and "Failed to import" not in proc.stderr, proc.stderr[-2000:]
    scalars, names = {}, {}
    reader = RrdReader(recording)
    first = next(store for store in reader.recordings() if store.recording_id == "episode_0")  # one per episode
    for chunk in reader.stream(store=first):
        batch = chunk.to_record_batch()
        if "Scalars:scalars" in batch.schema.names:
            scalars.setdefault(chunk.entity_path, {}).update(zip(batch.column("frame_index").to_pylist(),
                                                                 batch.column("Scalars:scalars").to_pylist()))
        elif "SeriesLines:names" in batch.schema.names:
            names[chunk.entity_path] = batch.column("SeriesLines:names").to_pylist()[0]
    assert set(scalars) == {"/observation.state", "/observation.tactile", "/observation.trackers", "/observation.tactile_valid",
                            "/observation.trackers_valid", "/observation.views_valid"}
    # the pressure as labelled values: the right glove's cell (row 10, column 10) at frame 5 of the first episode
    cell = names["/observation.tactile"].index("right.r10c10")
    with open_episode(sorted(two_episodes.glob("*/*/*"))[0]) as raw:
        assert scalars["/observation.tactile"][5][cell] == pytest.approx(float(raw.pressure.grids[5, 1, 10, 10]), abs=1e-6)
        joint = names["/observation.state"].index("left.index_4.z")  # joint 8 (index tip), z
        assert scalars["/observation.state"][5][joint] == pytest.approx(float(raw.wilor.joints[5, 0, 8, 2]), abs=1e-5)
    assert names["/observation.trackers"][:4] == ["chest.x", "chest.y", "chest.z", "chest.qw"]
    assert names["/observation.views_valid"] == ["ego", "wrist_left", "wrist_right"]


def test_the_export_reads_back_as_the_same_episodes(two_episodes, tmp_path, capsys):
    out = tmp_path / "lerobot"
    assert main(["export-lerobot", str(two_episodes), str(out)]) == 0
    for index, source in enumerate(sorted(two_episodes.glob("*/*/*"))):
        with open_episode(source) as raw, open_episode(out / f"episode_{index:06d}") as back:
            _same_episode(raw, back, [0, raw.num_frames - 1])
            assert back.problems == []
    assert main(["info", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "2 LeRobot episode(s)" in printed and "episode_000001: 9 frames" in printed
    with pytest.raises(DataError, match="a LeRobot dataset of 2 episodes; open one as"):
        open_episode(out)
    with pytest.raises(DataError, match="no such episode"):
        open_episode(out / "episode_000002")


def test_export_refuses_what_would_lose_or_mix_data(two_episodes, tmp_path, capsys):
    out = tmp_path / "lerobot"
    out.mkdir()
    (out / "keep").write_text("mine")
    cases = [([str(two_episodes), str(out)], "not empty; pass --overwrite"),
             ([str(two_episodes), str(two_episodes / "inside")], "would lie inside the input"),
             ([str(tmp_path / "none"), str(tmp_path / "x")], "not found"),
             ([str(tmp_path / "lerobot"), str(tmp_path / "y")], "no episodes found")]
    for args, message in cases:
        assert main(["export-lerobot", *args]) == 2
        error = capsys.readouterr().err
        assert message in error and len(error.strip().splitlines()) == 1
    assert (out / "keep").read_text() == "mine" and not (two_episodes / "inside").exists()
    assert main(["export-lerobot", str(two_episodes), str(out), "--overwrite"]) == 0
    assert not (out / "keep").exists() and (out / "meta" / "info.json").is_file()
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []  # no temporary folder left


def test_an_episode_that_does_not_fit_is_left_out_and_said(two_episodes, tmp_path, capsys):
    write_episode(two_episodes / "Home" / "pick_up_bottle" / "003", frames=5, size=(32, 48), seed=3)
    assert main(["export-lerobot", str(two_episodes), str(tmp_path / "out")]) == 1
    printed = capsys.readouterr().out
    assert "exported  2 episodes" in printed and "skipped   " in printed and "003" in printed


def test_the_community_layout_reads_in_the_official_hand_order(tmp_path, capsys):
    rng = np.random.default_rng(0)
    layout = TactileLayout.default()
    grids = [np.where(layout.valid, rng.random((t, 2, 21, 21)), np.nan).astype(np.float32) for t in (10, 7)]
    images = [np.stack([np.full((32, 48, 3), 20 * i, np.uint8) for i in range(len(g))]) for g in grids]
    root = write_community_dataset(tmp_path / "community", grids, images)
    with open_episode(root / "episode_000001") as episode:
        assert episode.view_names == ("ego",) and episode.num_frames == 7 and episode.wilor is None
        np.testing.assert_array_equal(episode.pressure.grids, grids[1])  # [right, left] on disk, [left, right] here
        assert np.abs(episode.views["ego"].read(3).astype(int) - 60).max() <= 2
        assert episode.task == "touch things" and np.array_equal(episode.timestamps_us, np.round(np.arange(7) / 30 * 1e6))
        assert any("no hand order in its names; read as [right, left]" in p for p in episode.problems)
    source = ReplaySource(open_episode(root / "episode_000000"), ReplayConfig(speed=None))
    snapshots = list(source)
    assert len(snapshots) == 10 and np.array_equal(snapshots[4].pressure_grid, grids[0][4], equal_nan=True)
    assert main(["info", str(root)]) == 0 and "2 LeRobot episode(s)" in capsys.readouterr().out


def test_broken_metadata_is_one_clear_line(two_episodes, tmp_path, capsys):
    out = tmp_path / "lerobot"
    assert main(["export-lerobot", str(two_episodes), str(out)]) == 0
    capsys.readouterr()
    (out / "meta" / "info.json").write_text("{not json")
    assert main(["info", str(out / "episode_000000")]) == 2
    error = capsys.readouterr().err
    assert "info.json" in error and "not a readable JSON file" in error and len(error.strip().splitlines()) == 1
    (out / "meta" / "info.json").write_text(json.dumps({"features": {}, "fps": "fast"}))
    with pytest.raises(DataError, match="is not a frame rate"):
        open_episode(out / "episode_000000")


@pytest.fixture(scope="module")
def sample_export(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("lerobot") / "sample"
    assert main(["export-lerobot", str(SAMPLE), str(out)]) == 0
    return out


@pytest.mark.slow
def test_the_bundled_sample_round_trips_through_replay(sample_export):
    episodes = pq.read_table(sample_export / "meta" / "episodes" / "chunk-000" / "file-000.parquet").to_pylist()
    assert sorted(e["source"] for e in episodes) == sorted(str(p.relative_to(SAMPLE)) for p in SAMPLE.glob("*/*/*") if p.is_dir())
    for index, row in enumerate(episodes):
        with open_episode(SAMPLE / row["source"]) as raw, open_episode(sample_export / f"episode_{index:06d}") as back:
            _same_episode(raw, back, [0, 150, raw.num_frames - 1])
            a = list(ReplaySource(raw, ReplayConfig(speed=None)))
            b = list(ReplaySource(back, ReplayConfig(speed=None)))
            assert len(a) == len(b) == raw.num_frames
            for x, y in zip(a[::50], b[::50]):
                np.testing.assert_array_equal(x.joints, y.joints)
                np.testing.assert_array_equal(x.pressure_grid, y.pressure_grid)
                assert all(np.abs(x.images[v].astype(int) - y.images[v].astype(int)).mean() < 4 for v in x.images)


@pytest.mark.slow
def test_eval_and_replay_run_on_the_export(sample_export, tmp_path, capsys):
    split = json.loads((sample_export / "split.json").read_text())
    # episodes in the split's order (the sample: one train, one val, one test_seen episode), each list a range
    assert split == {"train": ["episode_000000"], "val": ["episode_000001"], "test_seen": ["episode_000002"],
                     "test_unseen": []}
    info = json.loads((sample_export / "meta" / "info.json").read_text())
    assert info["splits"] == {"train": "0:1", "val": "1:2", "test_seen": "2:3"}
    assert main(["eval", "--checkpoint", str(NANO), "--data", str(sample_export), "--split", "val", "--views", "ego",
                 "--out", str(tmp_path / "eval")]) == 0
    results = json.loads((tmp_path / "eval" / "results.json").read_text())["results"][0]["trajectories"]
    assert [Path(r["path"]).name for r in results] == split["val"]
    copy = tmp_path / "copy"
    shutil.copytree(sample_export, copy)
    assert main(["replay", str(copy / "episode_000001"), "--out", str(tmp_path / "r.mp4")]) == 0
    assert "frames    300 written, 300 with a prediction" in capsys.readouterr().out


def test_an_episode_is_named_by_its_place_under_the_exported_root():
    from touchanything.devices.episodes.lerobot_export import source_name

    root = Path("/data/raw")
    assert source_name(root, root / "Home" / "press" / "001") == "Home/press/001"
    assert source_name(root / "Home" / "press" / "001.hdf5", root / "Home" / "press" / "001.hdf5") == "001.hdf5"


def test_episodes_are_exported_in_the_split_s_order_with_its_ranges():
    from touchanything.devices.episodes.lerobot_export import in_split_order

    a, b, c, d, e = (Path(f"/r/{name}") for name in "abcde")
    split = {"train": [Path("/r/d.hdf5"), Path("/r/b")], "val": [], "test_seen": [Path("/r/a")], "test_unseen": [Path("/r/zz")]}
    # a raw root's split names the .hdf5 files convert writes: /r/d.hdf5 is the raw folder /r/d; c and e are in no list
    assert in_split_order([a, b, c, d, e], split) == ([b, d, a, c, e], {"train": "0:2", "test_seen": "2:3"})
    assert in_split_order([a, b], None) == ([a, b], {"train": "0:2"})


def test_the_hand_order_reads_from_the_old_and_the_new_names():
    from touchanything.devices.episodes.lerobot_episode import hand_order

    old = {"axes": ["hand", "row", "column"], "hand": ["left", "right"]}  # exports written before 2026-11-27
    for names in (old, {"hand": ["right", "left"]}, ["left", "right"]):
        info = {"codebase_version": "v3.0", "features": {"observation.tactile": {"names": names}}}
        stated = names["hand"] if isinstance(names, dict) else names
        assert hand_order(info, "observation.tactile") == (stated, True)
