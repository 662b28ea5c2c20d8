"""Motion primitives executed on the physics: Insert (7 parameters, clip frame), Pull and Flatten.

Every primitive is one pick-and-place: grasp a rope particle, drag it through via points in the table
plane, release, let the rope settle. Insert's via points are given in the target clip's frame; Pull and
Flatten are fixed primitives that move the rope's head to the target clip's approach pose (a point on
the clip's axis in front of the entry face, the rope pointing along the axis) along a collision-free path:
Pull leads the head along a smooth curve that the trailing rope follows (feeding rope through the clips
behind it), Flatten drags it in straight strokes that straighten the front segment.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dloroute.sim.clip_frame import (
    CLIP_DEPTH,
    POST_WIDTH,
    SUCCESS_DISTANCE,
    clip_status,
    front_heading,
    opening_width,
    to_clip_frame,
    to_world_frame,
    yaw_to_clip_frame,
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
"""Length (m) of Flatten's last stroke, along the target's axis: the front segment lines up with the axis
over this length."""
PULL_AXIAL = 0.05
"""Length (m) of the straight end of Pull's path, along the target's axis. Longer straight ends need
sharper turns before them, which draw the rope around clip corners (on Table II's seeds 0-29, 0.08-0.12
routed fewer episodes and drew ropes through posts)."""
PULL_TANGENT = 0.7
"""Tangent length of Pull's Hermite curve segments, as a fraction of each segment's chord."""
PULL_MAX_HEADING = math.radians(45)
"""A Pull succeeds when it leaves the head in front of the target with the front segment within this angle
(rad) of the target's axis."""
PATH_STEP = 0.01
"""Spacing (m) of the points sampled on Pull's curve."""
PATH_MARGIN = 0.015
"""Pull's curve keeps this distance (m) from every clip's footprint."""
LEAD_OUT = 0.04
"""Length (m) of the straight lead-out ahead of the head that Pull tries when a curve starting at once
would bring the fingers against a clip."""
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


def _placed(physics: Physics, target: ClipSpec, max_heading: float = math.pi) -> bool:
    """The head lies in front of ``target``'s entry, within 3 cm of its axis, and the rope's front points
    within ``max_heading`` (rad) of the axis (target's clip frame)."""
    rope = physics.rope()
    head = to_clip_frame(target, rope[0, :2])
    aligned = abs(yaw_to_clip_frame(target, front_heading(rope))) <= max_heading
    return bool(head[0] < 0 and abs(head[1]) < 0.03 and aligned)


def flatten(physics: Physics, target: ClipSpec) -> SkillResult:
    """Flatten: straighten the front segment and lay it along ``target``'s axis in front of it.

    Grasp the graspable particle nearest the head, step straight away from a clip it lies against, then
    drag it in straight strokes (around the target if needed) to the target's axis, ending with an axial
    stroke of up to AXIAL_STROKE to the approach pose. Succeeds when it ends without collision with the
    head in front of the target.
    """
    t0 = physics.time
    index = _first_free_particle(physics)
    if index is None:
        return SkillResult(skill="flatten", clip=target.name, success=False, reason="no graspable particle near the head")
    physics.grasp(index)
    back = index * physics.scene.rope.spacing  # the head leads the gripper by this much (m)
    x, y, yaw = physics.gripper_pose()
    start = np.array([x, y])
    strokes: list[tuple[float, float, float]] = []
    near = [c for c in physics.scene.clips if np.hypot(start[0] - c.x, start[1] - c.y) < RETREAT]
    if near:  # first step straight away from the clip the head lies against
        away = start - np.array([near[0].x, near[0].y])
        start = np.array([near[0].x, near[0].y]) + RETREAT * away / max(np.linalg.norm(away), 1e-9)
        strokes.append((float(start[0]), float(start[1]), yaw))
    path = _path_to_approach(physics, start, target)
    for p in path[:-1]:
        strokes.append((float(p[0]), float(p[1]), target.yaw))
    goal = to_world_frame(target, np.array([APPROACH_X - back, 0.0]))
    strokes.append((float(goal[0]), float(goal[1]), target.yaw))
    hit = physics.move(strokes).collision

    return _finish(physics, "flatten", target, hit, t0, success=lambda _: _placed(physics, target))


def hermite_path(points: list[np.ndarray], start_yaw: float, end_yaw: float, step: float = PATH_STEP) -> np.ndarray:
    """A smooth curve (m, world xy, shape (k, 2)) through ``points``, leaving the first along ``start_yaw`` and
    arriving at the last along ``end_yaw`` (rad); inner points get Catmull-Rom tangents. Cubic Hermite
    segments with tangents PULL_TANGENT x chord, sampled about every ``step`` metres."""
    pts = [np.asarray(p, dtype=float) for p in points]
    tangents = [np.array([math.cos(start_yaw), math.sin(start_yaw)])]
    for a, b in zip(pts[:-2], pts[2:]):
        tangents.append((b - a) / max(float(np.linalg.norm(b - a)), 1e-9))
    tangents.append(np.array([math.cos(end_yaw), math.sin(end_yaw)]))
    out = [pts[0][None]]
    for (p0, m0), (p1, m1) in zip(zip(pts, tangents), zip(pts[1:], tangents[1:])):
        chord = float(np.linalg.norm(p1 - p0))
        s = np.linspace(0.0, 1.0, max(3, int(chord / step) + 1))[1:, None]
        h00, h10, h01, h11 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s, -2 * s**3 + 3 * s**2, s**3 - s**2
        k = PULL_TANGENT * chord
        out.append(h00 * p0 + h10 * k * m0 + h01 * p1 + h11 * k * m1)
    return np.concatenate(out)


def _path_clear(physics: Physics, path: np.ndarray) -> bool:
    """True when every point of ``path`` (m, world xy) keeps PATH_MARGIN from every clip's footprint."""
    for c in physics.scene.clips:
        local = to_clip_frame(c, path)
        half_span = opening_width(c) / 2 + POST_WIDTH
        inside = (np.abs(local[:, 0]) < CLIP_DEPTH / 2 + PATH_MARGIN) & (np.abs(local[:, 1]) < half_span + PATH_MARGIN)
        if inside.any():
            return False
    return True


def _follow(path: np.ndarray, back: float) -> list[tuple[float, float, float]]:
    """Gripper poses (x, y, yaw; m, rad, world) that put a point ``back`` metres ahead of the gripper, along
    its yaw, on each point of ``path`` after the first, the yaw along the path's tangent."""
    tangent = np.gradient(path, axis=0)
    yaws = np.arctan2(tangent[:, 1], tangent[:, 0])
    return [
        (float(p[0] - back * math.cos(a)), float(p[1] - back * math.sin(a)), float(a))
        for p, a in zip(path[1:], yaws[1:])
    ]


def _lead_strokes(physics: Physics, target: ClipSpec, back: float) -> list[tuple[float, float, float]]:
    """Gripper poses for Pull, holding the rope ``back`` metres behind the head (m, rad, world).

    The head's path is a Hermite curve from the head, along its front segment, to PULL_AXIAL before the
    approach point on the target's axis, then straight along the axis to it. Candidates: the direct curve,
    then curves through via points beside the target (clip frame y = +-DETOUR), each also with a first
    lead-out of LEAD_OUT straight ahead of the head (clear of a clip the head just left). The first whose
    head path keeps clear of every clip (``_path_clear``, after its first few points) and whose gripper
    poses touch no clip wins, else the direct curve.
    """
    rope = physics.rope()
    head, yaw = rope[0, :2], front_heading(rope)
    goal = to_world_frame(target, np.array([APPROACH_X, 0.0]))
    far = to_world_frame(target, np.array([APPROACH_X - PULL_AXIAL, 0.0]))
    axial = np.linspace(far, goal, max(2, round(PULL_AXIAL / PATH_STEP) + 1))[1:]
    beside = [[(-0.02, side * DETOUR)] for side in (1.0, -1.0)] + [
        [(0.08, side * DETOUR), (-0.04, side * DETOUR)] for side in (1.0, -1.0)
    ]
    lead_out = head + LEAD_OUT * np.array([math.cos(yaw), math.sin(yaw)])
    fallback = None
    for first in ([head], [head, lead_out]):
        for via in [np.zeros((0, 2)), *beside]:
            curve = hermite_path([*first, *to_world_frame(target, np.array(via)), far], yaw, target.yaw)
            path = np.concatenate([curve, axial])
            strokes = _follow(path, back)
            if _path_clear(physics, path[3:]) and all(physics.gripper_collision(*g) is None for g in strokes):
                return strokes
            fallback = fallback or strokes
    return fallback


def pull(physics: Physics, target: ClipSpec) -> SkillResult:
    """Pull: lead the head along a smooth curve to ``target``'s approach pose (``_lead_strokes``).

    The gripper holds the graspable particle nearest the head and follows the head's path, turned along
    its tangent, so the rope trails along the curve and slides through the clips behind it as it goes.
    Succeeds when it ends without collision with the head in front of the target and its front segment
    within PULL_MAX_HEADING of the axis.
    """
    t0 = physics.time
    index = _first_free_particle(physics)
    if index is None:
        return SkillResult(skill="pull", clip=target.name, success=False, reason="no graspable particle near the head")
    strokes = _lead_strokes(physics, target, back=index * physics.scene.rope.spacing)
    physics.grasp(index)
    hit = physics.move(strokes).collision

    return _finish(
        physics, "pull", target, hit, t0, success=lambda _: _placed(physics, target, max_heading=PULL_MAX_HEADING)
    )
