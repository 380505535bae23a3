"""`touchanything export-onnx`: the streaming engine's per-frame encoder and window head as ONNX graphs."""
from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from touchanything.core.snapshot import VIEW_NAMES
from touchanything.inference.engine.onnx_export_folder import check_export_folder, export_files, export_names
from touchanything.inference.engine.onnx_manifest import MANIFEST

if TYPE_CHECKING:
    from touchanything.inference.engine.engine_runtime import TorchRuntime
    from touchanything.inference.engine.onnx_runtime import OnnxRuntime


def add_parser(commands: argparse._SubParsersAction) -> None:
    parser = commands.add_parser("export-onnx", help="export a checkpoint's streaming graphs to ONNX (fp32, int8)")
    parser.add_argument("--checkpoint", type=Path, required=True, help="model checkpoint in the official format")
    parser.add_argument("--config", type=Path, help="config.yaml (default: beside the checkpoint)")
    parser.add_argument("--out", type=Path, required=True,
                        help="output folder for the encoder/head graphs and engine.json; the files of an earlier "
                             "export there are replaced (those this export does not write, removed), any other file "
                             "is kept")
    parser.add_argument("--int8", action="store_true", help="also write int8 graphs (dynamic quantisation)")
    parser.add_argument("--overwrite", action="store_true",
                        help="write into a non-empty --out that holds no earlier export, and replace a file there "
                             "that has the name of an export file but no earlier export wrote (default: refuse; "
                             "the folder's other files are kept; an input of the command is never replaced)")
    parser.set_defaults(run=run)


def agreement(torch_runtime: TorchRuntime, onnx_runtime: OnnxRuntime, size: int, seed: int = 0) -> float:
    """Max |ONNX − torch| over one random three-view window, both hands."""
    from touchanything.inference.engine.onnx_export import WINDOW

    rng = np.random.default_rng(seed)
    ids = np.arange(len(VIEW_NAMES), dtype=np.int64)
    images = [rng.normal(0, 1, (len(ids), 3, size, size)).astype(np.float32) for _ in range(WINDOW)]
    joints = (rng.normal(0, 2, (1, 42, 3)) + [0, 0, 40]).astype(np.float32)
    args = (joints, np.arange(42, dtype=np.int64), np.array([WINDOW - 1], np.int64))
    outputs = [rt.head([rt.encode(im, ids) for im in images], *args) for rt in (torch_runtime, onnx_runtime)]
    return float(np.abs(outputs[0] - outputs[1]).max())


def run(args: argparse.Namespace) -> int:
    from touchanything.inference.engine.engine_runtime import TorchRuntime
    from touchanything.inference.engine.onnx_export import export_onnx
    from touchanything.inference.engine.onnx_runtime import OnnxRuntime
    from touchanything.inference.model.checkpoint import load_model

    check_export_folder(args.out, export_names(export_files(args.int8)), (args.checkpoint, args.config), args.overwrite)
    model = load_model(args.checkpoint, args.config)
    manifest = export_onnx(model, args.out, int8=args.int8, source=str(args.checkpoint.resolve()),
                           overwrite=args.overwrite)
    reference = TorchRuntime(model)
    for precision, files in manifest["files"].items():
        sizes = ", ".join(f"{name} {(args.out / name).stat().st_size / 1e6:.1f} MB" for name in files.values())
        difference = agreement(reference, OnnxRuntime(args.out, precision), model.config.image_size)
        print(f"{precision}: {sizes}; max |ONNX − torch| on a random window: {difference:.2e}")
    print(f"engine manifest: {args.out / MANIFEST} (weights sha256 {manifest['weights_sha256'][:12]}…)")
    return 0
