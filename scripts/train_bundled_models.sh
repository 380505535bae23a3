#!/usr/bin/env bash
# Retrain the bundled CPU models from scratch on simulated data and evaluate them (docs/findings.md).
# About two and a half hours on the 2-core CPU machine (nano 27 min, nano_no_dropout 27 min, tiny 24 min,
# the evaluations about 10 min per model). Run from the repository root after `make test` (or any
# command that created .venv).
set -euo pipefail
TA=.venv/bin/touchanything
$TA simulate data/sim --episodes 50 --seconds 10 --seed 11 --workers 2 --overwrite
$TA convert data/sim data/sim_h5 --workers 2 --compression-level 1
for name in nano nano_no_dropout tiny; do
  $TA train --config configs/$name.yaml --data data/sim_h5 --out data/runs/$name
done
for name in nano tiny; do
  .venv/bin/python scripts/bundle_model.py data/runs/$name/best_model.pth models/$name
done
for name in nano nano_no_dropout tiny; do
  for split in test_seen test_unseen; do
    $TA eval --checkpoint data/runs/$name/best_model.pth --data data/sim_h5 --split $split \
      --views ego ego+left ego+right all --ego-path views --out data/eval/$name/$split
  done
done
