"""Do the fish of a school circle the cage one by one, or wander? (issue 21,
NOTES "Session 58"), from the trajectories.csv that `deepfoids simulate` writes.

    python3 docs/reproduction/circling.py RUN/trajectories.csv [FROM_S] [CORE_M] [HALF_M]

Seen from above (the x-z plane), about the cage's centre (x = z = 0):
- `own circling`: the mean over fish of |<L_i>|, where L_i = (r_i x d_i)_y /
  |r_i| / |d_i| is fish i's angular momentum about the centre at one decision
  and <.> its mean over the recorded time. A fish that circles the centre one
  way all the time has |<L_i>| = 1; one that wanders, turning either way, has
  |<L_i>| -> 0 as the window grows.
- `school M about the centre`: |<L>_i| per decision, averaged over time (a
  collective mill about the centre gives 1; fish circling singly in mixed
  senses give about |2 share - 1| of the own circling).
- `radius`: the horizontal distance from the centre, median and 10th/90th
  percentiles, in m; `in core`: the share of fish-decisions whose horizontal
  distance to every side of a box is at least CORE_M (default 1.47 m, a coho's
  d_sense: no side wall's r_BD there) in a box of half-width HALF_M (default
  2 m, `density_sparse`).

FROM_S: ignore the first FROM_S simulated seconds (default 10, the protocol's
warm-up)."""
import collections
import csv
import math
import sys


def main():
    path = sys.argv[1]
    t0 = float(sys.argv[2]) if len(sys.argv) > 2 else 10.0
    core = float(sys.argv[3]) if len(sys.argv) > 3 else 1.47
    half = float(sys.argv[4]) if len(sys.argv) > 4 else 2.0
    frames = collections.defaultdict(list)
    with open(path) as f:
        for r in csv.DictReader(f):
            t = float(r["t"])
            if t < t0:
                continue
            x, z = float(r["x"]), float(r["z"])
            dx, dz = float(r["dx"]), float(r["dz"])
            frames[t].append((int(r["fish"]), x, z, dx, dz))
    if not frames:
        sys.exit(f"{path}: no rows at or after t = {t0} s")
    own = collections.defaultdict(list)
    school, radii, inside = [], [], 0
    for t in sorted(frames):
        ls = []
        for fish, x, z, dx, dz in frames[t]:
            r, d = math.hypot(x, z), math.hypot(dx, dz)
            radii.append(r)
            inside += half - max(abs(x), abs(z)) >= core
            if r < 1e-6 or d < 1e-6:
                continue
            # y component of r x d with r = (x, 0, z), d = (dx, ., dz).
            l = (z * dx - x * dz) / (r * d)
            own[fish].append(l)
            ls.append(l)
        if ls:
            school.append(abs(sum(ls) / len(ls)))
    means = [sum(v) / len(v) for v in own.values()]
    radii.sort()
    q = lambda p: radii[min(len(radii) - 1, int(p * len(radii)))]
    print(
        f"{path}: {len(frames)} decisions from {t0:g} s, {len(means)} fish, box half-width {half:.2f} m\n"
        f"  own circling {sum(abs(m) for m in means) / len(means):.2f}"
        f" (fish with |<L>| > 0.5: {sum(abs(m) > 0.5 for m in means)}/{len(means)},"
        f" of them + {sum(m > 0.5 for m in means)})\n"
        f"  school M about the centre {sum(school) / len(school):.2f}\n"
        f"  radius median {q(0.5):.2f} m (10 % {q(0.1):.2f}, 90 % {q(0.9):.2f});"
        f" in core (>= {core:g} m from every side) {inside / len(radii):.0%}"
    )


if __name__ == "__main__":
    main()
