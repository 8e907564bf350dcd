#!/usr/bin/env python3
"""The variant table of NOTES.md from the evaluations variants.sh wrote.

    python3 docs/reproduction/variants_table.py [runs/variants] > table.md

One row per (profile, scene): the mean over the evaluation seeds of P, M, the
state shares, the mean speed, the nearest-neighbour distance, boundary and
neighbour collisions per fish-hour and the reward per decision, and the
agreement of a fish's heading with its nearest neighbour's (`nn_alignment`,
mean cos) and each fish's circling of the cage axis (`own_circling`); "–" for
evaluations written before either was measured."""
import json
import re
import sys
from collections import defaultdict
from pathlib import Path

root = Path(sys.argv[1] if len(sys.argv) > 1 else "runs/variants")
rows = defaultdict(list)
pattern = re.compile(r"eval-(?P<run>.+)-(?P<stage>pre|default|sparse|dense)-(?P<scene>\w+?)-s(?P<seed>\d+)$")
for summary in sorted(root.glob("eval-*/summary.json")):
    m = pattern.match(summary.parent.name)
    if not m:
        continue
    s = json.loads(summary.read_text())["summary"]
    # transfer_variants.sh's transfers into coho_default (stage `default`)
    # share their scene with the pretraining they start from: label them.
    run = m["run"] + (" (transfer)" if m["stage"] == "default" else "")
    rows[(run, m["scene"])].append(s)


def share(s, state):
    for name, value in s["state_share"]:
        if name.lower() == state:
            return value
    return 0.0


def mean(xs):
    return sum(xs) / len(xs)


def measured(ss, key):
    """The mean of `key` over the summaries, "–" if any predates it."""
    xs = [s[key] for s in ss if s.get(key) is not None]
    return f"{mean(xs):.2f}" if len(xs) == len(ss) else "–"


order = ["coho_default", "density_sparse", "density_dense"]
print("| profile | scene | seeds | P | M | swarm / mill / polar / trans % | speed BL/s "
      "| NN BL | NN heading agreement | own circling | boundary /fish-h | neighbour /fish-h | reward /decision |")
print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
for (run, scene) in sorted(rows, key=lambda k: (k[0], order.index(k[1]) if k[1] in order else 9)):
    ss = rows[(run, scene)]
    shares = " / ".join(
        f"{100 * mean([share(s, st) for s in ss]):.0f}"
        for st in ["swarm", "milling", "polarised", "transitional"])

    print(f"| {run} | {scene} | {len(ss)} | {mean([s['p_mean'] for s in ss]):.2f} "
          f"| {mean([s['m_mean'] for s in ss]):.2f} | {shares} "
          f"| {mean([s['mean_speed_bl'] for s in ss]):.2f} | {mean([s['nn_mean_bl'] for s in ss]):.2f} "
          f"| {measured(ss, 'nn_alignment')} | {measured(ss, 'own_circling')} "
          f"| {mean([s['boundary_collisions_per_fish_hour'] for s in ss]):,.0f} "
          f"| {mean([s['neighbour_collisions_per_fish_hour'] for s in ss]):,.0f} "
          f"| {mean([s['reward_per_decision'] for s in ss]):.1f} |")
