"""SAC training of the Insert policy with Stable-Baselines3, read top to bottom (CleanRL style).

``dloroute train-insert`` calls ``train``. Environments run in parallel processes (one per core), the
curriculum switches the clip scale range after ``curriculum_steps`` environment steps (paper, Sec. IV-A),
TensorBoard logs go to ``<out>/tb``, and the actor's weights are exported with a card (policy.py).
"""

from __future__ import annotations

import dataclasses
import json
import os
import platform
import shlex
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import gymnasium as gym
import numpy as np

from dloroute.skills.policy import export_actor
from dloroute.skills.primitives import GRASP_INDICES, WORKSPACE_HALF

SCRIPTED = np.array([2, -0.08, 0.0, 0.0, -0.016, 0.0, 0.0])
"""The scripted insertion (grasp index, via 1 x, y, yaw, via 2 x, y, yaw; m, rad, clip frame): grasp 5 cm
behind the head, line up on the axis 8 cm before the clip, push until the fingers are 1 cm short of it."""


def scripted_action(rng: np.random.Generator, noise: float = 0.15) -> np.ndarray:
    """SCRIPTED as a policy action in [-1, 1]^7, with Gaussian noise (std ``noise``) for variety."""
    scale = np.array([(GRASP_INDICES - 1) / 2, *[WORKSPACE_HALF, WORKSPACE_HALF, np.pi / 2] * 2])
    base = SCRIPTED / scale
    base[0] -= 1.0  # index 0..7 -> [-1, 1]
    return np.clip(base + rng.normal(0.0, noise, 7), -1.0, 1.0).astype(np.float32)


def prefill_demonstrations(model, env, steps: int, rng: np.random.Generator) -> None:
    """Step every environment with ``scripted_action`` and store the transitions in the replay buffer."""
    obs = env.reset()
    for _ in range(steps):
        actions = np.stack([scripted_action(rng) for _ in range(env.num_envs)])
        new_obs, rewards, dones, infos = env.step(actions)
        next_obs = new_obs.copy()
        for i, done in enumerate(dones):
            if done:  # the vec env already reset this one: store the true final observation
                next_obs[i] = infos[i]["terminal_observation"]
        model.replay_buffer.add(obs, next_obs, actions, rewards, dones, infos)
        obs = new_obs


class BootstrapOnSuccess(gym.Wrapper):
    """For the learner only: a successful insertion ends the episode as a truncation, not a termination.

    The paper's reward pays every step the rope stays in (0.5 rope_in + 10 d_floor + eta r_flat), so with
    success as a terminal state a critic values lingering half-inserted above finishing. Bootstrapping the
    success state's value (the reward it would keep earning) removes that incentive without changing the
    reward; the environment itself still terminates on success, as its spec says.
    """

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        if terminated and info.get("success"):
            terminated, truncated = False, True
        return obs, reward, terminated, truncated, info


@dataclass(frozen=True)
class TrainConfig:
    """SAC hyper-parameters and run settings; the field docs are the CLI's --help."""

    steps: int = 6200
    """Environment steps (Insert primitives) in total; the paper trains for 6.2k."""
    seed: int = 0
    """Seed of the environments and the learner."""
    n_envs: int = 2
    """Parallel environment processes (use the number of cores)."""
    bend_probability: float = 0.5
    """Share of episodes whose rope starts curved (as after a Pull); 0 = the paper's distribution."""
    curriculum_steps: int = 1600
    """Steps with clip scale U(1.0, 2.2) before switching to U(0.9, 1.5)."""
    learning_starts: int = 300
    """Random-action steps before learning starts."""
    demo_steps: int = 0
    """Vectorised steps of a noisy scripted insertion stored in the replay buffer before learning (SAC from
    demonstrations; 0 = the paper's plain SAC). See ``scripted_action``."""
    batch_size: int = 256
    learning_rate: float = 3e-4
    gamma: float = 0.9
    """Discount; an insertion episode lasts at most 7 primitives."""
    ent_coef: str = "auto_0.05"
    """SAC entropy coefficient: tuned automatically from 0.05 (SB3's default start, 1.0, keeps a 7-D policy
    near-random for thousands of steps when rewards are of order 1)."""
    gradient_steps: int = 2
    """Gradient steps per environment step (per vectorised step: x n_envs)."""
    net_arch: tuple[int, ...] = (256, 256)
    out: str = "runs/train_insert"
    """Run folder: TensorBoard logs, the full SB3 checkpoint, the exported actor and its card."""
    resume: str | None = None
    """Run folder of an earlier training to continue (its checkpoint and replay buffer), past its curriculum."""


def train(config: TrainConfig, *, progress: bool = True) -> Path:
    """Train, export the actor into ``<out>/insert_sac.npz`` with a card, and return that path."""
    import torch
    from stable_baselines3 import SAC
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import SubprocVecEnv

    import dloroute  # noqa: F401  (registers dloroute/ClipInsert-v0)

    torch.set_num_threads(1)
    out = Path(config.out)
    out.mkdir(parents=True, exist_ok=True)
    env = make_vec_env(
        "dloroute/ClipInsert-v0", n_envs=config.n_envs, seed=config.seed,
        vec_env_cls=SubprocVecEnv if config.n_envs > 1 else None,
        env_kwargs={"scale_range": (1.0, 2.2), "bend_probability": config.bend_probability},
        wrapper_class=BootstrapOnSuccess,
    )

    class Curriculum(BaseCallback):
        """Switch the clip scale range once, after ``curriculum_steps`` environment steps."""

        switched = False

        def _on_step(self) -> bool:
            if not self.switched and self.num_timesteps >= config.curriculum_steps:
                self.training_env.env_method("set_scale_range", 0.9, 1.5)
                self.switched = True
            return True

    previous = None
    if config.resume:
        before = Path(config.resume)
        model = SAC.load(before / "sac_full.zip", env=env, device="cpu", tensorboard_log=str(out / "tb"))
        if (before / "replay_buffer.pkl").exists():
            model.load_replay_buffer(before / "replay_buffer.pkl")
        previous = json.loads((before / "insert_sac.json").read_text())
        env.env_method("set_scale_range", 0.9, 1.5)
    else:
        model = SAC(
            "MlpPolicy", env, seed=config.seed, learning_rate=config.learning_rate, batch_size=config.batch_size,
            gamma=config.gamma, learning_starts=config.learning_starts, gradient_steps=config.gradient_steps,
            ent_coef=config.ent_coef, buffer_size=100_000, policy_kwargs={"net_arch": list(config.net_arch)},
            tensorboard_log=str(out / "tb"), verbose=0, device="cpu",
        )
    start = time.time()
    if config.demo_steps and not config.resume:
        prefill_demonstrations(model, env, config.demo_steps, np.random.default_rng(config.seed))
    model.learn(
        total_timesteps=config.steps, callback=None if config.resume else Curriculum(), progress_bar=progress,
        reset_num_timesteps=not config.resume,
    )
    wall = time.time() - start
    env.close()
    model.save(out / "sac_full")
    model.save_replay_buffer(out / "replay_buffer.pkl")
    path = out / "insert_sac.npz"
    card = {
        "command": shlex.join(["dloroute", *sys.argv[1:]]),
        "config": dataclasses.asdict(config),
        "wall_time_s": round(wall, 1),
        "total_steps": int(model.num_timesteps),
        "total_wall_time_s": round(wall + (previous["total_wall_time_s"] if previous else 0.0), 1),
        "resumed_from": previous,
        "machine": f"{platform.machine()} {os.cpu_count()} cores, {platform.python_implementation()} {platform.python_version()}",
        "evaluation": None,
    }
    export_actor(model, path, card)
    return path
