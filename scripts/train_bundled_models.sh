#!/usr/bin/env bash
# Retrain the bundled CPU models from scratch on simulated data, evaluate them on the held-out set and bundle them
# (docs/findings.md): nano (the default model), nano with a second seed (the seed spread), nano on black frames
# (nano_pose_only), the two baselines every model is judged against (baseline_pose, baseline_frames, and the frames
# baseline with nano's colour augmentation), pico (nano's design at 64 px with a narrower backbone: faster), and
# pico and nano on about 400 episodes (pico_more, nano_more: the same models, more data). Runs the trainings side
# by side, one torch thread each (docs/training.md has the times on the 2-core CPU machine). Run from the repository
# root after `make test` (or any command that created .venv). The data come from scripts/make_datasets.sh; the
# atlas of the bundled models is then `touchanything bench --data data/heldout --workers 2 --out docs/bench`.
set -euo pipefail
TA=.venv/bin/touchanything
bash scripts/make_datasets.sh
mkdir -p data/runs
train() {  # train NAME [SPLIT_FILE]
  OMP_NUM_THREADS=1 $TA train --config "configs/$1.yaml" --data data/sim240_h5 --split-file "${2:-data/split_train.json}" \
    --out "data/runs/$1" > "data/runs/$1.train.log" 2>&1
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
train pico & train pico_more data/split_train_more.json & train nano_more data/split_train_more.json & wait
evaluate nano ego ego+left ego+right all
for name in nano_seed7 nano_pose_only baseline_pose baseline_frames baseline_frames_aug pico pico_more nano_more; do
  evaluate "$name"
done
bundle() {  # bundle NAME TRAINED_ON
  .venv/bin/python scripts/bundle_model.py "data/runs/$1/best_model.pth" "models/$1" --trained-on "$2" \
    --eval "test_seen=data/runs/$1/heldout_test_seen/results.json" "test_unseen=data/runs/$1/heldout_test_unseen/results.json"
}
for name in nano nano_pose_only baseline_pose baseline_frames pico; do bundle "$name" "simulated EgoTouch world, 162 episodes"; done
bundle pico_more "simulated EgoTouch world, 402 episodes"
