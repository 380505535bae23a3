#!/usr/bin/env bash
# Retrain the bundled CPU models from scratch on simulated data, evaluate them on the held-out set and bundle them
# (docs/findings.md). On the 162 training trajectories of data/split_train.json: nano (the default model), nano with
# a second seed (the seed spread), nano on black frames (nano_pose_only) and the two baselines every model is judged
# against (baseline_pose, baseline_frames, and the frames baseline with nano's colour augmentation); pico (nano's
# design at 64 px with a narrower backbone), one change from nano. On the 398 of data/split_train_more.json (the
# same plus a further simulator seed's seen-object episodes): pico (faster and more accurate than nano), nano, and
# both baselines, trained the same way. On the 831 of data/split_train_2x.json (twice that): pico again, the one
# bundled (pico_2x: the data axis of the frontier, docs/findings.md). Runs the trainings side by side, one torch thread each
# (docs/training.md has the times on the 2-core CPU machine). Run from the repository root after `make test` (or any
# command that created .venv). The data come from scripts/make_datasets.sh; the atlas of the bundled models is then
# `touchanything bench --data data/heldout --workers 2 --out models/atlas`.
set -euo pipefail
TA=.venv/bin/touchanything
bash scripts/make_datasets.sh
mkdir -p data/runs
train() {  # train CONFIG [RUN [SPLIT_FILE]]: configs/CONFIG.yaml into data/runs/RUN (default CONFIG)
  local run=${2:-$1}
  OMP_NUM_THREADS=1 $TA train --config "configs/$1.yaml" --data data/sim240_h5 --split-file "${3:-data/split_train.json}" \
    --out "data/runs/$run" > "data/runs/$run.train.log" 2>&1
}
evaluate() {  # evaluate NAME [VIEWS...]: the official protocol on both lists of the held-out set (108 trajectories)
  local name=$1; shift
  for split in test_seen test_unseen; do
    $TA eval --checkpoint "data/runs/$name/best_model.pth" --data data/heldout --split $split --ego-path views \
      --device cpu --views "${@:-all}" --out "data/runs/$name/heldout_$split" --overwrite
  done
}
train nano & train nano_seed7 & train nano_pose_only & wait
train baseline_pose & train baseline_frames & train baseline_frames_aug & wait
MORE=data/split_train_more.json
train pico pico_162 & train pico pico $MORE & train nano nano_more $MORE & wait
train baseline_pose baseline_pose_more $MORE & train baseline_frames baseline_frames_more $MORE & wait
train pico pico_2x data/split_train_2x.json
evaluate nano ego ego+left ego+right all
for name in nano_seed7 nano_pose_only baseline_pose baseline_frames baseline_frames_aug pico_162 pico nano_more \
    baseline_pose_more baseline_frames_more pico_2x; do
  evaluate "$name"
done
bundle() {  # bundle RUN MODEL TRAINED_ON: data/runs/RUN into models/MODEL with its held-out card
  .venv/bin/python scripts/bundle_model.py "data/runs/$1/best_model.pth" "models/$2" --trained-on "$3" \
    --eval "test_seen=data/runs/$1/heldout_test_seen/results.json" "test_unseen=data/runs/$1/heldout_test_unseen/results.json"
}
for name in nano nano_pose_only baseline_pose baseline_frames; do bundle "$name" "$name" "simulated EgoTouch world, 162 episodes"; done
bundle pico_2x pico "simulated EgoTouch world, 831 episodes"
.venv/bin/python scripts/held_out_table.py data/runs nano nano_seed7 nano_pose_only baseline_pose baseline_frames pico_162 \
  nano_more baseline_pose_more baseline_frames_more pico pico_2x --against nano
