"""ClipInsert-v0: Gymnasium compliance, determinism, the paper's reward, termination and the policy."""

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import dloroute  # noqa: F401  (registers the env)
from dloroute.sim.clip_frame import to_clip_frame
from dloroute.skills.insert_env import BETA, ETA, GAMMA, N_OBS, ClipInsertEnv, insertion_reward
from dloroute.skills.primitives import GRASP_INDICES, WORKSPACE_HALF
from dloroute.types import ClipStatus


def action(index, v1, v2):
    """Unscaled Insert parameters -> a policy action in [-1, 1]^7."""
    a = [index / (GRASP_INDICES - 1) * 2 - 1]
    for x, y, yaw in (v1, v2):
        a += [x / WORKSPACE_HALF, y / WORKSPACE_HALF, yaw / (np.pi / 2)]
    return np.array(a, dtype=np.float32)


def status(rope_in=False, rope_out=False, d_floor=0.05, d_ceil=0.07):
    return ClipStatus("red", rope_in, rope_out, rope_out, d_floor, d_ceil, d_ceil if rope_out else -d_ceil)


def straight(y=0.0, x0=-0.05, n=8):
    return np.stack([x0 - 0.025 * np.arange(n), np.full(n, y)], axis=1)


def test_registered_env_passes_check_env():
    env = gym.make("dloroute/ClipInsert-v0")
    check_env(env.unwrapped, skip_render_check=True)
    assert env.observation_space.shape == (2 * N_OBS + 3,) and env.action_space.shape == (7,)


def test_same_seed_same_episode():
    def run():
        env = ClipInsertEnv()
        obs, _ = env.reset(seed=11)
        out = [obs]
        for a in (action(2, (-0.08, 0, 0), (-0.03, 0, 0)), action(2, (-0.06, 0.01, 0.1), (-0.016, 0, 0))):
            obs, r, *_ = env.step(a)
            out += [obs, np.array([r])]
        return np.concatenate(out)

    assert np.array_equal(run(), run())


# Hand-computed reward terms, paper eq. (1)-(3): r = 0.5 (in + out) + beta collide + gamma t + r_dist + eta r_flat.
def test_reward_head_in_region_straight_rope():
    # Not in: r_dist = 1/(4 + 80 d_floor) = 1/(4 + 4) = 0.125; straight -> r_flat = 1.
    r = insertion_reward(status(d_floor=0.05), straight(), collided=False, t=1)
    assert r == pytest.approx(0.125 + GAMMA * 1 + ETA * 1.0)


def test_reward_head_outside_region_and_bent():
    local = straight(y=0.0, x0=-0.2)
    local[6, 1] = 0.003  # only |p6 - p3|_y = 0.003 -> sum 0.003 -> r_flat = 1 / (1 + 1000/3 * 0.003) = 1/2
    r = insertion_reward(status(d_floor=0.19), local, collided=False, t=2)
    assert r == pytest.approx(GAMMA * 2 + ETA * 0.5)


def test_reward_rope_in_and_out_and_collision():
    r_in = insertion_reward(status(rope_in=True, d_floor=0.01), straight(x0=0.0), collided=False, t=1)
    assert r_in == pytest.approx(0.5 + 10 * 0.01 + GAMMA + ETA)
    r_out = insertion_reward(status(rope_in=True, rope_out=True, d_ceil=0.03), straight(x0=0.04), collided=True, t=3)
    assert r_out == pytest.approx(1.0 + BETA + 3 * GAMMA + 20 * 0.03 + ETA)


def test_success_terminates():
    env = ClipInsertEnv(scale_range=(1.0, 1.0))
    obs, _ = env.reset(seed=3)
    head_y = obs[1] / 10  # dm -> m
    obs, reward, terminated, truncated, info = env.step(action(2, (-0.08, 0, 0), (-0.016, 0, 0)))
    assert info["success"] and terminated and not truncated, head_y
    assert info["signed_distance"] > 0.02 and reward > 1.0


def test_collision_terminates_with_penalty():
    env = ClipInsertEnv(scale_range=(1.0, 1.0))
    env.reset(seed=3)
    _, reward, terminated, _, info = env.step(action(0, (-0.08, 0, 0), (0.0, 0, 0)))  # head held, fingers into the clip
    assert info["collision"] and terminated and not info["success"] and reward < BETA + 1.5


def test_truncates_after_seven_primitives():
    env = ClipInsertEnv(scale_range=(1.0, 1.0))
    env.reset(seed=5)
    idle = action(7, (-0.08, 0.08, 0), (-0.08, 0.08, 0))  # grasp far back, stay aside: nothing happens
    for _ in range(7):
        _, _, terminated, truncated, _ = env.step(idle)
        assert not terminated
    assert truncated


def test_bent_start_is_curved():
    env = ClipInsertEnv(bend_probability=1.0)
    env.reset(seed=0)
    local = to_clip_frame(env.clip, env.physics.rope()[:, :2])
    assert np.ptp(local[:16, 1]) > 0.03
