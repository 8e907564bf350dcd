#!/usr/bin/env bash
# The reward-profile variant protocol of issue 21 (NOTES.md, "Variants"):
# per profile, one coho pretrained in coho_default, then transfers into
# density_sparse and density_dense; each policy evaluated with sampled actions
# (as Unity's ML-Agents 1.x inference did) on seeds 11 and 12, 60 s after a
# 10 s warm-up. Resumable: finished runs and evaluations are skipped.
#
#   docs/reproduction/variants.sh PROFILE [PROFILE …]
#
# Env: BIN (default target/release/deepfoids), OUT (runs/variants),
# PRE (pretraining steps, 600000), TRANSFER (300000), TAG (suffix of run ids).
set -euo pipefail
BIN=${BIN:-target/release/deepfoids}
OUT=${OUT:-runs/variants}
PRE=${PRE:-600000}
TRANSFER=${TRANSFER:-300000}
TAG=${TAG:-}
mkdir -p "$OUT"
train() { # profile scene phase steps run [init]
    local profile=$1 scene=$2 phase=$3 steps=$4 run=$5 init=${6:-}
    if [[ -f $OUT/$run/final/state.json ]]; then return; fi
    local resume=()
    [[ -d $OUT/$run ]] && resume=(--resume)
    "$BIN" train --reward-profile "$profile" --scene "$scene" --phase "$phase" \
        --steps "$steps" --run-id "$run" --runs-dir "$OUT" --eval-seconds 0 --quiet \
        ${init:+--init-from "$OUT/$init"} "${resume[@]}"
}
evaluate() { # profile scene phase run
    local profile=$1 scene=$2 phase=$3 run=$4
    for seed in 11 12; do
        local dir=$OUT/eval-$run-$scene-s$seed
        [[ -f $dir/summary.json ]] && continue
        "$BIN" eval --reward-profile "$profile" --scene "$scene" --phase "$phase" \
            --policy "$OUT/$run" --stochastic --seed "$seed" --warmup 10 --seconds 60 \
            --out "$dir" >/dev/null
    done
}
for p in "$@"; do
    pre=$p$TAG-pre
    echo "== $p: pretraining ($(date +%T))"
    train "$p" coho_default pretrain "$PRE" "$pre"
    evaluate "$p" coho_default pretrain "$pre"
    for scene in density_sparse density_dense; do
        run=$p$TAG-${scene#density_}
        echo "== $p: transfer into $scene ($(date +%T))"
        train "$p" "$scene" transfer "$TRANSFER" "$run" "$pre"
        evaluate "$p" "$scene" transfer "$run"
    done
done
echo "== done ($(date +%T))"
