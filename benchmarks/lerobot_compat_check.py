"""Run inside the side venv that holds LeRobot (`benchmarks/lerobot_compat.py` starts it): checks one export with
LeRobot's own code and prints the findings as JSON on the last line.

    python lerobot_compat_check.py EXPORT [--policy]

1. `LeRobotDataset` loads EXPORT; 2. a DataLoader yields every frame (shapes as info.json says, every number
finite, images on [0, 1]); 3. statistics recomputed per episode with `compute_episode_stats` (numeric features
from the dataset's frames; video features from the frames LeRobot decodes at the indices LeRobot's
`sample_indices` picks, as PNG files, since LeRobot computes them from image files) and merged with
`aggregate_stats`, compared with `meta/stats.json`; 4. with --policy: an ACT config built from the dataset's
features (`dataset_to_policy_features`), the policy made by `make_policy`, one training forward pass on a batch
through LeRobot's pre-processor (normalisation by the export's statistics): the loss must be finite.
"""
from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np
import torch
from lerobot.datasets.compute_stats import aggregate_stats, compute_episode_stats, sample_indices
from lerobot.datasets.lerobot_dataset import LeRobotDataset
from PIL import Image


def video_backend() -> str:
    """LeRobot's default decoder, torchcodec, when it loads here (it needs FFmpeg's shared libraries); else PyAV."""
    try:
        import torchcodec.decoders  # noqa: F401
    except (ImportError, OSError, RuntimeError):
        return "pyav"
    return "torchcodec"


def iterate_all(dataset: LeRobotDataset) -> dict:
    """Every frame through a DataLoader: frames seen, non-finite numbers, images outside [0, 1], shape mismatches."""
    loader = torch.utils.data.DataLoader(dataset, batch_size=32, num_workers=0, shuffle=False)
    frames, non_finite, outside, shapes = 0, [], [], []
    for batch in loader:
        frames += len(batch["index"])
        for key, feature in dataset.meta.features.items():
            value = batch.get(key)
            if not isinstance(value, torch.Tensor):
                continue
            if not torch.isfinite(value.float()).all():
                non_finite.append(key)
            if feature["dtype"] == "video":
                if value.min() < 0 or value.max() > 1:
                    outside.append(key)
                expected = (feature["shape"][2], feature["shape"][0], feature["shape"][1])
            else:
                expected = tuple(feature["shape"]) if tuple(feature["shape"]) != (1,) else ()
            if tuple(value.shape[1:]) != expected:
                shapes.append(f"{key}: {tuple(value.shape[1:])} != {expected}")
    return {"frames": frames, "non_finite": sorted(set(non_finite)), "images_outside_0_1": sorted(set(outside)),
            "shape_mismatches": sorted(set(shapes))}


def _video_paths(dataset: LeRobotDataset, key: str, first: int, length: int, folder: Path) -> list[str]:
    """The frames LeRobot would sample from an episode of `length` frames, decoded by LeRobot, as PNG files."""
    paths = []
    for k in sample_indices(length):
        image = dataset[first + k][key]  # (3, H, W) float on [0, 1]
        path = folder / f"{key}_{first + k}.png"
        Image.fromarray((image.permute(1, 2, 0).numpy() * 255).round().astype(np.uint8)).save(path)
        paths.append(str(path))
    return paths


def recompute_stats(dataset: LeRobotDataset) -> dict[str, dict[str, np.ndarray]]:
    """The dataset's statistics as LeRobot computes them when it records the episodes."""
    features = dataset.meta.features
    columns = dataset.hf_dataset.with_format("numpy")
    per_episode = []
    with tempfile.TemporaryDirectory() as tmp:
        for episode in range(dataset.meta.total_episodes):
            first = int(dataset.meta.episodes[episode]["dataset_from_index"])
            end = int(dataset.meta.episodes[episode]["dataset_to_index"])
            rows = columns.select(range(first, end))
            data = {}
            for key, feature in features.items():
                if feature["dtype"] == "video":
                    data[key] = _video_paths(dataset, key, first, end - first, Path(tmp))
                elif feature["dtype"] not in ("string", "language"):
                    data[key] = np.asarray(rows[key])
            per_episode.append(compute_episode_stats(data, features))
    return aggregate_stats(per_episode)


def compare_stats(recomputed: dict, written: dict, features: dict) -> dict:
    """Per feature: same keys and shapes, and the largest difference (videos: decoded frames against the source
    frames the export took them from, so the codec's loss shows)."""
    rows = {}
    for key, stats in recomputed.items():
        mine = written.get(key, {})
        shapes_equal = set(stats) == set(mine) and all(np.shape(stats[s]) == np.shape(np.asarray(mine[s])) for s in stats)
        diff = max(float(np.max(np.abs(np.asarray(stats[s], np.float64) - np.asarray(mine[s], np.float64))))
                   for s in stats if s in mine) if mine else float("inf")
        finite = all(np.isfinite(np.asarray(v, np.float64)).all() for v in mine.values())
        rows[key] = {"video": features[key]["dtype"] == "video", "same_keys_and_shapes": shapes_equal,
                     "max_abs_difference": diff, "finite": finite, "shape": list(np.shape(stats["mean"]))}
    return rows


def policy_forward(dataset_root: Path, repo_id: str) -> dict:
    """ACT made from the dataset's features, one training forward pass."""
    from lerobot.configs.types import FeatureType
    from lerobot.policies.act.configuration_act import ACTConfig
    from lerobot.policies.factory import make_policy, make_pre_post_processors
    from lerobot.utils.feature_utils import dataset_to_policy_features

    meta = LeRobotDataset(repo_id, root=dataset_root, video_backend=video_backend()).meta
    features = dataset_to_policy_features(meta.features)
    outputs = {k: f for k, f in features.items() if f.type is FeatureType.ACTION}
    inputs = {k: f for k, f in features.items() if k not in outputs}
    config = ACTConfig(input_features=inputs, output_features=outputs, chunk_size=10, n_action_steps=10,
                       pretrained_backbone_weights=None, device="cpu")
    policy = make_policy(config, ds_meta=meta)
    preprocessor, _ = make_pre_post_processors(config, dataset_stats=meta.stats)
    deltas = {"action": [i / meta.fps for i in range(config.chunk_size)]}
    dataset = LeRobotDataset(repo_id, root=dataset_root, delta_timestamps=deltas, video_backend=video_backend())
    batch = next(iter(torch.utils.data.DataLoader(dataset, batch_size=2, shuffle=True)))
    policy.train()
    loss, _ = policy.forward(preprocessor(batch))
    return {"policy": "act", "input_features": {k: list(f.shape) for k, f in inputs.items()},
            "output_features": {k: list(f.shape) for k, f in outputs.items()}, "loss": float(loss),
            "loss_finite": bool(torch.isfinite(loss))}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("export", type=Path)
    parser.add_argument("--policy", action="store_true", help="also make an ACT policy and run one training step")
    args = parser.parse_args()
    began = time.perf_counter()
    dataset = LeRobotDataset("local/egotouch", root=args.export, video_backend=video_backend())
    found = {"video_backend": video_backend(), "episodes": dataset.meta.total_episodes, "frames": len(dataset), "fps": dataset.meta.fps,
             "splits": dataset.meta.info.get("splits")}
    found["iteration"] = iterate_all(dataset)
    written = json.loads((args.export / "meta" / "stats.json").read_text())
    found["stats"] = compare_stats(recompute_stats(dataset), written, dataset.meta.features)
    if args.policy:
        found["policy"] = policy_forward(args.export, "local/egotouch")
    found["seconds"] = round(time.perf_counter() - began, 1)
    print(json.dumps(found))


if __name__ == "__main__":
    main()
