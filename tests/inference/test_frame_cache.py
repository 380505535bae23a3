"""The training frame cache: the same frames as decoding per clip, reused by content, rebuilt when the content
changes, written atomically, and read the same by loader workers."""
from __future__ import annotations

import fcntl
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
import torch

from touchanything.core.errors import UserError
from touchanything.inference.model.preprocess import resize_frame
from touchanything.inference.training import frame_cache as frame_cache_module
from touchanything.inference.training.clip_dataset import ClipDataset, clip_loader, load_episode
from touchanything.inference.training.frame_cache import BUILD_LOCK, CACHE_DIR, FRAMES, FrameCache, write_entry


@pytest.fixture
def root(sim_hdf5_root, tmp_path) -> Path:
    copy = tmp_path / "h5"
    shutil.copytree(sim_hdf5_root, copy, ignore=shutil.ignore_patterns(CACHE_DIR))
    return copy


def trajectories(root: Path) -> list[Path]:
    return sorted(root.rglob("*.hdf5"))


def test_cached_clips_equal_clips_decoded_from_the_file(root):
    files = trajectories(root)
    cache = FrameCache.beside(root, 56)
    cached, decoded = ClipDataset(files, 56, cache=cache), ClipDataset(files, 56)
    assert cache.built == len(files) and cache.reused == 0
    for index in (0, len(decoded) - 1):
        a, b = cached[index]["views"], decoded[index]["views"]
        assert a.keys() == b.keys() == {"ego", "wrist_left", "wrist_right"}
        for view in a:
            assert torch.equal(a[view], b[view])


def test_the_cache_beside_a_dataset_is_not_taken_for_trajectories(root, capsys):
    from touchanything.app.cli import main
    from touchanything.devices.episodes.episode_loader import find_empty_folders, find_hdf5_files

    files = trajectories(root)
    ClipDataset(files, 56, cache=FrameCache.beside(root, 56))
    assert len(list((root / CACHE_DIR).glob("*.h5"))) == len(files) == 3
    assert find_hdf5_files(root) == files and find_empty_folders(root) == []
    assert main(["split", str(root), "--min-frames", "10", "--out", str(root / "again.json"), "--allow-empty"]) == 0
    assert "train 1, val 1, test_seen 1, test_unseen 0; excluded 0" in capsys.readouterr().out


def test_entries_are_reused_by_content_and_rebuilt_when_it_changes(root):
    files = trajectories(root)
    ClipDataset(files, 56, cache=FrameCache.beside(root, 56))
    entries = sorted((root / CACHE_DIR).glob("*.h5"))
    assert len(entries) == len(files)

    again = FrameCache.beside(root, 56)
    ClipDataset(files, 56, cache=again)
    assert (again.built, again.reused) == (0, len(files))

    moved = root / "renamed.hdf5"  # the same bytes under another name: still the same entry
    shutil.copy2(files[0], moved)
    renamed = FrameCache.beside(root, 56)
    renamed.entry(moved, ("ego", "wrist_left", "wrist_right"))
    assert (renamed.built, renamed.reused) == (0, 1)

    with h5py.File(files[0], "r+") as file:  # new content: a new entry, with the new frames
        file["images/chest_color"][0] = 255
    changed = FrameCache.beside(root, 56)
    frames = changed.clip(files[0], ("ego", "wrist_left", "wrist_right"), np.array([0, 1]))
    assert changed.built == 1 and np.all(frames[0, 0] == 255) and not np.all(frames[1, 0] == 255)
    assert len(list((root / CACHE_DIR).glob("*.h5"))) == len(files) + 1


def test_an_interrupted_build_leaves_no_entry_and_no_temporary_file(root, monkeypatch):
    calls = []

    def interrupted(image, size):  # Ctrl-C on the second frame: the entry's file is half written
        calls.append(size)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return resize_frame(image, size)

    cache = FrameCache.beside(root, 56)
    monkeypatch.setattr(frame_cache_module, "resize_frame", interrupted)
    with pytest.raises(KeyboardInterrupt):
        cache.entry(trajectories(root)[0], ("ego",))
    monkeypatch.undo()

    def full_disk(image, size):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(frame_cache_module, "resize_frame", full_disk)
    with pytest.raises(OSError, match="No space left"):
        cache.entry(trajectories(root)[0], ("ego",))
    leftovers = [p.name for p in (root / CACHE_DIR).iterdir() if p.name not in ("index.json", BUILD_LOCK)]
    assert leftovers == []


def test_what_a_killed_build_left_is_removed_by_the_next_run(root, capsys):
    """A training killed (SIGKILL) while it writes an entry leaves the entry's marked temporary file; the next run
    that opens the cache removes it, and says so. A look-alike without the project's marker stays."""
    path = trajectories(root)[0]
    code = ("import os, signal, sys; from pathlib import Path\n"
            "from touchanything.inference.training import frame_cache as m\n"
            "calls = []\n"
            "def killed(image, size):\n"
            "    calls.append(size)\n"
            "    if len(calls) == 3: os.kill(os.getpid(), signal.SIGKILL)\n"
            "    return original(image, size)\n"
            "original, m.resize_frame = m.resize_frame, killed\n"
            "m.FrameCache.beside(Path(sys.argv[1]), 56).entry(Path(sys.argv[2]), ('ego',))\n")
    killed = subprocess.run([sys.executable, "-c", code, str(root), str(path)])
    assert killed.returncode == -signal.SIGKILL
    left = [p for p in (root / CACHE_DIR).iterdir() if ".partial-" in p.name and not p.name.endswith(".owner")]
    assert len(left) == 1 and Path(f"{left[0]}.owner").is_file()
    users = root / CACHE_DIR / ".notes.partial-1"
    users.write_text("not the project's")
    cache = FrameCache.beside(root, 56)
    assert f"removed {left[0]}: left half-written by an interrupted run" in capsys.readouterr().err
    assert not left[0].exists() and not Path(f"{left[0]}.owner").exists() and users.is_file()
    assert cache.clip(path, ("ego",), np.array([0])).shape == (1, 1, 56, 56, 3) and cache.built == 1


def test_a_folder_that_cannot_be_written_is_one_line(root):
    (root / CACHE_DIR).write_text("a file where the cache folder should be")
    with pytest.raises(UserError, match=r"\.frame_cache: cannot write the frame cache"):
        FrameCache.beside(root, 56)


@pytest.mark.multiprocess
def test_loader_workers_read_the_same_cached_batches(root):
    files = trajectories(root)
    dataset = ClipDataset(files, 56, cache=FrameCache.beside(root, 56))
    batches = []
    for workers in (0, 2):
        loader = clip_loader(dataset, 2, workers, seed=4, shuffle=True)
        loader.sampler.set_epoch(1)
        batches.append([b["views"]["ego"] for b in loader])
        del loader
    assert len(batches[0]) == len(batches[1])
    assert all(torch.equal(a, b) for a, b in zip(*batches))


def test_the_index_spares_hashing_unchanged_files(root, monkeypatch):
    files = trajectories(root)
    FrameCache.beside(root, 56).digest(files[0])
    hashed = []
    monkeypatch.setattr(frame_cache_module, "file_digest", lambda path: hashed.append(path) or "x")
    FrameCache.beside(root, 56).digest(files[0])
    assert hashed == []
    os.utime(files[0], ns=(0, 0))
    FrameCache.beside(root, 56).digest(files[0])
    assert hashed == [files[0]]


def test_a_second_training_waits_for_the_entry_the_first_is_building(root):
    """Two trainings side by side on one dataset: while one holds the build lock, the other waits and then reuses
    the entry it finds, instead of decoding the trajectory a second time."""
    file, views = trajectories(root)[0], ("ego", "wrist_left", "wrist_right")
    folder = FrameCache.beside(root, 56).folder
    code = ("import sys; from pathlib import Path; from touchanything.inference.training.frame_cache import FrameCache; "
            "cache = FrameCache.beside(Path(sys.argv[1]), 56); print('ready', flush=True); "
            f"cache.entry(Path(sys.argv[2]), {views!r}); print(cache.built, cache.reused)")
    with open(folder / BUILD_LOCK, "a") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # the first training, building this entry
        child = subprocess.Popen([sys.executable, "-c", code, str(root), str(file)], stdout=subprocess.PIPE,
                                 stderr=subprocess.PIPE, text=True)
        assert child.stdout.readline() == "ready\n"
        time.sleep(1.0)  # the second training reaches the entry
        name = f"{FrameCache(folder, 56).digest(file)}.{'-'.join(views)}.56px.h5"
        write_entry(file, views, 56, folder / name)
    out, err = child.communicate(timeout=60)
    assert out.split() == ["0", "1"]  # built none, reused the first one's
    assert err.count("another run is building entries; waiting for them") == 1


def test_entries_are_compressed_and_read_the_same_in_a_forked_child(root):
    """An entry is smaller than the frames it holds (gzip chunks), and a child forked after the parent read it
    opens its own handle and reads the same frames (a DataLoader worker of the default start method)."""
    file, views = trajectories(root)[0], ("ego", "wrist_left", "wrist_right")
    cache = FrameCache.beside(root, 56)
    frames = np.array([0, 2, 4])
    in_parent = cache.clip(file, views, frames)
    parent_handle = cache._open[file]
    with h5py.File(cache.entry(file, views), "r") as entry:
        count = len(entry["frames"])
    assert (root / CACHE_DIR / cache.entry(file, views).name).stat().st_size < count * 3 * 56 * 56 * 3 / 1.5
    reader, writer = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child: report whether its frames equal the parent's, never return into pytest
        try:
            same = np.array_equal(cache.clip(file, views, frames), in_parent) and cache._open[file] is not parent_handle
            os.write(writer, b"same" if same else b"different")
        finally:
            os._exit(0)
    os.close(writer)
    os.waitpid(pid, 0)
    assert os.read(reader, 16) == b"same"


@pytest.fixture
def raw_root(sim_raw_root, tmp_path) -> Path:
    copy = tmp_path / "raw"
    shutil.copytree(sim_raw_root, copy)
    return copy


def raw_twins(raw_root: Path, h5_root: Path) -> tuple[list[Path], list[Path]]:
    """The raw episode folders and the HDF5 files `convert` made of them, in the same order."""
    files = trajectories(h5_root)
    return [raw_root / f.relative_to(h5_root).with_suffix("") for f in files], files


def test_raw_episode_folders_train_on_the_clips_of_their_converted_files(raw_root, root):
    """Data too large to keep as HDF5 train from their raw folders: every item (frames, poses, target, mask) equals
    the one of the HDF5 file `convert` made of the folder."""
    folders, files = raw_twins(raw_root, root)
    from_raw = ClipDataset(folders, 56, cache=FrameCache.beside(root, 56))
    from_h5 = ClipDataset(files, 56, cache=FrameCache.beside(root, 56))
    assert len(from_raw) == len(from_h5) > 0
    for index in range(len(from_raw)):
        a, b = from_raw[index], from_h5[index]
        assert a["views"].keys() == b["views"].keys() == {"ego", "wrist_left", "wrist_right"}
        assert all(torch.equal(a["views"][v], b["views"][v]) for v in a["views"])
        for key in ("poses", "target", "mask", "frames"):
            assert torch.equal(a[key], b[key]), key
    assert [e.normalized for e in from_raw.episodes] == [e.normalized for e in from_h5.episodes]


def test_a_raw_folder_is_keyed_by_its_videos(raw_root, root):
    folders, _ = raw_twins(raw_root, root)
    cache = FrameCache.beside(root, 56)
    first = cache.digest(folders[0])
    moved = raw_root / "elsewhere"
    shutil.copytree(folders[0], moved)
    (moved / "wilor_hands.json").write_text("[]")  # not a source of its frames
    assert FrameCache.beside(root, 56).digest(moved) == first
    with open(moved / "left.mp4", "ab") as video:
        video.write(b"\0")
    assert FrameCache.beside(root, 56).digest(moved) != first


def test_a_raw_folder_without_the_cache_or_a_video_is_one_line(raw_root, root):
    folders, _ = raw_twins(raw_root, root)
    with pytest.raises(UserError, match="a raw episode folder trains from the frame cache, and there is none"):
        ClipDataset(folders[:1], 56)
    assert len(ClipDataset(folders[:1], 56, blank=True)) > 0  # the pose-only baseline reads no frame
    (folders[0] / "right.mp4").write_bytes(b"not a video")  # trained without that view, as an HDF5 file without it
    assert ClipDataset(folders[:1], 56, cache=FrameCache.beside(root, 56))[0]["views"].keys() == {"ego", "wrist_left"}
    with pytest.raises(UserError, match=r"no readable right\.mp4; cannot train on its frames"):
        FrameCache.beside(root, 56).entry(folders[0], ("ego", "wrist_left", "wrist_right"))


def test_a_raw_video_cut_short_cuts_the_trajectory_where_it_stops_decoding(raw_root, root):
    """A video that declares more frames than it decodes (a copy cut short): the trajectory ends at the last frame
    every view decodes, as `convert` cuts it, poses and pressure with it."""
    from touchanything.devices.episodes.video_io import VideoReader

    folder = raw_twins(raw_root, root)[0][0]
    chest = folder / "chest.mp4"
    with open(chest, "r+b") as video:
        video.truncate(chest.stat().st_size // 2)
    reader = VideoReader(chest)
    decoded = next(i for i in range(reader.num_frames + 1) if reader.read(i) is None)
    reader.close()
    assert 0 < decoded < load_episode(folder, "wilor").poses.shape[0]
    episode = ClipDataset([folder], 56, cache=FrameCache.beside(root, 56)).episodes[0]
    assert episode.poses.shape[0] == episode.pressure.shape[0] == decoded


def test_entries_built_in_worker_processes_equal_those_built_here(raw_root, root, tmp_path, monkeypatch):
    """A training's missing entries are decoded in as many processes as it has torch threads (not in this one: its
    resizing fails here once the serial build is done): the frames equal those decoded in this process, byte for
    byte, every entry counts once and the progress ticks once each."""
    folders, files = raw_twins(raw_root, root)
    views = ("ego", "wrist_left", "wrist_right")
    serial, parallel = FrameCache(tmp_path / "serial", 56), FrameCache(tmp_path / "parallel", 56)
    serial.folder.mkdir(), parallel.folder.mkdir()
    ticks = []
    serial.build([(f, views) for f in folders + files])
    monkeypatch.setattr(frame_cache_module, "resize_frame", lambda image, size: 1 / 0)
    parallel.build([(f, views) for f in folders + files], workers=2, on_entry=lambda: ticks.append(1))
    assert (parallel.built, parallel.reused, len(ticks)) == (len(folders) + len(files), 0, len(folders) + len(files))
    for path in folders + files:
        with h5py.File(serial.entry(path, views), "r") as a, h5py.File(parallel.entry(path, views), "r") as b:
            assert np.array_equal(a[FRAMES][()], b[FRAMES][()])
    again = FrameCache(parallel.folder, 56)
    again.build([(f, views) for f in files], workers=2)
    assert (again.built, again.reused) == (0, len(files))


def test_a_trajectory_a_worker_cannot_decode_is_one_line_and_leaves_no_file(raw_root, root):
    folders, _ = raw_twins(raw_root, root)
    (folders[1] / "right.mp4").unlink()
    cache = FrameCache.beside(root, 56)
    with pytest.raises(UserError, match=r"no readable right\.mp4; cannot train on its frames"):
        cache.build([(f, ("ego", "wrist_left", "wrist_right")) for f in folders], workers=2)
    assert not [p for p in cache.folder.iterdir() if ".partial-" in p.name]
