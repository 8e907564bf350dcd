"""How a trained policy turns in answer to a neighbour's heading (issue 21,
NOTES "Session 55"), read from its exported ONNX with onnxruntime.

    python3 docs/reproduction/heading_response.py RUN [RUN ...]

RUN is a training run folder (its final/<behaviour>.onnx is read) or an .onnx
file. The policy is shown one neighbour 1 m straight ahead (the four centre
cells of all three stacked frames, as env/tests/sensing.rs places it) whose
heading is turned by phi in the horizontal plane (+ to the fish's left), so
the vector observation's u = (-sin phi, 0, 1 - cos phi) (local frame: +x
left); depth half the cage, no chase. It prints the mean (deterministic) yaw
action for phi = -90 ... +90 degrees (+ turns left, ONNX metadata's
action_layout) and the slope, the yaw at +90 minus the yaw at -90: positive
for a fish that turns with its neighbour (alignment), negative for one that
turns away (avoidance), about 0 for one that ignores it (a policy's
handedness shows as an offset, not a slope)."""
import glob
import math
import sys

import numpy as np
import onnxruntime as ort

PHIS = [-90, -60, -30, 0, 30, 60, 90]


def neighbour_ahead():
    """Three stacked frames of [proximity, fish, net, surface, obstacle,
    chase partner] x 20 elevation rows x 34 azimuth columns, a fish 1 m ahead
    of a coho (d_sense 1.47 m)."""
    g = np.zeros((18, 20, 34), np.float32)
    for frame in range(3):
        for h, w in [(9, 16), (9, 17), (10, 16), (10, 17)]:
            g[frame * 6 + 0, h, w] = 1 - 1 / 1.47
            g[frame * 6 + 1, h, w] = 1.0
    return g


def model_of(run):
    if run.endswith(".onnx"):
        return run
    found = sorted(glob.glob(run.rstrip("/") + "/final/*.onnx"))
    if not found:
        sys.exit(f"{run}: no final/*.onnx (a finished training run folder or an .onnx file)")
    return found[0]


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    print("| policy | " + " | ".join(f"{p:+d}°" for p in PHIS) + " | slope |")
    print("|---|" + "---|" * (len(PHIS) + 1))
    for run in sys.argv[1:]:
        session = ort.InferenceSession(model_of(run))
        grids = np.repeat(neighbour_ahead()[None], len(PHIS), 0)
        vectors = np.array(
            [[-math.sin(math.radians(p)), 0.0, 1 - math.cos(math.radians(p)), 0.5, 0, 0] for p in PHIS],
            np.float32,
        )
        yaw = session.run(["deterministic_continuous_actions"], {"obs_0": grids, "obs_1": vectors})[0][:, 2]
        name = run.rstrip("/").split("/")[-1]
        print(f"| {name} | " + " | ".join(f"{y:+.2f}" for y in yaw) + f" | {yaw[-1] - yaw[0]:+.2f} |")


if __name__ == "__main__":
    main()
