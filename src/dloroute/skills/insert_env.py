"""Gymnasium environment for the Insert skill: ``dloroute/ClipInsert-v0``.

The class docstring is the spec.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import gymnasium as gym
import numpy as np

from dloroute.sim.clip_frame import CLIP_DEPTH, SUCCESS_DISTANCE, clip_status, to_clip_frame, to_world_frame
from dloroute.sim.physics import Physics, SimulationError
from dloroute.sim.scene import HEAD_ANGLE, HEAD_RECT
from dloroute.skills.primitives import InsertParams, insert
from dloroute.types import ClipSpec, ClipStatus, RopeSpec, SceneSpec

N_OBS = 8
"""Front particles in the observation (17.5 cm of rope at 2.5 cm spacing): the segment an insertion
moves. Farther particles in a routed rope curve back to the previous clip, a shape no single-clip
training scene shows, so they are left out."""
OBS_SCALE = 10.0
"""Particle coordinates enter the observation in decimetres (x 10), so the network sees values of order 1."""
MAX_PRIMITIVES = 7
"""Insert primitives per episode (paper, Sec. IV-B)."""
BETA, GAMMA, ETA = -2.0, -0.001, 0.5
"""Reward weights of eq. (1) (paper, Sec. IV-A)."""
REGION_X = (-0.12, -CLIP_DEPTH / 2)
REGION_Y = 0.05
"""Insertion-possible region R in front of the clip (m, clip frame): x range and |y| bound."""
INSERT_ROPE = RopeSpec(length=0.6, n_particles=25, mass=0.03)
"""Rope of the insertion env: the routing rope's spacing and section, half its length."""


def observation_vector(clip: ClipSpec, rope: np.ndarray, rope_in: bool, primitives: int) -> np.ndarray:
    """The policy's observation from world particles (n, 2|3) (see the class docstring's table)."""
    local = to_clip_frame(clip, np.asarray(rope)[:N_OBS, :2])
    local = np.clip(OBS_SCALE * local, -10.0, 10.0)  # dm; only particles over 1 m away are clipped
    return np.concatenate(
        [local.ravel(), [clip.scale, float(rope_in), primitives / MAX_PRIMITIVES]]
    ).astype(np.float32)


def insertion_reward(status: ClipStatus, local: np.ndarray, collided: bool, t: int) -> float:
    """Paper eq. (1)-(3). ``local``: particles (m, clip frame, head first); ``t``: primitives so far.

    r_dist = 10 d_floor if rope_in and not rope_out; 20 d_ceil if rope_out; else 1_R(p1) / (4 + 80 d_floor).
    r_flat = 1 / (1 + 1000/3 * sum_{i=0..3} |p_{i+3} - p_i|_y).
    """
    if status.rope_out:
        r_dist = 20 * status.d_ceil
    elif status.rope_in:
        r_dist = 10 * status.d_floor
    else:
        hx, hy = local[0, 0], local[0, 1]
        in_region = REGION_X[0] <= hx <= REGION_X[1] and abs(hy) <= REGION_Y
        r_dist = float(in_region) / (4 + 80 * status.d_floor)
    r_flat = 1.0 / (1.0 + 1000.0 / 3.0 * float(sum(abs(local[i + 3, 1] - local[i, 1]) for i in range(4))))
    return float(
        0.5 * (status.rope_in + status.rope_out) + BETA * collided + GAMMA * t + r_dist + ETA * r_flat
    )


@dataclass(frozen=True)
class InsertOutcome:
    """``evaluate()``'s verdict after a primitive (ManiSkill-style: success never comes from reward)."""

    success: bool
    signed_distance: float


class ClipInsertEnv(gym.Env):
    """One clip at a random pose on the table and a straight rope whose head starts in a 5 cm (along the clip's
    axis) x 10 cm (lateral) rectangle in front of it, within +-10 deg of the axis (paper, Sec. IV-A). Each
    step executes one Insert primitive with the action's 7 parameters.
    
    | | |
    |---|---|
    | Observation | ``Box((2*N_OBS + 3,))``: the front ``N_OBS`` = 8 particles' (x, y) in the clip frame (dm, head first), then clip scale, ``rope_in`` (0/1), primitives used / 7 |
    | Action | ``Box(-1, 1, (7,))``: grasp index (-> particle 0..7), via 1 (x, y, yaw), via 2 (x, y, yaw); x, y scaled to +-0.08 m, yaw to +-pi/2 rad, clip frame |
    | Reward | paper eq. (1)-(3): 0.5 (rope_in + rope_out) + beta collide + gamma t + r_dist + eta r_flat; beta = -2, gamma = -0.001, eta = 0.5 |
    | Termination | success (signed endpoint distance > +2 cm, ``evaluate()``), a gripper-clip collision, or an unstable simulation (``info["error"]``) |
    | Truncation | after 7 primitives |
    | Bending | with ``bend_probability``, a reset first drags a particle 15-30 cm behind the head sideways, so the rope starts curved as after a Pull (our addition; 0 = the paper's distribution) |
    | Curriculum | clip scale ~ U(``scale_range``); ``set_scale_range`` switches it (SAC training: U(1.0, 2.2) for the first 1,600 steps, then U(0.9, 1.5)) |
    
    The insertion env's rope is 0.6 m long (25 particles) with the routing rope's 2.5 cm spacing and
    section, so particle indices and the front segment behave the same at half the simulation cost.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 4}

    def __init__(
        self, scale_range: tuple[float, float] = (0.9, 1.5), bend_probability: float = 0.0,
        render_mode: str | None = None,
    ):
        self.scale_range = scale_range
        self.bend_probability = bend_probability
        self.render_mode = render_mode
        high = np.array([10.0] * (2 * N_OBS) + [3.0, 1.0, 1.0], np.float32)
        low = np.array([-10.0] * (2 * N_OBS) + [0.0, 0.0, 0.0], np.float32)
        self.observation_space = gym.spaces.Box(low, high, dtype=np.float32)
        self.action_space = gym.spaces.Box(-1.0, 1.0, (7,), np.float32)
        self.physics: Physics | None = None
        self.clip: ClipSpec | None = None
        self.t = 0
        self._renderer = None

    def set_scale_range(self, low: float, high: float) -> None:
        """Curriculum hook: the clip scale of the following episodes is drawn from U(low, high)."""
        self.scale_range = (low, high)

    def sample_scene(self, rng: np.random.Generator, scale: float | None = None) -> SceneSpec:
        """A one-clip scene: clip at the table centre with a random yaw, rope start as in the paper."""
        yaw = float(rng.uniform(-math.pi, math.pi))
        s = float(rng.uniform(*self.scale_range)) if scale is None else scale
        clip = ClipSpec("red", 0.0, 0.0, yaw, scale=s)
        hx, hy = rng.uniform(*HEAD_RECT[0]), rng.uniform(*HEAD_RECT[1])
        head = (hx * math.cos(yaw) - hy * math.sin(yaw), hx * math.sin(yaw) + hy * math.cos(yaw))
        return SceneSpec(
            family="insertion", seed=0, clips=(clip,), order=("red",), instruction="insert the rope",
            rope_head=(float(head[0]), float(head[1])), rope_yaw=yaw + float(rng.uniform(-HEAD_ANGLE, HEAD_ANGLE)),
            rope=INSERT_ROPE,
        )

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        options = options or {}
        scene = options.get("scene") or self.sample_scene(self.np_random, options.get("scale"))
        self.physics = Physics(scene)
        self.physics.settle(0.2)
        self.clip = scene.clips[0]
        if options.get("scene") is None and self.np_random.random() < self.bend_probability:
            self._bend(self.np_random)
        self.t = 0
        return self._obs(clip_status(self.clip, self.physics.rope())), {}

    def _bend(self, rng: np.random.Generator) -> None:
        """Curve the rope like a rope that comes out of a previous clip: drag a particle 15-30 cm behind
        the head sideways by 4-10 cm (clip frame), release. Used to widen the training distribution."""
        index = int(rng.integers(6, 13))
        p = to_clip_frame(self.clip, self.physics.rope()[index, :2])
        dy = float(rng.choice([-1.0, 1.0]) * rng.uniform(0.04, 0.10))
        dx = float(rng.uniform(-0.05, 0.02))
        target = to_world_frame(self.clip, np.array([p[0] + dx, p[1] + dy]))
        self.physics.grasp(index)
        _, _, yaw = self.physics.gripper_pose()
        self.physics.move([(float(target[0]), float(target[1]), yaw + float(rng.uniform(-0.5, 0.5)))])
        self.physics.release()
        self.physics.settle(0.3)
        self.physics.park_gripper()

    def _obs(self, status: ClipStatus) -> np.ndarray:
        return observation_vector(self.clip, self.physics.rope(), status.rope_in, self.t)

    def evaluate(self) -> InsertOutcome:
        status = clip_status(self.clip, self.physics.rope())
        return InsertOutcome(status.signed_distance > SUCCESS_DISTANCE, status.signed_distance)

    def step(self, action):
        self.t += 1
        before = self.physics.rope()
        try:
            result = insert(self.physics, self.clip, InsertParams.from_action(action))
        except SimulationError as err:
            # Never return numbers from a broken state: the last valid observation, terminated.
            status = clip_status(self.clip, before)
            return self._obs(status), BETA, True, False, {"error": str(err), "success": False}
        rope = self.physics.rope()
        status = clip_status(self.clip, rope)
        reward = insertion_reward(status, to_clip_frame(self.clip, rope[:, :2]), result.collision, self.t)
        outcome = self.evaluate()
        terminated = outcome.success or result.collision
        truncated = not terminated and self.t >= MAX_PRIMITIVES
        info = {"success": outcome.success, "is_success": outcome.success, "collision": result.collision, "signed_distance": outcome.signed_distance}
        return self._obs(status), reward, terminated, truncated, info

    def render(self):
        from dloroute.sim.render import SceneRenderer

        if self._renderer is None or self._renderer.physics is not self.physics:
            self.close()
            self._renderer = SceneRenderer(self.physics)
        return self._renderer.render(self.clip.name)

    def close(self):
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
