#!/usr/bin/env bash
# The simulated datasets the bundled models are trained and judged on (docs/findings.md, docs/bench), made
# from fixed simulator seeds, so the same files come out on every machine:
#   data/sim240_h5     240 episodes, seed 11: training (its train list), validation (val), held out (test_seen, test_unseen)
#   data/sim_extra_h5   24 episodes, seed 12: training (its train, val and test_seen lists)
#   data/sim_more_h5   300 episodes, seed 14: more training (its train, val and test_seen lists; never its
#                      test_unseen, whose objects are the held-out ones)
#   data/sim_test_h5    60 episodes, seed 13: held out only, never trained on
#   data/sim_more2_h5  520 episodes, seed 15: the data axis of the frontier (its train, val and test_seen lists)
#   data/sim_fresh_h5   48 episodes, seed 16: a second fresh seed, held out only (the frontier's confirmation)
# and the split files that say which is which:
#   data/split_train.json       162 training trajectories (sim240 train + sim_extra), sim240's val and test lists
#   data/split_train_more.json  the same plus sim_more's seen episodes (about 400 training trajectories)
#   data/split_eval.json        split_train.json with every other test_unseen trajectory (the findings' tables)
#   data/split_test13.json      the seed-13 episodes: seen objects → test_seen, unseen → test_unseen
#   data/split_train_2x.json    split_train_more.json plus sim_more2's seen episodes (about 800: twice 398)
#   data/fresh/split.json       the seed-16 episodes, seen and unseen objects apart (never trained on)
#   data/heldout/split.json     THE HELD-OUT SET of the atlas (`touchanything bench --data data/heldout`): sim240's
#                               test_seen and every other test_unseen trajectory, plus every seed-13 episode,
#                               seen and unseen objects kept apart (108 trajectories: 67 test_seen, 41 test_unseen)
# A step whose output is there is skipped. Run from the repository root after `make test` (or any command that
# created .venv); about 4 h on the 2-core CPU machine (simulation ~20 frames/s with --workers 2) (docs/performance.md, "Simulation").
set -euo pipefail
TA=.venv/bin/touchanything
# The episodes simulated so far live beside the datasets (devices/sim/episode_cache.py): a run stopped halfway —
# a session that ends — and run again on this checkout copies them instead of simulating them again.
export XDG_CACHE_HOME="$PWD/data/.cache"
simulate() {  # simulate NAME EPISODES SEED
  [ -d "data/$1" ] || $TA simulate "data/$1" --episodes "$2" --seconds 10 --seed "$3" --workers 2
  [ -d "data/$1_h5" ] || $TA convert "data/$1" "data/$1_h5" --workers 2 --compression-level 1
}
simulate sim240 240 11
simulate sim_extra 24 12
simulate sim_test 60 13
simulate sim_more 300 14
simulate sim_more2 520 15
simulate sim_fresh 48 16
.venv/bin/python - <<'PY'
import json
from pathlib import Path

data = Path("data").resolve()
def read(root):
    return json.loads((data / root / "split.json").read_text())
def under(root, paths):
    return [str(data / root / p) for p in paths]
main, extra, more, test = read("sim240_h5"), read("sim_extra_h5"), read("sim_more_h5"), read("sim_test_h5")
more2, fresh = read("sim_more2_h5"), read("sim_fresh_h5")
split = {key: under("sim240_h5", paths) for key, paths in main.items()}
split["train"] += [p for key in ("train", "val", "test_seen") for p in under("sim_extra_h5", extra[key])]
(data / "split_train.json").write_text(json.dumps(split, indent=1))
bigger = dict(split, train=split["train"] + [p for key in ("train", "val", "test_seen") for p in under("sim_more_h5", more[key])])
(data / "split_train_more.json").write_text(json.dumps(bigger, indent=1))
twice = dict(bigger, train=bigger["train"] + [p for key in ("train", "val", "test_seen") for p in under("sim_more2_h5", more2[key])])
(data / "split_train_2x.json").write_text(json.dumps(twice, indent=1))
split["test_unseen"] = split["test_unseen"][::2]  # every other unseen trajectory (30 of 60; evaluation time)
(data / "split_eval.json").write_text(json.dumps(split, indent=1))
seen13 = sorted(test["train"] + test["val"] + test["test_seen"])  # the simulator's own lists: all seen objects
test13 = {"train": [], "val": [], "test_seen": under("sim_test_h5", seen13), "test_unseen": under("sim_test_h5", test["test_unseen"])}
(data / "split_test13.json").write_text(json.dumps(test13, indent=1))
held = data / "heldout"
held.mkdir(exist_ok=True)
relative = {key: [str(Path("..") / Path(p).relative_to(data)) for p in split[key] + test13[key]] for key in ("test_seen", "test_unseen")}
(held / "split.json").write_text(json.dumps({"train": [], "val": [], **relative}, indent=1))
seen16 = sorted(fresh["train"] + fresh["val"] + fresh["test_seen"])
(data / "fresh").mkdir(exist_ok=True)
(data / "fresh" / "split.json").write_text(json.dumps({"train": [], "val": [], "test_seen": [f"../sim_fresh_h5/{p}" for p in seen16],
                                                       "test_unseen": [f"../sim_fresh_h5/{p}" for p in fresh["test_unseen"]]}, indent=1))
trained = set(twice["train"])
assert not trained & {str(data / p[3:]) for key in relative for p in relative[key]}, "a held-out trajectory is trained on"
print("training:", len(split["train"]), "(split_train.json),", len(bigger["train"]), "(split_train_more.json),",
      len(twice["train"]), "(split_train_2x.json);",
      "held out:", {key: len(v) for key, v in relative.items()})
PY
