"""Fuzzed readers: any single corruption of any one file of a valid episode (truncation, byte flips, a deleted
byte range, a JSON-lines line replaced by random JSON, an npz array or HDF5 dataset of another shape or dtype)
gives `touchanything info` / `convert` / headless `replay` either a result that names the problem or one
error line (exit 2, no traceback); never an unhandled exception, never a hang, never a frame shifted.
The same for `split.json`, `config.yaml`, scene files and checkpoints.

`FUZZ_EXAMPLES=10 pytest tests/test_fuzz_readers.py` multiplies the number of examples (a longer hunt).
"""
from __future__ import annotations

import contextlib
import faulthandler
import io
import json
import os
import shutil
import signal
import tempfile
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from helpers.episode_files import write_masks
from tests.conftest import write_episode
from touchanything.app.cli import main
from touchanything.devices.episodes.episode_files import Masks, save_npz
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
from touchanything.devices.errors import UserError

ROOT = Path(__file__).resolve().parents[1]
NANO = ROOT / "models" / "nano"
FRAMES = 8
SIZE = (32, 48)
SCALE = int(os.environ.get("FUZZ_EXAMPLES", "1"))
STEP_SECONDS = 60
"""A single command on a corrupted file taking longer than this is a hang."""

JSONL_FILES = (WILOR_FILE, ROKOKO_FILE, VIVE_FILE, GLOVE_FILE)
RAW_FILES = (*VIDEO_FILES.values(), GRIDS_FILE, MASKS_FILE, *JSONL_FILES, "quality_issues.json", "camera_matrix.txt")
STREAM_FILES = {"wilor": WILOR_FILE, "rokoko": ROKOKO_FILE, "trackers": VIVE_FILE, "glove": GLOVE_FILE,
                "pressure": GRIDS_FILE}


def fuzz(examples: int) -> settings:
    """Hypothesis settings of these properties: `examples` (times FUZZ_EXAMPLES), no deadline."""
    return settings(max_examples=examples * SCALE, deadline=None, suppress_health_check=list(HealthCheck), database=None)


# ---------------------------------------------------------------------------------------------- guards

class Hang(Exception):
    pass


@contextlib.contextmanager
def no_hang(seconds: int = STEP_SECONDS):
    """A Python-level hang raises Hang; one stuck in C code ends the process with every thread's traceback."""
    def alarm(signum, frame):
        raise Hang(f"still running after {seconds} s")

    previous = signal.signal(signal.SIGALRM, alarm)
    signal.alarm(seconds)
    faulthandler.dump_traceback_later(seconds * 3, exit=True)
    try:
        yield
    finally:
        signal.alarm(0)
        faulthandler.cancel_dump_traceback_later()
        signal.signal(signal.SIGALRM, previous)


@dataclass
class Outcome:
    code: int
    out: str
    err: str


def cli(*argv: str) -> Outcome:
    """`touchanything ARGV` in this process, output captured; an unhandled exception fails the test."""
    out, err = io.StringIO(), io.StringIO()
    with no_hang(), contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main([str(a) for a in argv])
    return Outcome(code, out.getvalue(), err.getvalue())


def assert_one_error_line(outcome: Outcome, command: str, names: str | None = None) -> str:
    """Exit 2 and exactly one `touchanything COMMAND: error: …` line on stderr (progress bars aside)."""
    assert outcome.code == 2, outcome
    assert "Traceback" not in outcome.err
    errors = [line for line in outcome.err.splitlines() if "error:" in line]
    assert len(errors) == 1 and errors[0].startswith(f"touchanything {command}: error: "), outcome.err
    assert "\n" not in errors[0]
    if names is not None:
        assert names in errors[0], errors[0]
    return errors[0]


# ---------------------------------------------------------------------------------------------- corruptions

def _spans(data: bytes) -> list[tuple[int, int]]:
    """(start, end) of each line, its newline included."""
    spans, start = [], 0
    while start < len(data):
        end = data.find(b"\n", start)
        end = len(data) if end < 0 else end + 1
        spans.append((start, end))
        start = end
    return spans


@dataclass
class Corruption:
    """One edit of one file; `touched` is the byte range [lo, hi) of the original it changes (hi = None: to
    the end), `line` the replaced JSONL line, `array` / `dataset` the replaced npz array / HDF5 dataset."""

    name: str
    kind: str
    lo: int = 0
    hi: int | None = None
    line: int | None = None
    array: str | None = None
    dataset: str | None = None

    def frames_touched(self, original: bytes) -> set[int]:
        """JSONL frames this edit may change: the lines it touches and one line either side (a removed or
        added newline merges or splits lines); everything from the first one on for a truncation."""
        if self.line is not None:
            return {self.line}
        spans = _spans(original)
        hit = [i for i, (a, b) in enumerate(spans) if a < (self.hi if self.hi is not None else len(original)) and b > self.lo]
        if not hit:
            return set()
        last = len(spans) + FRAMES if self.hi is None else hit[-1] + 1
        return set(range(max(hit[0] - 1, 0), last + 1))


def _fraction(data: bytes, f: float) -> int:
    return min(int(f * len(data)), max(len(data) - 1, 0))


json_values = st.recursive(
    st.none() | st.booleans() | st.integers() | st.sampled_from([2**63, -2**63 - 1, 10**400, -1, 255, 256])
    | st.floats() | st.text(max_size=12),
    lambda inner: st.lists(inner, max_size=25) | st.dictionaries(st.text(max_size=10), inner, max_size=5),
    max_leaves=60)


def _replace_somewhere(draw, value, depth: int = 0):
    """`value` with one node (perhaps itself) replaced by random JSON."""
    if depth > 4 or draw(st.integers(0, 3)) == 0:
        return draw(json_values)
    if isinstance(value, dict) and value:
        key = draw(st.sampled_from(sorted(value)))
        return {**value, key: _replace_somewhere(draw, value[key], depth + 1)}
    if isinstance(value, list) and value:
        i = draw(st.integers(0, len(value) - 1))
        return value[:i] + [_replace_somewhere(draw, value[i], depth + 1)] + value[i + 1:]
    return draw(json_values)


def _odd_array(draw, like: np.ndarray) -> np.ndarray:
    """An array of another shape and/or dtype than `like`."""
    shapes = [like.shape, (), (3,), like.shape + (1,), tuple(max(s - 1, 0) for s in like.shape)]
    if like.ndim:
        shapes += [like.shape[:-1], (like.shape[0] + 5,) + like.shape[1:], (0,) + like.shape[1:]]
    shape = draw(st.sampled_from(shapes))
    dtype = draw(st.sampled_from(["float32", "float64", "float16", "int32", "uint8", "bool", "complex64", "U3", "S2"]))
    if shape == like.shape and np.dtype(dtype) == like.dtype:
        shape = (3,)
    values = draw(st.sampled_from([0.0, 1.0, 7.5, float("nan"), float("inf")]))
    with np.errstate(invalid="ignore"):
        return np.full(shape, values).astype(dtype)


def apply(path: Path, draw, name: str, extra_kinds: tuple[str, ...] = ()) -> Corruption:
    """Corrupt `path` in place with one edit drawn by `draw`."""
    data = path.read_bytes()
    kind = draw(st.sampled_from(("delete_file", "truncate", "flip", "delete_range") + extra_kinds))
    if kind == "delete_file":
        path.unlink()
        return Corruption(name, kind, 0, None)
    if kind == "truncate":
        at = _fraction(data, draw(st.floats(0, 1)))
        path.write_bytes(data[:at])
        return Corruption(name, kind, at, None)
    if kind == "flip":
        at = [_fraction(data, f) for f in draw(st.lists(st.floats(0, 1), min_size=1, max_size=3))]
        span = (max(at) - min(at)) if len(data) else 0
        if span > 64:  # flips in one region, so a JSONL edit touches a few lines
            at = [at[0] + (a - at[0]) % 64 for a in at if at[0] + (a - at[0]) % 64 < len(data)]
        out = bytearray(data)
        for a in at:
            out[a] ^= draw(st.integers(1, 255))
        path.write_bytes(bytes(out))
        return Corruption(name, kind, min(at, default=0), max(at, default=0) + 1)
    if kind == "delete_range":
        lo = _fraction(data, draw(st.floats(0, 1)))
        hi = min(lo + draw(st.integers(1, 300)), len(data))
        path.write_bytes(data[:lo] + data[hi:])
        return Corruption(name, kind, lo, hi)
    if kind == "line_break":  # a newline lost, a stray one, or a whole line gone: later lines move
        spans = _spans(data)
        i = draw(st.integers(0, len(spans) - 1))
        a, b = spans[i]
        how = draw(st.sampled_from(("join", "split", "drop")))
        at = b - 1 if how == "join" else a + draw(st.integers(0, b - a - 1)) if how == "split" else a
        path.write_bytes(data[:at] + (b"\n" if how == "split" else b"") + data[{"join": at + 1, "split": at, "drop": b}[how]:])
        return Corruption(name, kind, a, b)
    if kind == "hdf5_storage":  # flips inside one dataset's stored bytes (a chunk, or contiguous data)
        with h5py.File(path, "r") as file:
            keys = []
            file.visit(lambda k: keys.append(k) if isinstance(file[k], h5py.Dataset) and file[k].size else None)
            key = draw(st.sampled_from(sorted(keys)))
            dataset = file[key]
            if dataset.chunks:
                info = dataset.id.get_chunk_info(draw(st.integers(0, dataset.id.get_num_chunks() - 1)))
                start, size = info.byte_offset, info.size
            else:
                start, size = dataset.id.get_offset(), dataset.id.get_storage_size()
        out = bytearray(data)
        for f in draw(st.lists(st.floats(0, 1), min_size=1, max_size=4)):
            out[start + min(int(f * size), size - 1)] ^= draw(st.integers(1, 255))
        path.write_bytes(bytes(out))
        return Corruption(name, kind, dataset=key)
    if kind == "jsonl_line":
        lines = data.decode().splitlines()
        i = draw(st.integers(0, len(lines) - 1))
        whole = draw(st.booleans())
        value = draw(json_values) if whole else _replace_somewhere(draw, json.loads(lines[i]))
        lines[i] = json.dumps(value)
        path.write_text("\n".join(lines) + "\n")
        return Corruption(name, kind, line=i)
    if kind == "npz_array":
        with np.load(path) as npz:
            arrays = {k: npz[k] for k in npz.files}
        key = draw(st.sampled_from(sorted(arrays)))
        if draw(st.integers(0, 4)) == 0:
            del arrays[key]
        else:
            arrays[key] = _odd_array(draw, arrays[key])
        save_npz(path, arrays)
        return Corruption(name, kind, array=key)
    if kind == "hdf5_dataset":
        with h5py.File(path, "a") as file:
            keys = []
            file.visit(lambda k: keys.append(k) if isinstance(file[k], h5py.Dataset) else None)
            key = draw(st.sampled_from(sorted(keys)))
            like = file[key][()]
            del file[key]
            if draw(st.integers(0, 4)):
                odd = _odd_array(draw, np.asarray(like))
                file.create_dataset(key, data=odd.astype("S") if odd.dtype.kind == "U" else odd)
        return Corruption(name, kind, dataset=key)
    raise AssertionError(kind)


# ---------------------------------------------------------------------------------------------- the episode

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


# ---------------------------------------------------------------------------------------------- other files

def corrupt_text(path: Path, draw) -> None:
    """Truncate, flip bytes, delete a range, or replace one line with random JSON (valid YAML and TOML-ish)."""
    kind = draw(st.sampled_from(("truncate", "flip", "delete_range", "line")))
    if kind == "line":
        lines = path.read_text().splitlines() or [""]
        i = draw(st.integers(0, len(lines) - 1))
        keep = lines[i].split("=", 1)[0] + "= " if "=" in lines[i] else lines[i].split(":", 1)[0] + ": "
        lines[i] = (keep if draw(st.booleans()) else "") + json.dumps(draw(json_values))
        path.write_text("\n".join(lines) + "\n")
    else:
        apply(path, draw, path.name)


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


@fuzz(80)
@given(st.data())
def test_a_corrupted_model_config_gives_one_line_naming_it(tmp_path_factory, data) -> None:
    from touchanything.inference.model.checkpoint import load_model

    folder = Path(tempfile.mkdtemp(prefix="fuzz-config-"))
    try:
        shutil.copyfile(NANO / "config.yaml", folder / "config.yaml")
        corrupt_text(folder / "config.yaml", data.draw)
        with no_hang():
            try:
                load_model(NANO / "best_model.pth", folder / "config.yaml")
            except UserError as exc:
                message = str(exc)
                assert "\n" not in message and ("config.yaml" in message or "best_model.pth" in message), message
    finally:
        shutil.rmtree(folder, ignore_errors=True)


@fuzz(150)
@given(st.sampled_from(sorted((ROOT / "scenes").glob("*.toml"))), st.data())
def test_a_corrupted_scene_file_gives_one_line_naming_it(scene, data) -> None:
    from touchanything.app.sessions.scene import read_scene

    folder = Path(tempfile.mkdtemp(prefix="fuzz-scene-"))
    try:
        path = folder / scene.name
        shutil.copyfile(scene, path)
        corrupt_text(path, data.draw)
        with no_hang():
            try:
                read_scene(path)
            except UserError as exc:
                assert str(exc).startswith(str(path)) and "\n" not in str(exc), str(exc)
    finally:
        shutil.rmtree(folder, ignore_errors=True)


@fuzz(50)
@given(st.data())
def test_a_corrupted_checkpoint_gives_one_line_naming_it(data) -> None:
    from touchanything.inference.model.checkpoint import load_model

    folder = Path(tempfile.mkdtemp(prefix="fuzz-ckpt-"))
    try:
        path = folder / "best_model.pth"
        shutil.copyfile(NANO / "best_model.pth", path)
        raw = path.read_bytes()
        if data.draw(st.booleans(), label="truncate"):
            path.write_bytes(raw[:_fraction(raw, data.draw(st.floats(0, 1)))])
        else:
            out = bytearray(raw)
            for f in data.draw(st.lists(st.floats(0, 1), min_size=1, max_size=4)):
                out[_fraction(raw, f)] ^= data.draw(st.integers(1, 255))
            path.write_bytes(bytes(out))
        with no_hang():
            try:
                load_model(path, NANO / "config.yaml")
            except UserError as exc:
                assert str(exc).startswith(str(path)) and "\n" not in str(exc), str(exc)
    finally:
        shutil.rmtree(folder, ignore_errors=True)


# ---------------------------------------------------------------------------------------------- what the fuzzing found

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
    from touchanything.devices.episodes.episode_files import read_pressure_grids
    from touchanything.devices.errors import DataError

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


@pytest.mark.parametrize("entry", ["", "x" * 300 + ".hdf5", "a\x00b.hdf5"])
def test_a_split_entry_that_is_no_path_is_one_line(tmp_path, entry):
    from touchanything.devices.episodes.dataset_split import read_split
    from touchanything.devices.errors import DataError

    (tmp_path / "split.json").write_text(json.dumps({"train": ["a.hdf5"], "val": [], "test_seen": [entry]}))
    with pytest.raises(DataError, match=r"split.json: test_seen: entry 1 is not a usable file path"):
        read_split(tmp_path / "split.json")
