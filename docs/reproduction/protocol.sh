# The variant protocol's two steps, shared by variants.sh, transfer_variants.sh
# and extend.sh (sourced, not run). Both skip what is finished and resume what
# was interrupted. Expects BIN (the deepfoids binary) and OUT (the runs folder);
# SEED, when set, is the training seed (otherwise train's default, 0): give
# each seed its own OUT.

# train PROFILE SCENE PHASE STEPS RUN [INIT]: one training run, initialised
# from run INIT when given.
train() {
    local profile=$1 scene=$2 phase=$3 steps=$4 run=$5 init=${6:-}
    if [[ -f $OUT/$run/final/state.json ]]; then return; fi
    local resume=()
    [[ -d $OUT/$run ]] && resume=(--resume)
    "$BIN" train --reward-profile "$profile" --scene "$scene" --phase "$phase" \
        --steps "$steps" --run-id "$run" --runs-dir "$OUT" --eval-seconds 0 --quiet \
        ${SEED:+--seed "$SEED"} ${init:+--init-from "$OUT/$init"} "${resume[@]}"
}

# evaluate PROFILE SCENE PHASE RUN: sampled actions (as Unity's ML-Agents 1.x
# inference did) on seeds 11 and 12, 60 s after a 10 s warm-up, into
# OUT/eval-RUN-SCENE-sSEED.
evaluate() {
    local profile=$1 scene=$2 phase=$3 run=$4
    for seed in 11 12; do
        local dir=$OUT/eval-$run-$scene-s$seed
        [[ -f $dir/summary.json ]] && continue
        "$BIN" eval --reward-profile "$profile" --scene "$scene" --phase "$phase" \
            --policy "$OUT/$run" --seed "$seed" --warmup 10 --seconds 60 \
            --out "$dir" >/dev/null
    done
}

# transfer PROFILE SCENE RUN PRE: the TRANSFER-step transfer of run PRE into
# SCENE under PROFILE's transfer weights, then its evaluation.
transfer() {
    local profile=$1 scene=$2 run=$3 pre=$4
    echo "== $profile: transfer into $scene ($(date +%T))"
    train "$profile" "$scene" transfer "$TRANSFER" "$run" "$pre"
    evaluate "$profile" "$scene" transfer "$run"
}
