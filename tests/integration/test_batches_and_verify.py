"""Batches go on past a trajectory that fails, links under a root are followed, `info --verify` finds damage,
and wrong-kind HDF5 attributes, NaN checkpoints, bad quaternions and out-of-range grids are named."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest
import torch
import yaml

from tests.conftest import write_episode
from tests.integration.test_refused_inputs import checksums, refused
from touchanything.app.cli import main
from touchanything.devices.episodes.dataset_split import SPLIT_FILE
from touchanything.devices.episodes.episode_files import read_pressure_grids, write_pressure_grids
from touchanything.devices.episodes.hdf5_convert import convert_trajectory

ROOT = Path(__file__).resolve().parents[2]
NANO = ROOT / "models" / "nano"
NAMES = ("Home/a/1", "Home/b/2", "Office/c/3")


@pytest.fixture(scope="module")
def small_h5(tmp_path_factory) -> Path:
    """Three short raw episodes converted to HDF5 (`ROOT/raw/...`, `ROOT/h5/<Scene>/<task>/<id>.hdf5`)."""
    root = tmp_path_factory.mktemp("small")
    for i, name in enumerate(NAMES):
        folder = write_episode(root / "raw" / name, frames=40, size=(32, 32), seed=i)
        scene_task, trajectory = name.rsplit("/", 1)
        assert convert_trajectory(folder, root / "h5" / scene_task / f"{trajectory}.hdf5", 1).status == "converted"
    return root


def h5_copy(small_h5: Path, tmp_path: Path, tested: tuple[str, ...] = NAMES) -> Path:
    """A fresh copy of the HDF5 root with a split.json listing every trajectory in train, `tested` in test_seen."""
    root = tmp_path / "h5"
    shutil.copytree(small_h5 / "h5", root)
    files = [f"{name}.hdf5" for name in NAMES]
    test = [f"{name}.hdf5" for name in tested]
    (root / SPLIT_FILE).write_text(json.dumps({"train": files, "val": [], "test_seen": test, "test_unseen": []}))
    return root


def flip_bytes(path: Path, count: int = 200, seed: int = 0) -> None:
    """Flip `count` random bytes of a file (every bit of each)."""
    data = bytearray(path.read_bytes())
    for offset in np.random.default_rng(seed).choice(len(data), size=count, replace=False):
        data[offset] ^= 0xFF
    path.write_bytes(bytes(data))


# --- point 3: config bounds before anything is built ---------------------------------------------------------------

@pytest.mark.parametrize("key, value, words", [
    (("data", "image_size"), [56000, 56000], ("data.image_size", "1024", "56000")),
    (("model", "temporal_transformer", "window_size"), 100000, ("window_size", "100000")),
    (("model", "fusion", "num_layers"), 5000, ("fusion.num_layers", "5000")),
    (("model", "tactile_decoder", "conv_channels"), 10**7, ("conv_channels", str(10**7))),
])
def test_a_config_out_of_bounds_beside_a_checkpoint_is_refused_before_replay(capsys, tmp_path, episode_dir, key, value,
                                                                              words):
    shutil.copy(NANO / "best_model.pth", tmp_path / "best_model.pth")
    config = yaml.safe_load((NANO / "config.yaml").read_text())
    section = config
    for part in key[:-1]:
        section = section[part]
    section[key[-1]] = value
    (tmp_path / "config.yaml").write_text(yaml.safe_dump(config))
    before = checksums(episode_dir)
    refused(capsys, ["replay", str(episode_dir), "--headless", "--checkpoint", str(tmp_path / "best_model.pth")], *words)
    assert checksums(episode_dir) == before and not list(episode_dir.glob("*.mp4.*"))


def test_the_activation_estimate_refuses_what_the_machine_cannot_hold():
    from touchanything.core.errors import UserError
    from touchanything.inference.model.model_config import PRESETS, activation_bytes, machine_memory_bytes

    big = PRESETS["paper"].__class__(image_size=1022)
    assert activation_bytes(PRESETS["nano"]) < activation_bytes(big)
    assert activation_bytes(PRESETS["nano"]) < 0.01 * machine_memory_bytes()
    if activation_bytes(big) > 0.5 * machine_memory_bytes():
        with pytest.raises(UserError, match="data.image_size: 1022 needs about"):
            big.check()
    else:
        big.check()


# --- point 4: batches go on; links followed ------------------------------------------------------------------------

def test_convert_follows_symlinked_episode_folders(tmp_path, small_h5, capsys):
    elsewhere = tmp_path / "storage"
    shutil.copytree(small_h5 / "raw", elsewhere)
    raw = tmp_path / "raw"
    for name in NAMES:
        (raw / name).parent.mkdir(parents=True, exist_ok=True)
        (raw / name).symlink_to(elsewhere / name, target_is_directory=True)
    (raw / "loop").symlink_to(raw, target_is_directory=True)  # a link loop is read once
    assert main(["convert", str(raw), str(tmp_path / "out")]) == 0
    out = sorted(str(p.relative_to(tmp_path / "out")) for p in (tmp_path / "out").rglob("*.hdf5"))
    assert out == ["Home/a/1.hdf5", "Home/b/2.hdf5", "Office/c/3.hdf5"]
    assert "converted 3, skipped 0, failed 0" in capsys.readouterr().out


def test_info_and_split_follow_symlinked_hdf5_folders(tmp_path, small_h5, capsys):
    root = tmp_path / "root"
    (root / "Home").mkdir(parents=True)
    (root / "Home" / "a").symlink_to(small_h5 / "h5" / "Home" / "a", target_is_directory=True)
    (root / "Office").symlink_to(small_h5 / "h5" / "Office", target_is_directory=True)
    assert main(["info", str(root)]) == 0
    out = capsys.readouterr().out
    assert "0 raw episode(s), 2 HDF5 file(s)" in out and "Home/a/1.hdf5: 40 frames" in out


def test_convert_goes_on_past_a_trajectory_that_raises_anything(tmp_path, small_h5, capsys):
    raw = tmp_path / "raw"
    shutil.copytree(small_h5 / "raw", raw)
    before = checksums(raw)
    (raw / "Home" / "b" / "2" / "camera_matrix.txt").unlink()
    (raw / "Home" / "b" / "2" / "chest.mp4").write_bytes(b"\x00" * 1000)  # unreadable video
    assert main(["convert", str(raw), str(tmp_path / "out")]) == 1
    captured = capsys.readouterr()
    assert "converted 2, skipped 0, failed 1" in captured.out
    report = (tmp_path / "out" / "conversion_report.txt").read_text()
    assert "failed" in report and "Home/b/2" in report
    assert {k: v for k, v in checksums(raw).items() if "Home/b/2" not in k} == \
        {k: v for k, v in before.items() if "Home/b/2" not in k}


def test_info_root_names_a_damaged_trajectory_and_reads_the_others(tmp_path, small_h5, capsys):
    root = h5_copy(small_h5, tmp_path)
    (root / "Home" / "b" / "2.hdf5").write_bytes(b"garbage" * 100)
    assert main(["info", str(root)]) == 1
    out = capsys.readouterr().out
    assert "Home/b/2.hdf5: unreadable:" in out and "Home/a/1.hdf5: 40 frames" in out and "Office/c/3.hdf5: 40 frames" in out
    assert "1 trajectory unreadable or damaged" in out


def test_eval_names_a_failing_trajectory_and_evaluates_the_others(tmp_path, small_h5, capsys):
    root = h5_copy(small_h5, tmp_path)
    flip_bytes(root / "Home" / "b" / "2.hdf5", count=4000)
    (root / "Home" / "b" / "2.hdf5").write_bytes((root / "Home" / "b" / "2.hdf5").read_bytes()[:3000])
    code = main(["eval", "--data", str(root), "--split", "test_seen", "--checkpoint", str(NANO / "best_model.pth"),
                 "--views", "ego", "--out", str(tmp_path / "results"), "--device", "cpu"])
    captured = capsys.readouterr()
    assert code == 1, captured.err
    assert "touchanything eval: failed:" in captured.err and "Home/b/2.hdf5" in captured.err
    results = json.loads((tmp_path / "results" / "results.json").read_text())["results"][0]
    assert len(results["trajectories"]) == 2 and len(results["failed"]) == 1


def test_bench_data_names_a_corrupted_trajectory(tmp_path, small_h5, capsys):
    root = h5_copy(small_h5, tmp_path)
    bad = root / "Home" / "b" / "2.hdf5"
    bad.write_bytes(bad.read_bytes()[:3000])
    refused(capsys, ["bench", "--data", str(bad), "--quick", "--out", str(tmp_path / "bench"), "--device", "cpu",
                     "--models", str(NANO)], "2.hdf5", "no episode could be read")


# --- point 5: info --verify ----------------------------------------------------------------------------------------

def test_info_verify_reports_200_flipped_bytes_and_plain_info_says_it_did_not_read_the_frames(tmp_path, small_h5, capsys):
    path = tmp_path / "1.hdf5"
    shutil.copy(small_h5 / "h5" / "Home" / "a" / "1.hdf5", path)
    assert main(["info", "--verify", str(path)]) == 0
    assert "verified  every chunk and video frame read: no damage" in capsys.readouterr().out
    flip_bytes(path)
    code = main(["info", str(path)])
    out = capsys.readouterr().out
    assert "verified  no: video frames and image chunks were not read" in out
    assert main(["info", "--verify", str(path)]) == 1
    out = capsys.readouterr().out
    assert "damaged part(s)" in out and "unreadable" in out
    assert code in (0, 2)


def test_info_verify_decodes_every_video_frame_of_a_raw_episode(episode_dir, capsys):
    video = episode_dir / "left.mp4"
    data = video.read_bytes()
    video.write_bytes(data[: len(data) * 2 // 3])
    assert main(["info", "--verify", str(episode_dir)]) == 1
    assert "wrist_left" in capsys.readouterr().out


# --- point 6: wrong-kind attributes, NaN checkpoints, quaternions, grid range ------------------------------------

def _soft_loop(file: h5py.File, key: str) -> None:
    del file[key]
    file[key] = h5py.SoftLink("/" + key)


def _zero_frames(file: h5py.File) -> None:
    for key in ("images/chest_color", "images/left_color", "images/right_color"):
        del file[key]
        file.create_dataset(key, shape=(0, 32, 32, 3), dtype=np.uint8)


def _replace(key: str, value):
    def change(file: h5py.File) -> None:
        del file[key]
        file.create_dataset(key, data=value)
    return change


WRONG_KINDS = {
    "fps_string": (lambda f: f["metadata"].attrs.__setitem__("fps", "thirty"), "fps"),
    "fps_array": (lambda f: f["metadata"].attrs.__setitem__("fps", np.array([30, 30])), "fps"),
    "num_frames_array": (lambda f: f["metadata"].attrs.__setitem__("num_frames", np.array([40, 40])), "num_frames"),
    "scalar_valid": (_replace("hands/wilor_left_valid", 1), "hands/wilor_left_valid"),
    "soft_link_loop": (lambda f: _soft_loop(f, "hands/wilor_left_valid"), "hands/wilor_left_valid"),
    "zero_frame_images": (_zero_frames, "images/chest_color"),
}


@pytest.mark.parametrize("kind", list(WRONG_KINDS))
def test_wrong_kind_hdf5_attributes_are_named_by_every_reader(tmp_path, small_h5, capsys, kind):
    change, name = WRONG_KINDS[kind]
    root = h5_copy(small_h5, tmp_path, tested=NAMES[:1])  # eval going on past it: test_eval_names_a_failing_…
    path = root / "Home" / "a" / "1.hdf5"
    with h5py.File(path, "a") as file:
        change(file)
    before = checksums(root)
    # info on the file: a summary naming it among the problems, or one error line naming it
    code = main(["info", str(path)])
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err and name in captured.out + captured.err, captured
    assert code in (0, 2) and (code == 0 or len(captured.err.strip().splitlines()) == 1)
    # info on the root: the others read
    main(["info", str(root)])
    out = capsys.readouterr().out
    assert "Office/c/3.hdf5: 40 frames" in out
    # split: excluded with the reason naming it (or read: fps is not split's business)
    assert main(["split", str(root), "--out", str(tmp_path / "split.json"), "--allow-empty", "--min-frames", "1"]) == 0
    out = capsys.readouterr().out
    if kind not in ("fps_string", "fps_array"):
        assert f"excluded {path}" in out and name in out, out
    # eval: named on stderr (or read with a problem)
    code = main(["eval", "--data", str(root), "--split", "test_seen", "--checkpoint", str(NANO / "best_model.pth"),
                 "--views", "ego", "--device", "cpu"])
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err
    if code == 1:
        assert name in captured.err and "1.hdf5" in captured.err, captured.err
    assert checksums(root) == before


def test_bench_names_a_wrong_kind_dataset(tmp_path, small_h5, capsys):
    root = h5_copy(small_h5, tmp_path)
    path = root / "Home" / "a" / "1.hdf5"
    with h5py.File(path, "a") as file:
        _zero_frames(file)
    refused(capsys, ["bench", "--data", str(path), "--quick", "--out", str(tmp_path / "bench"), "--device", "cpu",
                     "--models", str(NANO)], "images/chest_color", "0 frames")


def test_a_checkpoint_with_nan_weights_is_refused_naming_the_tensor(capsys, tmp_path, episode_dir):
    checkpoint = torch.load(NANO / "best_model.pth", map_location="cpu", weights_only=True)
    state = checkpoint["model_state_dict"]
    name = next(k for k, v in state.items() if v.is_floating_point() and v.numel() > 1)
    state[name] = state[name].clone()
    state[name].view(-1)[0] = float("nan")
    torch.save(checkpoint, tmp_path / "best_model.pth")
    shutil.copy(NANO / "config.yaml", tmp_path / "config.yaml")
    refused(capsys, ["replay", str(episode_dir), "--headless", "--out", str(tmp_path / "out.mp4"),
                     "--checkpoint", str(tmp_path / "best_model.pth")], name, "NaN")
    assert not (tmp_path / "out.mp4").exists()


@pytest.mark.parametrize("quat", [[0, 0, 0, 0], [float("nan"), 0, 0, 1], [1, 0, 0], "up"])
def test_bad_glove_quaternions_are_reported_not_replaced_by_identity(episode_dir, quat):
    from touchanything.devices.episodes.episode_streams import read_glove

    path = episode_dir / "jq_pressure.json"
    lines = path.read_text().splitlines()
    row = json.loads(lines[3])
    row["left"]["quat_wxyz"] = quat
    lines[3] = json.dumps(row).replace("NaN", "NaN")
    path.write_text("\n".join(lines) + "\n")
    stream, problems = read_glove(path)
    assert not stream.present[3, 0] and stream.present[3, 1]
    assert any("left.quat_wxyz" in p and "line 4" in p for p in problems), problems


def test_grid_values_outside_0_1_are_reported(episode_dir, capsys):
    path = episode_dir / "pressure_grids.npz"
    grids = read_pressure_grids(path).grids
    grids[5, 0, 10, 10] = 3.5
    grids[6, 1, 10, 10] = -0.25
    write_pressure_grids(path, grids)
    assert any("2 value(s) outside [0, 1] (from -0.25 to 3.5)" in p for p in read_pressure_grids(path).problems)
    assert main(["info", str(episode_dir)]) == 0
    assert "outside [0, 1]" in capsys.readouterr().out
