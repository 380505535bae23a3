"""scripts/write_splits.py on dataset roots holding only their split.json: each split file appears once its datasets
exist, the held-out set is sim240's test_seen, every other test_unseen trajectory of sim240 and every seed-13 episode,
seen and unseen objects apart, and a training list that would hold a held-out trajectory is refused."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "write_splits.py"


def dataset(data: Path, root: str, **lists: list[str]) -> None:
    (data / root).mkdir(parents=True)
    (data / root / "split.json").write_text(json.dumps({key: lists.get(key, []) for key in
                                                        ("train", "val", "test_seen", "test_unseen")}))


def run(data: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(SCRIPT), "--data", str(data)], capture_output=True, text=True)


def read(path: Path) -> dict[str, list[str]]:
    return json.loads(path.read_text())


def first_datasets(data: Path, sim240_train: tuple[str, ...] = ("a", "b")) -> None:
    dataset(data, "sim240_h5", train=list(sim240_train), val=["v"], test_seen=["s1", "s2"], test_unseen=["u1", "u2", "u3"])
    dataset(data, "sim_extra_h5", train=["e1"], val=["e2"], test_seen=["e3"], test_unseen=["e4"])
    dataset(data, "sim_test_h5", train=["t2"], val=["t1"], test_seen=["t3"], test_unseen=["tu"])


def test_the_held_out_set_and_the_first_training_lists_come_before_the_later_datasets(tmp_path):
    data = tmp_path / "data"
    first_datasets(data)
    done = run(data)
    assert done.returncode == 0, done.stderr
    held = read(data / "heldout" / "split.json")
    assert held == {"train": [], "val": [],
                    "test_seen": ["../sim240_h5/s1", "../sim240_h5/s2", "../sim_test_h5/t1", "../sim_test_h5/t2",
                                  "../sim_test_h5/t3"],
                    "test_unseen": ["../sim240_h5/u1", "../sim240_h5/u3", "../sim_test_h5/tu"]}
    train = read(data / "split_train.json")
    assert train["train"] == [str(data / "sim240_h5" / p) for p in ("a", "b")] + \
        [str(data / "sim_extra_h5" / p) for p in ("e1", "e2", "e3")]  # sim_extra's seen episodes; never e4
    assert len(train["test_unseen"]) == 3 and len(read(data / "split_eval.json")["test_unseen"]) == 2
    assert not (data / "split_train_more.json").exists() and not (data / "fresh").exists()
    assert "split_train_more.json, split_train_2x.json and split_train_3x.json wait for sim_more" in done.stdout

    dataset(data, "sim_more", train=["S/t/m1.hdf5"], test_unseen=["S/t/mu.hdf5"])  # raw: its folders are listed
    dataset(data, "sim_fresh_h5", train=["f2"], test_seen=["f1"], test_unseen=["fu"])
    done = run(data)
    assert done.returncode == 0, done.stderr
    assert read(data / "split_train_more.json")["train"][-1:] == [str(data / "sim_more" / "S" / "t" / "m1")]
    assert read(data / "fresh" / "split.json") == {"train": [], "val": [],
                                                  "test_seen": ["../sim_fresh_h5/f1", "../sim_fresh_h5/f2"],
                                                  "test_unseen": ["../sim_fresh_h5/fu"]}
    assert "split_train_2x.json and split_train_3x.json wait for sim_more2" in done.stdout

    dataset(data, "sim_more2", train=["S/t/n1.hdf5", "S/t/n2.hdf5"], val=["S/t/n3.hdf5"])  # raw: its folders are listed
    done = run(data)
    assert done.returncode == 0
    assert read(data / "split_train_2x.json")["train"][-4:] == [str(data / "sim_more" / "S" / "t" / "m1")] + \
        [str(data / "sim_more2" / "S" / "t" / n) for n in ("n1", "n2", "n3")]
    assert "data/split_train_3x.json waits for sim_more3" in done.stdout and not (data / "split_train_3x.json").exists()

    dataset(data, "sim_more3", test_seen=["S/t/o1.hdf5"], test_unseen=["S/t/ou.hdf5"])
    assert run(data).returncode == 0
    assert not list(data.rglob(".*.tmp"))  # each list renamed into place
    assert read(data / "split_train_3x.json")["train"] == read(data / "split_train_2x.json")["train"] + \
        [str(data / "sim_more3" / "S" / "t" / "o1")]  # its seen episodes; never ou


def test_a_training_list_that_holds_a_held_out_trajectory_is_refused(tmp_path):
    data = tmp_path / "data"
    first_datasets(data, sim240_train=("a", "s2"))  # s2 is also in sim240's test_seen
    done = run(data)
    assert done.returncode != 0
    assert "split_train.json would train on 1 held-out trajectories" in done.stderr
    assert not (data / "split_train.json").exists()
