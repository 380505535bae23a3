#!/usr/bin/env bash
# Retrain the bundled CPU models from scratch on simulated data, evaluate them (on the held-out trajectories of
# the split and on 60 episodes of a further simulator seed) and bundle them
# (docs/findings.md): nano (the bundled model), nano with a second seed (the seed spread), nano on black frames
# (nano_pose_only, for `eval --pose-only-baseline`) and the two baselines every model is judged against
# (baseline_pose, baseline_frames, and the frames baseline with nano's colour augmentation). Runs the trainings
# side by side, one torch thread each (docs/training.md has the times on the 2-core CPU machine). Run from the
# repository root after `make test` (or any command that created .venv). `configs/tiny.yaml` (several hours
# here) and `configs/nano_no_dropout.yaml` train and evaluate the same way: `train tiny; evaluate tiny --views all`.
set -euo pipefail
TA=.venv/bin/touchanything
$TA simulate data/sim240 --episodes 240 --seconds 10 --seed 11 --workers 2
$TA simulate data/sim_extra --episodes 24 --seconds 10 --seed 12 --workers 2
$TA simulate data/sim_test --episodes 60 --seconds 10 --seed 13 --workers 2  # test episodes only (never trained on)
$TA convert data/sim240 data/sim240_h5 --workers 2 --compression-level 1
$TA convert data/sim_extra data/sim_extra_h5 --workers 2 --compression-level 1
$TA convert data/sim_test data/sim_test_h5 --workers 2 --compression-level 1
# 162 training trajectories: sim240's train list and sim_extra's train, val and test_seen lists; sim240's val,
# test_seen and test_unseen lists held out.
.venv/bin/python - <<'PY'
import json
from pathlib import Path
data = Path("data").resolve()
main, extra = (json.loads((data / f"{root}/split.json").read_text()) for root in ("sim240_h5", "sim_extra_h5"))
split = {key: [str(data / "sim240_h5" / p) for p in paths] for key, paths in main.items()}
split["train"] += [str(data / "sim_extra_h5" / p) for key in ("train", "val", "test_seen") for p in extra[key]]
(data / "split_train.json").write_text(json.dumps(split, indent=1))
split["test_unseen"] = split["test_unseen"][::2]  # evaluation: every other unseen trajectory (30 of 60; time)
(data / "split_eval.json").write_text(json.dumps(split, indent=1))
# the seed-13 episodes: those with seen objects (whatever list the simulator put them in) → test_seen
test = json.loads((data / "sim_test_h5/split.json").read_text())
test = {"train": [], "val": [], "test_seen": sorted(test["train"] + test["val"] + test["test_seen"]),
        "test_unseen": test["test_unseen"]}
(data / "split_test13.json").write_text(json.dumps({k: [str(data / "sim_test_h5" / p) for p in v]
                                                     for k, v in test.items()}, indent=1))
PY
mkdir -p data/runs
train() {
  OMP_NUM_THREADS=1 $TA train --config "configs/$1.yaml" --data data/sim240_h5 --split-file data/split_train.json \
    --out "data/runs/$1" > "data/runs/$1.train.log" 2>&1
}
evaluate() {  # evaluate NAME VIEWS... [more eval options]
  local name=$1; shift
  for split in test_seen test_unseen; do
    $TA eval --checkpoint "data/runs/$name/best_model.pth" --data data/sim240_h5 --split-file data/split_eval.json \
      --split $split --ego-path views --device cpu --out "data/runs/$name/eval_$split" "$@"
    $TA eval --checkpoint "data/runs/$name/best_model.pth" --data data/sim_test_h5 --split-file data/split_test13.json \
      --split $split --ego-path views --device cpu --views all --out "data/runs/$name/eval13_$split"
  done
}
train nano & train nano_seed7 & train nano_pose_only & wait
train baseline_pose & train baseline_frames & train baseline_frames_aug & wait
evaluate nano --views ego ego+left ego+right all --pose-only-baseline data/runs/nano_pose_only/best_model.pth
evaluate nano_seed7 --views ego all --pose-only-baseline data/runs/nano_pose_only/best_model.pth
for name in baseline_pose baseline_frames baseline_frames_aug; do evaluate $name --views all; done
card() { echo "test_seen=data/runs/$1/eval_test_seen/results.json test_unseen=data/runs/$1/eval_test_unseen/results.json"; }
bundle() {  # bundle NAME RUN_EVALUATED_IN
  # shellcheck disable=SC2046
  .venv/bin/python scripts/bundle_model.py "data/runs/$1/best_model.pth" "models/$1" \
    --trained-on "simulated EgoTouch world, 162 episodes" --eval $(card "$2")
}
bundle nano nano; bundle nano_pose_only nano; bundle baseline_pose baseline_pose; bundle baseline_frames baseline_frames
.venv/bin/python scripts/findings_table.py data/runs nano nano_seed7 --others nano_pose_only baseline_pose baseline_frames baseline_frames_aug
