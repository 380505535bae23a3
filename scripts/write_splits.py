"""The split files of the simulated datasets (scripts/make_datasets.sh), each written as soon as every dataset it
names exists, so that what needs only the first datasets (the held-out set, the 398 training trajectories) can run
while the later ones are still being simulated:

    data/split_train.json       162 training trajectories (sim240 train + sim_extra), sim240's val and test lists
    data/split_eval.json        split_train.json with every other test_unseen trajectory (the findings' tables)
    data/split_test13.json      the seed-13 episodes: seen objects → test_seen, unseen → test_unseen
    data/heldout/split.json     THE HELD-OUT SET of the atlas: sim240's test_seen and every other test_unseen
                                trajectory, plus every seed-13 episode, seen and unseen objects kept apart (108)
        — these four once sim240_h5, sim_extra_h5 and sim_test_h5 exist;
    data/split_train_more.json  split_train.json plus sim_more's seen episodes (398) — once sim_more exists;
    data/split_train_2x.json    split_train_more.json plus sim_more2's seen episodes (831) — once sim_more2 exists;
    data/split_train_3x.json    split_train_2x.json plus sim_more3's seen episodes — once sim_more3 exists
        — these three list raw episode folders for sim_more, sim_more2 and sim_more3 (kept raw, too large as HDF5;
        `train` decodes their frames into its frame cache);
    data/fresh/split.json       the seed-16 episodes, seen and unseen objects apart (never trained on) — once sim_fresh_h5 exists.

    python scripts/write_splits.py [--data data]

Rewrites the files it can (the same content every time); refuses to write a training list that holds a held-out
trajectory; prints what it wrote and what still waits for which dataset.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

SPLITS = ("train", "val", "test_seen", "test_unseen")
SEEN = ("train", "val", "test_seen")
"""A dataset's lists whose episodes show seen objects (its test_unseen ones show the held-out objects)."""


def read(data: Path, root: str, raw: bool = False) -> dict[str, list[str]] | None:
    """The split.json of dataset `root` under `data`, its paths made absolute; None when it is not made yet. `raw`: a
    raw dataset's split names the HDF5 files `convert` would make; the episode folders are listed instead."""
    path = data / root / "split.json"
    if not path.is_file():
        return None
    return {key: [str(data / root / (p.removesuffix(".hdf5") if raw else p)) for p in paths]
            for key, paths in json.loads(path.read_text()).items()}


def seen(split: dict[str, list[str]]) -> list[str]:
    return [p for key in SEEN for p in split[key]]


def relative(folder: Path, data: Path, paths: list[str]) -> list[str]:
    """Paths under `data` as written in a split file of `folder` (a folder of `data`)."""
    return [str(Path("..") / Path(p).relative_to(data)) for p in paths]


def write(path: Path, split: dict[str, list[str]], written: list[str]) -> None:
    """Write `split` to `path` atomically (a temporary file beside it, renamed over it), and say so in `written`."""
    path.parent.mkdir(parents=True, exist_ok=True)
    temporary = path.with_name(f".{path.name}.tmp")
    temporary.write_text(json.dumps(split, indent=1))
    temporary.replace(path)
    written.append(f"{path} ({', '.join(f'{key} {len(split[key])}' for key in SPLITS)})")


def write_splits(data: Path) -> tuple[list[str], list[str]]:
    """Write every split file whose datasets exist under `data`; (what was written, what waits and for what)."""
    data = data.resolve()
    main, extra, test = read(data, "sim240_h5"), read(data, "sim_extra_h5"), read(data, "sim_test_h5")
    more, more2, more3 = (read(data, name, raw=True) for name in ("sim_more", "sim_more2", "sim_more3"))
    fresh = read(data, "sim_fresh_h5")
    written: list[str] = []
    waiting: list[str] = []
    if fresh is None:
        waiting.append("data/fresh/split.json waits for sim_fresh_h5")
    else:
        fresh_dir = data / "fresh"
        write(fresh_dir / "split.json", {"train": [], "val": [], "test_seen": relative(fresh_dir, data, sorted(seen(fresh))),
                                         "test_unseen": relative(fresh_dir, data, fresh["test_unseen"])}, written)
    if None in (main, extra, test):
        waiting.append("every other split file waits for sim240_h5, sim_extra_h5 and sim_test_h5")
        return written, waiting
    split = dict(main, train=main["train"] + seen(extra))
    test13 = {"train": [], "val": [], "test_seen": sorted(seen(test)), "test_unseen": test["test_unseen"]}
    held = {key: split[key][::2] if key == "test_unseen" else split[key] for key in ("test_seen", "test_unseen")}
    held = {key: held[key] + test13[key] for key in held}
    held_out = {p for paths in held.values() for p in paths}
    trained = [("split_train.json", split)]
    if more is None:
        waiting.append("data/split_train_more.json, split_train_2x.json and split_train_3x.json wait for sim_more")
    else:
        bigger = dict(split, train=split["train"] + seen(more))
        trained.append(("split_train_more.json", bigger))
        steps = [("split_train_2x.json", more2, "sim_more2"), ("split_train_3x.json", more3, "sim_more3")]
        for step, (name, added, needed) in enumerate(steps):
            if added is None:
                later = [n for n, _, _ in steps[step:]]
                waiting.append(f"data/{' and '.join(later)} wait{'s' if len(later) == 1 else ''} for {needed}")
                break
            bigger = dict(bigger, train=bigger["train"] + seen(added))
            trained.append((name, bigger))
    for name, training in trained:
        if leak := held_out & set(training["train"]):
            raise SystemExit(f"{name} would train on {len(leak)} held-out trajectories, e.g. {sorted(leak)[0]}")
        write(data / name, training, written)
    write(data / "split_eval.json", dict(split, test_unseen=split["test_unseen"][::2]), written)
    write(data / "split_test13.json", test13, written)
    heldout_dir = data / "heldout"
    write(heldout_dir / "split.json", {"train": [], "val": [], **{key: relative(heldout_dir, data, paths)
                                                                  for key, paths in held.items()}}, written)
    return written, waiting


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path("data"))
    args = parser.parse_args()
    written, waiting = write_splits(args.data)
    for line in written:
        print(f"wrote    {line}")
    for line in waiting:
        print(f"waiting  {line}")


if __name__ == "__main__":
    main()
