"""The one rule every command that writes follows (docs/data_safety.md):

1. Before any work, `check_output(out, inputs, overwrite, …)`: an output that is (or resolves to) one of the
   command's inputs, that would replace a file inside an input folder (an episode, a dataset) which is not
   an output of this kind, or that would replace a whole folder holding an input, is refused; an existing
   output of another kind (not recognised by `own`) is replaced only with `--overwrite`; the place the
   output goes is checked for writability (a probe file, created and removed: permissions, read-only
   mounts, a file where a folder should be).
2. Every file is written through `replacing(path)` (or `write_text`): to a hidden temporary file in the
   same folder, renamed over `path` only when complete; on any error, disk full included, the temporary
   file is removed and an OSError becomes one line (UserError) naming the output. A folder built as a whole
   goes through `replacing_folder(out)` the same way.

The only exceptions are the recorder's episode folders, written live so that a crash keeps what was
recorded (they are still checked by rule 1)."""
from __future__ import annotations

import argparse
import contextlib
import os
import shutil
import tempfile
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

from touchanything.devices.errors import UserError
from touchanything.devices.input_paths import collect_inputs

PARTIAL = ".partial-"
"""In the name of every temporary output: `.<name>.partial-<pid>` beside the output (hidden, and with no suffix
of its own, so no reader takes a half-written `.hdf5` or `.mp4` for data)."""


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


@contextlib.contextmanager
def replacing(path: Path) -> Iterator[Path]:
    """Rule 2: yields the temporary path to write; when the block ends it is renamed over `path` (its folder
    is created first). On any exception the temporary file is removed and `path` is left as it was; an
    OSError (no space, file too large, read-only…) is raised as a UserError naming `path`."""
    path = Path(path)
    temporary = temporary_path(path)
    with _removed_on_failure(temporary, path):
        path.parent.mkdir(parents=True, exist_ok=True)
        yield temporary
        os.replace(temporary, path)


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
        yield temporary
        if out.exists():
            if not overwrite and any(out.iterdir()):
                raise UserError(f"{out}: folder is not empty; pass --overwrite to replace it")
            old = out.with_name(f".{out.name}.old-{os.getpid()}")
            os.replace(out, old)
            os.replace(temporary, out)
            _remove(old)
        else:
            os.replace(temporary, out)
