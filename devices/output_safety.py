"""The one rule every command that writes follows (docs/data_safety.md):

1. Before any work, `check_output(out, inputs, overwrite, …)`: an output that is (or resolves to) one of the
   command's inputs, that would replace a file inside an input folder (an episode, a dataset) which is not
   an output of this kind, or that would replace a whole folder holding an input, is refused; an existing
   output of another kind (not recognised by `own`) is replaced only with `--overwrite`; the place the
   output goes is checked for writability (a probe file, created and removed: permissions, read-only
   mounts, a file where a folder should be).
2. Every file is written through `replacing(path)` (or `write_text`): to a hidden temporary file in the
   same folder, synced to disk and renamed over `path` only when complete (the folder synced after the
   rename, so that a power cut after the command reported success loses nothing); on any error, disk full
   included, the temporary file is removed and an OSError becomes one line (UserError) naming the output. A
   folder built as a whole goes through `replacing_folder(out)` the same way. The temporary files a process
   that no longer runs left in the output's folder (killed before it could clean up) are removed first, each
   named on stderr.

The only exceptions are the recorder's episode folders, written live so that a crash keeps what was
recorded (they are still checked by rule 1)."""
from __future__ import annotations

import argparse
import contextlib
import errno
import os
import re
import shutil
import sys
import tempfile
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

from touchanything.devices.errors import UserError
from touchanything.devices.input_paths import collect_inputs

PARTIAL = ".partial-"
"""In the name of every temporary output: `.<name>.partial-<pid>` beside the output (hidden, and with no suffix
of its own, so no reader takes a half-written `.hdf5` or `.mp4` for data)."""
_LEFT_BEHIND = re.compile(r"\..+\.(?:partial|old)-([0-9]+)")
"""A temporary output (`.<name>.partial-<pid>`) or a replaced folder awaiting removal (`.<name>.old-<pid>`)."""


def add_overwrite_argument(parser: argparse.ArgumentParser, what: str) -> None:
    """The commands' one `--overwrite` option: replace `what` (e.g. "--out") when it exists."""
    parser.add_argument("--overwrite", action="store_true",
                        help=f"replace {what} when it exists (default: refuse; never an input of the command)")


def _never(path: Path) -> bool:
    return False


def named(*names: str) -> Callable[[Path], bool]:
    """An `own` test for outputs with fixed names (a report folder's files): a file of one of these names."""
    return lambda path: path.name in names and path.is_file()


def check_output(out: Path, inputs: Iterable[Path | None] = (), overwrite: bool = False, *,
                 own: Callable[[Path], bool] = _never, folder: bool = False, whole: bool = False) -> None:
    """Rule 1 for the output `out` of a command reading `inputs` (files and folders). `own(path)`: an existing
    path is an earlier output of the same kind (replaced without `overwrite`). `folder`: `out` is a folder the
    command writes named files into (check each of them too); `whole`: a folder the command builds as a whole
    (an existing non-empty one is replaced only with `overwrite`, never when it holds an input). Raises
    UserError (one line); creates nothing. Inputs are every real path they resolve to, the targets of the
    links inside input folders included (`input_paths`), and an output that is a hard link of an input file
    is that input."""
    out = Path(out)
    check_name_lengths(out)
    target = out.resolve()
    found = collect_inputs(inputs)
    if (same := found.same_file(target)) is not None:
        raise UserError(f"{out}: is the input {same.named()} under another name (a hard link); choose another output")
    for source in found.paths:
        real, given = source.resolved, source.named()
        if target == real:
            raise UserError(f"{out}: is an input of this command ({given}); choose another output")
        if whole and (target in real.parents or (real in target.parents and target.is_dir())):
            raise UserError(f"{out}: {'holds' if target in real.parents else 'is a folder of'} the input {given}; "
                            "choose a folder outside it")
        if real in target.parents and target.exists() and not target.is_dir() and not own(target):
            raise UserError(f"{out}: would replace a file of the input {given} that touchanything did not write; "
                            "choose a path outside it")
    if folder or whole:
        if target.exists() and not target.is_dir():
            raise UserError(f"{out}: exists and is not a folder")
        if whole and target.is_dir() and any(target.iterdir()) and not overwrite:
            raise UserError(f"{out}: folder is not empty; pass --overwrite to replace it")
    elif target.is_dir():
        raise UserError(f"{out}: is a folder; give the file to write")
    elif target.exists() and not overwrite and not own(target):
        raise UserError(f"{out}: exists; pass --overwrite to replace it")
    check_writable(target if folder or whole else target.parent)


def check_outside(out: Path, folders: Iterable[Path]) -> None:
    """UserError when the output folder `out` is, or would lie inside, one of the input `folders` (an episode, a
    dataset a command builds a whole new folder from)."""
    target = Path(out).resolve()
    for folder in folders:
        real = Path(folder).resolve()
        if real.is_dir() and (real == target or real in target.parents):
            raise UserError(f"{out}: the output would lie inside the input {folder}; choose a folder outside it")


def check_name_lengths(out: Path) -> None:
    """UserError when a name in `out`, or the temporary name its file is first written under, is longer than the
    file system of its nearest existing folder allows (checked before any work; the OS would refuse it after)."""
    existing = Path(out)
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    try:
        limit = os.pathconf(existing if existing.is_dir() else existing.parent, "PC_NAME_MAX")
    except (OSError, ValueError):
        limit = 255
    names = [*Path(out).parts[1 if Path(out).is_absolute() else 0:], temporary_path(out).name]
    longest = max(names, key=lambda name: len(os.fsencode(name)))
    if len(os.fsencode(longest)) > limit:
        what = "the temporary name it is written under" if longest == names[-1] else f"the name {longest[:24]}…"
        raise UserError(f"{out}: {what} is {len(os.fsencode(longest))} bytes, longer than the file system allows "
                        f"({limit}); choose a shorter name")


def check_report_folder(out: Path, names: Iterable[str], inputs: Iterable[Path | None] = (),
                        keep: bool = False, overwrite: bool = False) -> None:
    """`check_output` for a folder the command writes files of fixed `names` into (a report folder): the
    folder, then each file (an earlier one of that name is replaced; an input never is). `keep`: an earlier
    one is replaced only with `overwrite` (results a user may want to keep)."""
    inputs = list(inputs)
    check_output(out, inputs, folder=True)
    for name in names:
        check_output(Path(out) / name, inputs, overwrite, own=_never if keep else named(name))


def check_writable(folder: Path) -> None:
    """The nearest existing folder of `folder` (itself or an ancestor) takes a new file: one is created and
    removed. UserError otherwise."""
    existing = Path(folder)
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if not existing.is_dir():
        raise UserError(f"{folder}: cannot be created ({existing} is not a folder)")
    try:
        handle, probe = tempfile.mkstemp(prefix=f".touchanything{PARTIAL}", dir=existing)
        os.close(handle)
        os.unlink(probe)
    except OSError as exc:
        raise UserError(f"{folder}: not writable ({describe(exc)})") from None


def describe(exc: OSError) -> str:
    """The OS's reason of an OSError ("No space left on device": for its error number, also when a library such
    as HDF5 put its own text in the message), else its first line."""
    if exc.errno:
        return os.strerror(exc.errno)
    return exc.strerror or (str(exc).splitlines() or [type(exc).__name__])[0]


def temporary_path(path: Path) -> Path:
    """The hidden temporary name of `path` in its folder (a writer that chooses the format by the suffix must
    be told the format)."""
    path = Path(path)
    return path.with_name(f".{path.name}{PARTIAL}{os.getpid()}")


def _remove(path: Path) -> None:
    with contextlib.suppress(OSError):
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        else:
            path.unlink(missing_ok=True)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # another user's process: alive
        return True
    return True


def remove_left_behind(folder: Path) -> list[Path]:
    """Remove the temporary outputs that processes which no longer run left in `folder` (killed before they
    could clean up), naming each on stderr; a running process's are left alone. Returns what was removed."""
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return []
    removed = []
    for entry in entries:
        match = _LEFT_BEHIND.fullmatch(entry.name)
        if match and int(match.group(1)) != os.getpid() and not _alive(int(match.group(1))):
            _remove(Path(entry.path))
            removed.append(Path(entry.path))
            print(f"removed {entry.path}: left half-written by an interrupted run (process {match.group(1)})",
                  file=sys.stderr)
    return removed


def sync(path: Path) -> None:
    """Flush `path` to disk: a file's data, or every file and folder entry under a folder."""
    if Path(path).is_dir():
        for root, _, files in os.walk(path):
            for name in files:
                fsync_path(Path(root) / name)
            fsync_path(Path(root), directory=True)
    else:
        fsync_path(Path(path))


def fsync_fd(fd: int, path: Path) -> None:
    """os.fsync(fd); an OSError names `path`. EINVAL (a special file such as /dev/null, which has nothing to
    put on a disk) is not an error."""
    try:
        os.fsync(fd)
    except OSError as exc:
        if exc.errno != errno.EINVAL:
            raise OSError(exc.errno, exc.strerror, str(path)) from exc


def fsync_path(path: Path, directory: bool = False) -> None:
    """fsync a file by name, or a directory (its entries: files created in it survive a power loss)."""
    try:
        fd = os.open(path, os.O_RDONLY | (os.O_DIRECTORY if directory else 0))
    except OSError as exc:
        raise OSError(exc.errno, exc.strerror, str(path)) from exc
    try:
        fsync_fd(fd, path)
    finally:
        os.close(fd)


@contextlib.contextmanager
def replacing(path: Path) -> Iterator[Path]:
    """Rule 2: yields the temporary path to write; when the block ends it is synced and renamed over `path`
    (its folder is created first, and synced after). On any exception the temporary file is removed and `path`
    is left as it was; an OSError (no space, file too large, read-only…) is raised as a UserError naming `path`.
    A sync that fails (the disk reports an I/O error) leaves the complete file in place and raises a UserError
    saying it is not confirmed on the disk: what was written is kept, and the command does not report success."""
    path = Path(path)
    temporary = temporary_path(path)
    with _removed_on_failure(temporary, path):
        path.parent.mkdir(parents=True, exist_ok=True)
        remove_left_behind(path.parent)
        yield temporary
        _synced_rename(temporary, path)


def _synced_rename(temporary: Path, path: Path, rename: Callable[[], None] | None = None) -> None:
    """Sync `temporary`, rename it over `path` (or run `rename`), sync the folder; a failed sync is raised (as
    "not confirmed on the disk") after the rename, a failed rename at once."""
    unconfirmed = _sync_failure(lambda: sync(temporary))
    (rename or (lambda: os.replace(temporary, path)))()
    unconfirmed = _sync_failure(lambda: fsync_path(path.parent, directory=True)) or unconfirmed
    if unconfirmed is not None:
        raise UserError(f"{path}: written, but not confirmed on the disk ({describe(unconfirmed)})")


def _swap_in(temporary: Path, out: Path) -> None:
    """`temporary` takes the place of the folder `out` (an existing one is moved aside first, then removed)."""
    if not out.exists():
        os.replace(temporary, out)
        return
    old = out.with_name(f".{out.name}.old-{os.getpid()}")
    os.replace(out, old)
    os.replace(temporary, out)
    _remove(old)


def _sync_failure(step: Callable[[], None]) -> OSError | None:
    try:
        step()
    except OSError as exc:
        return exc
    return None


@contextlib.contextmanager
def _removed_on_failure(temporary: Path, target: Path) -> Iterator[None]:
    """On any exception `temporary` is removed; an OSError is raised as one UserError naming `target`."""
    try:
        yield
    except BaseException as exc:
        _remove(temporary)
        if isinstance(exc, OSError):
            raise UserError(f"{target}: not written ({describe(exc)})") from None
        raise


def write_text(path: Path, text: str) -> None:
    """Write a text file under rule 2."""
    with replacing(path) as temporary:
        temporary.write_text(text)


@contextlib.contextmanager
def replacing_folder(out: Path, overwrite: bool = False) -> Iterator[Path]:
    """Rule 2 for a folder built as a whole: yields a temporary folder beside `out`; when the block ends it
    takes `out`'s place (an existing `out` is removed only then, and only with `overwrite`). On any exception
    the temporary folder is removed and `out` is left as it was."""
    out = Path(out)
    temporary = temporary_path(out)
    _remove(temporary)
    with _removed_on_failure(temporary, out):
        temporary.mkdir(parents=True)
        remove_left_behind(out.parent)
        yield temporary
        if out.exists() and not overwrite and any(out.iterdir()):
            raise UserError(f"{out}: folder is not empty; pass --overwrite to replace it")
        _synced_rename(temporary, out, lambda: _swap_in(temporary, out))
