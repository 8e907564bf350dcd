#!/usr/bin/env bash
# Train one variant's transfer further, a million steps at a time, evaluating
# after each million as variants.sh does (sampled actions, seeds 11 and 12, 60 s
# after a 10 s warm-up), to see where a figure stops moving with the budget.
# Resumable: finished runs and evaluations are skipped.
#
#   docs/reproduction/extend.sh PROFILE SCENE FROM_RUN FROM_MILLIONS TO_MILLIONS
#
# e.g. extend.sh bounce_budget_space20 density_dense \
#          bounce_budget_space20-thesis-dense-t3m 3 7
# trains -t4m … -t7m, each initialised from the one before.
# Env: BIN (default target/release/deepfoids), OUT (runs/variants).
set -euo pipefail
BIN=${BIN:-target/release/deepfoids}
OUT=${OUT:-runs/variants}
source "$(dirname "$0")/protocol.sh"
profile=$1 scene=$2 from=$3 start=$4 end=$5
base=${from%-t*m}
prev=$from
for ((m = start + 1; m <= end; m++)); do
    run=$base-t${m}m
    echo "== $run ($(date +%T))"
    train "$profile" "$scene" transfer 1000000 "$run" "$prev"
    evaluate "$profile" "$scene" transfer "$run"
    prev=$run
done
echo "== done ($(date +%T))"
