"""One Table I insertion trial: a fixed-seed ClipInsert scene solved by the heuristic or the RL policy."""

from __future__ import annotations

from typing import Any

import numpy as np

from dloroute.sim.clip_frame import SUCCESS_DISTANCE
from dloroute.sim.physics import SimulationError
from dloroute.skills.heuristic import heuristic_insert
from dloroute.skills.insert_env import ClipInsertEnv


def insertion_trial(
    low_level: str, seed: int, scale: float = 1.0, policy_path: str | None = None, perception: str = "oracle"
) -> dict[str, Any]:
    """Success, signed endpoint distance (cm) and primitives used, on the scene of ``seed`` at ``scale``.

    The scene is drawn as in training with the paper's start distribution (no bending). With
    ``perception="image"`` the RL policy observes the rope and clip measured from rendered images.
    """
    env = ClipInsertEnv(scale_range=(scale, scale))
    env.reset(options={"scene": env.sample_scene(np.random.default_rng(seed), scale)})
    try:
        if low_level == "heuristic":
            result = heuristic_insert(env.physics, env.clip)
        elif low_level == "rl":
            from dloroute.skills.policy import InsertPolicy

            observe = None
            if perception == "image":
                from dloroute.perception import perceive_physics

                observe = perceive_physics
            result = InsertPolicy.load(policy_path).insert(env.physics, env.clip, observe=observe)
        else:
            raise ValueError(f"unknown low-level policy {low_level!r}; choose rl or heuristic")
    except SimulationError as err:
        return {"success": False, "signed_distance_cm": None, "length": None, "error": str(err)}
    return {
        "success": bool(result.signed_distance > SUCCESS_DISTANCE and not result.collision),
        "signed_distance_cm": round(100 * result.signed_distance, 3),
        "length": result.primitives,
        "collision": result.collision,
    }
