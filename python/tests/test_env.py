"""crazyflie_cosim/World-v0 over real world-servers."""

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import crazyflie_cosim  # noqa: F401  (registers the environment)
from crazyflie_cosim.env import GateProgress, WorldEnv, motor_action, velocity_action


def rollout(env, seed, steps=40):
    """Observations and rewards of one episode from ``seed`` with actions
    drawn from a generator of the same seed."""
    obs, _ = env.reset(seed=seed)
    env.action_space.seed(seed)
    out = [obs]
    rewards = []
    for _ in range(steps):
        obs, r, term, trunc, _ = env.step(env.action_space.sample())
        out.append(obs)
        rewards.append(r)
        if term or trunc:
            break
    return np.array(out), rewards


def test_check_env_passes_in_both_action_modes():
    for action in ("motors", "velocity"):
        env = gym.make("crazyflie_cosim/World-v0", action=action)
        check_env(env.unwrapped, skip_render_check=True)
        env.close()


def test_check_env_passes_with_the_camera_image_and_rendering():
    env = WorldEnv(image=True, action="velocity", render_mode="rgb_array")
    check_env(env)
    obs, _ = env.reset(seed=0)
    assert obs["image"].shape == (320, 320) and obs["image"].dtype == np.uint8
    assert obs["image"].std() > 0  # the course, not a blank picture
    frame = env.render()
    assert frame.shape == (320, 320, 3) and np.array_equal(frame[:, :, 1], obs["image"])
    env.close()


def test_the_same_seed_gives_the_same_episode_and_another_seed_another():
    env = gym.make("crazyflie_cosim/World-v0")
    a, ra = rollout(env, 7)
    b, rb = rollout(env, 7)
    c, _ = rollout(env, 8)
    env.close()
    assert a.shape == b.shape and np.array_equal(a, b) and ra == rb
    assert a.shape != c.shape or not np.array_equal(a, c)


def test_velocity_mode_flies_the_demand_through_the_ported_controller():
    env = WorldEnv(action="velocity", start_jitter_m=0.0, start_jitter_yaw=0.0)
    obs, _ = env.reset(seed=1)
    z0 = obs[2]
    for _ in range(100):  # 3.2 s: climb at 0.3 m/s
        obs, *_ = env.step(velocity_action(0.0, 0.0, 0.3))
    assert obs[2] - z0 == pytest.approx(0.96, abs=0.35)
    for _ in range(100):  # 3.2 s: 0.5 m/s towards world +y
        obs, *_ = env.step(velocity_action(0.0, 0.5, 0.0))
    assert obs[4] == pytest.approx(0.5, abs=0.15)  # world vy
    assert abs(obs[3]) < 0.15 and abs(obs[6]) < 0.2 and abs(obs[7]) < 0.2
    env.close()


class Still(GateProgress):
    """A custom reward: minus the speed."""

    def __call__(self, env, before, after, passed_gate):
        return -float(np.linalg.norm([after.state.vx, after.state.vy, after.state.vz]))


def test_the_reward_is_pluggable_and_the_time_limit_truncates():
    env = WorldEnv(reward=Still(), max_time_s=0.32, steps_per_action=2)
    env.reset(seed=0)
    steps = 0
    while True:
        _, r, term, trunc, info = env.step(motor_action(np.full(4, 100.0)))
        steps += 1
        assert r <= 0.0
        if term or trunc:
            break
    assert trunc and not term and steps == 5 and info["time_s"] == pytest.approx(2.32)
    env.close()


def test_three_drones_in_one_environment(three_drone_world):
    env = WorldEnv(world=str(three_drone_world), action="velocity")
    assert list(env.observation_space.spaces) == ["alpha", "bravo", "charlie"]
    check_env(env, skip_render_check=True)
    obs, _ = env.reset(seed=3)
    # 3.2 s climbing at 0.3, 0.4, 0.5 m/s (the motors need ~2 s to spin up
    # at 30 rad/s per s): each drone flies its own demand.
    climb = {"alpha": 0.3, "bravo": 0.4, "charlie": 0.5}
    for _ in range(100):
        obs, _, _, _, info = env.step({n: velocity_action(0.0, 0.0, climb[n]) for n in env.names})
    assert set(info["rewards"]) == {"alpha", "bravo", "charlie"}
    z = [obs[n][2] for n in env.names]
    assert 0.2 < z[0] < z[1] < z[2], z
    env.close()
