"""Fuzzed episode readers: any single corruption of any one file of a valid episode gives `touchanything info`
/ `convert` / headless `replay` either a result that names the problem or one error line (exit 2, no
traceback); never an unhandled exception, never a hang, never a frame shifted. The same for a dataset
root's `split.json`. The corruptions are in tests/helpers/fuzzing.py."""
from __future__ import annotations

import contextlib
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import event, given
from hypothesis import strategies as st

from helpers.episode_files import write_masks
from helpers.fuzzing import (
    FRAMES,
    JSONL_FILES,
    NANO,
    RAW_FILES,
    Corruption,
    apply,
    assert_one_error_line,
    cli,
    corrupt_text,
    fuzz,
    no_hang,
)
from tests.conftest import write_episode
from touchanything.core.errors import UserError
from touchanything.devices.episodes.episode_files import Masks
from touchanything.devices.episodes.episode_loader import open_episode
from touchanything.devices.episodes.hdf5_convert import convert_trajectory
from touchanything.devices.episodes.raw_episode import (
    GLOVE_FILE,
    GRIDS_FILE,
    MASKS_FILE,
    ROKOKO_FILE,
    VIDEO_FILES,
    VIVE_FILE,
    WILOR_FILE,
)

SIZE = (32, 48)
STREAM_FILES = {"wilor": WILOR_FILE, "rokoko": ROKOKO_FILE, "trackers": VIVE_FILE, "glove": GLOVE_FILE,
                "pressure": GRIDS_FILE}


def streams(episode) -> dict[str, np.ndarray | None]:
    """The per-frame values of every non-video stream (None where absent)."""
    out: dict[str, np.ndarray | None] = {}
    for name in ("wilor", "rokoko"):
        hands = episode.hands(name)
        out[f"{name}.joints"] = hands and hands.joints
        out[f"{name}.valid"] = hands and hands.valid
    out["trackers.poses"] = episode.trackers and episode.trackers.poses
    out["trackers.valid"] = episode.trackers and episode.trackers.valid
    out["glove.raw"] = episode.glove and episode.glove.raw
    out["glove.present"] = episode.glove and episode.glove.present
    out["pressure"] = episode.pressure and episode.pressure.grids
    return out


def video_frames(episode) -> dict[str, list[np.ndarray]]:
    return {view: [source.read(i) for i in range(episode.num_frames)] for view, source in episode.views.items()}


class Pristine:
    """The valid episode every example starts from: its files' bytes and what reading them gives."""

    def __init__(self, folder: Path, hdf5: Path, files: dict[str, bytes], raw: dict, raw_videos: dict, h5: dict) -> None:
        self.folder, self.hdf5, self.bytes = folder, hdf5, files
        self.raw, self.raw_videos, self.h5 = raw, raw_videos, h5

    def __repr__(self) -> str:
        return f"Pristine({self.folder})"


@pytest.fixture(scope="module")
def pristine(tmp_path_factory) -> Pristine:
    root = tmp_path_factory.mktemp("fuzz")
    folder = write_episode(root / "Home" / "pick_up_bottle" / "0001", frames=FRAMES, size=SIZE)
    masks = np.zeros((FRAMES, 1) + SIZE, np.uint8)
    masks[:, :, 4:12, 6:20] = 1
    write_masks(folder / MASKS_FILE, Masks(masks, np.ones((FRAMES, 1), np.int32), np.ones(FRAMES, bool)))
    hdf5 = root / "0001.hdf5"
    assert convert_trajectory(folder, hdf5, compression_level=1).status == "converted"
    with open_episode(folder) as raw, open_episode(hdf5) as h5:
        assert raw.problems == [] and h5.problems == [] and raw.num_frames == h5.num_frames == FRAMES
        return Pristine(folder, hdf5, {n: (folder / n).read_bytes() for n in RAW_FILES}, streams(raw),
                        video_frames(raw), streams(h5))


@contextlib.contextmanager
def scratch_copy(pristine: Pristine):
    """A fresh copy of the pristine episode (`<tmp>/raw/Home/pick_up_bottle/0001`) and its HDF5 file."""
    tmp = Path(tempfile.mkdtemp(prefix="fuzz-"))
    try:
        folder = tmp / "raw" / "Home" / "pick_up_bottle" / "0001"
        shutil.copytree(pristine.folder, folder)
        shutil.copyfile(pristine.hdf5, tmp / "0001.hdf5")
        yield tmp, folder, tmp / "0001.hdf5"
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def assert_no_shift(now: dict, before: dict, frames: int, corruption: Corruption, original: bytes | None) -> None:
    """Streams of untouched files equal the original at every frame; the corrupted JSONL stream equals it
    at every frame the edit did not touch (a broken line never moves a later frame)."""
    for key, value in now.items():
        stream = key.split(".")[0]
        source = STREAM_FILES[stream]
        if before.get(key) is None:
            continue
        if source != corruption.name:
            assert value is not None, f"{key} lost by corrupting {corruption.name}"
            np.testing.assert_array_equal(value[:frames], before[key][:frames], err_msg=key)
        elif value is not None and source in JSONL_FILES:
            touched = corruption.frames_touched(original)
            keep = [i for i in range(frames) if i not in touched]
            np.testing.assert_array_equal(value[keep], before[key][keep], err_msg=f"{key} at frames {keep}")
        elif value is not None and source == GRIDS_FILE and corruption.kind != "npz_array":
            np.testing.assert_array_equal(value[:frames], before[key][:frames], err_msg=key)


def check_info(folder: Path, pristine: Pristine, corruption: Corruption) -> None:
    outcome = cli("info", folder)
    event(f"info exit {outcome.code}")
    if outcome.code == 2:
        assert_one_error_line(outcome, "info", str(folder))
        return
    assert outcome.code == 0 and "Traceback" not in outcome.err, outcome
    assert "problems  " in outcome.out
    if corruption.kind == "delete_file" and corruption.name in (*VIDEO_FILES.values(), GRIDS_FILE, WILOR_FILE, GLOVE_FILE):
        assert f"{corruption.name}: missing required file" in outcome.out
    elif corruption.kind == "npz_array" and corruption.name == GRIDS_FILE and "grid" in corruption.array:
        assert f"{GRIDS_FILE}: {corruption.array}" in outcome.out or "problems  none" in outcome.out, outcome.out
    with no_hang(), open_episode(folder) as episode:
        original = pristine.bytes.get(corruption.name)
        assert_no_shift(streams(episode), pristine.raw, episode.num_frames, corruption, original)
        for view, images in video_frames(episode).items():
            if VIDEO_FILES[view] != corruption.name:
                assert all(np.array_equal(a, b) for a, b in zip(images, pristine.raw_videos[view])), view


def check_convert(tmp: Path, pristine: Pristine, corruption: Corruption) -> None:
    out = tmp / "h5"
    outcome = cli("convert", tmp / "raw", out)
    event(f"convert exit {outcome.code}")
    if outcome.code == 2:
        assert_one_error_line(outcome, "convert")
        return
    report = (out / "conversion_report.txt").read_text()
    assert outcome.code in (0, 1) and "Traceback" not in outcome.err, outcome
    if outcome.code == 1:  # failed: the report and the progress output name the problem
        assert "failed" in report and str(tmp / "raw") in report, report
        assert "failed: " in outcome.out
        return
    converted = out / "Home" / "pick_up_bottle" / "0001.hdf5"
    with no_hang(), open_episode(converted) as episode:
        assert episode.problems == [] or corruption.name in VIDEO_FILES.values(), episode.problems
        original = pristine.bytes.get(corruption.name)
        assert_no_shift(streams(episode), pristine.h5, episode.num_frames, corruption, original)


FILE_CORRUPTION = st.sampled_from(RAW_FILES)


def extra_kinds(name: str) -> tuple[str, ...]:
    return ("jsonl_line", "line_break") if name in JSONL_FILES else ("npz_array",) if name.endswith(".npz") else ()


@fuzz(150)
@given(st.data())
def test_a_corrupted_raw_file_gives_info_and_convert_a_named_problem_or_one_line(pristine, data) -> None:
    name = data.draw(FILE_CORRUPTION, label="file")
    with scratch_copy(pristine) as (tmp, folder, _):
        corruption = apply(folder / name, data.draw, name, extra_kinds(name))
        check_info(folder, pristine, corruption)
        check_convert(tmp, pristine, corruption)


@fuzz(100)
@given(st.data())
def test_a_corrupted_hdf5_trajectory_gives_info_a_named_problem_or_one_line(pristine, data) -> None:
    with scratch_copy(pristine) as (tmp, _, hdf5):
        corruption = apply(hdf5, data.draw, hdf5.name, ("hdf5_dataset", "hdf5_dataset", "hdf5_storage", "hdf5_storage"))
        outcome = cli("info", hdf5)
        event(f"{corruption.kind}: info exit {outcome.code}")
        if outcome.code == 2:
            assert_one_error_line(outcome, "info", str(hdf5))
            return
        assert outcome.code == 0, outcome
        if corruption.kind == "hdf5_dataset":
            with no_hang(), open_episode(hdf5) as episode:
                now = streams(episode)
                for key, value in now.items():
                    dataset_stream = {"wilor": "hands/wilor", "rokoko": "hands/", "trackers": "poses/",
                                      "pressure": "pressure/"}.get(key.split(".")[0])
                    if pristine.h5[key] is None or dataset_stream is None:
                        continue
                    if corruption.dataset.startswith(dataset_stream):  # that stream lost: the dataset is named
                        assert value is not None or corruption.dataset in outcome.out, outcome.out
                        continue
                    if key.startswith("rokoko") and corruption.dataset.startswith("hands/wilor"):
                        assert value is not None
                    elif value is not None:
                        np.testing.assert_array_equal(value, pristine.h5[key][:episode.num_frames], err_msg=key)


@fuzz(30)
@given(st.data())
def test_a_corrupted_episode_gives_headless_replay_a_video_or_one_line(pristine, data) -> None:
    name = data.draw(st.sampled_from(RAW_FILES + ("0001.hdf5",)), label="file")
    with scratch_copy(pristine) as (tmp, folder, hdf5):
        target = hdf5 if name == "0001.hdf5" else folder / name
        apply(target, data.draw, name, ("hdf5_dataset", "hdf5_storage") if name == "0001.hdf5" else extra_kinds(name))
        video = tmp / "replay.mp4"
        outcome = cli("replay", hdf5 if name == "0001.hdf5" else folder, "--headless", "--out", video, "--device", "cpu")
        event(f"replay exit {outcome.code}")
        if outcome.code == 2:
            assert_one_error_line(outcome, "replay")
            return
        assert outcome.code == 0 and "Traceback" not in outcome.err, outcome
        assert video.is_file() and "problems  " in outcome.out and "video     " in outcome.out


@fuzz(100)
@given(st.data())
def test_a_corrupted_split_file_gives_one_line_naming_it(pristine, data) -> None:
    from touchanything.devices.episodes.dataset_split import read_split, write_split

    with scratch_copy(pristine) as (tmp, _, hdf5):
        root = tmp / "h5"
        (root / "Home" / "pick_up_bottle").mkdir(parents=True)
        shutil.move(hdf5, root / "Home" / "pick_up_bottle" / "0001.hdf5")
        split_file = root / "split.json"
        write_split(split_file, {"train": [], "val": [], "test_seen": [root / "Home" / "gone" / "x.hdf5"],
                                 "test_unseen": [root / "Home" / "pick_up_bottle" / "0001.hdf5"]})
        corrupt_text(split_file, data.draw)
        try:
            read_split(split_file)
        except UserError as exc:
            assert str(exc).startswith(str(split_file)) and "\n" not in str(exc)
        outcome = cli("eval", "--checkpoint", NANO / "best_model.pth", "--data", root, "--split", "test_seen",
                      "--device", "cpu")
        if outcome.code != 0:
            assert_one_error_line(outcome, "eval")
        outcome = cli("info", root)
        assert outcome.code == 0, outcome
        assert "split     " in outcome.out or not split_file.exists()
