"""Motion primitives executed on the physics: Insert (7 parameters, clip frame), Pull and Flatten.

Every primitive is one pick-and-place: grasp a rope particle, drag it through via points in the table
plane, release, let the rope settle. Insert's via points are given in the target clip's frame; Pull and
Flatten are fixed primitives that move the rope's head to the target clip's approach pose (a point on
the clip's axis in front of the entry face, the rope pointing along the axis) along a collision-free path.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dloroute.sim.clip_frame import (
    SUCCESS_DISTANCE,
    clip_status,
    routed_order,
    to_clip_frame,
    to_world_frame,
)
from dloroute.sim.physics import Physics
from dloroute.types import ClipSpec, SkillResult

WORKSPACE_HALF = 0.08
"""Insert via points lie in a 0.16 m x 0.16 m square centred on the clip (clip frame)."""
GRASP_INDICES = 8
"""Insert may grasp particles 0..GRASP_INDICES-1 (the front 17.5 cm of the rope at 2.5 cm spacing)."""
APPROACH_X = -0.075
"""Clip-frame x (m) where Pull and Flatten leave the head: in front of the entry face, on the axis."""
SETTLE_TIME = 0.3
"""Rest (s) after a release before the rope is measured."""
AXIAL_STROKE = 0.12
"""Length (m) of the last stroke of Pull and Flatten, along the target's axis: the rope trailing the head
lines up with the axis over this length."""
FEED_REACH = 0.12
"""Pull feeds rope (its first stroke) only when the gripper is within this distance (m) past the exit of the
last routed clip, near its axis; a head already farther on goes straight to the target."""
RETREAT = 0.07
"""A gripper starting closer than this (m) to a clip's centre first moves straight away from it to this
distance, so that the planned path starts clear of the clip."""
DETOUR = 0.11
"""Lateral offset (m, clip frame) of the via points that lead the gripper around a clip."""


@dataclass(frozen=True)
class InsertParams:
    """One Insert primitive: grasp particle ``grasp_index``, then drag through two via points.

    ``via`` holds two (x, y, yaw) gripper poses in the target clip's frame (m, rad); yaw is the heading
    of the held rope segment (pointing towards the head), 0 = along the insertion direction.
    """

    grasp_index: int
    via: tuple[tuple[float, float, float], tuple[float, float, float]]

    @classmethod
    def from_action(cls, action: np.ndarray) -> InsertParams:
        """Scale a policy action in [-1, 1]^7 to parameters (see ClipInsert-v0's action table)."""
        a = np.clip(np.asarray(action, dtype=float), -1.0, 1.0)
        index = int(round((a[0] + 1) / 2 * (GRASP_INDICES - 1)))
        via = tuple(
            (float(a[k] * WORKSPACE_HALF), float(a[k + 1] * WORKSPACE_HALF), float(a[k + 2] * math.pi / 2))
            for k in (1, 4)
        )
        return cls(index, via)  # type: ignore[arg-type]


def shielded(physics: Physics, clip: ClipSpec, params: InsertParams, step: float = 0.002) -> InsertParams:
    """A safety shield for executing a learned Insert among several clips (deployment, not training).

    The grasp index moves to the nearest particle the fingers can reach without touching a clip, and each
    via point backs off along the target's -x (clip frame) in ``step`` metres until the fingers' footprint
    at that pose clears every clip, as a collision-aware motion planner (the paper's MoveIt) would.
    """
    rope = physics.rope()
    order = sorted(range(GRASP_INDICES), key=lambda i: (abs(i - params.grasp_index), i))
    index = next(
        (i for i in order if physics.gripper_collision(rope[i, 0], rope[i, 1], physics.rope_yaw_at(i)) is None),
        params.grasp_index,
    )
    vias = []
    for x, y, yaw in params.via:
        while x > -WORKSPACE_HALF and physics.gripper_collision(*_world_pose(clip, (x, y, yaw))) is not None:
            x -= step
        vias.append((x, y, yaw))
    return InsertParams(index, (vias[0], vias[1]))


def _world_pose(clip: ClipSpec, pose: tuple[float, float, float]) -> tuple[float, float, float]:
    p = to_world_frame(clip, np.array([pose[0], pose[1]]))
    return float(p[0]), float(p[1]), clip.yaw + pose[2]


def _finish(physics: Physics, skill, clip: ClipSpec, collision: str | None, t0: float, success=None) -> SkillResult:
    """Release, settle and measure; ``success`` defaults to the Insert criterion."""
    physics.release()
    if collision is None:
        physics.settle(SETTLE_TIME)
    physics.park_gripper()
    status = clip_status(clip, physics.rope())
    ok = status.signed_distance > SUCCESS_DISTANCE if success is None else success(status)
    reason = f"gripper touched clip {collision!r}" if collision else ""
    return SkillResult(
        skill=skill, clip=clip.name, success=bool(ok and collision is None), collision=collision is not None,
        reason=reason, signed_distance=status.signed_distance, sim_time=physics.time - t0,
    )


def insert(physics: Physics, clip: ClipSpec, params: InsertParams) -> SkillResult:
    """One Insert primitive; success = signed endpoint distance > +2 cm after it (paper, Sec. IV-A)."""
    t0 = physics.time
    hit = physics.grasp(params.grasp_index)
    if hit is None:
        hit = physics.move([_world_pose(clip, v) for v in params.via]).collision
    return _finish(physics, "insert", clip, hit, t0)


def _clear(physics: Physics, a: np.ndarray, b: np.ndarray, margin: float = 0.025, clips=None) -> bool:
    """True when the straight gripper path a -> b (world xy, m) keeps ``margin`` from the clips (all by
    default)."""
    for s in np.linspace(0.0, 1.0, 25):
        p = a + s * (b - a)
        for c in physics.scene.clips if clips is None else clips:
            if np.hypot(p[0] - c.x, p[1] - c.y) < margin + 0.03:
                return False
    return True


def _path_to_approach(physics: Physics, start: np.ndarray, target: ClipSpec) -> list[np.ndarray]:
    """World xy via points from ``start`` to the target's approach point, avoiding clips.

    The last stroke runs along the target's axis for up to AXIAL_STROKE (shorter where another clip
    lies on the axis). Tries the direct line to that stroke, then detours around the target's sides.
    """
    goal = to_world_frame(target, np.array([APPROACH_X, 0.0]))
    others = [c for c in physics.scene.clips if c.name != target.name]
    stroke = AXIAL_STROKE
    while stroke > 0.0:
        far = to_world_frame(target, np.array([APPROACH_X - stroke, 0.0]))
        if _clear(physics, far, goal, clips=others):
            break
        stroke -= 0.02
    far = to_world_frame(target, np.array([APPROACH_X - max(stroke, 0.0), 0.0]))
    side_x = APPROACH_X - max(stroke, 0.0)
    candidates = [[far, goal]]
    for side in (1.0, -1.0):
        candidates.append([to_world_frame(target, np.array([0.0, side * DETOUR])),
                           to_world_frame(target, np.array([side_x, side * DETOUR * 0.6])), far, goal])
        candidates.append([to_world_frame(target, np.array([0.08, side * DETOUR])),
                           to_world_frame(target, np.array([-0.02, side * DETOUR])),
                           to_world_frame(target, np.array([side_x, side * DETOUR * 0.6])), far, goal])

    def ok(path):
        pts = [start, *path]
        return all(_clear(physics, a, b) for a, b in zip(pts[:-2], pts[1:-1]))  # last leg ends at the clip

    for path in candidates:
        if ok(path):
            return path
    return candidates[0]


def _first_free_particle(physics: Physics) -> int | None:
    """The particle nearest the head that the gripper can grasp without touching a clip."""
    p = physics.rope()
    for i in range(len(p) // 2):
        if physics.gripper_collision(p[i, 0], p[i, 1], physics.rope_yaw_at(i)) is None:
            return i
    return None


def reposition(physics: Physics, target: ClipSpec, *, away_from: ClipSpec | None, skill: str) -> SkillResult:
    """Grasp near the head and bring the head to ``target``'s approach pose (Pull and Flatten).

    With ``away_from`` (Pull after a clip) and the head just out of it, the first stroke drags the head 6 cm
    further out along that clip's axis, feeding rope through it. Without it (Flatten), the first stroke draws the head back
    along the target's axis, which straightens the front segment before it is laid in front of the clip.
    The primitive succeeds when it ends without collision with the head in front of the target.
    """
    t0 = physics.time
    index = _first_free_particle(physics)
    if index is None:
        return SkillResult(skill=skill, clip=target.name, success=False, reason="no graspable particle near the head")
    physics.grasp(index)
    back = index * physics.scene.rope.spacing  # the head leads the gripper by this much (m)
    x, y, _ = physics.gripper_pose()
    start = np.array([x, y])
    strokes: list[tuple[float, float, float]] = []
    local = to_clip_frame(away_from, start) if away_from is not None else None
    if local is not None and 0.0 < local[0] < FEED_REACH and abs(local[1]) < 0.04:  # just out of that clip
        out = to_world_frame(away_from, np.array([local[0] + 0.06, 0.0]))
        strokes.append((float(out[0]), float(out[1]), away_from.yaw))
        start = out
    near = [c for c in physics.scene.clips if np.hypot(start[0] - c.x, start[1] - c.y) < RETREAT]
    if near:  # first step straight away from the clip the head lies against
        away = start - np.array([near[0].x, near[0].y])
        start = np.array([near[0].x, near[0].y]) + RETREAT * away / max(np.linalg.norm(away), 1e-9)
        strokes.append((float(start[0]), float(start[1]), physics.gripper_pose()[2]))
    path = _path_to_approach(physics, start, target)
    for p in path[:-1]:
        strokes.append((float(p[0]), float(p[1]), target.yaw))
    goal = to_world_frame(target, np.array([APPROACH_X - back, 0.0]))
    strokes.append((float(goal[0]), float(goal[1]), target.yaw))
    hit = physics.move(strokes).collision

    def placed(status) -> bool:
        head = to_clip_frame(target, physics.rope()[0, :2])
        return bool(head[0] < 0 and abs(head[1]) < 0.03)

    return _finish(physics, skill, target, hit, t0, success=placed)


def pull(physics: Physics, target: ClipSpec) -> SkillResult:
    """Pull: feed rope out of the last clip routed and bring the head in front of ``target``."""
    done = routed_order(physics.scene.clips, physics.rope())
    last = physics.scene.clip(done[-1]) if done else None
    return reposition(physics, target, away_from=last, skill="pull")


def flatten(physics: Physics, target: ClipSpec) -> SkillResult:
    """Flatten: straighten the front segment and lay it along ``target``'s axis in front of it."""
    return reposition(physics, target, away_from=None, skill="flatten")
