"""Multi-agent PPO in Ray RLlib on the DeepFoids environment: one policy per behaviour.

    # one machine
    python python/examples/rllib_ppo.py --scene seabream_default --iterations 5
    # a Ray cluster: `ray start --head` on one node, `ray start --address=HEAD:6379`
    # on the others (deepfoids installed on every node), then on the head:
    python python/examples/rllib_ppo.py --address auto --env-runners 16 --scene coho_default

The network is the thesis' (SPEC §8, ML-Agents' "simple" visual encoder), one body
each for actor and critic: Conv 18→16 8×8/4, LeakyReLU, Conv 16→32 4×4/2,
LeakyReLU, Dense 128 LeakyReLU; the vector observation appended; 4 × Dense 128
Swish; a Gaussian head of 3 with a learned state-independent log-std (actor) or a
value (critic). The grid's azimuth is wrapped by 5 columns on each side so both
convolutions cover all 34 columns (SPEC §8). PPO settings follow Table 4.4 where
RLlib has them.

The environment reaches RLlib through `DeepFoidsRLlibEnv`, a small adapter over
`deepfoids.parallel_env`: only agents whose behaviour decided at a tick are asked
for actions (in three_species coho decide every other tick), each respawn is a
new agent id (``coho_regular_17.1``; see `deepfoids._parallel`), and the episode ends
when the PettingZoo episode does (``max_episode_decisions``).

Results: per-iteration lines on stdout; RLlib's own logs in the folder printed at
start (``~/ray_results/…``); the trained modules in ``--out`` (RLlib checkpoint).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

import deepfoids

import gymnasium as gym
import ray
import torch
from ray.rllib.algorithms.ppo import PPOConfig
from ray.rllib.core.columns import Columns
from ray.rllib.core.rl_module.apis import ValueFunctionAPI
from ray.rllib.core.rl_module.multi_rl_module import MultiRLModuleSpec
from ray.rllib.core.rl_module.rl_module import RLModuleSpec
from ray.rllib.core.rl_module.torch import TorchRLModule
from ray.rllib.env.multi_agent_env import MultiAgentEnv
from ray.tune.registry import register_env
from torch import nn


def behaviour_of(agent_id: str) -> str:
    """``coho_regular_17`` and ``coho_regular_17.3`` → ``coho_regular``."""
    return agent_id.rsplit("_", 1)[0]


class DeepFoidsRLlibEnv(MultiAgentEnv):
    """`deepfoids.parallel_env` for RLlib: observations only of agents that act next."""

    def __init__(self, config: dict | None = None):
        super().__init__()
        self.env = deepfoids.parallel_env(**(config or {}))
        self.possible_agents = list(self.env.possible_agents)
        self.agents = []
        self._obs_space = deepfoids.observation_space()
        self._act_space = deepfoids.action_space()
        self.observation_spaces = {a: self._obs_space for a in self.possible_agents}
        self.action_spaces = {a: self._act_space for a in self.possible_agents}

    # Respawned agents have new ids: every id has the one space.
    def get_observation_space(self, agent_id):
        return self._obs_space

    def get_action_space(self, agent_id):
        return self._act_space

    def reset(self, *, seed=None, options=None):
        obs, infos = self.env.reset(seed=seed, options=options)
        self.agents = list(self.env.agents)
        return obs, infos

    def step(self, action_dict):
        obs, rew, term, trunc, info = self.env.step(action_dict)
        ended = {a for a in rew if term[a] or trunc[a]}
        new = {info[a]["next_agent"] for a in ended if "next_agent" in info[a]}
        acting = [a for a in obs if info[a]["decided"] or a in ended]
        obs = {a: obs[a] for a in acting}
        info = {a: info[a] for a in acting}
        rew = {a: rew[a] for a in acting if a not in new}
        term = {a: term[a] for a in ended}
        trunc = {a: trunc[a] for a in ended}
        done = not self.env.agents
        term["__all__"] = done
        trunc["__all__"] = done
        self.agents = list(self.env.agents)
        return obs, rew, term, trunc, info


class Body(nn.Module):
    """SPEC §8's body: visual encoder, vector appended, 4 × Dense 128 Swish."""

    WRAP = 5

    def __init__(self, hidden: int = 128, layers: int = 4):
        super().__init__()
        self.conv = nn.Sequential(
            nn.Conv2d(18, 16, 8, stride=4),
            nn.LeakyReLU(0.01),
            nn.Conv2d(16, 32, 4, stride=2),
            nn.LeakyReLU(0.01),
            nn.Flatten(),
        )
        with torch.no_grad():
            n = self.conv(torch.zeros(1, 18, 20, 34 + 2 * self.WRAP)).shape[1]
        self.encode = nn.Sequential(nn.Linear(n, 128), nn.LeakyReLU(0.01))
        mlp, width = [], 128 + 6
        for _ in range(layers):
            mlp += [nn.Linear(width, hidden), nn.SiLU()]
            width = hidden
        self.mlp = nn.Sequential(*mlp)

    def forward(self, obs: dict) -> torch.Tensor:
        grid = nn.functional.pad(obs["grid"], (self.WRAP, self.WRAP, 0, 0), mode="circular")
        return self.mlp(torch.cat([self.encode(self.conv(grid)), obs["vector"]], dim=-1))


class FishPPOModule(TorchRLModule, ValueFunctionAPI):
    """Actor and critic, each with its own `Body` (as the thesis and ML-Agents)."""

    def setup(self):
        hidden = self.model_config.get("hidden", 128)
        layers = self.model_config.get("layers", 4)
        self.actor, self.critic = Body(hidden, layers), Body(hidden, layers)
        self.mean = nn.Linear(hidden, 3)
        self.log_std = nn.Parameter(torch.zeros(3))
        self.value = nn.Linear(hidden, 1)
        nn.init.normal_(self.mean.weight, std=0.01)
        nn.init.zeros_(self.mean.bias)

    def _forward(self, batch, **kwargs):
        mean = self.mean(self.actor(batch[Columns.OBS]))
        log_std = self.log_std.expand_as(mean)
        return {Columns.ACTION_DIST_INPUTS: torch.cat([mean, log_std], dim=-1)}

    def compute_values(self, batch, embeddings=None):
        return self.value(self.critic(batch[Columns.OBS])).squeeze(-1)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--scene", default="seabream_default")
    p.add_argument("--phase", default="pretrain", choices=["pretrain", "transfer"])
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--max-episode-decisions", type=int, default=None)
    p.add_argument("--iterations", type=int, default=5)
    p.add_argument("--env-runners", type=int, default=1,
                   help="sampling processes (one env each); 0 samples in the driver")
    p.add_argument("--train-batch", type=int, default=10240, help="agent steps per update (buffer, Table 4.4)")
    p.add_argument("--minibatch", type=int, default=1024)
    p.add_argument("--epochs", type=int, default=3)
    p.add_argument("--lr", type=float, default=1e-3)
    p.add_argument("--address", default=None, help="Ray cluster address ('auto' on a cluster node)")
    p.add_argument("--num-cpus", type=int, default=None, help="CPUs for a local Ray (default: all)")
    p.add_argument("--out", default="runs/rllib_ppo", help="folder for the final RLlib checkpoint")
    args = p.parse_args()

    if args.address:
        ray.init(address=args.address)
    else:
        ray.init(num_cpus=args.num_cpus, include_dashboard=False,
                 object_store_memory=2 * 1024**3)
    env_config = {"scene": args.scene, "phase": args.phase, "seed": args.seed,
                  "max_episode_decisions": args.max_episode_decisions}
    register_env("deepfoids", lambda cfg: DeepFoidsRLlibEnv(cfg))
    probe = deepfoids.BatchEnv(args.scene, args.phase, configs=None)
    behaviours = [b.name for b in probe.behaviours]
    fish = probe.n_agents
    decisions_per_tick = sum(b.count / b.period_ticks for b in probe.behaviours)
    print(f"{args.scene}: {fish} fish, behaviours {', '.join(behaviours)}; "
          f"{args.env_runners} env runner(s)", flush=True)

    module = RLModuleSpec(
        module_class=FishPPOModule,
        observation_space=deepfoids.observation_space(),
        action_space=deepfoids.action_space(),
        model_config={"hidden": 128, "layers": 4},
    )
    config = (
        PPOConfig()
        # The environment clips actions to [-1, 1] itself (SPEC §4); RLlib's
        # clipping connector looks spaces up by agent id, and respawned fish are
        # agents it has not seen.
        .environment("deepfoids", env_config=env_config,
                     normalize_actions=False, clip_actions=False)
        .env_runners(
            num_env_runners=args.env_runners,
            num_envs_per_env_runner=1,
            # Let each runner's env use the cores it gets (rayon inside).
            num_cpus_per_env_runner=1,
            rollout_fragment_length="auto",
            sample_timeout_s=600.0,
        )
        .multi_agent(
            policies=set(behaviours),
            policy_mapping_fn=lambda agent_id, episode, **kw: behaviour_of(agent_id),
            # Count ticks: RLlib's agent-step counter sums a statistic per agent
            # id and fails (NaN) once a respawned agent's old id has gone quiet.
            count_steps_by="env_steps",
        )
        .rl_module(rl_module_spec=MultiRLModuleSpec(
            rl_module_specs={b: module for b in behaviours}))
        .training(
            # In ticks: about --train-batch agent decisions per update.
            train_batch_size_per_learner=max(1, round(args.train_batch / decisions_per_tick)),
            minibatch_size=args.minibatch,
            num_epochs=args.epochs,
            lr=args.lr,
            gamma=0.99,
            lambda_=0.95,
            clip_param=0.2,
            vf_loss_coeff=0.5,
            entropy_coeff=0.0005,
        )
        .debugging(seed=args.seed)
    )
    algo = config.build_algo()
    print(f"RLlib logs: {algo.logdir}", flush=True)
    total_steps, total_time = 0, 0.0
    for i in range(1, args.iterations + 1):
        t = time.perf_counter()
        result = algo.train()
        dt = time.perf_counter() - t
        runners = result.get("env_runners", {})
        # Per agent id; ids of earlier lives that took no step this time are NaN.
        steps = [float(v) for v in runners.get("num_agent_steps_sampled", {}).values()]
        n = int(np.nansum(steps)) if steps else 0
        returns = [float(v) for v in runners.get("module_episode_returns_mean", {}).values()]
        mean_return = float(np.nanmean(returns)) if returns else float("nan")
        total_steps += n
        total_time += dt
        print(f"iteration {i}: {n} agent steps in {dt:.1f} s = {n / dt:,.0f} agent-steps/s; "
              f"mean episode return per behaviour {mean_return:.1f}", flush=True)
    print(f"{total_steps} agent steps in {total_time:.1f} s: "
          f"{total_steps / max(total_time, 1e-9):,.0f} agent-steps/s (sampling + PPO updates)")
    out = Path(args.out).resolve()
    algo.save_to_path(str(out))
    print(f"checkpoint: {out}")
    algo.stop()
    ray.shutdown()


if __name__ == "__main__":
    main()
