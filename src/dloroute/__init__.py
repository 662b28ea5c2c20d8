"""dloroute: hierarchical routing of a rope through clips (MuJoCo, SAC insertion skill, VLM planners)."""

import os

# Headless rendering by default; MuJoCo reads this when it is first imported.
os.environ.setdefault("MUJOCO_GL", "egl")

__version__ = "0.1.0"

import gymnasium as _gym

_gym.register(id="dloroute/ClipInsert-v0", entry_point="dloroute.skills.insert_env:ClipInsertEnv")
