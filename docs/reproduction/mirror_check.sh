#!/usr/bin/env bash
# Do the shipped schools order as schools, or because every fish turns the
# same way? (issue 21, NOTES.md "Session 53"). Each shipped policy in its
# scenes, evaluated as shipped and with half of its fish mirrored (profile
# mean_then_budget_space20_mirrored): sampled actions, seeds 11 and 12, 60 s
# after a 10 s warm-up; then one table. Resumable: finished evaluations are
# skipped.
#
#   docs/reproduction/mirror_check.sh
#
# Env: BIN (target/release/deepfoids), OUT (runs/mirror-check).
set -euo pipefail
BIN=${BIN:-target/release/deepfoids}
OUT=${OUT:-runs/mirror-check}
mkdir -p "$OUT"
for seed in 11 12; do
    for profile in mean_then_budget_space20 mean_then_budget_space20_mirrored; do
        for pair in coho_default:pretrained:coho density_sparse:pretrained:coho/density_sparse \
            density_dense:pretrained:coho/density_dense seabream_default:pretrained:seabream \
            yellowtail_default:pretrained:yellowtail; do
            scene=${pair%%:*}
            policy=${pair#*:}
            dir=$OUT/eval-$scene-$profile-s$seed
            [[ -f $dir/summary.json ]] && continue
            "$BIN" eval --reward-profile "$profile" --scene "$scene" --phase transfer \
                --policy "$policy" --seed "$seed" --warmup 10 --seconds 60 --out "$dir" >/dev/null
        done
    done
done
python3 - "$OUT" <<'PY'
import glob, json, os, sys
print("| run | P | M | swarm / mill / polarised / transitional % | NN BL | speed BL/s | net / contacts per fish-h |")
print("|---|---|---|---|---|---|---|")
for d in sorted(glob.glob(os.path.join(sys.argv[1], "eval-*", ""))):
    d = d.rstrip("/")
    if not os.path.isfile(os.path.join(d, "summary.json")):
        continue
    s = json.load(open(os.path.join(d, "summary.json")))["summary"]
    shares = " / ".join(f"{100 * v:.0f}" for _, v in s["state_share"])
    print(f"| {os.path.basename(d)[5:]} | {s['p_mean']:.2f} | {s['m_mean']:.2f} | {shares} | "
          f"{s['nn_mean_bl']:.2f} | {s['mean_speed_bl']:.2f} | "
          f"{s['boundary_collisions_per_fish_hour']:.0f} / {s['neighbour_collisions_per_fish_hour']:.0f} |")
PY
