"""The routing loop: end-to-end success, determinism, and every termination reason from a constructed case."""

import dataclasses
import json

import pytest
from scene_helpers import one_clip_scene

from dloroute.routing.episode import EpisodeConfig, run_episode, write_result
from dloroute.sim.physics import UnstableSimulation
from dloroute.sim.scene import generate_scene
from dloroute.types import Decision, SkillCall


class Scripted:
    """A planner that replays a fixed list of decisions, then repeats the last one."""

    name = "scripted"

    def __init__(self, *decisions):
        self.decisions = list(decisions)

    def reset(self, instruction, observation):
        pass

    def decide(self, ctx):
        return self.decisions.pop(0) if len(self.decisions) > 1 else self.decisions[0]


INSERT = Decision(call=SkillCall("insert", "red"))
PULL = Decision(call=SkillCall("pull", "red"))
DONE = Decision(call=None, done=True)
HEURISTIC = EpisodeConfig(planner="scripted", low_level="heuristic")


def test_scripted_success_on_one_clip():
    result = run_episode(one_clip_scene(), HEURISTIC, planner=Scripted(INSERT, DONE))
    assert result.success and result.termination == "success"
    assert result.clips_routed == 1 and result.length == 2 and result.routed_order == ("red",)


def test_done_too_early_is_early_termination():
    result = run_episode(one_clip_scene(), HEURISTIC, planner=Scripted(DONE))
    assert not result.success and result.termination == "early_termination" and result.length == 0


def test_collision_ends_the_episode():
    scene = one_clip_scene(head_x=0.0)  # the head lies in the tunnel: grasping it puts the fingers on the clip
    result = run_episode(scene, HEURISTIC, planner=Scripted(INSERT, DONE))
    assert result.termination == "collision" and not result.success
    assert result.steps[0]["collision"]


def test_step_limit_is_timeout():
    config = dataclasses.replace(HEURISTIC, step_limit=3)
    result = run_episode(one_clip_scene(), config, planner=Scripted(PULL))
    assert result.termination == "timeout" and result.length == 3


def test_done_at_the_step_limit_still_succeeds():
    config = dataclasses.replace(HEURISTIC, step_limit=2)  # the heuristic insertion takes 2 primitives
    result = run_episode(one_clip_scene(), config, planner=Scripted(INSERT, DONE))
    assert result.termination == "success" and result.length == 2


def test_failed_decisions_end_as_planner_failure():
    failed = Decision(call=None, failed=True, error="answer did not parse")
    result = run_episode(one_clip_scene(), HEURISTIC, planner=Scripted(failed))
    assert result.termination == "planner_failure" and result.length == 0
    assert all(s["failed"] for s in result.steps) and len(result.steps) == 3


def test_unstable_simulation_is_reported(monkeypatch):
    def explode(physics, clip):
        raise UnstableSimulation("rope velocity 99 m/s")

    monkeypatch.setattr("dloroute.skills.primitives.pull", explode)
    result = run_episode(one_clip_scene(), HEURISTIC, planner=Scripted(PULL))
    assert result.termination == "unstable" and not result.success
    assert "99 m/s" in result.steps[-1]["error"]


def test_instruction_naming_a_missing_colour_fails_before_motion():
    scene = dataclasses.replace(generate_scene("fixed_attribute", 0), instruction="Route the rope through the orange clip.")
    with pytest.raises(ValueError, match="orange"):
        run_episode(scene, EpisodeConfig(planner="rule_based", low_level="heuristic"))


def test_result_round_trips_to_json(tmp_path):
    result = run_episode(one_clip_scene(), HEURISTIC, planner=Scripted(INSERT, DONE))
    write_result(result, tmp_path / "result.json")
    loaded = json.loads((tmp_path / "result.json").read_text())
    assert loaded["success"] and loaded["termination"] == "success" and loaded["routed_order"] == ["red"]


def test_unmeasurable_scene_is_perception_failure(monkeypatch):
    from dloroute.perception import PerceptionError

    def blind(physics, renderer=None):
        raise PerceptionError("the head is not visible")

    monkeypatch.setattr("dloroute.perception.perceive_physics", blind)
    config = dataclasses.replace(HEURISTIC, perception="image")
    result = run_episode(one_clip_scene(), config, planner=Scripted(INSERT, DONE))
    assert result.termination == "perception_failure" and result.length == 0
    assert "not visible" in result.steps[-1]["error"]
