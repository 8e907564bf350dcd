#!/usr/bin/env bash
# Transfer-weight variants on one shared pretraining (issue 21, NOTES.md
# "Session 46"): coho pretrained once with BASE's pretraining weights at the
# thesis' budget, then transferred with each PROFILE's transfer weights into
# each scene, as the shipped policies are (4 M + 1 M); every policy evaluated
# with sampled actions on seeds 11 and 12, 60 s after a 10 s warm-up.
# Resumable: finished runs and evaluations are skipped. The evaluations' folder
# names follow variants.sh, so variants_table.py tables them.
#
#   docs/reproduction/transfer_variants.sh PROFILE [PROFILE …]
#
# Env: BIN (target/release/deepfoids), OUT (runs/transfer-variants), BASE
# (mean_then_budget_space20), PRE (4000000), TRANSFER (1000000), SCENES
# ("coho_default density_dense"), SEED (the training seed; default 0).
set -euo pipefail
BIN=${BIN:-target/release/deepfoids}
OUT=${OUT:-runs/transfer-variants}
BASE=${BASE:-mean_then_budget_space20}
PRE=${PRE:-4000000}
TRANSFER=${TRANSFER:-1000000}
SCENES=${SCENES:-coho_default density_dense}
mkdir -p "$OUT"
source "$(dirname "$0")/protocol.sh"
pre=$BASE-pre
echo "== $BASE: pretraining ($(date +%T))"
train "$BASE" coho_default pretrain "$PRE" "$pre"
evaluate "$BASE" coho_default pretrain "$pre"
for p in "$@"; do
    for scene in $SCENES; do
        stage=${scene#density_}
        [[ $scene == coho_default ]] && stage=default
        transfer "$p" "$scene" "$p-$stage" "$pre"
    done
done
echo "== done ($(date +%T))"
