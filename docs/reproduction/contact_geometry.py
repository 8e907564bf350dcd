#!/usr/bin/env python3
"""Where the fish of a `simulate` run touch (issue 21, NOTES.md "Session 49").

    python3 docs/reproduction/contact_geometry.py RUN/trajectories.csv [T0]

Needs numpy and scipy (pip). From the decision-sampled poses after T0 s
(default 10) it finds the pairs whose box colliders overlap (0.12 x 0.25 x 1 BL,
SAT; the box's up axis is the world's up made orthogonal to the heading, the
roll ignored), takes the pairs that overlap now but not at the previous
decision ("new contacts", as the metric counts them, but seen only at the
decisions, so fewer), and classifies each from both fish's side: crossing
(headings >= 30 deg apart; then mostly yaw or mostly pitch), parallel with the
partner ahead or behind in the lane (more than 0.5 BL along the heading), or
side by side. It also gives the re-contacts (the pair touched within the
previous 10 decisions) and how evenly the contacts fall on the fish."""
import csv, sys, collections
import numpy as np
from scipy.spatial import cKDTree

path, t0 = sys.argv[1], float(sys.argv[2]) if len(sys.argv) > 2 else 10.0
rows = collections.defaultdict(list)
with open(path) as f:
    for r in csv.DictReader(f):
        t = float(r["t"])
        if t < t0 - 0.5:
            continue
        rows[t].append((int(r["fish"]), float(r["x"]), float(r["y"]), float(r["z"]),
                        float(r["dx"]), float(r["dy"]), float(r["dz"]), float(r["bl"])))
times = sorted(rows)
HALF = np.array([0.06, 0.125, 0.5])

def axes(h):
    f = h / np.linalg.norm(h)
    up = np.array([0.0, 1.0, 0.0]) - f * f[1]
    n = np.linalg.norm(up)
    up = up / n if n > 1e-6 else np.array([1.0, 0, 0])
    side = np.cross(up, f)
    return np.stack([side, up, f])  # rows: x (width), y (height), z (length)

def overlap(ca, A, ha, cb, B, hb):
    d = cb - ca
    tests = list(A) + list(B)
    for a in A:
        for b in B:
            c = np.cross(a, b)
            if np.linalg.norm(c) > 1e-6:
                tests.append(c / np.linalg.norm(c))
    for L in tests:
        ra = np.sum(ha * np.abs(A @ L)); rb = np.sum(hb * np.abs(B @ L))
        if abs(d @ L) > ra + rb:
            return False
    return True

prev = set(); last_seen = {}; cross_ang = []; cross_kind = collections.Counter(); per_fish = collections.Counter()
cats = collections.Counter(); recontact = 0; new = 0; n_fish = 0; decisions = 0
for k, t in enumerate(times):
    a = np.array(rows[t]); ids = a[:, 0].astype(int)
    P, H, BL = a[:, 1:4], a[:, 4:7], a[:, 7]
    n_fish = len(ids)
    tree = cKDTree(P)
    pairs = tree.query_pairs(BL.max() * 1.12)
    Ax = [axes(h) for h in H]
    now = set()
    for i, j in pairs:
        if overlap(P[i], Ax[i], HALF * BL[i], P[j], Ax[j], HALF * BL[j]):
            now.add((i, j))
    if t >= t0:
        decisions += 1
        for (i, j) in now - prev:
            new += 1
            if last_seen.get((i, j), -99) >= k - 10:
                recontact += 1
            for me, other in ((i, j), (j, i)):
                f = Ax[me][2]; rel = P[other] - P[me]
                along = rel @ f / BL[me]
                ang = np.degrees(np.arccos(np.clip(f @ Ax[other][2], -1, 1)))
                if ang >= 30:
                    c = "crossing (>=30 deg)"
                    cross_ang.append(ang)
                    fo = Ax[other][2]
                    dyaw = abs(np.degrees(np.arctan2(f[0], f[2]) - np.arctan2(fo[0], fo[2])))
                    dyaw = min(dyaw, 360 - dyaw)
                    dpitch = abs(np.degrees(np.arcsin(np.clip(f[1], -1, 1)) - np.arcsin(np.clip(fo[1], -1, 1))))
                    cross_kind["mostly yaw" if dyaw >= dpitch else "mostly pitch"] += 1
                elif along > 0.5:
                    c = "parallel, partner ahead in lane"
                elif along < -0.5:
                    c = "parallel, partner behind in lane"
                else:
                    c = "parallel, side by side"
                cats[c] += 1
                per_fish[ids[me]] += 1
    for p in now:
        last_seen[p] = k
    prev = now
dt = times[1] - times[0]
hours = n_fish * decisions * dt / 3600
print(f"{decisions} decisions of {dt:.2f} s, {n_fish} fish; new pair contacts sampled at decisions: "
      f"{2*new/hours:,.0f} per fish-hour (each pair counts for both fish)")
print(f"re-contacts (the pair touched within the previous 10 decisions): {recontact/max(new,1):.0%}")
tot = sum(cats.values())
for c, v in cats.most_common():
    print(f"  {c}: {v/tot:.0%}")
print(f"crossings: median angle {np.median(cross_ang):.0f} deg (quartiles {np.percentile(cross_ang,25):.0f}-{np.percentile(cross_ang,75):.0f}); "
      + ", ".join(f"{k} {v/sum(cross_kind.values()):.0%}" for k, v in cross_kind.items()))
c = np.array(sorted(per_fish.values(), reverse=True) + [0] * (n_fish - len(per_fish)))
print(f"fish with no new contact: {np.mean(c == 0):.0%}; the 10 % who touch most have {c[: n_fish // 10].sum() / c.sum():.0%} of them")
