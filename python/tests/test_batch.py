"""The batch API: buffers, episodes, determinism and errors."""

import shutil

import numpy as np
import pytest

import deepfoids


def test_buffers_have_the_issue_shapes_and_are_rewritten_in_place():
    env = deepfoids.BatchEnv(scene="seabream_default", seed=0)
    batch = env.reset()
    n = env.n_agents
    assert n == 10
    expected = {
        "grid": ((n, 18, 20, 34), np.float32),
        "vector": ((n, 6), np.float32),
        "reward": ((n,), np.float32),
        "terms": ((n, 7), np.float32),
        "terminated": ((n,), np.bool_),
        "truncated": ((n,), np.bool_),
        "decided": ((n,), np.bool_),
    }
    for name, (shape, dtype) in expected.items():
        a = getattr(batch, name)
        assert a.shape == shape and a.dtype == dtype, name
        assert a.flags.c_contiguous and not a.flags.writeable, name
    # At reset: everyone decided, nothing earned, the two older frames empty.
    assert batch.decided.all() and not batch.reward.any() and not batch.terms.any()
    assert not batch.grid[:, :12].any() and batch.grid[:, 12:].any()
    before = batch.grid.copy()
    out = env.step(np.zeros((n, 3), dtype=np.float32))
    assert out is batch
    # The newest frame moved back one slot in the same array.
    np.testing.assert_array_equal(batch.grid[:, 6:12], before[:, 12:18])
    with pytest.raises(ValueError, match="read-only"):
        batch.reward[0] = 1.0


def test_vector_observation_depth_matches_the_state():
    """vector[3] is depth / cage height (SPEC §5): −y / 3 m in seabream's 3 m cube."""
    env = deepfoids.BatchEnv(scene="seabream_default", seed=1)
    batch = env.reset()
    rng = np.random.default_rng(0)
    for _ in range(20):
        batch = env.step(rng.uniform(-1, 1, (env.n_agents, 3)).astype(np.float32))
        state = env.state()
        np.testing.assert_allclose(batch.vector[:, 3], -state[:, 1] / 3.0, atol=1e-6)
        np.testing.assert_allclose(batch.terms.sum(axis=1), batch.reward, atol=1e-3)


def test_seeds_replay_exactly_and_episodes_differ():
    def trace(env, steps=15):
        rng = np.random.default_rng(3)
        out = [env.batch.grid.copy()]
        for _ in range(steps):
            b = env.step(rng.uniform(-1, 1, (env.n_agents, 3)).astype(np.float32))
            out += [b.vector.copy(), b.reward.copy(), b.terminated.copy()]
        return out

    def same(a, b):
        return all(np.array_equal(x, y) for x, y in zip(a, b))

    a = deepfoids.BatchEnv(scene="seabream_50", seed=9)
    b = deepfoids.BatchEnv(scene="seabream_50", seed=123)
    a.reset()
    b.reset(seed=9)
    first = trace(a)
    assert same(first, trace(b))
    a.reset()
    b.reset()
    second = trace(a)
    assert same(second, trace(b)) and not same(first, second)
    a.reset(seed=9)
    assert same(first, trace(a))
    assert a.seed == 9 and b.seed != 9


def test_batch_and_parallel_env_agree():
    batch_env = deepfoids.BatchEnv(scene="three_species", seed=2)
    par_env = deepfoids.parallel_env(scene="three_species", seed=2)
    batch = batch_env.reset()
    obs, _ = par_env.reset()
    rng = np.random.default_rng(4)
    for _ in range(4):
        actions = rng.uniform(-1, 1, (300, 3)).astype(np.float32)
        live = list(par_env.agents)  # in fish order
        batch = batch_env.step(actions)
        obs, rew, term, trunc, info = par_env.step(dict(zip(live, actions)))
        for i, name in enumerate(live):
            assert info[name]["fish"] == i
            np.testing.assert_array_equal(obs[name]["grid"], batch.grid[i])
            np.testing.assert_array_equal(obs[name]["vector"], batch.vector[i])
            assert rew[name] == batch.reward[i]
            assert info[name]["decided"] == batch.decided[i]


def test_short_episodes_truncate_every_fish_that_did_not_hit_a_boundary():
    env = deepfoids.BatchEnv(scene="seabream_default", seed=3, max_episode_decisions=4)
    env.reset()
    zero = np.zeros((env.n_agents, 3), dtype=np.float32)
    for _ in range(3):
        assert not env.step(zero).truncated.any()
    batch = env.step(zero)
    assert (batch.truncated | batch.terminated).all()
    assert not (batch.truncated & batch.terminated).any()
    assert env.max_episode_decisions == 4


def test_behaviours_give_each_ones_rows():
    env = deepfoids.BatchEnv(scene="three_species")
    assert [(b.name, b.species, b.rows) for b in env.behaviours] == [
        ("coho_regular", "coho", slice(0, 100)),
        ("yellowtail_regular", "yellowtail", slice(100, 200)),
        ("seabream_regular", "seabream", slice(200, 300)),
    ]
    assert [b.period_ticks for b in env.behaviours] == [2, 1, 1]
    assert env.tick_seconds == pytest.approx(0.1)


def test_a_users_configs_folder(tmp_path):
    configs = tmp_path / "configs"
    shutil.copytree(deepfoids.default_configs(), configs)
    scene = configs / "scenes" / "seabream_default.toml"
    scene.write_text(scene.read_text().replace("count = 10", "count = 7"))
    assert deepfoids.BatchEnv(scene="seabream_default", configs=configs).n_agents == 7
    assert deepfoids.BatchEnv(scene=str(scene)).n_agents == 7
    assert deepfoids.BatchEnv(scene="seabream_default").n_agents == 10


def test_bad_input_names_what_is_wrong(tmp_path):
    with pytest.raises(ValueError, match="unknown scene.*seabream_default"):
        deepfoids.BatchEnv(scene="no_such_scene")
    with pytest.raises(ValueError, match="unknown phase 'finetune'; allowed: pretrain, transfer"):
        deepfoids.BatchEnv(scene="seabream_default", phase="finetune")
    with pytest.raises(ValueError, match="no scenes/ sub-folder"):
        deepfoids.BatchEnv(scene="seabream_default", configs=tmp_path)
    with pytest.raises(ValueError, match="max_episode_decisions = 0"):
        deepfoids.BatchEnv(scene="seabream_default", max_episode_decisions=0)
    with pytest.raises(TypeError, match="seed must be an int"):
        deepfoids.BatchEnv(scene="seabream_default", seed=1.5)
    env = deepfoids.BatchEnv(scene="seabream_default")
    with pytest.raises(RuntimeError, match="reset"):
        env.step(np.zeros((10, 3), dtype=np.float32))
    env.reset()
    with pytest.raises(ValueError, match=r"shape \(10, 3\)"):
        env.step(np.zeros((9, 3), dtype=np.float32))
    bad = np.zeros((10, 3), dtype=np.float32)
    bad[4, 1] = np.nan
    with pytest.raises(ValueError, match="agent 4.*finite"):
        env.step(bad)
    # float64 actions are accepted (cast once into a float32 buffer).
    env.step(np.zeros((10, 3)))


def test_the_configs_ship_inside_the_package():
    configs = deepfoids.default_configs()
    assert configs.parent.name == "deepfoids"
    ids = sorted(p.stem for p in (configs / "scenes").glob("*.toml"))
    for scene in ("coho_default", "seabream_default", "three_species", "density_dense"):
        assert scene in ids
    for sub in ("species", "sites", "rewards/thesis"):
        assert any((configs / sub).glob("*.toml")), sub


def test_render_top_view():
    env = deepfoids.BatchEnv(scene="three_species")
    env.reset()
    image = env.render(size=256)
    assert image.shape == (256, 256, 3) and image.dtype == np.uint8
    colours = {tuple(c) for c in image.reshape(-1, 3)}
    for colour in [(240, 128, 48), (250, 220, 70), (230, 70, 90)]:
        assert colour in colours, colour
