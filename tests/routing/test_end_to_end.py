"""Offline routing end to end: the rule-based planner with the shipped RL policy routes real scenes,
and the same seed gives the same result."""

import dataclasses

import pytest

from dloroute.routing.episode import EpisodeConfig, run_episode
from dloroute.sim.scene import generate_scene
from dloroute.types import FAMILIES

CONFIG = EpisodeConfig(planner="rule_based", low_level="rl")


@pytest.mark.parametrize("family", FAMILIES)
@pytest.mark.parametrize("seed", [1, 2])
def test_rule_based_rl_routes_every_family(family, seed):
    scene = generate_scene(family, seed)
    result = run_episode(scene, CONFIG)
    assert result.success, result.steps
    assert result.routed_order == scene.order and result.clips_routed == len(scene.clips)


def test_episode_is_deterministic_and_recording_a_video_changes_nothing(tmp_path):
    scene = generate_scene("fixed_attribute", 2)
    a = run_episode(scene, CONFIG)
    b = run_episode(scene, dataclasses.replace(CONFIG, video=str(tmp_path / "episode.mp4")))
    assert (tmp_path / "episode.mp4").stat().st_size > 0
    assert a.steps == b.steps and a.termination == b.termination and a.length == b.length
