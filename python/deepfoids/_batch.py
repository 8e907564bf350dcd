"""The batch API: every agent of a scene in contiguous numpy arrays.

`BatchEnv.step(actions)` advances the world by one *tick* (SPEC §3: the
greatest common divisor of the behaviours' decision intervals) and returns a
`Batch` whose arrays are views of buffers owned by the Rust environment: the
next `step` overwrites them in place (copy what you keep). Rows follow the fish
order, behaviour by behaviour (`BatchEnv.behaviours` gives each one's rows).

Per row after a step (the step contract of `env/src/env.rs`):
* `decided` — the behaviour decided at this tick: observation and reward are
  fresh, and the row's action at the next step is used. Otherwise (only in
  scenes mixing decision intervals, e.g. coho at 200 ms beside seabream at
  100 ms) the observation is the previous one, the reward 0, and the next
  action is ignored: the fish keeps executing its last one.
* `terminated` — the fish crossed a wall, the bottom, the surface or an
  obstacle (reward −300). It has already respawned: the row's observation is the
  first of its new episode. Do not bootstrap.
* `truncated` — its episode reached `max_episode_decisions`; nothing happened to
  the fish. Bootstrap from the row's observation, which is both the last of the
  old episode and the first of the new one.
"""

from __future__ import annotations

from dataclasses import dataclass
from os import PathLike
from pathlib import Path
from typing import Optional, Union

import numpy as np

from . import _core
from ._spaces import observation_space, action_space

TERM_NAMES: tuple[str, ...] = tuple(_core.TERM_NAMES)
GRID_SHAPE: tuple[int, int, int] = tuple(_core.GRID_SHAPE)
VECTOR_SIZE: int = _core.VECTOR_OBS
PHASES = ("pretrain", "transfer")


def default_configs() -> Path:
    """The configuration folder shipped inside the package (scenes/, species/, sites/, rewards/)."""
    return Path(__file__).resolve().parent / "configs"


def _configs_dir(configs: Union[str, PathLike, None]) -> str:
    path = default_configs() if configs is None else Path(configs)
    if not (path / "scenes").is_dir():
        raise ValueError(
            f"configs folder {path} has no scenes/ sub-folder; pass a folder laid out like "
            f"{default_configs()} (scenes/, species/, sites/, rewards/)"
        )
    return str(path)


@dataclass(frozen=True)
class Behaviour:
    """One behaviour (species and size class sharing a policy) and its rows."""

    index: int
    name: str
    species: str
    size_class: str
    first: int
    count: int
    #: Physics steps per decision (`k` of SPEC §3).
    steps_per_decision: int
    #: Ticks per decision (1 unless the scene mixes decision intervals).
    period_ticks: int

    @property
    def rows(self) -> slice:
        return slice(self.first, self.first + self.count)


class Batch:
    """The latest output of a `BatchEnv` (arrays are read-only views, rewritten by `step`).

    grid ``float32 [N, 18, 20, 34]``, vector ``float32 [N, 6]``, reward ``float32 [N]``,
    terms ``float32 [N, 7]`` (in the order of ``TERM_NAMES``), terminated, truncated
    and decided ``bool [N]``.
    """

    __slots__ = ("grid", "vector", "reward", "terms", "terminated", "truncated", "decided")

    def __init__(self, arrays: dict):
        for name in self.__slots__:
            setattr(self, name, arrays[name])

    def __repr__(self) -> str:
        return f"Batch(N={len(self.reward)}, decided={int(self.decided.sum())})"


class BatchEnv:
    """Every agent of a scene in contiguous numpy arrays (see the module doc).

    Arguments are those of `deepfoids.parallel_env`: `scene` is an id of
    ``configs/scenes/`` or a path to a scene TOML file; `phase` chooses the reward
    weights (``"pretrain"`` or ``"transfer"``); `seed` draws the school (traits,
    poses, respawns, chases); `configs` is a configuration folder (default: the
    one shipped in the package); `max_episode_decisions` overrides the scene's
    per-agent episode limit; `reward_profile` names a folder of
    ``configs/rewards/`` (default: the CLI's default profile; ``"thesis"`` ends a
    fish's episode at the net, the default profile pushes it back inside).
    """

    def __init__(
        self,
        scene: str = "coho_default",
        phase: str = "pretrain",
        seed: int = 0,
        configs: Union[str, PathLike, None] = None,
        max_episode_decisions: Optional[int] = None,
        reward_profile: Optional[str] = None,
    ):
        if phase not in PHASES:
            raise ValueError(f"unknown phase {phase!r}; allowed: {', '.join(PHASES)}")
        self._seed = _check_seed(seed)
        self._episode = -1
        self._core = _core.Core(
            str(scene),
            phase,
            self._seed,
            _configs_dir(configs),
            max_episode_decisions,
            reward_profile,
        )
        self._core_used = False
        self.behaviours: list[Behaviour] = [
            Behaviour(index=i, **b) for i, b in enumerate(self._core.behaviours())
        ]
        self.n_agents: int = self._core.n_agents
        self.scene_id: str = self._core.scene_id
        self.max_episode_decisions: int = self._core.max_episode_decisions
        #: Simulated seconds per tick (per `step`).
        self.tick_seconds: float = self._core.tick_seconds
        self.term_names = TERM_NAMES
        #: One agent's spaces (every agent has the same).
        self.single_observation_space = observation_space()
        self.single_action_space = action_space()
        self.batch: Optional[Batch] = None
        self._actions = np.zeros((self.n_agents, 3), dtype=np.float32)

    @property
    def seed(self) -> int:
        """The seed of the current episode's world."""
        return self._core.seed

    @property
    def tick(self) -> int:
        """Ticks since the episode's reset."""
        return self._core.tick

    def reset(self, seed: Optional[int] = None) -> Batch:
        """Start an episode: a new school drawn from `seed`, or — when `seed` is
        None — from the next seed of the sequence started by the last given seed
        (the constructor's at first), so episodes differ and replay exactly."""
        if seed is not None:
            self._seed = _check_seed(seed)
            self._episode = 0
        else:
            self._episode += 1
        world_seed = _core.Core.episode_seed(self._seed, self._episode)
        if self._core_used or self._core.seed != world_seed:
            self._core = self._core.reseeded(world_seed)
        self._core_used = True
        self.batch = Batch(self._core.arrays())
        return self.batch

    def step(self, actions) -> Batch:
        """Advance one tick with `actions` ``float32 [N, 3]`` in [−1, 1] (values
        outside are clipped by the environment; rows with ``decided == False``
        are ignored). Returns the same `Batch`, rewritten."""
        if self.batch is None:
            raise RuntimeError("call reset() before step()")
        a = np.asarray(actions)
        if a.shape != (self.n_agents, 3):
            raise ValueError(
                f"actions must have shape ({self.n_agents}, 3) (one row per agent), got {a.shape}"
            )
        if a.dtype != np.float32 or not a.flags.c_contiguous:
            np.copyto(self._actions, a, casting="same_kind")
            a = self._actions
        self._core.step(a)
        return self.batch

    def state(self) -> np.ndarray:
        """Per fish: x, y, z (m), heading x, y, z, speed (m/s), body length (m),
        behaviour index — ``float32 [N, 9]`` (a new array)."""
        return self._core.state()

    def render(self, size: int = 512) -> np.ndarray:
        """The cage seen from above as ``uint8 [size, size, 3]``."""
        from ._render import top_view

        return top_view(self._core, self.behaviours, size)

    def close(self) -> None:
        pass

    def __repr__(self) -> str:
        names = ", ".join(f"{b.name}×{b.count}" for b in self.behaviours)
        return f"BatchEnv({self.scene_id!r}: {names}; seed {self.seed})"


def _check_seed(seed) -> int:
    if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, (int, np.integer)):
        raise TypeError(f"seed must be an int, got {seed!r}")
    if not 0 <= int(seed) < 2**64:
        raise ValueError(f"seed must be in [0, 2**64), got {seed}")
    return int(seed)
