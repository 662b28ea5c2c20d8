"""Skills on prepared scenes: where the rope actually goes."""

import numpy as np
import pytest
from scene_helpers import one_clip_scene

from dloroute.sim.clip_frame import clip_status, front_heading, routed_order, to_clip_frame, yaw_to_clip_frame
from dloroute.sim.physics import Physics
from dloroute.skills import primitives
from dloroute.skills.heuristic import heuristic_insert
from dloroute.skills.primitives import InsertParams
from dloroute.types import ClipSpec, SceneSpec

GOOD = InsertParams(2, ((-0.08, 0.0, 0.0), (-0.016, 0.0, 0.0)))
"""Grasp 5 cm behind the head, line up on the axis, push until the fingers are 1 cm short of the clip."""


def two_clip_scene(turn: float) -> SceneSpec:
    """Clip A at the origin facing +x; clip B 16 cm further on an arc turning by ``turn`` (rad)."""
    b_yaw = turn
    chord = 0.16
    bx, by = chord * np.cos(turn / 2), chord * np.sin(turn / 2)
    base = one_clip_scene(head_x=-0.09)
    clips = (ClipSpec("red", 0.0, 0.0, 0.0), ClipSpec("blue", float(bx), float(by), float(b_yaw)))
    return SceneSpec("test", 0, clips, ("red", "blue"), "red then blue", base.rope_head, 0.0, base.rope)


def test_insert_with_known_good_parameters_threads_the_head(clip_scene):
    physics = Physics(clip_scene)
    result = primitives.insert(physics, clip_scene.clips[0], GOOD)
    status = clip_status(clip_scene.clips[0], physics.rope())
    assert result.success and not result.collision
    assert status.routed and status.signed_distance > 0.02
    assert result.signed_distance == status.signed_distance


def test_insert_into_the_clip_is_a_collision(clip_scene):
    physics = Physics(clip_scene)
    result = primitives.insert(physics, clip_scene.clips[0], InsertParams(2, ((-0.08, 0.0, 0.0), (0.0, 0.0, 0.0))))
    assert result.collision and not result.success and "red" in result.reason


def _length_past(clip, rope) -> float:
    """Arc length (m) of rope between the head and where it crosses the clip's exit face."""
    local = to_clip_frame(clip, rope[:, :2])
    k = int(np.argmax(local[:, 0] < 0.01))  # first particle (from the head) back inside or before the exit
    return float(np.sum(np.linalg.norm(np.diff(rope[: k + 1, :2], axis=0), axis=1)))


@pytest.mark.parametrize("turn_deg", [45, 110])
def test_pull_feeds_rope_through_and_brings_the_head_to_the_next_clip(turn_deg):
    scene = two_clip_scene(np.radians(turn_deg))
    physics = Physics(scene)
    a, b = scene.clips
    assert primitives.insert(physics, a, GOOD).success
    before = _length_past(a, physics.rope())
    result = primitives.pull(physics, b)
    rope = physics.rope()
    assert not result.collision
    assert routed_order(scene.clips, rope) == ("red",)  # still through A
    assert _length_past(a, rope) > before + 0.05
    head = to_clip_frame(b, rope[0, :2])
    assert -0.15 < head[0] < 0 and abs(head[1]) < 0.03  # in front of B's opening
    heading = abs(yaw_to_clip_frame(b, front_heading(rope)))
    assert heading < np.radians(90)  # pointing into the opening: the planners' "aligned"
    assert result.success == (heading <= primitives.PULL_MAX_HEADING)
    assert result.success or turn_deg > 90  # a gentle turn ends aligned; a sharp one may spring back


def _lateral_deviation(clip, rope, n=6) -> float:
    """Mean |y| (m, clip frame) of the front ``n`` particles about the clip's axis."""
    return float(np.mean(np.abs(to_clip_frame(clip, rope[:n, :2])[:, 1])))


def test_flatten_straightens_the_front_segment(clip_scene):
    physics = Physics(clip_scene)
    clip = clip_scene.clips[0]
    physics.grasp(0)  # bend the front: drag the head 6 cm sideways
    x, y, yaw = physics.gripper_pose()
    physics.move([(x, y + 0.06, yaw + 1.0)])
    physics.release()
    physics.settle(0.3)
    before = _lateral_deviation(clip, physics.rope())
    result = primitives.flatten(physics, clip)
    after = _lateral_deviation(clip, physics.rope())
    assert result.success and before > 0.03 and after < 0.5 * before


def test_heuristic_inserts_a_straight_rope(clip_scene):
    physics = Physics(clip_scene)
    result = heuristic_insert(physics, clip_scene.clips[0])
    assert result.primitives == 2 and result.success


def test_shield_backs_vias_off_the_clip_and_moves_the_grasp(clip_scene):
    physics = Physics(clip_scene)
    clip = clip_scene.clips[0]
    risky = InsertParams(2, ((-0.08, 0.0, 0.0), (-0.016, 0.0, 0.4)))  # rotated fingers reach the clip
    safe = primitives.shielded(physics, clip, risky)
    assert safe.via[0] == risky.via[0] and -0.03 < safe.via[1][0] < -0.016
    assert physics.gripper_collision(*primitives._world_pose(clip, safe.via[1])) is None
    inside = Physics(one_clip_scene(head_x=0.005))  # the head and particle 1 lie in or at the tunnel
    moved = primitives.shielded(inside, clip, InsertParams(0, risky.via))
    assert moved.grasp_index > 0
    p = inside.rope()[moved.grasp_index]
    assert inside.gripper_collision(p[0], p[1], inside.rope_yaw_at(moved.grasp_index)) is None
