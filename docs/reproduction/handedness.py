"""Handedness of a school (issue 21, NOTES "Session 53"), from the
trajectories.csv that `deepfoids simulate` writes: each fish's mean turning
rate about the vertical (deg/s; + turns from +x towards +z), how many fish
turn +, and the school's signed vertical
milling Mz, the mean over fish of (r x d)_y / |r| about the centroid in the
x-z plane (a + turn around the centroid gives Mz < 0).

    python3 docs/reproduction/handedness.py runs/X/trajectories.csv [FROM_S]

FROM_S: ignore the first FROM_S simulated seconds (default 0). A lone fish of
a policy without a handedness turns either way; the shipped policies' turn
one way at 27-30 deg/s."""
import csv, sys, math, collections
rows = collections.defaultdict(list)
with open(sys.argv[1]) as f:
    for r in csv.DictReader(f):
        rows[float(r["t"])].append((int(r["fish"]), float(r["x"]), float(r["z"]), float(r["dx"]), float(r["dz"])))
ts = sorted(rows)
t0 = float(sys.argv[2]) if len(sys.argv) > 2 else 0.0
mz = []
prev = {}
turn = collections.defaultdict(float); tt = collections.defaultdict(float)
for t in ts:
    fr = rows[t]
    if t >= t0:
        cx = sum(p[1] for p in fr) / len(fr); cz = sum(p[2] for p in fr) / len(fr)
        s = 0.0
        for _, x, z, dx, dz in fr:
            rx, rz = x - cx, z - cz
            n = math.hypot(rx, rz)
            if n > 1e-9:
                # y component of r x d with r=(rx,0,rz), d=(dx,.,dz): rz*dx - rx*dz
                s += (rz * dx - rx * dz) / n
        mz.append(s / len(fr))
    for fi, x, z, dx, dz in fr:
        a = math.atan2(dz, dx)
        if fi in prev and t >= t0:
            pt, pa = prev[fi]
            d = a - pa
            d = (d + math.pi) % (2 * math.pi) - math.pi
            turn[fi] += d; tt[fi] += t - pt
        prev[fi] = (t, a)
rates = [math.degrees(turn[k] / tt[k]) for k in turn if tt[k] > 0]
pos = sum(1 for r in rates if r > 0)
print(f"frames {len(mz)}  mean Mz {sum(mz)/len(mz):+.3f}  fish turning + {pos}/{len(rates)}  mean turn rate {sum(rates)/len(rates):+.1f} deg/s")
