"""Every real path a command's inputs resolve to: each input itself (links and `..` resolved) and, inside an
input folder (an episode, a dataset root), every symbolic link's target — an episode or trajectory a dataset
reaches through a link is as much an input as one stored in it — followed into linked folders, each folder
once (a link loop ends). Files with more than one hard link are remembered by inode, so that an output that is
the same file under another name is known too. `output_safety.check_output` refuses any output that is,
holds or lies inside one of them."""
from __future__ import annotations

import os
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class InputPath:
    """`resolved`: a real path the command reads; `given`: the input as named on the command line; `link`: the
    symbolic link inside it that reaches `resolved` (None for the input itself)."""

    given: Path
    resolved: Path
    link: Path | None = None

    def named(self) -> str:
        """"ROOT" or "/data/ep (reached through ROOT/Home/task/001)"."""
        return str(self.given) if self.link is None else f"{self.resolved} (reached through {self.link})"


@dataclass
class Inputs:
    """The real paths of a command's inputs and the (device, inode) of every input file with other hard links."""

    paths: list[InputPath]
    inodes: dict[tuple[int, int], InputPath]

    def same_file(self, path: Path) -> InputPath | None:
        """The input `path` is a hard link of (an existing file with more than one link), or None."""
        try:
            status = os.stat(path)
        except OSError:
            return None
        return self.inodes.get((status.st_dev, status.st_ino)) if status.st_nlink > 1 else None


def collect_inputs(inputs: Iterable[Path | None]) -> Inputs:
    """`Inputs` of every input given (None: an optional input not used)."""
    found = Inputs([], {})
    walked: set[Path] = set()
    for given in (Path(p) for p in inputs if p is not None):
        resolved = given.resolve()
        found.paths.append(InputPath(given, resolved))
        _remember_inode(found, given, InputPath(given, resolved))
        if resolved.is_dir():
            _walk(found, given, resolved, walked)
    return found


def _remember_inode(found: Inputs, path: Path, entry: InputPath) -> None:
    try:
        status = os.stat(path)
    except OSError:
        return
    if status.st_nlink > 1 and not os.path.isdir(path):
        found.inodes.setdefault((status.st_dev, status.st_ino), entry)


def _walk(found: Inputs, given: Path, folder: Path, walked: set[Path]) -> None:
    """Links and multiply-linked files under `folder` (real), following linked folders once each."""
    if folder in walked:
        return
    walked.add(folder)
    for root, dirs, files in os.walk(folder, onerror=lambda error: None):
        for name in dirs + files:
            path = Path(root) / name
            if path.is_symlink():
                target = path.resolve()
                if not target.exists():
                    continue
                entry = InputPath(given, target, path)
                found.paths.append(entry)
                _remember_inode(found, target, entry)
                if target.is_dir():
                    _walk(found, given, target, walked)
            elif name in files:
                _remember_inode(found, path, InputPath(given, path.resolve()))
