"""The shipped Insert policy: the SAC actor's weights in a small .npz, evaluated with numpy.

Only the deterministic actor ships (hidden ReLU layers, then ``mu``; action = tanh(mu)), so running the
policy needs neither torch nor Stable-Baselines3. The card beside the weights (same name, .json) records
the training command, seed, steps, wall time and the evaluation result.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from importlib import resources
from pathlib import Path

import numpy as np

from dloroute.sim.clip_frame import clip_status
from dloroute.sim.physics import Physics
from dloroute.skills.insert_env import MAX_PRIMITIVES, observation_vector
from dloroute.skills.primitives import InsertParams, insert, shielded
from dloroute.types import ClipSpec, Observation, SkillResult

SHIPPED = "insert_sac.npz"
"""File name of the shipped weights in ``dloroute/skills/policies``."""


class InsertPolicy:
    """Deterministic SAC actor: observation (ClipInsert-v0) -> action in [-1, 1]^7."""

    def __init__(self, weights: dict[str, np.ndarray], card: dict | None = None):
        n_hidden = len([k for k in weights if k.startswith("hidden") and k.endswith("_w")])
        if n_hidden == 0 or "mu_w" not in weights:
            raise ValueError("policy weights must hold hidden0_w/b ... and mu_w/b (an exported SAC actor)")
        self.layers = [(weights[f"hidden{i}_w"], weights[f"hidden{i}_b"]) for i in range(n_hidden)]
        self.mu = (weights["mu_w"], weights["mu_b"])
        self.card = card or {}

    @classmethod
    def load(cls, path: str | Path | None = None) -> InsertPolicy:
        """Load exported weights; ``None`` loads the shipped policy."""
        p = Path(path) if path is not None else Path(str(resources.files("dloroute.skills.policies") / SHIPPED))
        if not p.exists():
            raise FileNotFoundError(f"no insertion policy at {p}; train one with `dloroute train-insert`")
        with np.load(p) as data:
            weights = {k: data[k] for k in data.files}
        card_path = p.with_suffix(".json")
        card = json.loads(card_path.read_text()) if card_path.exists() else None
        return cls(weights, card)

    def act(self, obs: np.ndarray) -> np.ndarray:
        h = np.asarray(obs, dtype=np.float64)
        for w, b in self.layers:
            h = np.maximum(w @ h + b, 0.0)
        return np.tanh(self.mu[0] @ h + self.mu[1])

    def insert(
        self, physics: Physics, clip: ClipSpec, max_primitives: int = MAX_PRIMITIVES,
        observe: Callable[[Physics], Observation] | None = None, shield: bool = True,
    ) -> SkillResult:
        """Closed-loop Insert: up to ``max_primitives`` primitives until success or a collision.

        ``observe`` supplies the rope and the clip's pose the policy sees (default: the simulator's state;
        e.g. ``perceive_physics`` for the image pipeline). ``shield`` keeps the executed grasp and via points
        clear of the clips (``primitives.shielded``); the policy was trained without it.
        """
        result = None
        sim_time = 0.0
        for t in range(max_primitives):
            seen = observe(physics) if observe else Observation(physics.scene.clips, physics.rope())
            seen_clip = seen.clip(clip.name)
            status = clip_status(seen_clip, seen.rope)
            obs = observation_vector(seen_clip, seen.rope, status.rope_in, t)
            params = InsertParams.from_action(self.act(obs))
            result = insert(physics, clip, shielded(physics, clip, params) if shield else params)
            sim_time += result.sim_time
            if result.success or result.collision:
                break
        return SkillResult(
            skill="insert", clip=clip.name, success=result.success, collision=result.collision,
            reason=result.reason, primitives=t + 1, signed_distance=result.signed_distance, sim_time=sim_time,
        )


def actor_weights(model) -> dict[str, np.ndarray]:
    """The deterministic actor of an SB3 SAC model as numpy arrays: hidden layers, then ``mu``."""
    weights = {}
    linear = [m for m in model.actor.latent_pi if hasattr(m, "weight")]
    for i, layer in enumerate(linear):
        weights[f"hidden{i}_w"] = layer.weight.detach().cpu().numpy().astype(np.float32)
        weights[f"hidden{i}_b"] = layer.bias.detach().cpu().numpy().astype(np.float32)
    weights["mu_w"] = model.actor.mu.weight.detach().cpu().numpy().astype(np.float32)
    weights["mu_b"] = model.actor.mu.bias.detach().cpu().numpy().astype(np.float32)
    return weights


def export_actor(model, path: Path, card: dict) -> None:
    """Write the actor's weights to ``path`` (.npz) and ``card`` beside it (.json)."""
    np.savez_compressed(path, **actor_weights(model))
    Path(path).with_suffix(".json").write_text(json.dumps(card, indent=2) + "\n")
