"""An ONNX export's `engine.json` (written by `touchanything.inference.engine.onnx_export`): the model config,
input size, graph files per precision, the SHA-256 of the weights the graphs were made from (`WEIGHTS_KEY`,
also stored in every graph file's metadata) and the checkpoint they were made from (`source`). Reading it
needs no torch (the command line resolves `--onnx DIR` with it)."""
from __future__ import annotations

import json
from pathlib import Path

from touchanything.core.errors import UserError

MANIFEST = "engine.json"
WEIGHTS_KEY = "weights_sha256"
"""The manifest's key, and every graph file's metadata key, for the SHA-256 of the weights (`weights_sha256`)."""
REEXPORT = "export again with `touchanything export-onnx`"


def read_manifest(folder: Path) -> dict:
    """The export's engine.json (config, input size, graph files per precision); UserError when it is missing
    or not a manifest."""
    path = Path(folder) / MANIFEST
    try:
        manifest = json.loads(path.read_text())
        manifest["files"], manifest["image_size"]
    except FileNotFoundError:
        raise UserError(f"{folder}: no {MANIFEST}; create the folder with `touchanything export-onnx`") from None
    except (OSError, ValueError, KeyError, TypeError):
        raise UserError(f"{path}: not a valid ONNX export manifest") from None
    return manifest


def is_export(folder: Path) -> bool:
    """Whether `folder` holds an earlier export (its engine.json is a manifest): replaced as a whole by a new one."""
    try:
        read_manifest(folder)
    except UserError:
        return False
    return True


def export_weights(folder: Path, manifest: dict) -> str:
    """The SHA-256 of the weights the export was made from; UserError for an export made before it was
    recorded: its weights cannot be checked, so it is refused rather than trusted."""
    digest = manifest.get(WEIGHTS_KEY)
    if not isinstance(digest, str) or not digest:
        raise UserError(f"{folder}: the ONNX export does not record the SHA-256 of its weights (made by an older "
                        f"touchanything), so they cannot be checked; {REEXPORT}")
    return digest


def check_weights(folder: Path, manifest: dict, digest: str) -> None:
    """UserError (one line naming both digests) unless the export was made from the weights whose SHA-256 is
    `digest`."""
    exported = export_weights(folder, manifest)
    if exported != digest:
        raise UserError(f"{folder}: the ONNX graphs were exported from other weights (sha256 {exported[:12]}… ≠ this "
                        f"model's {digest[:12]}…); {REEXPORT}")


def export_source(folder: Path) -> Path | None:
    """The checkpoint the export in `folder` was made from (None when it records none: the user cache's exports);
    UserError when the folder is no export, or the recorded checkpoint is no longer there."""
    source = read_manifest(folder).get("source") or ""
    if not source:
        return None
    if not Path(source).is_file():
        raise UserError(f"{folder}: the checkpoint it was exported from, {source}, is not there; {REEXPORT}")
    return Path(source)
