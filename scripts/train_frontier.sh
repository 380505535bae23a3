#!/usr/bin/env bash
# The frontier of docs/findings.md: three ways to buy accuracy with time, each one change from the bundled `pico`
# (configs/pico.yaml on the 398 training trajectories of data/split_train_more.json), trained by the committed
# configs and measured on the held-out set (data/heldout) and on a second fresh seed (data/fresh):
#   data        pico and nano on twice the data (data/split_train_2x.json), beside both at 162 and 398, and pico on
#               three times (data/split_train_3x.json)
#   resolution  pico at 96 and 128 px (configs/pico_96.yaml, configs/pico_128.yaml)
#   ensembles   pico with seeds 1, 2 and 3 (configs/pico_seedN.yaml): with the bundled pico (seed 42) the members
#               of a 4-member ensemble, all of one recipe and data
# Resumable: a stopped run (a session that ends kills it) continues from its last.pth when this script is run again; a
# finished run (data/runs/RUN/.done) and an evaluation whose results.json exists are skipped, and a run that another
# instance of this script is training or evaluating is left to it (data/runs/RUN.lock). Two jobs (trainings, the
# bundled models' evaluations) run side by side, one torch thread each, counting those another instance runs, the next
# starting when one ends. Run from the repository root once scripts/make_datasets.sh has made the held-out set and the
# 162 training trajectories (sim240, sim_extra, sim_test): a run whose data is not made yet (~400 trajectories: split_train_more.json; twice
# that: split_train_2x.json; three times: split_train_3x.json) waits, said in one line, and so does the evaluation on the fresh seed; run this script
# again as scripts/make_datasets.sh makes them. The tables and the curves' pictures cover the runs trained so far.
set -euo pipefail
TA=.venv/bin/touchanything
for needed in data/split_train.json data/heldout/split.json; do
  [ -f "$needed" ] || { echo "$needed is missing: run scripts/make_datasets.sh first" >&2; exit 2; }
done
mkdir -p data/runs
hold() {  # hold RUN: true when this shell now holds RUN's lock (kept until it exits); else says who has it
  exec {lock}>"data/runs/$1.lock"
  flock -n "$lock" || { echo "$1 is being trained or evaluated by another run of this script"; return 1; }
}
train() {  # train CONFIG RUN SPLIT_FILE: configs/CONFIG.yaml into data/runs/RUN, continued from its last.pth
  local out=data/runs/$2 resume=()
  [ -f "$out/.done" ] && return 0
  [ -f "$3" ] || { echo "$2 waits for $3 (scripts/make_datasets.sh)"; return 0; }
  hold "$2" || return 0
  [ -f "$out/last.pth" ] && resume=(--resume "$out/last.pth")
  OMP_NUM_THREADS=1 $TA train --config "configs/$1.yaml" --data data/sim240_h5 --split-file "$3" --out "$out" \
    "${resume[@]}" >> "data/runs/$2.train.log" 2>&1
  touch "$out/.done"
}
evaluate() (  # evaluate RUN CHECKPOINT: all views, causal, both splits of the held-out set and of the fresh seed
  hold "$1" || exit 0
  for root in heldout fresh; do
    [ -f "data/$root/split.json" ] || { echo "$1 on data/$root waits for scripts/make_datasets.sh"; continue; }
    for split in test_seen test_unseen; do
      out="data/runs/$1/${root}_$split"
      [ -f "$out/results.json" ] || OMP_NUM_THREADS=1 $TA eval --checkpoint "$2" --data "data/$root" --split $split --ego-path views \
        --device cpu --views all --out "$out" --overwrite > /dev/null
    done
  done
)
SEEN=data/split_train.json MORE=data/split_train_more.json TWICE=data/split_train_2x.json THRICE=data/split_train_3x.json
running() {  # trainings and evaluations running on this checkout, this instance's and any other's
  pgrep -fc -- "$TA (train|eval) " || true
}
side_by_side() {  # side_by_side COMMAND...: in the background once fewer than two jobs run
  while [ "$(running)" -ge 2 ]; do sleep 15; done
  "$@" &
  sleep 5  # its training or evaluation has started (or it has returned: done, held, waiting) before the next count
}
side_by_side train pico_seed1 pico_seed1 $MORE
side_by_side train pico_96 pico_96 $MORE
side_by_side train pico_seed2 pico_seed2 $MORE
side_by_side train pico_seed3 pico_seed3 $MORE
side_by_side train pico_128 pico_128 $MORE
side_by_side train pico pico_2x $TWICE
side_by_side train nano nano_2x $TWICE
side_by_side train pico pico_162 $SEEN
side_by_side train nano nano_more $MORE  # nano at 398 is in docs/findings.md; retrained for paired intervals
side_by_side train pico pico_3x $THRICE
mkdir -p data/runs/bundled_pico data/runs/bundled_nano
side_by_side evaluate bundled_pico models/pico/best_model.pth
side_by_side evaluate bundled_nano models/nano/best_model.pth
for job in $(jobs -p); do wait "$job" || echo "a job stopped with an error: see data/runs/*.train.log"; done
trained=()
for run in pico_162 pico_2x pico_3x nano_more nano_2x pico_96 pico_128 pico_seed1 pico_seed2 pico_seed3; do
  [ -f "data/runs/$run/.done" ] || continue  # not trained yet: a half-trained best_model.pth is never evaluated
  evaluate "$run" "data/runs/$run/best_model.pth"
  if [ -f "data/runs/$run/heldout_test_unseen/results.json" ]; then trained+=("$run"); fi  # else another instance evaluates it
done
for set in heldout fresh; do
  [ -f "data/$set/split.json" ] || continue
  echo "## data/$set"
  .venv/bin/python scripts/held_out_table.py data/runs bundled_pico "${trained[@]}" --against bundled_pico --set "$set"
  echo "## data/$set: the three axes (docs/bench/frontier_curves_$set.png)"
  .venv/bin/python scripts/frontier_curves.py data/runs --set "$set" --plot "docs/bench/frontier_curves_$set.png"
done
