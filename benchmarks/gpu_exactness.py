"""How exact the streaming engine is on a device: the numbers `docs/engine.md` ("The GPU path") reports.

    python benchmarks/gpu_exactness.py [--device cuda] [--frames 40] [--out recordings/bench]

On the bundled sample's first episode (real frames and poses), for the `paper` and `small` presets (random
weights, seed 0) and the bundled `nano` (trained weights), each a newest-frame engine with all views:
- `fp32 vs batch`: the engine's newest-frame output against the batch forward of the same 8-frame clip on
  the same device, fp32, with the same preprocessing (max |difference| over the hands the engine predicted);
- `eager vs graphs`: the engine with CUDA graphs off against on (both fp32; on the CPU both are eager);
- `bf16 vs fp32`, `fp16 vs fp32`, `tf32 vs fp32` (fp16 and tf32 on a GPU only): max and mean |difference|, and the share of hand-frames
  whose contact (the dashboard's lamp: the official rule per hand, `viz.frame_facts.hand_contact`) is the same;
- `preprocessing`: the device's resize (`model_input_on_device`) against cv2's (`model_input`), in intensity
  levels of 1/255, over every frame and view of the clip at each model's input size.
Writes `gpu_exactness.json` and `.md` into `--out`. The same code runs on the CPU (CI runs it there).
"""
from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path

import numpy as np
import torch

from touchanything.app.sessions.bundled import SAMPLE_DIR, bundled_models
from touchanything.core.snapshot import VIEW_NAMES, Snapshot
from touchanything.core.tactile_layout import TactileLayout
from touchanything.inference.engine.engine_setting import EngineSetting
from touchanything.inference.engine.streaming_engine import StreamingEngine
from touchanything.inference.evaluation.bench_data import episode_paths, first_latency_clip
from touchanything.inference.model.checkpoint import load_model
from touchanything.inference.model.model_config import CLIP_LENGTH, FRAME_INTERVAL, SPAN, preset
from touchanything.inference.model.pose_encoder import prepare_poses
from touchanything.inference.model.preprocess import IMAGENET_STD, model_input, model_input_on_device
from touchanything.inference.model.torch_device import PRECISIONS, device_label, resolve_device
from touchanything.inference.model.touch_model import TouchAnything
from touchanything.viz.frame_facts import hand_contact

BEND = TactileLayout.default().bend


def models(device: torch.device) -> dict[str, torch.nn.Module]:
    """paper and small with random weights (seed 0), and the bundled nano."""
    out = {}
    for name in ("paper", "small"):
        torch.manual_seed(0)
        out[name] = TouchAnything(preset(name)).eval()
    out["nano (bundled)"] = load_model(bundled_models()["nano"])
    return {name: model.to(device) for name, model in out.items()}


def prepare(snapshot: Snapshot, size: int, device: torch.device) -> torch.Tensor:
    """(V, 3, S, S) model input of a snapshot's views as the engine prepares it on `device`."""
    frames = [snapshot.images[v] for v in VIEW_NAMES]
    if device.type == "cuda":
        return model_input_on_device(frames, size, device)
    return torch.from_numpy(model_input(frames, size))


@torch.inference_mode()
def batch_newest(model: torch.nn.Module, clip: list[Snapshot], end: int, device: torch.device) -> np.ndarray:
    """The batch forward (fp32) of the 8-frame clip ending at `end` → its last frame (2, 21, 21)."""
    picks = [clip[end - FRAME_INTERVAL * k] for k in range(CLIP_LENGTH - 1, -1, -1)]
    size = model.config.image_size
    frames = torch.stack([prepare(s, size, device) for s in picks])  # (T, V, 3, S, S)
    views = {v: frames[:, i][None] for i, v in enumerate(VIEW_NAMES)}
    joints = np.stack([np.asarray(s.joints).reshape(42, 3) for s in picks])
    poses = torch.from_numpy(prepare_poses(joints, np.stack([s.joints_valid for s in picks]))).to(device)[None]
    return model(poses=poses, views=views)["tactile"][0, -1].float().cpu().numpy()


def engine_outputs(model: torch.nn.Module, clip: list[Snapshot], device: torch.device, precision: str,
                   capture: bool) -> tuple[dict[int, np.ndarray], str]:
    """frame index → newest-frame pressure (2, 21, 21) (NaN outside the layout), and the runtime's capture
    status. Hands without a pose are fed as the official protocol does (`invalid_hands="official"`), as the
    batch forward does."""
    config = EngineSetting(precision=precision, device=str(device), capture=capture, invalid_hands="official")
    engine = StreamingEngine(model, config)
    out = {p.frame_index: p.pressure for s in clip for p in engine.step(s)}
    return out, engine.runtime.capture


def max_difference(a: dict[int, np.ndarray], b: dict[int, np.ndarray], frames) -> tuple[float, float]:
    """(max, mean) |a − b| over the cells both predicted in `frames`."""
    diff = np.abs(np.stack([a[f] for f in frames]) - np.stack([b[f] for f in frames]))
    diff = diff[np.isfinite(diff)]
    return float(diff.max(initial=0.0)), float(diff.mean()) if diff.size else 0.0


def contact_agreement(a: dict[int, np.ndarray], b: dict[int, np.ndarray], frames) -> float:
    """Share of predicted hand-frames whose contact state is the same in `a` and `b`."""
    same = []
    for f in frames:
        both = [h for h in range(2) if np.isfinite(a[f][h]).any() and np.isfinite(b[f][h]).any()]
        same += list((hand_contact(a[f], BEND) == hand_contact(b[f], BEND))[both])
    return float(np.mean(same)) if same else float("nan")


def preprocessing_levels(clip: list[Snapshot], size: int, device: torch.device) -> float:
    """Max |device − cv2| model input of every frame and view, in intensity levels (1/255)."""
    worst = 0.0
    for s in clip:
        frames = [s.images[v] for v in VIEW_NAMES]
        diff = (model_input_on_device(frames, size, device).cpu().numpy() - model_input(frames, size))
        worst = max(worst, float(np.abs(diff * IMAGENET_STD.numpy()[None] * 255).max()))
    return worst


def measure(model: torch.nn.Module, clip: list[Snapshot], device: torch.device) -> dict:
    """Every comparison of the module docstring for one model."""
    frames = [s.frame_index for s in clip[SPAN - 1:]]  # full windows only
    fp32, status = engine_outputs(model, clip, device, "fp32", capture=True)
    batch = {f: batch_newest(model, clip, i, device) for i, f in enumerate(s.frame_index for s in clip) if f in frames}
    eager, _ = engine_outputs(model, clip, device, "fp32", capture=False)
    row = {"capture": status, "fp32 vs batch": max_difference(fp32, batch, frames)[0],
           "eager vs graphs": max_difference(eager, fp32, frames)[0],
           "preprocessing levels": preprocessing_levels(clip, model.config.image_size, device)}
    for precision in (p for p in PRECISIONS if p != "fp32" and (p not in ("fp16", "tf32") or device.type == "cuda")):
        low, _ = engine_outputs(model, clip, device, precision, capture=True)
        worst, mean = max_difference(low, fp32, frames)
        row[f"{precision} vs fp32"] = {"max": worst, "mean": mean, "contact agreement": contact_agreement(low, fp32, frames)}
    return row


def markdown(record: dict) -> str:
    lines = ["# Streaming-engine exactness on a device (`benchmarks/gpu_exactness.py`)", "",
             f"{record['machine']}; device {record['device']}; {record['frames']} frames of `{record['episode']}`.", "",
             "| model | capture | fp32 vs batch | eager vs graphs | bf16 vs fp32 max / mean / contact | "
             "fp16 vs fp32 max / mean / contact | tf32 vs fp32 max / mean / contact | preprocessing (levels) |",
             "|---|---|---|---|---|---|---|---|"]
    for name, r in record["models"].items():
        low = [r.get(f"{p} vs fp32") for p in ("bf16", "fp16", "tf32")]
        cells = ["n/a" if x is None else f"{x['max']:.4f} / {x['mean']:.5f} / {x['contact agreement']:.1%}" for x in low]
        lines.append(f"| {name} | {r['capture']} | {r['fp32 vs batch']:.2e} | {r['eager vs graphs']:.2e} | "
                     f"{cells[0]} | {cells[1]} | {cells[2]} | {r['preprocessing levels']:.2f} |")
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--device", default="cuda", help="cuda, cuda:N or cpu (default cuda)")
    parser.add_argument("--frames", type=int, default=40, help="frames of the sample episode (default 40, at least 16)")
    parser.add_argument("--out", type=Path, default=Path("recordings/bench"), help="report folder (default recordings/bench)")
    args = parser.parse_args()
    if args.frames < SPAN + 1:
        parser.error(f"--frames must be at least {SPAN + 1} (one full window and a newest frame after it)")
    device = resolve_device(args.device)
    path = episode_paths(SAMPLE_DIR)[0]
    clip = first_latency_clip([path], args.frames)
    started = time.perf_counter()
    record = {"machine": f"{platform.node()}, torch {torch.__version__}", "device": device_label(device),
              "episode": path.name, "frames": len(clip),
              "models": {name: measure(model, clip, device) for name, model in models(device).items()}}
    record["seconds"] = time.perf_counter() - started
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "gpu_exactness.json").write_text(json.dumps(record, indent=1) + "\n")
    (args.out / "gpu_exactness.md").write_text(markdown(record))
    print(markdown(record))


if __name__ == "__main__":
    main()
