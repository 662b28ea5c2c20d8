"""Physics: the rope settles, moves deterministically, threads a clip only through its opening, and
every failure mode (gripper collision, instability) is reported, never returned as numbers."""

import dataclasses

import mujoco
import numpy as np
import pytest
from scene_helpers import one_clip_scene

from dloroute.sim.clip_frame import (
    CLIP_DEPTH,
    POST_WIDTH,
    clip_status,
    opening_width,
    to_clip_frame,
    to_world_frame,
)
from dloroute.sim.physics import Physics, UnstableSimulation
from dloroute.sim.scene import generate_scene
from dloroute.types import FAMILIES


def world_pose(clip, x, y, yaw=0.0):
    p = to_world_frame(clip, np.array([x, y]))
    return float(p[0]), float(p[1]), clip.yaw + yaw


def push(physics, clip, grasp, xs, y=0.0, yaw=0.0):
    """Grasp particle ``grasp`` and drag it along the clip-frame line y through the x values."""
    assert physics.grasp(grasp) is None
    return physics.move([world_pose(clip, x, y, yaw) for x in xs])


@pytest.mark.parametrize("family", FAMILIES)
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_scenes_compile_and_settle(family, seed):
    scene = generate_scene(family, seed)
    physics = Physics(scene)
    start = physics.rope()
    physics.settle(0.5)
    rope = physics.rope()
    assert all(int(w.number) == 0 for w in physics.data.warning)
    assert np.abs(physics.rope_velocities()).max() < 0.01  # at rest
    assert np.abs(rope[:, :2] - start[:, :2]).max() < 0.005  # it lay where the scene put it
    assert np.allclose(rope[0, :2], scene.rope_head, atol=0.005)
    spacing = np.linalg.norm(np.diff(rope, axis=0), axis=1)
    assert np.allclose(spacing, scene.rope.spacing, rtol=0.02)  # inextensible
    assert np.all(rope[:, 2] > 0) and np.all(rope[:, 2] < 2 * scene.rope.radius)  # on the table


def test_same_seed_gives_bit_identical_trajectories():
    def run():
        scene = generate_scene("fixed_attribute", 4)
        physics = Physics(scene)
        physics.settle(0.2)
        clip = scene.clip(scene.order[0])
        push(physics, clip, 2, [-0.08, -0.016])
        physics.release()
        physics.settle(0.2)
        return physics.rope(), physics.data.qvel.copy()

    (a, va), (b, vb) = run(), run()
    assert np.array_equal(a, b) and np.array_equal(va, vb)


def test_scripted_push_goes_in_then_out_then_routed(clip_scene):
    physics = Physics(clip_scene)
    physics.settle(0.2)
    clip = clip_scene.clips[0]
    seen = []
    for x in (-0.09, -0.05, -0.016):  # the gripper holds particle 2, 5 cm behind the head
        push(physics, clip, 2, [x])
        physics.release()
        physics.settle(0.2)
        seen.append(clip_status(clip, physics.rope()))
        physics.grasp(2)
    assert [s.rope_in for s in seen] == [False, True, True]
    assert [s.rope_out for s in seen] == [False, False, True]
    assert seen[-1].routed
    head = to_clip_frame(clip, physics.rope()[0, :2])
    exit_centre = np.array([CLIP_DEPTH / 2, 0.0])
    assert seen[-1].signed_distance == pytest.approx(np.linalg.norm(head - exit_centre), abs=1e-9)
    assert seen[-1].signed_distance > 0.02


def test_head_pushed_into_a_post_does_not_pass(clip_scene):
    clip = clip_scene.clips[0]
    post_y = (opening_width(clip) + POST_WIDTH) / 2
    scene = one_clip_scene(head_y=post_y)
    physics = Physics(scene)
    physics.settle(0.2)
    push(physics, clip, 2, [-0.05, -0.016], y=post_y)  # head aimed at the post's centre, 3 cm past it
    physics.release()
    physics.settle(0.2)
    head = to_clip_frame(clip, physics.rope()[0, :2])
    status = clip_status(clip, physics.rope())
    assert not status.rope_in and not status.routed
    assert head[0] < -CLIP_DEPTH / 2 or abs(head[1]) > post_y  # stopped in front, or deflected sideways


def test_gripper_driven_into_a_clip_reports_collision(clip_scene):
    physics = Physics(clip_scene)
    physics.settle(0.2)
    clip = clip_scene.clips[0]
    result = push(physics, clip, 2, [-0.05, 0.0])  # the fingers cannot enter the tunnel
    assert result.collision == "red"
    fingers_x = to_clip_frame(clip, np.array(physics.gripper_pose()[:2]))[0]
    assert fingers_x < -CLIP_DEPTH / 2  # stopped before touching


def test_grasp_on_a_clip_reports_collision():
    physics = Physics(one_clip_scene(head_x=0.0))  # the head lies inside the tunnel
    assert physics.grasp(0) == "red"
    assert physics.grasped is None


def test_unstable_setting_is_caught():
    """A 50 ms step with a 1 mg rope tunnels through the clip: the guard refuses the state."""
    from dloroute.sim.physics import SimulationError

    scene = one_clip_scene()
    scene = dataclasses.replace(scene, rope=dataclasses.replace(scene.rope, young=1e8, mass=1e-6))
    physics = Physics(scene, timestep=0.05)
    with pytest.raises(SimulationError):
        physics.grasp(5)
        physics.move([(0.3, 0.2, 1.0)])
        physics.settle(1.0)


def test_exploding_velocity_is_caught(clip_scene):
    physics = Physics(clip_scene)
    physics.data.qvel[physics._slide_dofs[0]] = 50.0  # m/s
    with pytest.raises(UnstableSimulation, match="rope velocity"):
        physics.step(1)


def test_nan_state_is_caught(clip_scene):
    physics = Physics(clip_scene)
    physics.data.qvel[0] = np.nan
    with pytest.raises(UnstableSimulation, match="non-finite or huge"):
        physics.step(4)


def test_penetration_is_caught(clip_scene):
    from dloroute.sim.physics import Penetration

    physics = Physics(clip_scene)
    clip = clip_scene.clips[0]
    body = physics._particles[3]
    post_y = (opening_width(clip) + POST_WIDTH) / 2
    # Teleport one particle into the post's solid: the guard must refuse the state.
    jnt = physics.model.body_jntadr[body]
    qadr = physics.model.jnt_qposadr[jnt]
    offset = np.array([0.0, post_y, 0.0]) - physics.rope()[3] + physics.data.qpos[qadr : qadr + 3]
    physics.data.qpos[qadr : qadr + 3] = offset
    mujoco.mj_forward(physics.model, physics.data)
    with pytest.raises(Penetration, match="red"):
        physics.check()
