"""What each command does with inputs and outputs that could lose data, with its real command: seeds and
durations refused alike, an output inside an input episode, unreadable videos named, replays that predicted
nothing or met damage, a LeRobot count that is wrong, a recording on a full disk (a real tmpfs), a video written
onto a full disk or past a file-size limit, a pose file under a video's name, and skipped glove samples named."""
from __future__ import annotations

import contextlib
import errno
import json
import os
import resource
import shutil
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import h5py
import numpy as np
import pytest

from tests.conftest import write_episode
from tests.integration.test_convert_safety import rewrite_line, tmpfs, with_nan
from tests.integration.test_input_links import digest
from tests.integration.test_refused_inputs import refused
from tests.timing.test_output_safety import leftovers
from touchanything.app.cli import main
from touchanything.devices.episodes.hdf5_convert import convert_trajectory
from touchanything.devices.episodes.hdf5_episode import IMAGE_KEYS, WILOR_VALID_KEYS
from touchanything.devices.episodes.video_io import VideoReader, VideoWriter
from touchanything.viz.comparison_video import is_comparison_video

REPO = Path(__file__).resolve().parents[2]
AS_ROOT = pytest.mark.skipif(os.geteuid() != 0, reason="mounting a tmpfs needs root")


@pytest.fixture(scope="module")
def small(tmp_path_factory) -> tuple[Path, Path]:
    """A short raw episode and its HDF5 trajectory."""
    root = tmp_path_factory.mktemp("small")
    raw = write_episode(root / "raw" / "Home" / "press" / "001", frames=40, size=(32, 32))
    h5 = root / "h5" / "Home" / "press" / "001.hdf5"
    assert convert_trajectory(raw, h5, 1).status == "converted"
    return raw, h5


def test_seeds_and_durations_are_refused_alike(tmp_path, capsys, small):
    refused(capsys, ["split", str(small[1].parents[2]), "--seed", "-1", "--out", str(tmp_path / "s.json")],
            "--seed must be an integer 0–4294967295, got -1")
    refused(capsys, ["simulate", str(tmp_path / "sim"), "--episodes", "1", "--seconds", "1e9"],
            "--seconds must be 1–3600", "got 1000000000.0")
    assert not (tmp_path / "sim").exists() and not (tmp_path / "s.json").exists()


def test_convert_into_an_input_episode_is_refused(tmp_path, capsys, small):
    raw = tmp_path / "raw"
    shutil.copytree(small[0].parents[2], raw)
    episode = raw / "Home" / "press" / "001"
    before = digest(raw)
    refused(capsys, ["convert", str(raw), str(episode / "conv2")], "the output would lie inside the input",
            str(episode))
    assert digest(raw) == before and not (episode / "conv2").exists()


def test_convert_names_the_video_that_does_not_read(tmp_path, capsys, small):
    raw = tmp_path / "raw"
    shutil.copytree(small[0].parents[2], raw)
    (raw / "Home" / "press" / "001" / "left.mp4").write_bytes(b"not a video at all" * 100)
    assert main(["convert", str(raw), str(tmp_path / "h5")]) == 1
    assert "cannot convert: unreadable left.mp4" in capsys.readouterr().out


def h5_copy(small, tmp_path: Path) -> Path:
    path = tmp_path / "Home" / "press" / "001.hdf5"
    path.parent.mkdir(parents=True)
    shutil.copyfile(small[1], path)
    return path


def test_a_replay_that_predicted_nothing_claims_no_metrics(tmp_path, capsys, small):
    path = h5_copy(small, tmp_path)
    with h5py.File(path, "a") as file:
        for key in WILOR_VALID_KEYS:
            file[key][...] = 0
    assert main(["replay", str(path), "--out", str(tmp_path / "r.mp4")]) == 0
    out = capsys.readouterr().out
    assert "metrics   n/a (no frame had a hand pose to predict from)" in out and "lamps agree" not in out


def test_a_replay_names_the_damage_it_met_while_reading(tmp_path, capsys, small):
    path = h5_copy(small, tmp_path)
    with h5py.File(path, "r") as file:
        chunk = file[IMAGE_KEYS["ego"]].id.get_chunk_info(20)
    with open(path, "r+b") as handle:
        handle.seek(chunk.byte_offset + 2)
        handle.write(b"\xff" * max(chunk.size - 4, 1))
    assert main(["replay", str(path), "--out", str(tmp_path / "r.mp4")]) == 0
    out = capsys.readouterr().out
    assert "problems  none" in out  # before the frames were read
    assert "problems  1 more found while replaying" in out and "images/chest_color" in out


def test_info_names_a_lerobot_count_that_is_wrong(tmp_path, capsys, small):
    out = tmp_path / "lerobot"
    assert main(["export-lerobot", str(small[0]), str(out)]) == 0
    info = out / "meta" / "info.json"
    data = json.loads(info.read_text())
    info.write_text(json.dumps({**data, "total_frames": -5, "total_episodes": 3}))
    capsys.readouterr()
    assert main(["info", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "meta/info.json: total_frames: -5 is not a count (a whole number ≥ 0)" in printed
    assert "meta/info.json: total_episodes: says 3; the dataset holds 1" in printed


@pytest.mark.skipif(os.geteuid() != 0, reason="mounting a tmpfs needs root")
def test_a_recording_on_a_full_disk_says_how_many_frames_replay(tmp_path):
    disk = tmp_path / "disk"
    disk.mkdir()
    subprocess.run(["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", str(disk)], check=True)
    try:
        run = subprocess.run([sys.executable, "-m", "touchanything.app.cli", "record", "--scene", str(REPO / "scenes" / "sim.toml"),
                              "--out", str(disk / "ep"), "--seconds", "4"], capture_output=True, text=True, timeout=300)
        err = run.stderr.strip().splitlines()
        assert run.returncode == 2 and len(err) == 1 and "No space left on device" in err[0], run.stderr[-2000:]
        assert "can be replayed (no frame of the head camera's video decodes)" in err[0] or " frames written before replay" in err[0]
    finally:
        subprocess.run(["umount", str(disk)], check=True)


def test_record_into_the_episode_the_simulated_rig_replays_is_refused(capsys):
    episode = REPO / "recordings" / "sample" / "Home" / "slide_box_cardboard" / "sim0007_00000"
    refused(capsys, ["record", "--scene", str(REPO / "scenes" / "sim.toml"), "--out", str(episode / "rec"), "--seconds", "1"],
            "the output would lie inside the input", "sim0007_00000")
    assert not (episode / "rec").exists()


# --- a video onto a full disk, a pose file under a video's name --------------------------------------------------

NOISE = [np.random.default_rng(k).integers(0, 256, (64, 64, 3), np.uint8) for k in range(60)]
"""Two seconds of noise: x264 writes the same bytes every run."""
PAGE = 4096


def noise_writer(path: Path, fragmented: bool) -> VideoWriter:
    """A writer for NOISE without scene cuts: a key frame every second, so that a fragmented video's second and last
    fragment is written when it closes, as a replay's last second is."""
    return VideoWriter(path, fragmented=fragmented, codec_options={"sc_threshold": "0"})


def noise_sizes(path: Path, fragmented: bool) -> tuple[int, int]:
    """The bytes a video of NOISE holds once every frame was given (what FFmpeg wrote before the close), and once
    closed."""
    writer = noise_writer(path, fragmented)
    for frame in NOISE:
        writer.write(frame)
    given = path.stat().st_size
    writer.close()
    return given, path.stat().st_size


@contextlib.contextmanager
def room_for(limit: str, size: int, folder: Path) -> Iterator[None]:
    """Files in the new `folder` take `size` bytes in all: it is a tmpfs of that size ("full disk"), or this
    process may not write a file past it ("file-size limit": RLIMIT_FSIZE; SIGXFSZ ignored, as Python does at start,
    so that the write fails with EFBIG: a native library loaded by an earlier test (depthai's crash handler) may
    have put its own handler there, which ends the process)."""
    if limit == "full disk":
        tmpfs(folder, str(size))
        try:
            yield
        finally:
            subprocess.run(["umount", str(folder)], check=True)
        return
    folder.mkdir()
    soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    resource.setrlimit(resource.RLIMIT_FSIZE, (size, hard))
    try:
        yield
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))


@pytest.mark.parametrize("limit, code", [pytest.param("full disk", errno.ENOSPC, marks=AS_ROOT),
                                         ("file-size limit", errno.EFBIG)])
@pytest.mark.parametrize("stage", ["muxing", "closing"])
@pytest.mark.parametrize("fragmented", [True, False])
def test_the_video_writer_raises_a_write_error_where_it_happens(tmp_path, limit, code, stage, fragmented):
    """FFmpeg dropped the error of the flush that writes the last fragment at close: the writer returned and the
    file was cut short. Now an error while muxing a frame, and one at close, is an OSError naming the file."""
    given, closed = noise_sizes(tmp_path / "whole.mp4", fragmented)
    size = PAGE * ((given // 2 if stage == "muxing" else (given + closed) // 2) // PAGE)
    assert (0 < size < given) if stage == "muxing" else (given < size < closed)
    path, written = tmp_path / "disk" / "noise.mp4", 0
    with room_for(limit, size, path.parent):
        with pytest.raises(OSError) as raised, noise_writer(path, fragmented) as writer:
            for frame in NOISE:
                writer.write(frame)
                written += 1
    assert (raised.value.errno, raised.value.filename) == (code, str(path))
    assert (written == len(NOISE)) == (stage == "closing")


def cli(*args: str) -> subprocess.CompletedProcess:
    """`touchanything ARGS` in a process of its own."""
    return subprocess.run([sys.executable, "-m", "touchanything.app.cli", *args], capture_output=True, text=True,
                          timeout=300)


@AS_ROOT
def test_a_replay_onto_a_full_disk_is_one_line_and_the_earlier_video_stays(tmp_path):
    """A replay that runs out of room while writing its video says so in one line (exit 2) instead of reporting the
    frames written, and the earlier video stays byte for byte: the replay first writes its video whole, then again
    with room for 3/4 of it."""
    episode = write_episode(tmp_path / "raw" / "Home" / "press" / "001", frames=60, size=(32, 32))
    disk = tmpfs(tmp_path / "disk", "8m")
    out = disk / "X.mp4"
    try:
        run = cli("replay", str(episode), "--headless", "--out", str(out))
        assert run.returncode == 0 and "frames    60 written" in run.stdout, run.stderr[-2000:]
        assert is_comparison_video(out) and leftovers(disk) == []
        with VideoReader(out) as video:
            assert video.num_frames == 60 and video.read(59).shape == (806, 1440, 3)
        before, pages = digest(out), -(-out.stat().st_size // PAGE)
        room = PAGE * (pages + 3 * pages // 4)  # the earlier video, and 3/4 of another: the second second does not fit
        subprocess.run(["mount", "-o", f"remount,size={room}", str(disk)], check=True)
        run = cli("replay", str(episode), "--headless", "--out", str(out))
        said = [line for line in run.stderr.splitlines() if line.strip() and not line.startswith("replay:")]  # not tqdm
        assert run.returncode == 2, run.stderr[-2000:]
        assert said == [f"touchanything replay: error: {out}: not written (No space left on device)"], said
        assert " written" not in run.stdout and "video     " not in run.stdout
        assert digest(out) == before and leftovers(disk) == []
    finally:
        subprocess.run(["umount", str(disk)], check=True)


def test_pose_refuses_an_output_that_is_not_a_json_file(tmp_path, capsys, small):
    out = tmp_path / "x.mp4"
    argv = ["pose", str(small[0] / "chest.mp4"), "--out", str(out)]
    refused(capsys, argv, f"{out}: the pose file is JSON lines and must be a .json file")
    assert not out.exists()
    out.write_bytes(b"a video of the user's")
    refused(capsys, [*argv, "--overwrite"], "must be a .json file")
    assert out.read_bytes() == b"a video of the user's" and leftovers(tmp_path) == []


def test_grids_names_the_glove_samples_it_skipped(tmp_path, capsys, small):
    episode = tmp_path / "001"
    shutil.copytree(small[0], episode)
    glove = episode / "jq_pressure.json"
    rewrite_line(glove, 5, lambda text: text[:40])  # malformed lines
    rewrite_line(glove, 12, lambda text: "[1, 2]")
    rewrite_line(glove, 3, lambda text: with_nan(text, "left", "raw", 0))  # a NaN where a pressure value belongs
    rewrite_line(glove, 8, lambda text: with_nan(text, "right", "raw", 17))
    rewrite_line(glove, 9, lambda text: with_nan(text, "right", "quat_wxyz", 0))
    before = digest(glove)
    grids = digest(episode / "pressure_grids.npz")
    assert main(["grids", str(episode)]) == 0  # the grids could be computed: the status is unchanged
    printed = capsys.readouterr().out.splitlines()
    assert printed[0].startswith(f"{episode}: 40 frames; ") and printed[1:] == [
        f"{glove}: 5 glove samples skipped: malformed lines (2 lines, first line 5); left: expected raw[256] integers "
        "0–255 and quat_wxyz[4]; sample dropped (line 3); right: expected raw[256] integers 0–255 and quat_wxyz[4]; "
        "sample dropped (line 8); right.quat_wxyz: [nan, 0.0, 0.0, 0.0] is not 4 finite numbers of non-zero length; "
        "sample dropped (line 9)"]
    assert digest(glove) == before and digest(episode / "pressure_grids.npz") != grids
    shutil.copyfile(small[0] / "jq_pressure.json", glove)  # an intact glove stream: no such line
    assert main(["grids", str(episode)]) == 0 and len(capsys.readouterr().out.splitlines()) == 1
