"""Export the streaming engine's two graphs to ONNX (fp32, optionally int8 by dynamic quantisation).

- `encoder.onnx`: images (V, 3, S, S) float32 ImageNet-normalised, V = 1…3; view_ids (V,) int64
  → frame_tokens (N, D). Position embeddings are baked for S (no interpolation in the graph).
- `head.onnx`: frame_tokens (8, N, D), joints (P, J, 3), joint_ids (J,) int64 with J = 21 or 42,
  positions (P,) int64 → pressure (P, J // 21, 21, 21).
- `*.int8.onnx`: the same graphs with MatMul/Gemm weights quantised to int8 (ONNX Runtime dynamic
  quantisation; activations are quantised per call at run time).
- `engine.json`: the model config, input size, token count, the graph files per precision, the SHA-256 of the
  weights (`weights_sha256`, also in every graph file's metadata) and the source checkpoint
  (`touchanything.inference.engine.onnx_manifest`).

Only the export's own files are replaced in the folder (`onnx_export_folder`): each is written to a temporary
file beside it, and all are renamed into place once every one is complete, `engine.json` last, so an
interrupted export leaves the folder as it was. The graphs an earlier export listed that this one does not
write (its int8 graphs, say) are removed after that; any other file there is left alone.
"""
from __future__ import annotations

import copy
import hashlib
import io
import json
import logging
import warnings
from contextlib import ExitStack, contextmanager, redirect_stderr, redirect_stdout
from pathlib import Path

import torch

from touchanything.core.hand_pose import JOINTS_PER_HAND
from touchanything.core.output_safety import replacing
from touchanything.inference.engine.frame_encoder import bake_position_embedding
from touchanything.inference.engine.model_halves import model_halves
from touchanything.inference.engine.onnx_export_folder import check_export_folder, export_files, export_names, remove_stale
from touchanything.inference.engine.onnx_manifest import MANIFEST, WEIGHTS_KEY
from touchanything.inference.model.model_config import config_to_dict
from touchanything.inference.model.models import TactileModel

WINDOW = 8
OPSET = 18


@contextmanager
def quiet_exporter():
    """The exporter reports progress and missing optional ops (torchvision) on stdout, stderr and its loggers."""
    loggers = [logging.getLogger(name) for name in ("torch.onnx", "onnxscript")]
    levels = [logger.level for logger in loggers]
    with warnings.catch_warnings(), redirect_stdout(io.StringIO()), redirect_stderr(io.StringIO()):
        warnings.simplefilter("ignore")
        for logger in loggers:
            logger.setLevel(logging.ERROR)
        try:
            yield
        finally:
            for logger, level in zip(loggers, levels):
                logger.setLevel(level)


def weights_sha256(model: TactileModel) -> str:
    """The SHA-256 (hex) of the model's weights: every state-dict entry, in name order, as its name, dtype,
    shape and raw bytes. Equal for the same weights however they were loaded; any changed value changes it."""
    digest = hashlib.sha256()
    for name, tensor in sorted(model.state_dict().items()):
        tensor = tensor.detach().cpu().contiguous()
        digest.update(f"{name}|{tensor.dtype}|{tuple(tensor.shape)}|".encode())
        digest.update(tensor.reshape(-1).view(torch.uint8).numpy().tobytes())
    return digest.hexdigest()


def _export(module: torch.nn.Module, args: tuple, names: list[str], output: str, dynamic: dict, path: Path,
            weights: str) -> None:
    with quiet_exporter():
        program = torch.onnx.export(module, args, dynamo=True, input_names=names, output_names=[output],
                                    dynamic_shapes=dynamic, opset_version=OPSET, verbose=False)
    program.model.metadata_props[WEIGHTS_KEY] = weights
    program.save(str(path))


def export_encoder(model: TactileModel, path: Path, weights: str) -> None:
    size = model.config.image_size
    views = torch.export.Dim("views", min=1, max=3)
    args = (torch.zeros(2, 3, size, size), torch.arange(2))
    _export(model_halves(model)[0].eval(), args, ["images", "view_ids"], "encoder",
            {"images": {0: views}, "view_ids": {0: views}}, path, weights)


def export_head(model: TactileModel, path: Path, weights: str) -> None:
    tokens, width = model.frame_token_shape
    outputs, hands = torch.export.Dim("outputs", min=1, max=WINDOW), torch.export.Dim("hands", min=1, max=2)
    args = (torch.zeros(WINDOW, tokens, width), torch.zeros(2, 42, 3), torch.arange(42),
            torch.tensor([WINDOW - 1, 0]))
    dynamic = {"frame_tokens": None, "joints": {0: outputs, 1: JOINTS_PER_HAND * hands},
               "joint_ids": {0: JOINTS_PER_HAND * hands}, "positions": {0: outputs}}
    _export(model_halves(model)[1].eval(), args, ["frame_tokens", "joints", "joint_ids", "positions"], "head", dynamic,
            path, weights)


def quantize_int8(source: Path, target: Path) -> None:
    """`target`: `source` with its MatMul/Gemm weights quantised to int8 (its metadata, the weights' SHA-256
    included, is kept). Per output channel and in 7 bits (`reduce_range`): on an x86 CPU without VNNI (AVX2 only,
    e.g. an AMD EPYC of this project's machines) ONNX Runtime's u8×s8 products saturate with 8-bit weights — the
    bundled nano's int8 output then differed from fp32 by up to 0.72 (p99 0.18); per-channel 7-bit weights keep
    it at 0.08 (p99 0.02) there, and the graph means the same on every CPU."""
    from onnxruntime.quantization import QuantType, quantize_dynamic

    logging.disable(logging.WARNING)  # it logs advice on the root logger for every graph
    try:
        quantize_dynamic(str(source), str(target), weight_type=QuantType.QInt8, op_types_to_quantize=["MatMul", "Gemm"],
                         reduce_range=True, per_channel=True)
    finally:
        logging.disable(logging.NOTSET)


def export_onnx(model: TactileModel, out_dir: Path, *, int8: bool = False, source: str = "",
                overwrite: bool = False) -> dict:
    """Write the graphs and `engine.json` (`source`: the checkpoint's path, "" when there is none) into `out_dir`,
    replacing only an earlier export's files there (`onnx_export_folder`); return the manifest. A non-empty
    `out_dir` that holds no earlier export, or a file of another origin at one of the export's names, needs
    `overwrite` (else UserError, nothing written)."""
    out_dir = Path(out_dir)
    files = export_files(int8)
    stale = check_export_folder(out_dir, export_names(files), overwrite=overwrite)
    weights = weights_sha256(model)
    model = copy.deepcopy(model).float().cpu().eval()
    bake_position_embedding(model)
    manifest = {"config": config_to_dict(model.config), "image_size": model.config.image_size,
                "tokens": model.frame_token_shape[0], "width": model.frame_token_shape[1],
                "window": WINDOW, "opset": OPSET, WEIGHTS_KEY: weights, "source": source, "files": files}
    with ExitStack() as stack:  # when all are written, each is renamed into place, the first written (engine.json) last
        def temporary(name: str) -> Path:
            return stack.enter_context(replacing(out_dir / name))

        temporary(MANIFEST).write_text(json.dumps(manifest, indent=2) + "\n")
        fp32 = {"encoder": temporary(files["fp32"]["encoder"])}  # each entered as it is written: an error names it
        export_encoder(model, fp32["encoder"], weights)
        fp32["head"] = temporary(files["fp32"]["head"])
        export_head(model, fp32["head"], weights)
        for part, name in files.get("int8", {}).items():
            quantize_int8(fp32[part], temporary(name))
    remove_stale(stale)
    return manifest
