"""`deepfoids reproduce` on a Ray cluster: each (seed, stage) trains as a Ray
task once the stages it starts from are finished, then one last task
measures, judges the claims and writes the report from the finished stages.

The tasks run the `deepfoids` binary, so every node needs it (the same
build) and the output folder must be one file system all nodes see (NFS or
similar): results land in the layout of a local run, `OUT/s<seed>/<stage>`
and `OUT/report/`, and a local `deepfoids reproduce --out OUT` afterwards
reuses them. Reward-profile variants each get their own output folder.

    import ray
    from deepfoids.ray import reproduce
    ray.init(address="auto")
    reproduce("runs/repro", ["--profile", "quick", "--only", "density"],
              reward_profiles=["thesis", "bounce"])

The command line does the same: `python -m deepfoids.ray --out DIR -- OPTIONS`.
See docs/training.md ("On a Ray cluster").
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from pathlib import Path
from typing import Iterable, Optional, Sequence

import ray


def find_binary(binary: Optional[str] = None) -> str:
    """The `deepfoids` binary: `binary`, else $DEEPFOIDS_BIN, else the one on PATH."""
    found = binary or os.environ.get("DEEPFOIDS_BIN") or shutil.which("deepfoids")
    if not found:
        raise FileNotFoundError(
            "no `deepfoids` binary: pass binary=, set DEEPFOIDS_BIN, or put it on PATH "
            "(cargo install --path . in the repository)"
        )
    return str(found)


def _run(args: Sequence[str]) -> str:
    """Run the binary to its end; its error output in the exception if it fails."""
    done = subprocess.run(list(args), capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError(
            f"{' '.join(args)} failed (exit {done.returncode}):\n{done.stderr.strip()}"
        )
    return done.stdout


def plan(binary: str, out: Path, options: Sequence[str]) -> list[dict]:
    """The stages `reproduce` would train with `options`: one dict per
    (seed, stage) with `seed`, `stage`, `init_from`, `scene`, `phase`, `algo`."""
    text = _run([binary, "reproduce", "--out", str(out), "--plan", *options])
    return [json.loads(line) for line in text.splitlines() if line.strip()]


@ray.remote
def _train_stage(binary: str, out: str, options: list, seed: int, stage: str, *after):
    """Train one stage of one seed; `after`: the tasks it waits for."""
    _run([binary, "reproduce", "--out", out, "--stage", stage, "--seeds", str(seed), *options])
    return {"seed": seed, "stage": stage}


@ray.remote
def _report(binary: str, out: str, options: list, *after) -> str:
    """Measure, judge and write the report from the finished stages."""
    _run([binary, "reproduce", "--out", out, *options])
    return str(Path(out) / "report" / "REPORT.md")


def submit(
    out: str | os.PathLike,
    options: Sequence[str] = (),
    *,
    binary: Optional[str] = None,
    cpus_per_stage: float = 2,
):
    """Submit one reproduction to the connected Ray cluster; returns the
    report task's ObjectRef (`ray.get` it for the path of REPORT.md).

    `options`: `deepfoids reproduce` options besides `--out` (`--profile`,
    `--only`, `--seeds`, `--reward-profile`, …). `cpus_per_stage`: the CPUs
    Ray reserves for each training task (a stage trains on all of a node's
    cores; 2 keeps two stages from sharing a 2-core node)."""
    binary = find_binary(binary)
    # Absolute: the tasks' working folder is Ray's, not the caller's.
    out = Path(out).resolve()
    options = [str(o) for o in options]
    if "--out" in options:
        raise ValueError("give the output folder as `out`, not in options")
    stages = plan(binary, out, options)
    refs = {}
    for s in stages:
        after = [refs[(s["seed"], d)] for d in s["init_from"]]
        refs[(s["seed"], s["stage"])] = _train_stage.options(num_cpus=cpus_per_stage).remote(
            binary, str(out), options, s["seed"], s["stage"], *after
        )
    return _report.options(num_cpus=cpus_per_stage).remote(
        binary, str(out), options, *refs.values()
    )


def reproduce(
    out: str | os.PathLike,
    options: Sequence[str] = (),
    *,
    reward_profiles: Optional[Iterable[str]] = None,
    binary: Optional[str] = None,
    cpus_per_stage: float = 2,
) -> list[Path]:
    """Run `deepfoids reproduce` on the connected Ray cluster (call
    `ray.init` first) and wait for it; returns the REPORT.md paths.

    With `reward_profiles`, one reproduction per profile, in `out/<profile>`,
    all scheduled at once."""
    if reward_profiles is None:
        jobs = [(Path(out), list(options))]
    else:
        jobs = [
            (Path(out) / p, [*options, "--reward-profile", p]) for p in reward_profiles
        ]
    refs = [submit(o, opts, binary=binary, cpus_per_stage=cpus_per_stage) for o, opts in jobs]
    return [Path(p) for p in ray.get(refs)]


def main(argv: Optional[Sequence[str]] = None) -> None:
    import argparse

    parser = argparse.ArgumentParser(
        prog="python -m deepfoids.ray",
        description="deepfoids reproduce on a Ray cluster (stages as Ray tasks)",
    )
    parser.add_argument("--out", required=True, help="output folder, on a file system every node sees")
    parser.add_argument("--address", default=None, help="Ray address [default: start a local Ray]")
    parser.add_argument("--reward-profiles", default=None, help="comma-separated; one reproduction each, in OUT/<profile>")
    parser.add_argument("--binary", default=None, help="the deepfoids binary [default: $DEEPFOIDS_BIN or PATH]")
    parser.add_argument("--cpus-per-stage", type=float, default=2)
    parser.add_argument("options", nargs=argparse.REMAINDER, help="after --: deepfoids reproduce options")
    a = parser.parse_args(argv)
    options = a.options[1:] if a.options[:1] == ["--"] else a.options
    ray.init(address=a.address, include_dashboard=False, log_to_driver=False)
    profiles = a.reward_profiles.split(",") if a.reward_profiles else None
    for report in reproduce(
        a.out, options, reward_profiles=profiles, binary=a.binary, cpus_per_stage=a.cpus_per_stage
    ):
        print(f"wrote {report}")


if __name__ == "__main__":
    main()
