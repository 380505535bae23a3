"""HDF5 files the project writes: under the output rule (`output_safety.replacing`: a hidden temporary file,
renamed into place when complete), with a completion mark, and safe when the disk fills.

The mark is the root attribute `touchanything_written` (the writer's name) with `touchanything_source` (what it
was written from), set as the last writes before the file is closed: a file that carries them was written to
the end by this project from that source; one that does not is someone else's or was cut short, and `convert`
neither trusts (`--skip-existing`) nor replaces (without `--overwrite`) it.

A full disk: HDF5 keeps written chunks in a cache and flushes them when the file closes; when that flush fails
the library is left in a state in which closing the file again — as the garbage collector does — crashes the
process (a segmentation fault, seen with h5py 3 on a full tmpfs). So the files are written without a chunk
cache (the writers write whole chunks, so nothing is lost), and a file whose writing failed is emptied before it
is closed again and removed: the close then has room for what it still writes, and returns.
"""
from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator
from pathlib import Path

import h5py

from touchanything.core.output_safety import replacing

WRITTEN_MARK = "touchanything_written"
"""Root attribute of every HDF5 file the project wrote to the end (its value names the writer)."""
SOURCE_MARK = "touchanything_source"
"""Root attribute naming what the file was written from (for `convert`, the episode's place under the raw root)."""


@contextlib.contextmanager
def hdf5_output(path: Path, writer: str, source: str) -> Iterator[h5py.File]:
    """A new HDF5 file at `path` (rule 2 of the output rule), marked complete by `writer` from `source` when the
    block ends; on any failure (an OSError becomes one UserError naming `path`) nothing is left at `path` or
    beside it."""
    with replacing(Path(path)) as partial:
        file = h5py.File(partial, "w", rdcc_nbytes=0)
        try:
            yield file
            file.attrs[SOURCE_MARK] = source
            file.attrs[WRITTEN_MARK] = writer
            file.close()
        except BaseException:
            _abandon(file, partial)
            raise


def _abandon(file: h5py.File, partial: Path) -> None:
    """Close a file whose writing failed without crashing: empty it first, so that the close's flush fits."""
    with contextlib.suppress(OSError):
        os.truncate(partial, 0)
    with contextlib.suppress(Exception):  # h5py raises its own kinds here; the file is removed next anyway
        file.close()


def written_from(path: Path) -> str | None:
    """What the HDF5 file `path` was written from, when it opens and carries the completion mark; else None."""
    try:
        with h5py.File(path, "r") as file:
            return str(file.attrs[SOURCE_MARK]) if WRITTEN_MARK in file.attrs and SOURCE_MARK in file.attrs else None
    except Exception:  # noqa: BLE001 - any file h5py cannot open (truncated, not HDF5) is not one of ours
        return None
