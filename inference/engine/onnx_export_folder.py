"""Which files an ONNX export replaces in its folder (docs/data_safety.md): its own, and nothing else.

An export writes its graph files and `engine.json` into the folder; any other file there is the user's and is
left as it is. A file at one of the export's names is replaced without asking only when the folder's earlier
export (its `engine.json`) lists it; any other needs `overwrite`, and so does a non-empty folder that holds no
earlier export. The files the earlier export lists that the new one does not write (its int8 graphs, say) are
removed once the new `engine.json` is in place: only plain files directly in the folder that carry the project's
tag (`temporary_files.written_here`), never through a link.
Needs no torch: the command line checks the folder before it loads a model."""
from __future__ import annotations

import os
import sys
from collections.abc import Iterable
from pathlib import Path

from touchanything.core.errors import UserError
from touchanything.core.output_safety import check_output
from touchanything.core.temporary_files import written_here
from touchanything.inference.engine.onnx_manifest import MANIFEST, read_manifest

PARTS = ("encoder", "head")


def export_files(int8: bool) -> dict[str, dict[str, str]]:
    """The graph files of an export, per precision and part (the manifest's "files")."""
    files = {"fp32": {part: f"{part}.onnx" for part in PARTS}}
    if int8:
        files["int8"] = {part: f"{part}.int8.onnx" for part in PARTS}
    return files


def export_names(files: dict[str, dict[str, str]]) -> list[str]:
    """Every file an export of `files` writes, `engine.json` last."""
    return [*(name for parts in files.values() for name in parts.values()), MANIFEST]


def _plain_name(name: object) -> bool:
    """`name` names an entry directly in a folder (no separator, not "." or "..")."""
    return isinstance(name, str) and name not in ("", ".", "..") and "/" not in name and "\0" not in name


def earlier_files(folder: Path) -> frozenset[str]:
    """The files the earlier export in `folder` lists (its graph files, and `engine.json`); empty when the folder
    holds no export. Only names of entries directly in the folder count."""
    try:
        files = read_manifest(folder)["files"]
    except UserError:
        return frozenset()
    groups = files.values() if isinstance(files, dict) else ()
    names = (name for group in groups if isinstance(group, dict) for name in group.values())
    return frozenset({MANIFEST, *filter(_plain_name, names)})


def check_export_folder(folder: Path, names: Iterable[str], inputs: Iterable[Path | None] = (),
                        overwrite: bool = False) -> list[Path]:
    """Rule 1 for an export writing the files `names` into `folder`, reading `inputs`: UserError (one line) for
    a non-empty folder that holds no earlier export, or a file at one of `names` that its earlier export does
    not list, unless `overwrite`; for an input at any of `names`, always. Returns the earlier export's files
    that this one does not write (to remove once it is complete), none of them an input. Creates nothing."""
    folder, inputs = Path(folder), list(inputs)
    check_output(folder, inputs, folder=True)
    earlier = earlier_files(folder)
    if not earlier and not overwrite and folder.is_dir() and any(folder.iterdir()):
        raise UserError(f"{folder}: folder is not empty and holds no earlier export; pass --overwrite to write the "
                        "export's files into it (nothing else there is removed)")
    names = list(names)
    for name in names:
        path, replaceable = folder / name, overwrite or name in earlier
        check_output(path, inputs, replaceable)
        if not replaceable and os.path.lexists(path):  # a dangling link, which check_output looks through
            raise UserError(f"{path}: exists; pass --overwrite to replace it")
    stale = [folder / name for name in sorted(earlier - set(names)) if written_here(folder / name)]
    for path in stale:
        check_output(path, inputs, overwrite=True)  # the earlier export's own file: refused only as an input
    return stale


def remove_stale(paths: Iterable[Path]) -> list[Path]:
    """Remove those of `paths` (from `check_export_folder`) that are still plain files, naming them in one line
    on stderr; return them. UserError (one line) when one cannot be removed."""
    removed = []
    for path in paths:
        if written_here(path):
            try:
                path.unlink()
            except OSError as exc:
                raise UserError(f"{path}: a file of the earlier export, not removed ({exc.strerror})") from None
            removed.append(path)
    if removed:
        print(f"removed {', '.join(map(str, removed))}: listed by the earlier export, not written by this one",
              file=sys.stderr)
    return removed
