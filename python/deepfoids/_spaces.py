"""The spaces of one agent (SPEC §4–5)."""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from . import _core


def observation_space() -> spaces.Dict:
    """``Dict(grid=Box(0, 1, (18, 20, 34)), vector=Box(-inf, inf, (6,)))``, float32.

    grid: three stacked frames (oldest first) of the 34 × 20 angular grid sensor,
    six channels each (proximity, fish, net, surface, obstacle, chase partner);
    vector: forward direction minus the nearest front neighbour's (3), depth /
    cage height, aggressor, target.
    """
    return spaces.Dict(
        {
            "grid": spaces.Box(0.0, 1.0, tuple(_core.GRID_SHAPE), dtype=np.float32),
            "vector": spaces.Box(-np.inf, np.inf, (_core.VECTOR_OBS,), dtype=np.float32),
        }
    )


def action_space() -> spaces.Box:
    """``Box(-1, 1, (3,))``: speed change (× Δv_max), pitch and yaw change (× θ_max)."""
    return spaces.Box(-1.0, 1.0, (3,), dtype=np.float32)
