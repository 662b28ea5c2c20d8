"""Perception on rendered scenes against the simulator's ground truth (mm in the table plane)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from dloroute.perception import ImagePerceiver, OraclePerceiver, PerceptionError, View, perceive_physics
from dloroute.sim.clip_frame import clip_status, to_clip_frame, to_world_frame, wrap_angle
from dloroute.sim.physics import Physics
from dloroute.sim.render import SceneRenderer
from dloroute.sim.scene import generate_scene

CLIP_MM, YAW_DEG, ROPE_MM, HEAD_MM = 3.0, 3.0, 5.0, 5.0
"""The issue's targets."""


def _check_against_truth(physics: Physics, perceiver: ImagePerceiver):
    res = perceiver.analyse_physics(physics)
    obs, scene, truth = res.observation, physics.scene, physics.rope()
    assert obs.source == "perception"
    assert sorted(c.name for c in obs.clips) == sorted(c.name for c in scene.clips)
    for c in scene.clips:
        p = obs.clip(c.name)
        assert 1000 * math.hypot(p.x - c.x, p.y - c.y) < CLIP_MM
        assert abs(math.degrees(float(wrap_angle(p.yaw - c.yaw)))) < YAW_DEG
        assert p.scale == pytest.approx(c.scale, abs=0.08)
    assert obs.rope.shape == truth.shape
    err = 1000 * np.linalg.norm(obs.rope[: res.n_visible, :2] - truth[: res.n_visible, :2], axis=1)
    assert res.n_visible >= 4
    assert err.mean() < ROPE_MM and err[0] < HEAD_MM
    return res


@pytest.mark.parametrize("family,seed", [("implicit", 0), ("fixed_spatial", 1), ("clips_4_5", 2)])
def test_straight_rope_meets_targets(family, seed):
    physics = Physics(generate_scene(family, seed))
    physics.settle(0.3)
    with ImagePerceiver() as perceiver:
        res = _check_against_truth(physics, perceiver)
    assert res.head_end == "free"
    assert res.clip_mask(physics.scene.clips[0].name).any()


def test_rope_through_a_clip_stays_continuous_and_ordered():
    physics = Physics(generate_scene("implicit", 1))
    clip = physics.scene.clip(physics.scene.order[0])
    physics.settle(0.3)
    physics.grasp(3)  # 7.5 cm behind the head; push it along the clip's axis through the tunnel
    a, b = to_world_frame(clip, np.array([[-0.06, 0.0], [-0.03, 0.0]]))
    physics.move([(a[0], a[1], clip.yaw), (b[0], b[1], clip.yaw)])
    physics.release()
    physics.park_gripper()
    physics.settle(0.5)
    assert clip_status(clip, physics.rope()).routed
    with ImagePerceiver() as perceiver:
        res = _check_against_truth(physics, perceiver)
    rope = res.observation.rope
    steps = np.linalg.norm(np.diff(rope[:, :2], axis=0), axis=1)
    np.testing.assert_allclose(steps, physics.scene.rope.spacing, rtol=1e-6)  # no gap under the roof
    under = res.centreline[res.bridged]
    assert len(under) > 0 and all(abs(to_clip_frame(clip, under[:, :2])[:, 0]) < 0.03)
    seen = clip_status(res.observation.clip(clip.name), rope)
    assert seen.routed and seen.rope_out
    assert seen.crossing_index == pytest.approx(clip_status(clip, physics.rope()).crossing_index, abs=0.3)


def test_perceive_physics_with_the_episode_renderer():
    physics = Physics(generate_scene("fixed_spatial", 2))
    physics.settle(0.3)
    with SceneRenderer(physics) as renderer:
        obs = perceive_physics(physics, renderer)
        renderer.render(None)  # the lent renderer stays usable
    assert obs.source == "perception" and obs.rope.shape == physics.rope().shape
    assert 1000 * np.linalg.norm(obs.head[:2] - physics.rope()[0, :2]) < HEAD_MM
    with pytest.raises(ValueError, match="another Physics"):
        ImagePerceiver(renderer=renderer).perceive(Physics(generate_scene("fixed_spatial", 3)))


def test_oracle_matches_physics():
    physics = Physics(generate_scene("implicit", 3))
    physics.settle(0.1)
    obs = OraclePerceiver().perceive(physics)
    assert obs.source == "oracle"
    assert obs.clips == physics.scene.clips
    np.testing.assert_array_equal(obs.rope, physics.rope())


def test_scene_view_alone_and_an_image_without_rope():
    physics = Physics(generate_scene("clips_4_5", 0))
    physics.settle(0.1)
    with SceneRenderer(physics) as renderer:
        view = View(renderer.render(None), renderer.camera(None))
    res = ImagePerceiver(zoom=False).analyse(view, rope=physics.scene.rope)
    assert 1000 * np.linalg.norm(res.observation.head[:2] - physics.rope()[0, :2]) < HEAD_MM
    blank = View(np.full_like(view.image, 210), view.camera)
    with pytest.raises(PerceptionError, match="no rope"):
        ImagePerceiver(zoom=False).analyse(blank, rope=physics.scene.rope)


def test_whole_rope_in_view_picks_the_end_near_the_clip():
    """Both rope ends free in the image (a higher camera): the head is the end nearest a clip."""
    physics = Physics(generate_scene("implicit", 4))
    physics.settle(0.3)
    with SceneRenderer(physics) as renderer:
        cam = renderer.scene_camera
        pts = np.vstack([physics.rope()[:, :2], [[c.x, c.y] for c in physics.scene.clips]])
        lo, hi = pts.min(axis=0) - 0.05, pts.max(axis=0) + 0.05
        half = max((hi[0] - lo[0]) * cam.rows / cam.width, hi[1] - lo[1]) / 2
        renderer.scene_camera = replace(cam, cx=(lo[0] + hi[0]) / 2, cy=(lo[1] + hi[1]) / 2, width=1280, rows=960,
                                        height=half / math.tan(cam.fovy / 2))  # twice the pixels: rope 5 px wide
        view = View(renderer.render(None), renderer.camera(None))
    uv = view.camera.world_to_pixel(physics.rope())
    assert (uv >= 10).all() and (uv[:, 0] < view.camera.width - 10).all() and (uv[:, 1] < view.camera.rows - 10).all()
    res = ImagePerceiver(zoom=False).analyse(view, rope=physics.scene.rope)
    assert res.n_visible == physics.scene.rope.n_particles
    err = 1000 * np.linalg.norm(res.observation.rope[:, :2] - physics.rope()[:, :2], axis=1)
    assert err[0] < HEAD_MM and err.mean() < ROPE_MM


def test_too_coarse_an_image_is_refused():
    physics = Physics(generate_scene("implicit", 4))
    with SceneRenderer(physics) as renderer:
        renderer.scene_camera = replace(renderer.scene_camera, height=3 * renderer.scene_camera.height)
        view = View(renderer.render(None), renderer.camera(None))
    with pytest.raises(PerceptionError, match="px wide"):
        ImagePerceiver(zoom=False).analyse(view, rope=physics.scene.rope)
