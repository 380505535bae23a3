"""`touchanything simulate OUT --episodes N`: generate simulated EgoTouch episodes, split and card."""
from __future__ import annotations

import argparse
from pathlib import Path

from touchanything.core.output_safety import add_overwrite_argument, check_output, replacing_folder


def add_parser(commands: argparse._SubParsersAction) -> None:
    parser = commands.add_parser("simulate", help="generate simulated EgoTouch episodes (raw folders), split.json and a dataset card")
    parser.add_argument("out", type=Path, help="output root (<Scene>/<task>/<id>/ folders are written here)")
    parser.add_argument("--episodes", type=int, required=True, help="how many episodes to generate")
    parser.add_argument("--seconds", type=float, default=10.0, help="length of each episode (default 10)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the whole dataset: the same seed gives the same "
                                                                  "episodes and split (default 0)")
    parser.add_argument("--workers", type=int, default=1, help="episodes generated in parallel (default 1)")
    add_overwrite_argument(parser, "a non-empty OUT (only once the new dataset is complete)")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from touchanything.app.sessions.progress_bar import ProgressBar
    from touchanything.devices.episodes.dataset_split import SPLIT_FILE, empty_split_problem, read_split
    from touchanything.devices.sim.dataset_generator import CARD_MD, SimulationConfig, check_config, percent, simulate_dataset

    config = SimulationConfig(args.episodes, args.seconds, args.seed, args.workers)
    check_config(config)
    check_output(args.out, (), args.overwrite, whole=True)
    with ProgressBar(total=config.episodes, unit="episode", desc="simulate") as bar, \
            replacing_folder(args.out, args.overwrite) as folder:
        frames = [0]

        def progress(stats) -> None:
            frames[0] += stats.frames
            bar.set_postfix(fps=f"{frames[0] / max(bar.format_dict['elapsed'], 1e-9):.1f}", refresh=False)
            bar.update(1)

        card = simulate_dataset(folder, config, on_episode=progress)
    reused = f" ({card['from_cache']} copied from the cache of earlier runs)" if card["from_cache"] else ""
    print(f"{card['episodes']} episodes, {card['frames']} frames at {card['generation_fps']} frames/s{reused}")
    for camera, v in card["contact_visibility"].items():
        print(f"contact visible from {camera}: {percent(v['share'])} of {v['contact_points']} contact points")
    ambiguity, error = card["pose_ambiguity"], card["pose_error_mm"]
    if ambiguity is not None:
        print(f"pose error (RMS over joints): median {error['median']} mm, visible hands {error['visible_hand_median']} mm, "
              f"occluded hands {error['occluded_hand_median']} mm")
        print(f"pose-ambiguous contact: {percent(ambiguity['ambiguous_share'])} of {ambiguity['contact_frames']} sampled "
              f"contact hand-frames (a no-contact pose within {ambiguity['tolerance_mm']} mm)")
    print(f"dataset card: {args.out / CARD_MD}; split: {args.out / SPLIT_FILE}")
    split = read_split(args.out / SPLIT_FILE)
    print("split     " + ", ".join(f"{key} {len(paths)}" for key, paths in split.items()))
    if problem := empty_split_problem(split, {}):
        print(f"warning   {problem.replace('would be', 'is')}: simulate more episodes (--episodes) to train and test on it")
    return 0
