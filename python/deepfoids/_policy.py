"""Trained policies: exported ONNX files (ML-Agents' interface) run by tract in Rust."""

from __future__ import annotations

from os import PathLike
from pathlib import Path
from typing import Optional, Union

import numpy as np

from . import _core


def load_policy(path: Union[str, PathLike]) -> "Policy":
    """A trained policy from an ``.onnx`` file or a run folder.

    A run folder is read through ``final/<behaviour>.onnx`` (one file per behaviour,
    written at the end of training); a folder without them is an error that says
    how to export them with ``deepfoids export``.
    """
    path = Path(path)
    if path.is_dir():
        files = sorted((path / "final").glob("*.onnx"))
        if not files:
            raise FileNotFoundError(
                f"run folder {path} has no final/<behaviour>.onnx; export the trained "
                f"policy with `deepfoids export --run {path} [--behaviour NAME] "
                f"--out {path / 'final'}/<behaviour>.onnx`"
            )
        return Policy({f.stem: _core.OnnxModel(str(f)) for f in files})
    if path.suffix != ".onnx":
        raise ValueError(f"{path} is neither a run folder nor an .onnx file")
    if not path.is_file():
        raise FileNotFoundError(f"no such policy file: {path}")
    model = _core.OnnxModel(str(path))
    return Policy({model.metadata.get("behaviour", path.stem): model})


class Policy:
    """One network per behaviour; acts on batch observations.

    ``act(grid, vector)`` for one behaviour's rows, or ``act(batch, env=env)``
    for a whole `BatchEnv` output (rows routed to each behaviour's network by
    behaviour name, else by species).
    """

    def __init__(self, models: dict):
        self.models = models

    @property
    def behaviours(self) -> list[str]:
        return list(self.models)

    @property
    def metadata(self) -> dict[str, dict[str, str]]:
        return {name: m.metadata for name, m in self.models.items()}

    def model_for(self, behaviour: Optional[str] = None, species: Optional[str] = None):
        if behaviour is None and len(self.models) == 1:
            return next(iter(self.models.values()))
        if behaviour in self.models:
            return self.models[behaviour]
        matches = [m for m in self.models.values() if m.metadata.get("species") == species]
        if species is not None and len(matches) == 1:
            return matches[0]
        raise KeyError(
            f"this policy has no network for behaviour {behaviour!r}"
            + (f" (species {species})" if species else "")
            + f"; it has: {', '.join(self.models)}"
        )

    def act(self, grid, vector=None, *, env=None, behaviour: Optional[str] = None,
            stochastic: bool = False) -> np.ndarray:
        """Actions ``float32 [n, 3]``: the mean action, or a sample if `stochastic`.

        Either `grid` ``[n, 18, 20, 34]`` and `vector` ``[n, 6]`` of one behaviour,
        or a `Batch` as `grid` with its `BatchEnv` as `env`.
        """
        if env is not None:
            batch = grid
            out = np.zeros((env.n_agents, 3), dtype=np.float32)
            for b in env.behaviours:
                rows = b.rows
                model = self.model_for(b.name, b.species)
                out[rows] = model.run(
                    np.ascontiguousarray(batch.grid[rows], dtype=np.float32),
                    np.ascontiguousarray(batch.vector[rows], dtype=np.float32),
                    stochastic,
                )
            return out
        if vector is None:
            raise TypeError("act(grid, vector) needs the vector observations too")
        return self.model_for(behaviour).run(
            np.ascontiguousarray(grid, dtype=np.float32),
            np.ascontiguousarray(vector, dtype=np.float32),
            stochastic,
        )

    def __repr__(self) -> str:
        return f"Policy({', '.join(self.models)})"
