"""The features of `export-lerobot` as LeRobot's training stack and Rerun's importer take them: every value named
and 1-D, no NaN stored, a hand not measured flagged, `--action`, statistics computed as LeRobot 0.6.1 computes
them (hand-worked here; `benchmarks/lerobot_compat.py` compares with the library itself), the metadata checks,
and older exports still read."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from conftest import frame_image, write_episode
from helpers.lerobot_old_export import make_old_export
from touchanything.app.cli import main
from touchanything.core.errors import DataError
from touchanything.core.tactile_layout import TactileLayout
from touchanything.devices.episodes.episode_loader import open_episode
from touchanything.devices.episodes.episode_writer import EpisodeFrame, RawEpisodeWriter
from touchanything.devices.episodes.lerobot_checks import metadata_problems
from touchanything.devices.episodes.lerobot_stats import aggregate, feature_stats


@pytest.fixture
def raw_root(tmp_path: Path) -> Path:
    """Two episodes; the second one's right glove map is missing (NaN) every 4th frame, its left hand unseen every
    3rd."""
    root = tmp_path / "raw"
    write_episode(root / "Home" / "pick_up_bottle" / "001", frames=12, seed=1)
    rng = np.random.default_rng(5)
    second = root / "Office" / "press_button" / "002"
    with RawEpisodeWriter(second, crf=10) as writer:
        for i in range(9):
            raw = rng.integers(0, 200, size=(2, 256)).astype(np.uint8)
            writer.write(EpisodeFrame(images={v: frame_image(k, i, (48, 64)) for k, v in enumerate(("ego", "wrist_left", "wrist_right"))},
                                      wilor=(rng.uniform(-3, 3, (2, 21, 3)).astype(np.float32), np.array([i % 3 != 0, True])),
                                      glove=(raw, np.array([True, True]), np.tile(np.float32([1, 0, 0, 0]), (2, 1))),
                                      trackers=(rng.normal(0, 1, (3, 7)).astype(np.float32), np.array([True, True, False]))))
    with np.load(second / "pressure_grids.npz") as grids:
        arrays = dict(grids)
    arrays["right_pressure_grid"][::4] = np.nan
    np.savez(second / "pressure_grids.npz", **arrays)
    return root


def _episodes(root: Path) -> list[Path]:
    return sorted(p for p in root.glob("*/*/*") if p.is_dir())


def test_no_value_is_nan_and_the_maps_come_back_exactly(raw_root, tmp_path):
    out = tmp_path / "lerobot"
    assert main(["export-lerobot", str(raw_root), str(out)]) == 0
    data = pq.read_table(out / "data" / "chunk-000" / "file-000.parquet")
    for name in data.column_names:
        column = data[name].combine_chunks()
        while pa.types.is_fixed_size_list(column.type):
            column = column.flatten()
        assert np.isfinite(column.to_numpy(zero_copy_only=False).astype(np.float64)).all(), name
    measured = np.array(data["observation.tactile_valid"].to_pylist())
    assert measured[:12].all() and measured[12:, 0].all()
    assert measured[12:, 1].tolist() == [i % 4 != 0 for i in range(9)]
    state = np.array(data["observation.state"].to_pylist())
    assert state[12:, 126].tolist() == [float(i % 3 != 0) for i in range(9)]  # left hand seen
    for index, source in enumerate(_episodes(raw_root)):
        with open_episode(source) as raw, open_episode(out / f"episode_{index:06d}") as back:
            np.testing.assert_array_equal(back.pressure.grids, raw.pressure.grids)  # NaN where NaN
            np.testing.assert_array_equal(back.wilor.joints, raw.wilor.joints)
            np.testing.assert_array_equal(back.wilor.valid, raw.wilor.valid)
            np.testing.assert_array_equal(back.trackers.valid, raw.trackers.valid)
            assert back.problems == []


def test_action_moves_one_feature_and_reads_back(raw_root, tmp_path, capsys):
    out = tmp_path / "lerobot"
    assert main(["export-lerobot", str(raw_root), str(out), "--action", "observation.tactile"]) == 0
    features = json.loads((out / "meta" / "info.json").read_text())["features"]
    assert "observation.tactile" not in features and features["action"]["info"]["exported_from"] == "observation.tactile"
    assert features["action"]["shape"] == [434] and "action" in json.loads((out / "meta" / "stats.json").read_text())
    with open_episode(_episodes(raw_root)[1]) as raw, open_episode(out / "episode_000001") as back:
        np.testing.assert_array_equal(back.pressure.grids, raw.pressure.grids)
    capsys.readouterr()
    assert main(["export-lerobot", str(raw_root), str(tmp_path / "other"), "--action", "observation.pressure"]) == 2
    error = capsys.readouterr().err
    assert "--action observation.pressure" in error and "observation.tactile" in error and len(error.strip().splitlines()) == 1
    assert not (tmp_path / "other").exists()


def test_an_export_made_before_the_flat_features_still_reads(raw_root, tmp_path):
    out = tmp_path / "lerobot"
    assert main(["export-lerobot", str(raw_root), str(out)]) == 0
    make_old_export(out, _episodes(raw_root))
    for index, source in enumerate(_episodes(raw_root)):
        with open_episode(source) as raw, open_episode(out / f"episode_{index:06d}") as back:
            np.testing.assert_array_equal(back.pressure.grids, raw.pressure.grids)
            np.testing.assert_array_equal(back.wilor.joints, raw.wilor.joints)
            np.testing.assert_array_equal(back.trackers.poses, raw.trackers.poses)
            assert back.problems == []


def test_quantiles_come_from_lerobot_s_5000_bin_histogram():
    """Hand-worked for 0, 1, …, 99: bins of width 99/5000 = 0.0198 from 0; the quantile is the upper edge of the bin
    where the count reaches q · 100 (value 49's bin ends at 2475 · 0.0198 = 49.005, value 98's at 98.01), and the
    first bin's lower edge (−1e-10) when the first bin reaches it."""
    stats = feature_stats(np.arange(100, dtype=np.float32))
    assert stats["q50"] == pytest.approx([49.005], abs=1e-5) and stats["q99"] == pytest.approx([98.01], abs=1e-5)
    assert stats["q01"] == pytest.approx([0.0], abs=1e-9) and stats["count"].tolist() == [100]
    assert stats["mean"] == pytest.approx([49.5]) and stats["std"] == pytest.approx([np.sqrt((100**2 - 1) / 12)], rel=1e-6)
    two = feature_stats(np.array([[[1.0, 2.0], [3.0, 4.0]], [[5.0, 6.0], [7.0, 8.0]]], np.float32))  # every axis but the last
    assert two["mean"].tolist() == [4.0, 5.0] and two["min"].tolist() == [1.0, 2.0] and two["count"].tolist() == [2]
    one = feature_stats(np.array([[3.0, 4.0]], np.float32))  # one frame: LeRobot's quantiles are the mean
    assert one["q10"].tolist() == [3.0, 4.0] and one["std"].tolist() == [0.0, 0.0]
    merged = aggregate([feature_stats(np.arange(10.0)), feature_stats(np.arange(10.0, 40.0))])
    assert merged["mean"] == pytest.approx([19.5]) and merged["std"] == pytest.approx([np.std(np.arange(40.0))], rel=1e-6)
    # q50 of 0…9 ends value 4's bin (width 0.0018): 4.0014; of 10…39, value 24's (width 0.0058): 24.0012
    assert merged["count"].tolist() == [40] and merged["q50"] == pytest.approx([(10 * 4.0014 + 30 * 24.0012) / 40], abs=1e-4)


def test_the_statistics_have_lerobot_s_shapes_and_values(raw_root, tmp_path):
    out = tmp_path / "lerobot"
    assert main(["export-lerobot", str(raw_root), str(out)]) == 0
    stats = json.loads((out / "meta" / "stats.json").read_text())
    shapes = {"observation.tactile": (434,), "observation.state": (128,), "observation.trackers": (21,),
              "observation.tactile_valid": (2,), "timestamp": (1,), "observation.images.ego": (3, 1, 1)}
    for name, shape in shapes.items():
        assert np.array(stats[name]["q90"]).shape == shape, name
    assert stats["observation.state"]["count"] == [21] and stats["observation.images.ego"]["count"] == [21]
    joints, ego = [], []
    for source in _episodes(raw_root):
        with open_episode(source) as raw:
            joints.append(raw.wilor.joints.reshape(raw.num_frames, -1))
            ego += [raw.views["ego"].read(i) for i in range(raw.num_frames)]  # under 100 frames: every one sampled
    joints = np.concatenate(joints).astype(np.float64)
    np.testing.assert_allclose(stats["observation.state"]["mean"][:126], joints.mean(axis=0), rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(stats["observation.state"]["std"][:126], joints.std(axis=0), rtol=1e-4, atol=1e-5)
    assert stats["observation.state"]["max"][:126] == pytest.approx(joints.max(axis=0).tolist())
    pixels = np.stack(ego).reshape(-1, 3).astype(np.float64) / 255
    np.testing.assert_allclose(np.array(stats["observation.images.ego"]["mean"]).ravel(), pixels.mean(axis=0), rtol=1e-5)
    assert metadata_problems(out, 2, 21) == []


def _rewrite(path: Path, change) -> None:
    data = json.loads(path.read_text())
    change(data)
    path.write_text(json.dumps(data))


def test_malformed_metadata_is_named_or_read_correctly(raw_root, tmp_path, capsys):
    out = tmp_path / "lerobot"
    assert main(["export-lerobot", str(raw_root), str(out)]) == 0
    info, stats = out / "meta" / "info.json", out / "meta" / "stats.json"
    _rewrite(info, lambda d: d["splits"].update(train="0:9"))
    _rewrite(stats, lambda d: d["observation.state"].update(mean=[0.0] * 3))
    _rewrite(stats, lambda d: d["observation.tactile"].update(std=[float("nan")] * 434))
    problems = metadata_problems(out, 2, 21)
    for field in ("splits.train", "observation.state.mean", "observation.tactile.std"):
        assert sum(field in p for p in problems) == 1, (field, problems)
    capsys.readouterr()
    assert main(["info", str(out)]) == 0  # the episodes read; the problems are listed
    assert capsys.readouterr().out.count("problem   ") == len(problems) == 3
    _rewrite(info, lambda d: d["features"]["observation.trackers"].update(names={"axes": ["tracker"], "pose": ["x"]}))
    assert any("observation.trackers names: not None, a list or a map with one entry" in p for p in metadata_problems(out, 2, 21))
    with pytest.raises(DataError, match="observation.trackers names"):
        open_episode(out / "episode_000000")
    stats.unlink()
    assert any("stats.json: missing" in p for p in metadata_problems(out, 2, 21))
    _rewrite(info, lambda d: d["features"]["observation.tactile"].update(names=["left.r02c01", "palm"] * 217))
    assert main(["info", str(out / "episode_000000")]) == 2
    error = capsys.readouterr().err
    assert "observation.tactile names" in error and len(error.strip().splitlines()) == 1
    _rewrite(info, lambda d: d["features"]["observation.tactile"].update(names=None))
    _rewrite(info, lambda d: d["features"]["observation.state"].update(names=["x"] * 128))
    with pytest.raises(DataError, match="observation.state names"):
        open_episode(out / "episode_000000")


def test_the_exported_cells_are_the_official_sensor_maps_cells(raw_root, tmp_path, official_dir):
    """The 434 values are named by the cells the official mapping files (pressure_position_mapping_{left,right}.json,
    the right one mirrored) give a sensor — read here from the released files, not the project's copy."""
    official = TactileLayout.from_dir(official_dir).valid
    out = tmp_path / "lerobot"
    assert main(["export-lerobot", str(raw_root), str(out)]) == 0
    names = json.loads((out / "meta" / "info.json").read_text())["features"]["observation.tactile"]["names"]
    left = json.loads((official_dir / "pressure_position_mapping_left.json").read_text())
    assert sorted(n for n in names if n.startswith("left.")) == sorted(
        f"left.r{int(k.split(',')[0]):02d}c{int(k.split(',')[1]):02d}" for k in left)  # the file's own keys
    assert len(names) == int(official.sum()) == 434
