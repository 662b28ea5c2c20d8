"""SAC training of the Insert policy with Stable-Baselines3, read top to bottom (CleanRL style).

``dloroute train-insert`` calls ``train``. Environments run in parallel processes (one per core), the
curriculum switches the clip scale range after ``curriculum_steps`` environment steps (paper, Sec. IV-A),
TensorBoard logs go to ``<out>/tb``, and the actor's weights are exported with a card (policy.py).
"""

from __future__ import annotations

import dataclasses
import os
import platform
import shlex
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from dloroute.skills.policy import export_actor


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
    batch_size: int = 256
    learning_rate: float = 3e-4
    gamma: float = 0.9
    """Discount; an insertion episode lasts at most 7 primitives."""
    gradient_steps: int = 2
    """Gradient steps per environment step (per vectorised step: x n_envs)."""
    net_arch: tuple[int, ...] = (256, 256)
    out: str = "runs/train_insert"
    """Run folder: TensorBoard logs, the full SB3 checkpoint, the exported actor and its card."""


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
    )

    class Curriculum(BaseCallback):
        """Switch the clip scale range once, after ``curriculum_steps`` environment steps."""

        switched = False

        def _on_step(self) -> bool:
            if not self.switched and self.num_timesteps >= config.curriculum_steps:
                self.training_env.env_method("set_scale_range", 0.9, 1.5)
                self.switched = True
            return True

    model = SAC(
        "MlpPolicy", env, seed=config.seed, learning_rate=config.learning_rate, batch_size=config.batch_size,
        gamma=config.gamma, learning_starts=config.learning_starts, gradient_steps=config.gradient_steps,
        policy_kwargs={"net_arch": list(config.net_arch)}, tensorboard_log=str(out / "tb"), verbose=0,
        device="cpu",
    )
    start = time.time()
    model.learn(total_timesteps=config.steps, callback=Curriculum(), progress_bar=progress)
    wall = time.time() - start
    env.close()
    model.save(out / "sac_full")
    path = out / "insert_sac.npz"
    card = {
        "command": shlex.join(["dloroute", *sys.argv[1:]]),
        "config": dataclasses.asdict(config),
        "wall_time_s": round(wall, 1),
        "machine": f"{platform.machine()} {os.cpu_count()} cores, {platform.python_implementation()} {platform.python_version()}",
        "evaluation": None,
    }
    export_actor(model, path, card)
    return path
