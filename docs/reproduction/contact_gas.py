#!/usr/bin/env python3
"""How often fish that ignore each other touch: the contact rate of a "gas" of coho.

Issue 21 asks for <= 2,000 neighbour collisions per fish-hour in every shipped policy's
scene; the shipped coho make about 4,600 in `coho_default`, with a nearest neighbour of
0.55 BL and a median heading difference of ~27 degrees to it (NOTES, session 50). This
script asks what a school with no collision avoidance at all would score at the same
density, speed and alignment, so that the policy's figure can be read against it.

The model (numpy + scipy, no deepfoids code):
- N fish in a periodic cube at the scene's density, uniformly placed; body scale drawn
  from the regular coho's 0.9-1.1; box colliders [0.12, 0.25, 1.0] BL of 0.49 m
  (configs/species/coho.toml), dorsal side up;
- every fish swims straight along its heading at a fixed speed (BL/s); its heading is
  normalize(k * e + g), e a common direction, g a 3-D Ornstein-Uhlenbeck vector with unit
  standard deviation per component and a correlation time `tau` (s): k = 0 is an isotropic
  gas, larger k a more polarised school (the local picture of a mill, whose neighbours
  swim nearly parallel);
- physics steps of 0.02 s, decisions of 10 steps (coho: 0.2 s); a contact is an overlap
  of the two boxes (separating-axis test), counted as env/src/state.rs counts it: per
  fish, the partners touched during a decision that it did not touch during the previous
  one; per fish-hour over the recorded time.

It prints, per k: the global polarisation P, the median angle between a fish's heading and
its nearest neighbour's, the mean nearest-neighbour distance (BL) and the contact rate.

    python3 docs/reproduction/contact_gas.py [--density 5.0] [--speed 1.5] [--k 0 1 2 4 8]
"""
import argparse

import numpy as np
from scipy.spatial import cKDTree

BL = 0.49
COLLIDER_BL = np.array([0.12, 0.25, 1.0])  # width (x), height (y), length (z)
DT, STEPS_PER_DECISION = 0.02, 10


def axes_of(h):
    """Columns x (right), y (up), z (forward) of each fish's box, dorsal side up."""
    up = np.array([0.0, 1.0, 0.0])
    x = np.cross(up, h)
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    y = np.cross(h, x)
    return np.stack([x, y, h], axis=2)  # [n, 3 (world), 3 (axis)]


def overlap(ca, aa, ea, cb, ab, eb):
    """Separating-axis test of box pairs (centres, axes [n,3,3], half extents [n,3])."""
    r = np.einsum("nki,nkj->nij", aa, ab)  # R[i][j] = a_i . b_j
    abs_r = np.abs(r) + 1e-6
    t = np.einsum("nki,nk->ni", aa, cb - ca)  # the centre offset in a's frame
    sep = np.zeros(len(ca), dtype=bool)
    for i in range(3):  # a's faces
        sep |= np.abs(t[:, i]) > ea[:, i] + (eb * abs_r[:, i, :]).sum(1)
    for j in range(3):  # b's faces
        sep |= np.abs((t * r[:, :, j]).sum(1)) > (ea * abs_r[:, :, j]).sum(1) + eb[:, j]
    for i in range(3):  # edge pairs a_i x b_j
        i1, i2 = (i + 1) % 3, (i + 2) % 3
        for j in range(3):
            j1, j2 = (j + 1) % 3, (j + 2) % 3
            ra = ea[:, i1] * abs_r[:, i2, j] + ea[:, i2] * abs_r[:, i1, j]
            rb = eb[:, j1] * abs_r[:, i, j2] + eb[:, j2] * abs_r[:, i, j1]
            sep |= np.abs(t[:, i2] * r[:, i1, j] - t[:, i1] * r[:, i2, j]) > ra + rb
    return ~sep


def run(n, density, speed_bl, k, tau, seconds, warmup, seed):
    rng = np.random.default_rng(seed)
    side = (n / density) ** (1 / 3)
    scale = rng.uniform(0.9, 1.1, n)
    half = 0.5 * COLLIDER_BL[None, :] * BL * scale[:, None]
    reach = 2 * np.linalg.norm(half, axis=1).max()
    pos = rng.uniform(0, side, (n, 3))
    e = np.array([1.0, 0.0, 0.0])
    g = rng.standard_normal((n, 3))
    prev = [set() for _ in range(n)]
    now = [set() for _ in range(n)]
    contacts, steps, stats = 0, 0, []
    total = int(round((warmup + seconds) / DT))
    first = int(round(warmup / DT))
    for step in range(total):
        g += -g * DT / tau + np.sqrt(2 * DT / tau) * rng.standard_normal((n, 3))
        h = k * e + g
        h /= np.linalg.norm(h, axis=1, keepdims=True)
        pos = (pos + h * speed_bl * BL * scale[:, None] * DT) % side
        tree = cKDTree(pos, boxsize=side)
        pairs = tree.query_pairs(reach, output_type="ndarray")
        if len(pairs):
            a, b = pairs[:, 0], pairs[:, 1]
            d = pos[b] - pos[a]
            d -= side * np.round(d / side)  # the nearest periodic image
            ax = axes_of(h)
            hit = overlap(np.zeros_like(d), ax[a], half[a], d, ax[b], half[b])
            for i, j in pairs[hit]:
                now[i].add(j)
                now[j].add(i)
        if (step + 1) % STEPS_PER_DECISION == 0:
            if step >= first:
                contacts += sum(len(now[i] - prev[i]) for i in range(n))
                steps += STEPS_PER_DECISION
                dist, idx = tree.query(pos, k=2)
                cos = np.clip((h * h[idx[:, 1]]).sum(1), -1, 1)
                stats.append(
                    (
                        np.linalg.norm(h.mean(0)),
                        np.median(np.degrees(np.arccos(cos))),
                        (dist[:, 1] / (BL * scale)).mean(),
                    )
                )
            prev, now = now, [set() for _ in range(n)]
    hours = n * steps * DT / 3600
    p, nn_angle, nn = np.mean(stats, axis=0)
    return p, nn_angle, nn, contacts / hours


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=1000)
    ap.add_argument("--density", type=float, default=5.0, help="fish/m^3 (coho_default: 5.0)")
    ap.add_argument("--speed", type=float, default=1.5, help="BL/s")
    ap.add_argument("--tau", type=float, default=1.0, help="heading correlation time, s")
    ap.add_argument("--k", type=float, nargs="+", default=[0, 1, 2, 4, 8])
    ap.add_argument("--seconds", type=float, default=30)
    ap.add_argument("--warmup", type=float, default=2)
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()
    print("| k | P | NN heading difference, median (deg) | NN (BL) | contacts /fish-h |")
    print("|---|---|---|---|---|")
    for k in a.k:
        p, ang, nn, rate = run(a.n, a.density, a.speed, k, a.tau, a.seconds, a.warmup, a.seed)
        print(f"| {k:g} | {p:.2f} | {ang:.0f} | {nn:.2f} | {rate:,.0f} |")


if __name__ == "__main__":
    main()
