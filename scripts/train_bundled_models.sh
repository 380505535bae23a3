#!/usr/bin/env bash
# Retrain the bundled CPU models from scratch on simulated data and evaluate them (docs/findings.md):
# nano (the bundled model), nano with a second seed (the seed spread), nano on black frames (the pose-only
# baseline), nano without view dropout (the ablation) and tiny. Runs two trainings at a time, one torch
# thread each (docs/findings.md has the times on the 2-core CPU machine). Run from the repository root after
# `make test` (or any command that created .venv).
set -euo pipefail
TA=.venv/bin/touchanything
$TA simulate data/sim --episodes 50 --seconds 10 --seed 11 --workers 2 --overwrite
$TA convert data/sim data/sim_h5 --workers 2 --compression-level 1
mkdir -p data/runs
train() { OMP_NUM_THREADS=1 $TA train --config "configs/$1.yaml" --data data/sim_h5 --out "data/runs/$1" > "data/runs/$1.log" 2>&1; }
train nano & train nano_pose_only & wait
train nano_seed7 & train tiny & wait
train nano_no_dropout
for name in nano tiny; do
  .venv/bin/python scripts/bundle_model.py "data/runs/$name/best_model.pth" "models/$name"
done
for name in nano nano_seed7 nano_no_dropout tiny; do
  for split in test_seen test_unseen; do
    $TA eval --checkpoint "data/runs/$name/best_model.pth" --data data/sim_h5 --split $split \
      --views ego ego+left ego+right all --ego-path views --device cpu \
      --pose-only-baseline data/runs/nano_pose_only/best_model.pth --out "data/eval/$name/$split"
  done
done
.venv/bin/python scripts/findings_table.py data/eval nano nano_seed7 nano_no_dropout tiny
