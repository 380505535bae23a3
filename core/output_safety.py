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
   folder built as a whole goes through `replacing_folder(out)` the same way. Every temporary entry carries an
   ownership marker written before it (`temporary_files`); only entries whose marker proves this project wrote
   them, and whose process provably no longer runs, are removed as leftovers (each named on stderr).

The recorder's streams (`RawEpisodeWriter`) are written under temporary names too, renamed into place at the end
without replacing anything (`rename_new`); a recording cut short keeps its marked streams, which the readers
find (`temporary_files.recorded_stream`)."""
from __future__ import annotations

import argparse
import contextlib
import errno
import os
import shutil
import tempfile
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

from touchanything.core.errors import UserError
from touchanything.core.input_paths import collect_inputs
from touchanything.core.temporary_files import mark, marker_path, remove_left_behind, tag_written, temporary_path, unmark, written_here


def add_overwrite_argument(parser: argparse.ArgumentParser, what: str) -> None:
    """The commands' one `--overwrite` option: replace `what` (e.g. "--out") when it exists."""
    parser.add_argument("--overwrite", action="store_true",
                        help=f"replace {what} when it exists (default: refuse; never an input of the command)")


def _never(path: Path) -> bool:
    return False


def named(*names: str) -> Callable[[Path], bool]:
    """An `own` test for outputs with fixed names (a report folder's files): a file of one of these names that the
    project wrote (its tag, `temporary_files.written_here`; a user's file of that name is not)."""
    return lambda path: path.name in names and written_here(path)


def check_output(out: Path, inputs: Iterable[Path | None] = (), overwrite: bool = False, *,
                 own: Callable[[Path], bool] = _never, folder: bool = False, whole: bool = False) -> None:
    """Rule 1 for the output `out` of a command reading `inputs` (files and folders). `own(path)`: an existing
    path is an earlier output of the same kind (replaced without `overwrite`). `folder`: `out` is a folder the
    command writes named files into (check each of them too); `whole`: a folder the command builds as a whole
    (an existing non-empty one is replaced only with `overwrite`, never when it holds an input). Raises
    UserError (one line); creates nothing. Inputs are every real path they resolve to, the targets of the
    links inside input folders included (`input_paths`), and an output that is a hard link of an input file
    is that input. What interrupted runs left beside the output (in it, for a `folder`) is removed first when their
    markers prove it (`temporary_files.remove_left_behind`), each named."""
    out = Path(out)
    check_name_lengths(out, temporary=not folder)
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
    for place in (target.parent, target) if folder else (target.parent,):
        remove_left_behind(place)  # before any work, so the lines come before any progress bar


def check_outside(out: Path, folders: Iterable[Path]) -> None:
    """UserError when the output folder `out` is, or would lie inside, one of the input `folders` (an episode, a
    dataset a command builds a whole new folder from)."""
    target = Path(out).resolve()
    for folder in folders:
        real = Path(folder).resolve()
        if real.is_dir() and (real == target or real in target.parents):
            raise UserError(f"{out}: the output would lie inside the input {folder}; choose a folder outside it")


def check_name_lengths(out: Path, temporary: bool = True) -> None:
    """UserError when a name in `out`, or (`temporary`: `out` is first written under a temporary name) the name of
    its temporary's ownership marker, the longest the output needs, is longer than the file system of its nearest
    existing folder allows (checked before any work; the OS would refuse it after)."""
    existing = Path(out)
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    try:
        limit = os.pathconf(existing if existing.is_dir() else existing.parent, "PC_NAME_MAX")
    except (OSError, ValueError):
        limit = 255
    names = [*Path(out).parts[1 if Path(out).is_absolute() else 0:]]
    names += [marker_path(temporary_path(out)).name] if temporary else []
    longest = max(names, key=lambda name: len(os.fsencode(name)))
    if len(os.fsencode(longest)) > limit:
        what = ("the temporary name it is written under" if temporary and longest == names[-1]
                else f"the name {longest[:24]}…")
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
    """The nearest existing folder of `folder` (itself or an ancestor) takes a new file and a byte in it (a full
    disk is said before any work): one is created, written and removed. UserError otherwise."""
    existing = Path(folder)
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if not existing.is_dir():
        raise UserError(f"{folder}: cannot be created ({existing} is not a folder)")
    try:
        handle, probe = tempfile.mkstemp(prefix=".touchanything-probe-", dir=existing)
        try:
            os.write(handle, b"\0")
        finally:
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


def _remove(path: Path) -> None:
    with contextlib.suppress(OSError):
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        else:
            path.unlink(missing_ok=True)


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
    with _claimed(temporary, path, "file"):
        remove_left_behind(path.parent)
        yield temporary
        tag_written(temporary)
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
    mark(old, "replaced", place=out.name)
    os.replace(out, old)
    os.replace(temporary, out)
    _remove(old)
    unmark(old)


def _sync_failure(step: Callable[[], None]) -> OSError | None:
    try:
        step()
    except OSError as exc:
        return exc
    return None


@contextlib.contextmanager
def _claimed(temporary: Path, target: Path, kind: str) -> Iterator[None]:
    """The block writes `temporary` (a `kind` of temporary_files.KINDS) for `target`: its folder is created and
    its ownership marker written first (a taken name is refused, never reused); on any exception `temporary`
    is removed, and an OSError is raised as one UserError naming `target`; the marker goes when the block ends."""
    try:
        temporary.parent.mkdir(parents=True, exist_ok=True)
        mark(temporary, kind)
    except OSError as exc:
        raise UserError(f"{target}: not written ({describe(exc)})") from None
    try:
        yield
    except BaseException as exc:
        _remove(temporary)
        if isinstance(exc, OSError):
            raise UserError(f"{target}: not written ({describe(exc)})") from None
        raise
    finally:
        unmark(temporary)


def rename_new(temporary: Path, path: Path) -> None:
    """Rename `temporary` to `path`, which must not exist: never replaces anything, not even a link that appeared
    meanwhile (FileExistsError). A hard link then an unlink, so the check and the rename are one step."""
    try:
        os.link(temporary, path, follow_symlinks=False)
    except OSError as exc:
        if exc.errno not in (errno.EPERM, errno.EOPNOTSUPP, errno.EMLINK, errno.EXDEV):
            raise
        if os.path.lexists(path):  # a file system without hard links: checked, then renamed
            raise FileExistsError(errno.EEXIST, os.strerror(errno.EEXIST), str(path)) from None
        os.rename(temporary, path)
        return
    os.unlink(temporary)


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
    with _claimed(temporary, out, "folder"):
        temporary.mkdir()
        remove_left_behind(out.parent)
        yield temporary
        if out.exists() and not overwrite and any(out.iterdir()):
            raise UserError(f"{out}: folder is not empty; pass --overwrite to replace it")
        _synced_rename(temporary, out, lambda: _swap_in(temporary, out))
