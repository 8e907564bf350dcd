"""Trained policies from Python: `.onnx` files and run folders.

The ONNX files are those `cargo test -p deepfoids-onnx` exports from Burn actors
(PPO and SAC) into ``target/onnx-check/``, with observations and the Burn actor's
deterministic actions beside them; `.ci/run` runs cargo test first. Set
DEEPFOIDS_ONNX_CHECK to use another folder.
"""

import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest

import deepfoids

CHECK = Path(
    os.environ.get(
        "DEEPFOIDS_ONNX_CHECK", Path(__file__).resolve().parents[2] / "target" / "onnx-check"
    )
)
CASES = [CHECK, CHECK / "sac"]


def case(folder):
    if not (folder / "policy.onnx").is_file():
        if os.environ.get("CI"):
            pytest.fail(f"{folder}/policy.onnx is missing: run `cargo test -p deepfoids-onnx` first")
        pytest.skip(f"{folder}/policy.onnx not there (run `cargo test -p deepfoids-onnx`)")
    batch = json.loads((folder / "case.json").read_text())["batch"]
    grid = np.fromfile(folder / "obs_0.bin", dtype="<f4").reshape(batch, 18, 20, 34)
    vector = np.fromfile(folder / "obs_1.bin", dtype="<f4").reshape(batch, 6)
    expected = np.fromfile(folder / "expected.bin", dtype="<f4").reshape(batch, 3)
    return folder / "policy.onnx", grid, vector, expected


@pytest.mark.parametrize("folder", CASES, ids=["ppo", "sac"])
def test_onnx_policy_acts_like_the_burn_actor(folder):
    path, grid, vector, expected = case(folder)
    policy = deepfoids.load_policy(path)
    actions = policy.act(grid, vector)
    assert actions.shape == expected.shape and actions.dtype == np.float32
    assert np.abs(actions - expected).max() <= 1e-4
    assert np.abs(expected).max() > 0.05  # the case is not trivially zero
    assert policy.metadata[policy.behaviours[0]]["species"] == "seabream"
    sampled = policy.act(grid, vector, stochastic=True)
    assert sampled.shape == expected.shape and np.all(np.abs(sampled) <= 1.0)
    assert not np.array_equal(sampled, actions)


def test_a_run_folder_is_read_through_final_behaviour_onnx(tmp_path):
    path, *_ = case(CHECK)
    run = tmp_path / "run"
    (run / "final").mkdir(parents=True)
    with pytest.raises(FileNotFoundError, match=f"{run}.*final/<behaviour>.onnx.*deepfoids export"):
        deepfoids.load_policy(run)
    shutil.copy(path, run / "final" / "seabream.onnx")
    policy = deepfoids.load_policy(run)
    assert policy.behaviours == ["seabream"]

    env = deepfoids.BatchEnv(scene="seabream_default", seed=0)
    batch = env.reset()
    for _ in range(5):
        actions = policy.act(batch, env=env)
        assert actions.shape == (10, 3) and np.all(np.abs(actions) <= 1.0)
        np.testing.assert_array_equal(actions, policy.act(batch.grid, batch.vector))
        batch = env.step(actions)


def test_policy_errors_name_the_path(tmp_path):
    with pytest.raises(FileNotFoundError, match="no such policy file.*missing.onnx"):
        deepfoids.load_policy(tmp_path / "missing.onnx")
    with pytest.raises(ValueError, match="neither a run folder nor an .onnx"):
        deepfoids.load_policy(tmp_path / "notes.txt")
    broken = tmp_path / "broken.onnx"
    broken.write_bytes(b"not a model")
    with pytest.raises(ValueError, match="broken.onnx is not an ONNX model"):
        deepfoids.load_policy(broken)
    path, grid, vector, _ = case(CHECK)
    policy = deepfoids.load_policy(path)
    with pytest.raises(ValueError, match=r"vector must be float32 \[4, 6\]"):
        policy.act(grid[:4], vector[:3])
    env = deepfoids.BatchEnv(scene="coho_small")
    with pytest.raises(KeyError, match=r"no network for behaviour 'coho_small' \(species coho\); it has: seabream_regular"):
        policy.act(env.reset(), env=env)
