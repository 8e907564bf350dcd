"""The environment as a PettingZoo `ParallelEnv`.

# Agents and their life cycle

Every fish is an agent named ``"<behaviour>_<index>"`` (index within its
behaviour, e.g. ``coho_regular_17``). The Rust environment gives every fish a stream of
per-agent episodes (SPEC §7): a boundary collision *terminates* the episode and
the fish respawns at once; reaching ``max_episode_decisions`` *truncates* it and
the fish swims on. PettingZoo never revives an agent that ended, so each new
episode of a fish is a new agent:

* ``coho_regular_17`` is fish 17's first episode; its second is ``coho_regular_17.1``, its third
  ``coho_regular_17.2``, and so on.
* At the step where ``coho_regular_17`` terminates (reward −300) or is truncated, the
  step's dicts hold ``coho_regular_17`` with ``terminated``/``truncated`` True, and the
  next life ``coho_regular_17.1`` with its first observation, reward 0, both flags False
  and ``infos["coho_regular_17"]["next_agent"] == "coho_regular_17.1"``. From then on
  ``env.agents`` lists ``coho_regular_17.1`` instead of ``coho_regular_17``, and
  ``possible_agents`` gains it: unlike PettingZoo's usual fixed list,
  ``possible_agents`` holds the first lives at reset and grows by one name per
  respawn (it always contains every agent ever listed in the episode).
* The observation given with ``terminated`` is the respawned fish's (the fish
  ended outside the cage; nothing should bootstrap from it). The observation
  given with ``truncated`` is both the last of the ended episode (bootstrap from
  it) and the first of the next life.
* The PettingZoo episode ends after ``max_episode_decisions`` decisions of the
  slowest-deciding behaviour: at that step every agent is truncated (if not
  terminated), no new lives are named, and ``env.agents`` becomes empty.

# Steps and decision intervals

One `step` is one tick of the environment. In scenes where all behaviours decide
at the same interval (every scene but ``three_species``) every agent decides at
every step. Where intervals differ (coho every 200 ms beside seabream and
yellowtail every 100 ms), an agent whose behaviour does not decide at a step gets
its previous observation and reward 0, and its action at the next step is
ignored; ``infos[agent]["decided"]`` is False then. Learners should skip such
steps (the RLlib example passes only deciding agents to RLlib).

# Infos

``infos[agent]``: ``reward_terms`` (the seven terms of Eq. 4.5 by name, summing
to the reward), ``decided``, ``behaviour``, ``fish`` (index in the school) and,
at the end of a life, ``next_agent``.
"""

from __future__ import annotations

import functools
from typing import Optional

import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv

from ._batch import BatchEnv, TERM_NAMES
from ._spaces import action_space, observation_space


class DeepFoidsParallelEnv(ParallelEnv):
    """The DeepFoids environment as a PettingZoo `ParallelEnv` (see this module's doc).

    Arguments as `deepfoids.BatchEnv`'s, plus `render_mode` (None or ``"rgb_array"``).
    """

    metadata = {"name": "deepfoids_v0", "render_modes": ["rgb_array"], "is_parallelizable": True}

    def __init__(
        self,
        scene: str = "coho_default",
        phase: str = "pretrain",
        seed: int = 0,
        configs=None,
        max_episode_decisions: Optional[int] = None,
        render_mode: Optional[str] = None,
        reward_profile: Optional[str] = None,
    ):
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"unknown render_mode {render_mode!r}; allowed: None, 'rgb_array'")
        self.render_mode = render_mode
        self.batch_env = BatchEnv(
            scene, phase, seed, configs, max_episode_decisions, reward_profile=reward_profile
        )
        behaviours = self.batch_env.behaviours
        n = self.batch_env.n_agents
        #: Per fish: its first agent name, behaviour and rows.
        self._first_names = [f"{b.name}_{i}" for b in behaviours for i in range(b.count)]
        self._behaviour_of_fish = np.concatenate(
            [np.full(b.count, b.index, dtype=np.int64) for b in behaviours]
        )
        self._behaviour_names = [b.name for b in behaviours]
        # One space object per behaviour and env (seeding one env's spaces must
        # not change another's samples).
        self._obs_spaces = [observation_space() for _ in behaviours]
        self._act_spaces = [action_space() for _ in behaviours]
        self.possible_agents = list(self._first_names)
        self.agents: list[str] = []
        self._names = list(self._first_names)
        self._lives = np.zeros(n, dtype=np.int64)
        self._fish_of: dict[str, int] = {}
        self._decisions_per_episode_ticks = self.batch_env.max_episode_decisions * max(
            b.period_ticks for b in behaviours
        )
        self._actions = np.zeros((n, 3), dtype=np.float32)
        n_states = self.batch_env.state().shape
        self.state_space = spaces.Box(-np.inf, np.inf, n_states, dtype=np.float32)

    # Spaces --------------------------------------------------------------

    def observation_space(self, agent: str) -> spaces.Dict:
        return self._obs_spaces[self._behaviour_of_fish[self._fish(agent)]]

    def action_space(self, agent: str) -> spaces.Box:
        return self._act_spaces[self._behaviour_of_fish[self._fish(agent)]]

    def _fish(self, agent: str) -> int:
        fish = self._fish_of.get(agent)
        if fish is None:
            fish = _parse_fish(agent, self._first_names_index)
            if fish is None:
                raise KeyError(
                    f"{agent!r} is not an agent of this environment (agents are "
                    f"'<behaviour>_<index>' or '<behaviour>_<index>.<life>', e.g. {self._first_names[0]!r})"
                )
        return fish

    @functools.cached_property
    def _first_names_index(self) -> dict[str, int]:
        return {name: i for i, name in enumerate(self._first_names)}

    # Episode -------------------------------------------------------------

    def reset(self, seed: Optional[int] = None, options: Optional[dict] = None):
        batch = self.batch_env.reset(seed)
        self._lives[:] = 0
        self._names = list(self._first_names)
        self._fish_of = {name: i for i, name in enumerate(self._names)}
        self.possible_agents = list(self._first_names)
        self.agents = list(self._names)
        observations = self._observations(batch, range(len(self._names)))
        infos = {
            name: self._info(i, batch) for i, name in enumerate(self._names)
        }
        return observations, infos

    def step(self, actions: dict):
        if not self.agents:
            raise RuntimeError("the episode is over (no agents left): call reset()")
        a = self._actions
        a[:] = 0.0
        for agent, action in actions.items():
            fish = self._fish_of.get(agent)
            if fish is None or self._names[fish] != agent:
                raise ValueError(
                    f"action for {agent!r}, which is not a live agent of this step"
                )
            a[fish] = action
        batch = self.batch_env.step(a)
        episode_over = self.batch_env.tick >= self._decisions_per_episode_ticks
        names = self._names
        fish = range(len(names))
        observations = self._observations(batch, fish)
        rewards = dict(zip(names, batch.reward.tolist()))
        terminated = dict(zip(names, batch.terminated.tolist()))
        truncated = dict(zip(names, batch.truncated.tolist()))
        infos = {name: self._info(i, batch) for i, name in enumerate(names)}
        if episode_over:
            for name in names:
                if not terminated[name]:
                    truncated[name] = True
            self.agents = []
            return observations, rewards, terminated, truncated, infos
        for i in np.flatnonzero(batch.terminated | batch.truncated).tolist():
            old = names[i]
            self._lives[i] += 1
            new = f"{self._first_names[i]}.{self._lives[i]}"
            names[i] = new
            self._fish_of[new] = i
            del self._fish_of[old]
            self.possible_agents.append(new)
            observations[new] = observations[old]
            rewards[new] = 0.0
            terminated[new] = False
            truncated[new] = False
            infos[new] = self._info(i, batch, fresh_life=True)
            infos[old]["next_agent"] = new
        self.agents = list(names)
        return observations, rewards, terminated, truncated, infos

    def _observations(self, batch, fish) -> dict:
        # One copy of the whole batch per step: the batch's arrays are rewritten
        # by the next step, and learners keep observations.
        grid, vector = batch.grid.copy(), batch.vector.copy()
        return {self._names[i]: {"grid": grid[i], "vector": vector[i]} for i in fish}

    def _info(self, i: int, batch, fresh_life: bool = False) -> dict:
        terms = batch.terms[i]
        return {
            "reward_terms": {
                name: (0.0 if fresh_life else float(v)) for name, v in zip(TERM_NAMES, terms)
            },
            "decided": bool(batch.decided[i]),
            "behaviour": self._behaviour_names[self._behaviour_of_fish[i]],
            "fish": i,
        }

    # Views ---------------------------------------------------------------

    def state(self) -> np.ndarray:
        """Per fish: x, y, z (m), heading x, y, z, speed (m/s), body length (m),
        behaviour index — ``float32 [N, 9]``."""
        return self.batch_env.state()

    def render(self):
        if self.render_mode is None:
            return None
        return self.batch_env.render()

    def close(self):
        self.batch_env.close()


def _parse_fish(agent: str, first_names: dict[str, int]) -> Optional[int]:
    """The fish of an agent name: ``name`` of a first life or ``name.<life>``."""
    if not isinstance(agent, str):
        return None
    if agent in first_names:
        return first_names[agent]
    base, dot, life = agent.rpartition(".")
    if dot and life.isdigit() and int(life) > 0:
        return first_names.get(base)
    return None


#: ``deepfoids.parallel_env(scene="coho_default", phase="pretrain", seed=0, configs=None,
#: max_episode_decisions=None, render_mode=None, reward_profile=None)``, as PettingZoo
#: environments name it.
parallel_env = DeepFoidsParallelEnv
