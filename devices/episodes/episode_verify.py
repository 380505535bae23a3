"""Verify an episode on request: read every chunk of every HDF5 dataset and decode every video frame.

Opening an episode reads its streams but not its pictures, and an HDF5 file's damaged chunks stay unseen until
a frame in them is asked for. `verify_episode` reads everything and returns one line per damaged part (empty:
nothing found). It cannot see a flipped byte in data stored without a checksum or compression (HDF5's
uncompressed contiguous datasets), only what the file's own checks or a decoder reject.
"""
from __future__ import annotations

from pathlib import Path

import h5py

from touchanything.core.errors import describe, failure_line
from touchanything.devices.episodes.episode_loader import is_hdf5_path, open_episode
from touchanything.devices.episodes.hdf5_episode import H5_ERRORS


def _reason(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return text[0] if text else exc.__class__.__name__


def _dataset_damage(path: Path, dataset: h5py.Dataset) -> str | None:
    """Read `dataset` chunk by chunk (whole when it is not chunked); a line for its unreadable chunks."""
    name = dataset.name.lstrip("/")
    if dataset.size == 0:
        return None
    if dataset.chunks is None:
        try:
            dataset[()]
            return None
        except H5_ERRORS as exc:
            return describe(path, name, f"unreadable ({_reason(exc)})")
    bad, first = 0, None
    for chunk in dataset.iter_chunks():
        try:
            dataset[chunk]
        except H5_ERRORS as exc:
            bad += 1
            first = first or (chunk, exc)
    if not bad:
        return None
    start = first[0][0].start if dataset.ndim else 0
    return describe(path, name, f"{bad} unreadable chunk(s), the first at index {start} ({_reason(first[1])})")


def hdf5_damage(path: Path) -> list[str]:
    """Every dataset of an HDF5 file read in full; a line per damaged dataset or unreadable object."""
    problems: list[str] = []
    try:
        file = h5py.File(path, "r")
    except H5_ERRORS as exc:
        return [describe(path, None, f"not a readable HDF5 file ({_reason(exc)})")]
    with file:
        def visit(name: str) -> None:
            try:
                item = file[name]
            except H5_ERRORS as exc:
                problems.append(describe(path, name, f"unreadable ({_reason(exc)})"))
                return
            try:
                line = _dataset_damage(path, item) if isinstance(item, h5py.Dataset) else None
            except H5_ERRORS as exc:
                line = describe(path, name, f"unreadable ({_reason(exc)})")
            if line:
                problems.append(line)

        try:
            file.visit(visit)
        except H5_ERRORS as exc:
            problems.append(describe(path, None, f"the file's structure is unreadable ({_reason(exc)})"))
    return problems


def frame_damage(path: Path) -> list[str]:
    """Decode every frame of every view of the episode at `path`; a line per view that stops early."""
    problems: list[str] = []
    with open_episode(path) as episode:
        for view, source in episode.views.items():
            missing = [i for i in range(source.num_frames) if source.read(i) is None]
            if missing:
                problems.append(describe(path, view, f"{len(missing)} of {source.num_frames} frames do not decode "
                                         f"(the first is frame {missing[0]})"))
    return problems


def verify_episode(path: Path) -> list[str]:
    """What is damaged in an episode (an HDF5 file: every dataset; a raw folder or LeRobot episode: every video
    frame; their other files are read in full when the episode opens): a line each; never raises."""
    try:
        return hdf5_damage(path) if is_hdf5_path(Path(path)) else frame_damage(path)
    except Exception as exc:  # noqa: BLE001 - whatever breaks while reading damaged bytes is the finding
        return [failure_line(path, exc)]
