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
source "$(dirname "$0")/protocol.sh"
for p in "$@"; do
    pre=$p$TAG-pre
    echo "== $p: pretraining ($(date +%T))"
    train "$p" coho_default pretrain "$PRE" "$pre"
    evaluate "$p" coho_default pretrain "$pre"
    for scene in density_sparse density_dense; do
        transfer "$p" "$scene" "$p$TAG-${scene#density_}" "$pre"
    done
done
echo "== done ($(date +%T))"
