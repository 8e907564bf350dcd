"""Agent-decisions per second of the Python APIs beside `deepfoids bench env`.

Runs, interleaved in one process tree so machine load hits all alike:
  1. `deepfoids bench env --grids floats` (the Rust binary; random actions drawn
     in Rust; float grids, as Python gets them),
  2. `deepfoids.BatchEnv` with numpy random actions,
  3. the PettingZoo dict API (`deepfoids.parallel_env`) with the same actions,
for `--rounds` rounds, and prints each rate, the medians, and the ratios
batch / bench env and dict / bench env. The issue's bar: batch ≥ 80 %.

    python python/benchmarks/bench_env.py --deepfoids target/release/deepfoids
"""

from __future__ import annotations

import argparse
import re
import statistics
import subprocess
import time

import numpy as np

import deepfoids


def bench_binary(binary: str, scene: str, seconds: float, warmup: float) -> float:
    out = subprocess.run(
        [binary, "bench", "env", "--scene", scene, "--seconds", str(seconds), "--warmup", str(warmup),
         "--grids", "floats"],
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    match = re.search(r"^(\d+) agent-decisions/s", out, re.M)
    if not match:
        raise RuntimeError(f"`{binary} bench env` printed no rate:\n{out}")
    return float(match.group(1))


def bench_batch(scene: str, seconds: float, warmup: float) -> float:
    env = deepfoids.BatchEnv(scene=scene, seed=0)
    rng = np.random.default_rng(0)
    batch = env.reset()
    actions = np.empty((env.n_agents, 3), dtype=np.float32)

    def run(ticks: int) -> int:
        decisions = 0
        for _ in range(ticks):
            actions[:] = rng.uniform(-1.0, 1.0, actions.shape)
            env.step(actions)
            decisions += int(np.count_nonzero(batch.decided))
        return decisions

    run(max(1, round(warmup / env.tick_seconds)))
    start = time.perf_counter()
    decisions = run(max(1, round(seconds / env.tick_seconds)))
    return decisions / (time.perf_counter() - start)


def bench_dict(scene: str, seconds: float, warmup: float) -> float:
    env = deepfoids.parallel_env(scene=scene, seed=0)
    rng = np.random.default_rng(0)
    env.reset()
    tick = env.batch_env.tick_seconds

    def run(ticks: int) -> int:
        decisions = 0
        for _ in range(ticks):
            a = rng.uniform(-1.0, 1.0, (len(env.agents), 3)).astype(np.float32)
            obs, rew, term, trunc, info = env.step(dict(zip(env.agents, a)))
            decisions += sum(1 for i in info.values() if i["decided"])
            if not env.agents:
                env.reset()
        return decisions

    run(max(1, round(warmup / tick)))
    start = time.perf_counter()
    decisions = run(max(1, round(seconds / tick)))
    return decisions / (time.perf_counter() - start)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--deepfoids", default="target/release/deepfoids", help="the deepfoids binary")
    p.add_argument("--scene", default="coho_default")
    p.add_argument("--seconds", type=float, default=20.0, help="simulated seconds timed per run")
    p.add_argument("--warmup", type=float, default=2.0, help="simulated seconds of warm-up")
    p.add_argument("--rounds", type=int, default=3)
    args = p.parse_args()

    rates = {"bench env": [], "batch": [], "dict": []}
    for r in range(args.rounds):
        rates["bench env"].append(bench_binary(args.deepfoids, args.scene, args.seconds, args.warmup))
        rates["batch"].append(bench_batch(args.scene, args.seconds, args.warmup))
        rates["dict"].append(bench_dict(args.scene, args.seconds, args.warmup))
        print(f"round {r + 1}: " + ", ".join(f"{k} {v[-1]:,.0f}" for k, v in rates.items()), flush=True)
    med = {k: statistics.median(v) for k, v in rates.items()}
    print(f"{args.scene}, median of {args.rounds} rounds, agent-decisions/s:")
    for k, v in med.items():
        print(f"  {k:9} {v:10,.0f}  ({v / med['bench env']:.0%} of bench env)")
    per_round = [b / e for b, e in zip(rates["batch"], rates["bench env"])]
    print(f"batch / bench env per round: {', '.join(f'{x:.0%}' for x in per_round)}")


if __name__ == "__main__":
    main()
