"""The PettingZoo ParallelEnv, checked with PettingZoo's own tests and by hand."""

import numpy as np
import pytest
from pettingzoo.test import parallel_api_test, parallel_seed_test

import deepfoids

SCENES = ["seabream_default", "three_species", "coho_default"]


# PettingZoo's API test checks every agent's observation against its space at
# every cycle in Python: 1,000 cycles of coho_default's 1,000 fish took 191 s of
# CI's 30 minutes. The large scenes run 100 cycles (100,000 agent-steps; the
# checks are the same at every cycle); the short-episode test below runs 1,000
# to reach terminations and the final truncation.
API_CYCLES = {"seabream_default": 1000, "three_species": 200, "coho_default": 100}


@pytest.mark.parametrize("scene", SCENES)
def test_pettingzoo_parallel_api(scene):
    env = deepfoids.parallel_env(scene=scene, seed=1)
    parallel_api_test(env, num_cycles=API_CYCLES[scene])


@pytest.mark.parametrize("scene", SCENES)
def test_pettingzoo_parallel_seed(scene):
    parallel_seed_test(lambda: deepfoids.parallel_env(scene=scene), num_cycles=50)


def test_api_with_short_episodes_runs_out_of_agents():
    """Episodes of 30 decisions: the API test sees terminations, new lives and
    the final step where every agent is truncated and `agents` empties."""
    env = deepfoids.parallel_env(
        scene="seabream_default", seed=2, max_episode_decisions=30, reward_profile="thesis"
    )
    parallel_api_test(env, num_cycles=1000)
    assert env.agents == []


def random_actions(env, rng):
    return {a: rng.uniform(-1, 1, 3).astype(np.float32) for a in env.agents}


def test_same_seed_same_run_and_new_seed_new_run():
    def run(seed, steps=40):
        env = deepfoids.parallel_env(scene="seabream_default")
        obs, _ = env.reset(seed=seed)
        rng = np.random.default_rng(5)
        trace = [obs["seabream_regular_3"]["grid"].copy()]
        for _ in range(steps):
            obs, rew, term, trunc, info = env.step(random_actions(env, rng))
            trace.append(np.stack([obs[a]["vector"] for a in env.agents]))
            trace.append(np.array([rew[a] for a in rew]))
        return trace

    a, b, c = run(7), run(7), run(8)
    assert all(np.array_equal(x, y) for x, y in zip(a, b))
    assert not all(np.array_equal(x, y) for x, y in zip(a, c))


def test_every_observation_is_inside_its_space():
    for scene in SCENES:
        env = deepfoids.parallel_env(scene=scene, seed=3)
        obs, infos = env.reset()
        rng = np.random.default_rng(0)
        for step in range(25):
            for agent, o in obs.items():
                space = env.observation_space(agent)
                assert space.contains(o), f"{scene} step {step}: {agent}'s observation is outside its space"
            assert env.state_space.contains(env.state())
            obs, *_ = env.step(random_actions(env, rng))
        agent = env.agents[0]
        assert env.action_space(agent).shape == (3,)
        assert env.observation_space(agent)["grid"].shape == (18, 20, 34)


def test_a_terminated_fish_comes_back_as_the_next_life_of_its_agent():
    # `thesis`: a net collision ends the fish's episode (the default profile
    # pushes it back inside instead).
    env = deepfoids.parallel_env(scene="seabream_default", seed=4, reward_profile="thesis")
    env.reset()
    # Full speed ahead, always pitching up: every fish reaches a boundary soon.
    for _ in range(400):
        actions = {a: np.array([1.0, 1.0, 0.0], dtype=np.float32) for a in env.agents}
        obs, rew, term, trunc, info = env.step(actions)
        ended = [a for a in term if term[a]]
        if ended:
            break
    else:
        pytest.fail("no fish hit a boundary in 400 steps of full speed")
    old = ended[0]
    new = info[old]["next_agent"]
    assert new == f"{old}.1"
    assert rew[old] <= -300.0 + 1e-3  # r_BC = −300 plus possibly neighbour collisions
    assert info[old]["reward_terms"]["boundary_collision"] == -300.0
    assert rew[new] == 0.0 and not term[new] and not trunc[new]
    assert old not in env.agents and new in env.agents
    assert new in env.possible_agents and old in env.possible_agents
    assert info[new]["fish"] == info[old]["fish"]
    # A respawned fish's frame stack starts afresh: the two older frames are zeros.
    assert not obs[new]["grid"][:12].any()
    assert env.observation_space(new) is env.observation_space(old)
    with pytest.raises(ValueError, match="not a live agent"):
        env.step({old: np.zeros(3, dtype=np.float32)})


def test_truncation_and_the_end_of_the_episode():
    env = deepfoids.parallel_env(scene="seabream_default", seed=5, max_episode_decisions=3)
    env.reset()
    still = {a: np.zeros(3, dtype=np.float32) for a in env.agents}
    for step in range(2):
        obs, rew, term, trunc, info = env.step({a: still[a] for a in env.agents if a in still})
        assert not any(trunc.values())
    obs, rew, term, trunc, info = env.step({a: still[a] for a in env.agents if a in still})
    assert all(trunc[a] or term[a] for a in still)
    assert env.agents == []
    with pytest.raises(RuntimeError, match="reset"):
        env.step({})


def test_infos_carry_the_reward_terms():
    env = deepfoids.parallel_env(scene="seabream_default", seed=6)
    env.reset()
    rng = np.random.default_rng(1)
    for _ in range(30):
        obs, rew, term, trunc, info = env.step(random_actions(env, rng))
        for agent, r in rew.items():
            terms = info[agent]["reward_terms"]
            assert list(terms) == list(deepfoids.TERM_NAMES)
            assert sum(terms.values()) == pytest.approx(r, abs=1e-3)


def test_mixed_decision_intervals_in_three_species():
    env = deepfoids.parallel_env(scene="three_species", seed=0)
    obs, info = env.reset()
    assert all(i["decided"] for i in info.values())
    zero = {a: np.zeros(3, dtype=np.float32) for a in env.agents}
    obs1, rew, term, trunc, info = env.step(zero)
    by_behaviour = {}
    for agent, i in info.items():
        by_behaviour.setdefault(i["behaviour"], set()).add(i["decided"])
    # Coho decide every 200 ms, seabream and yellowtail every 100 ms (one tick).
    assert by_behaviour["coho_regular"] == {False}
    assert by_behaviour["seabream_regular"] == {True} and by_behaviour["yellowtail_regular"] == {True}
    coho = next(a for a in env.agents if a.startswith("coho_regular_"))
    assert rew[coho] == 0.0
    np.testing.assert_array_equal(obs1[coho]["grid"], obs[coho]["grid"])
    obs2, rew, term, trunc, info = env.step(zero)
    assert info[coho]["decided"]
    assert not np.array_equal(obs2[coho]["grid"], obs1[coho]["grid"])


def test_render_shows_the_cage_and_the_fish():
    env = deepfoids.parallel_env(scene="seabream_default", render_mode="rgb_array")
    env.reset(seed=0)
    image = env.render()
    assert image.shape == (512, 512, 3) and image.dtype == np.uint8
    colours = {tuple(c) for c in image.reshape(-1, 3)}
    assert (200, 210, 220) in colours  # the net
    assert (240, 128, 48) in colours  # the first (only) behaviour
    assert deepfoids.parallel_env(scene="seabream_default").render() is None
    with pytest.raises(ValueError, match="render_mode"):
        deepfoids.parallel_env(scene="seabream_default", render_mode="human")


def test_agent_names_and_state():
    env = deepfoids.parallel_env(scene="three_species")
    env.reset(seed=0)
    assert env.agents[:2] == ["coho_regular_0", "coho_regular_1"]
    assert len(env.agents) == 300 and "yellowtail_regular_99" in env.agents
    state = env.state()
    assert state.shape == (300, 9) and state.dtype == np.float32
    np.testing.assert_allclose(np.linalg.norm(state[:, 3:6], axis=1), 1.0, atol=1e-5)
    with pytest.raises(KeyError, match="not an agent"):
        env.observation_space("salmon_1")


def test_the_reward_profile_is_chosen_by_name():
    # The default profile pushes a fish back from the net: full speed ahead
    # never ends an episode there.
    env = deepfoids.parallel_env(scene="seabream_default", seed=4)
    env.reset()
    for _ in range(100):
        actions = {a: np.array([1.0, 1.0, 0.0], dtype=np.float32) for a in env.agents}
        obs, rew, term, trunc, info = env.step(actions)
        assert not any(term.values())
    with pytest.raises(ValueError, match="tuna"):
        deepfoids.parallel_env(scene="seabream_default", reward_profile="tuna")
