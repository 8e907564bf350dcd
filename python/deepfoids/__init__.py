"""DeepFoids for Python: the Rust fish-school environment as a PettingZoo
`ParallelEnv` (`parallel_env`), a batch API with numpy buffers (`BatchEnv`),
and trained policies (`load_policy`). See docs/python.md."""

from ._batch import (
    GRID_SHAPE,
    TERM_NAMES,
    VECTOR_SIZE,
    Batch,
    BatchEnv,
    Behaviour,
    default_configs,
)
from ._parallel import DeepFoidsParallelEnv, parallel_env
from ._policy import Policy, load_policy
from ._spaces import action_space, observation_space

__all__ = [
    "GRID_SHAPE",
    "TERM_NAMES",
    "VECTOR_SIZE",
    "Batch",
    "BatchEnv",
    "Behaviour",
    "DeepFoidsParallelEnv",
    "Policy",
    "action_space",
    "default_configs",
    "load_policy",
    "observation_space",
    "parallel_env",
]
