#!/usr/bin/env bash
# The simulated datasets the bundled models are trained and judged on (docs/findings.md, docs/bench), made
# from fixed simulator seeds, so the same files come out on every machine:
#   data/sim240_h5     240 episodes, seed 11: training (its train list), validation (val), held out (test_seen, test_unseen)
#   data/sim_extra_h5   24 episodes, seed 12: training (its train, val and test_seen lists)
#   data/sim_more      300 episodes, seed 14: more training (its train, val and test_seen lists; never its
#                      test_unseen, whose objects are the held-out ones), kept raw like sim_more2
#   data/sim_test_h5    60 episodes, seed 13: held out only, never trained on
#   data/sim_more2     520 episodes, seed 15: the data axis of the frontier (its train, val and test_seen lists),
#                      kept raw: training decodes their frames into its frame cache (3.4 MB per episode at 64 px;
#                      its clips equal those of the HDF5 file `convert` would make)
#   data/sim_fresh_h5   48 episodes, seed 16: a second fresh seed, held out only (the frontier's confirmation)
#   data/sim_more3     520 episodes, seed 17: the data axis's third step (its train, val and test_seen lists), raw
# and the split files that say which is which (scripts/write_splits.py, run after each dataset: a split file is
# written as soon as its datasets exist, so the held-out set and the ~400 training trajectories are there before
# the 520 episodes of sim_more2 are made): split_train.json (162 training trajectories), split_train_more.json
# (~400), split_train_2x.json (~800), split_train_3x.json (~1,260), split_eval.json, split_test13.json, fresh/split.json and
# heldout/split.json, THE HELD-OUT SET of the atlas (`touchanything bench --data data/heldout`; 108 trajectories:
# 67 test_seen, 41 test_unseen).
# A step whose output is there is skipped. Run from the repository root after `make test` (or any command that
# created .venv); about 2 h 30 min on the idle 2-core CPU machine (2026-12-06: the first six datasets, 1,192 episodes, in
# 1 h 48 min; simulation 62–67 frames/s with --workers 2, conversion about 1.7 s per episode) (docs/performance.md, "Simulation").
# The HDF5 files take about 93 MB per 10 s episode (the raw episodes 3 MB): all seven datasets would need about
# 160 GB, more than the ~100 GB this machine's disk holds beside the frame caches, so the three training-only datasets
# stay raw (sim_more 28 GB, sim_more2 and sim_more3 49 GB each as HDF5), and a conversion that the free space cannot hold stops the script
# before it starts, said in one line.
set -euo pipefail
TA=.venv/bin/touchanything
# The episodes simulated so far live beside the datasets (devices/sim/episode_cache.py): a run stopped halfway —
# a session that ends — and run again on this checkout copies them instead of simulating them again.
export XDG_CACHE_HOME="$PWD/data/.cache"
H5_MB_PER_EPISODE=93  # a 10 s episode's HDF5 at gzip level 1 (300 episodes: 27.8 GB)
enough_disk() {  # enough_disk NAME EPISODES: stop, saying so, before a conversion the disk cannot hold (2 GB spare)
  local need=$(( $2 * H5_MB_PER_EPISODE / 1024 + 2 )) free
  free=$(df --output=avail -BG data | tail -1 | tr -dc 0-9)
  [ "$free" -ge "$need" ] || { echo "data/$1_h5 needs about $need GB and $free GB are free: not converted" >&2; exit 3; }
}
simulate() {  # simulate NAME EPISODES SEED [raw], then (unless raw) convert, and write the split files it completes
  [ -d "data/$1" ] || $TA simulate "data/$1" --episodes "$2" --seconds 10 --seed "$3" --workers 2
  if [ "${4:-}" != raw ] && [ ! -d "data/$1_h5" ]; then
    enough_disk "$1" "$2"
    $TA convert "data/$1" "data/$1_h5" --workers 2 --compression-level 1
  fi
  .venv/bin/python scripts/write_splits.py --data data
}
simulate sim240 240 11
simulate sim_extra 24 12
simulate sim_test 60 13
simulate sim_more 300 14 raw
simulate sim_fresh 48 16
simulate sim_more2 520 15 raw
simulate sim_more3 520 17 raw
