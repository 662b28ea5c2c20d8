"""Offline planners on prepared states: synthetic ropes built in clip frames (no MuJoCo)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from planner_helpers import context, polyline_rope, step, straight_rope

from dloroute.planner.instruction import InstructionError
from dloroute.planner.planners import (
    INSERT_MAX_HEADING,
    FixedOrderPlanner,
    RuleBasedPlanner,
    SymbolicPlanner,
    VLMPlanner,
    failures_since_recovery,
    head_pose,
    make_planner,
)
from dloroute.planner.vlm import VLMConfig
from dloroute.sim.clip_frame import routed_order, to_world_frame
from dloroute.types import ClipSpec, Decision, SkillCall

RED, BLUE, GREEN = (
    ClipSpec("red", 0.0, 0.0, 0.0),
    ClipSpec("blue", 0.3, 0.12, 0.5),
    ClipSpec("green", 0.55, 0.0, -0.4),
)
CLIPS = (RED, BLUE, GREEN)
INSTRUCTION = "red, then blue, then green"


def local(clip: ClipSpec, x: float, y: float = 0.0) -> np.ndarray:
    return to_world_frame(clip, np.array([x, y]))


def routed_rope(through: list[ClipSpec], then: list[np.ndarray] | None = None) -> np.ndarray:
    """A rope threaded through ``through`` in order, along each clip's axis from 12 cm before its entry to
    12 cm past its exit; the head 5 cm past the last exit, or at the first of ``then`` (world points, head
    first) when given. 2 m long, so that it reaches back through every clip."""
    pts = list(then) if then else [local(through[-1], 0.06)]
    for clip in reversed(through):
        if then or clip is not through[-1]:
            pts.append(local(clip, 0.12))
        pts += [local(clip, 0.04), local(clip, -0.04), local(clip, -0.12)]
    pts.append(local(through[0], -1.0))
    return polyline_rope(pts, n=81)


def in_front(clip: ClipSpec, x: float = -0.06, y: float = 0.0, heading: float = 0.0) -> list[np.ndarray]:
    """Head at (x, y) in ``clip``'s frame with the front 5 cm of rope behind it along ``heading``."""
    return [local(clip, x, y), local(clip, x - 0.05 * math.cos(heading), y - 0.05 * math.sin(heading))]


def started(planner, rope, instruction: str = INSTRUCTION):
    planner.reset(instruction, context(CLIPS, rope).observation)
    return planner


def decide(planner, rope, history=(), failures: int = 0) -> Decision:
    return planner.decide(context(CLIPS, rope, history=history, consecutive_failures=failures))


START = straight_rope(RED, (-0.06, 0.0))


# ----------------------------------------------------------------------------- geometry
def test_head_pose_in_clip_frame() -> None:
    pose = head_pose(BLUE, straight_rope(BLUE, (-0.05, 0.02), 0.3))
    assert (
        pose.x == pytest.approx(-0.05)
        and pose.y == pytest.approx(0.02)
        and pose.heading == pytest.approx(0.3)
    )
    assert pose.in_region and pose.aligned and not pose.beside_or_behind
    assert not head_pose(BLUE, straight_rope(BLUE, (-0.05, 0.0), INSERT_MAX_HEADING + 0.1)).aligned
    assert head_pose(BLUE, straight_rope(BLUE, (0.02, 0.04))).beside_or_behind


def test_routed_rope_fixture() -> None:
    assert routed_order(CLIPS, routed_rope([RED, BLUE])) == ("red", "blue")
    assert routed_order(CLIPS, routed_rope([RED, BLUE], in_front(GREEN))) == ("red", "blue")
    assert routed_order(CLIPS, START) == ()


# ----------------------------------------------------------------------------- rule-based
def test_rule_inserts_when_head_aligned_in_front() -> None:
    planner = started(RuleBasedPlanner(), START)
    assert planner.order == ("red", "blue", "green")
    assert decide(planner, straight_rope(RED, (-0.06, 0.01), 0.2)).call == SkillCall("insert", "red")


def test_rule_inserts_when_head_inside_the_opening() -> None:
    planner = started(RuleBasedPlanner(), START)
    assert decide(planner, straight_rope(RED, (0.0, 0.0))).call == SkillCall("insert", "red")


def test_rule_pulls_when_head_far() -> None:
    planner = started(RuleBasedPlanner(), START)
    assert decide(planner, straight_rope(RED, (-0.4, 0.2))).call == SkillCall("pull", "red")


def test_rule_flattens_a_misaligned_head_once_then_pulls() -> None:
    planner = started(RuleBasedPlanner(), START)
    twisted = straight_rope(RED, (-0.05, 0.0), math.radians(135))  # pointing away from the opening
    assert decide(planner, twisted).call == SkillCall("flatten", "red")
    assert decide(planner, twisted, [step(0, "flatten", "red", True)]).call == SkillCall("pull", "red")


def test_rule_flattens_a_head_beside_or_behind_the_clip() -> None:
    planner = started(RuleBasedPlanner(), START)
    assert decide(planner, straight_rope(RED, (0.03, 0.05))).call == SkillCall("flatten", "red")
    assert decide(planner, straight_rope(RED, (0.08, -0.02))).call == SkillCall("flatten", "red")


def test_rule_flattens_after_two_failed_insertions() -> None:
    planner = started(RuleBasedPlanner(), START)
    aligned = straight_rope(RED, (-0.06, 0.0))
    one = [step(0, "pull", "red", True), step(1, "insert", "red", False)]
    two = [*one, step(2, "insert", "red", False)]
    assert decide(planner, aligned, one, failures=1).call == SkillCall("insert", "red")
    assert decide(planner, aligned, two, failures=2).call == SkillCall("flatten", "red")
    # After the Flatten the count restarts, even if the loop's counter was not reset by it.
    recovered = [*two, step(3, "flatten", "red", True)]
    assert decide(planner, aligned, recovered, failures=2).call == SkillCall("insert", "red")


def test_rule_flattens_after_two_failed_pulls() -> None:
    planner = started(RuleBasedPlanner(), START)
    far = straight_rope(RED, (-0.4, 0.2))
    one = [step(0, "pull", "red", False)]
    two = [*one, step(1, "pull", "red", False)]
    assert decide(planner, far, one).call == SkillCall("pull", "red")
    assert decide(planner, far, two).call == SkillCall("flatten", "red")
    assert decide(planner, far, [*two, step(2, "flatten", "red", True)]).call == SkillCall("pull", "red")


def test_rule_inserts_when_a_pull_did_not_clear_the_front() -> None:
    a, b = ClipSpec("red", 0.0, 0.0, 0.0), ClipSpec("blue", 0.13, 0.0, 0.0)
    # Through red, the head 4 cm past its exit: 9 cm in front of blue, aligned, but the front lies in red.
    rope = polyline_rope([local(a, 0.04), local(a, -0.04), local(a, -1.0)])
    planner = RuleBasedPlanner()
    planner.reset("red, then blue", context((a, b), rope).observation)
    inserted = [step(0, "insert", "red", True)]
    assert planner.decide(context((a, b), rope, history=inserted)).call == SkillCall("pull", "blue")
    pulled = [*inserted, step(1, "pull", "blue", False)]
    assert planner.decide(context((a, b), rope, history=pulled)).call == SkillCall("insert", "blue")


def test_rule_pulls_to_the_next_clip_after_a_routed_clip() -> None:
    planner = started(RuleBasedPlanner(), START)
    history = [step(0, "insert", "red", True)]
    assert decide(planner, routed_rope([RED]), history).call == SkillCall("pull", "blue")


def test_rule_inserts_into_the_next_clip_when_aligned() -> None:
    planner = started(RuleBasedPlanner(), START)
    assert decide(planner, routed_rope([RED], in_front(BLUE))).call == SkillCall("insert", "blue")
    assert decide(planner, routed_rope([RED, BLUE], in_front(GREEN, -0.1, 0.02))).call == SkillCall(
        "insert", "green"
    )


def test_rule_done_only_when_every_clip_is_routed_in_order() -> None:
    planner = started(RuleBasedPlanner(), START)
    assert decide(planner, routed_rope([RED, BLUE, GREEN])).done
    two = decide(planner, routed_rope([RED, BLUE]))
    assert not two.done and two.call is not None and two.call.clip == "green"
    wrong = routed_rope([RED, GREEN, BLUE])
    assert routed_order(CLIPS, wrong) == ("red", "green", "blue")
    decision = decide(planner, wrong)
    assert not decision.done and decision.failed and "not ('red', 'blue', 'green')" in decision.error


def test_rule_never_targets_a_routed_clip() -> None:
    planner = started(RuleBasedPlanner(), START)
    states = [
        routed_rope([RED]),
        routed_rope([RED], in_front(BLUE, -0.05, 0.0, math.radians(80))),
        routed_rope([RED], [local(RED, 0.3, 0.2), local(RED, 0.2, 0.1)]),
        routed_rope([RED, BLUE]),
        routed_rope([RED, BLUE], [local(BLUE, 0.05, 0.0), local(BLUE, 0.045, 0.0)]),
    ]
    for rope in states:
        for failures, history in [(0, []), (3, [step(i, "insert", "x", False) for i in range(3)])]:
            decision = decide(planner, rope, history, failures)
            routed = set(routed_order(CLIPS, rope))
            assert decision.call is not None and decision.call.clip not in routed


def test_rule_reset_rejects_a_bad_instruction() -> None:
    with pytest.raises(InstructionError, match="no clip is orange"):
        started(RuleBasedPlanner(), START, "red, then orange, then green")


# ----------------------------------------------------------------------------- symbolic
def test_symbolic_order_is_greedy_from_the_head_and_ignores_the_instruction() -> None:
    planner = started(SymbolicPlanner(), straight_rope(GREEN, (-0.06, 0.0)), "red, then blue, then green")
    assert planner.order[0] == "green"


def test_symbolic_flattens_after_three_failed_insertions() -> None:
    planner = started(SymbolicPlanner(), START)
    aligned = straight_rope(RED, (-0.06, 0.0))
    fails = [step(i, "insert", "red", False) for i in range(3)]
    assert decide(planner, aligned, fails[:2], failures=2).call == SkillCall("insert", "red")
    assert decide(planner, aligned, fails, failures=3).call == SkillCall("flatten", "red")
    assert decide(planner, aligned, [*fails, step(3, "flatten", "red", True)], failures=3).call == SkillCall(
        "insert", "red"
    )


def test_symbolic_inserts_in_front_regardless_of_heading_else_pulls() -> None:
    planner = started(SymbolicPlanner(), START)
    twisted = straight_rope(RED, (-0.05, 0.0), math.radians(135))  # pointing away from the opening
    assert decide(planner, twisted).call == SkillCall("insert", "red")
    assert decide(planner, straight_rope(RED, (-0.4, 0.2))).call == SkillCall("pull", "red")
    assert decide(planner, straight_rope(RED, (0.03, 0.05))).call == SkillCall("pull", "red")


def test_symbolic_done_when_every_clip_is_routed() -> None:
    planner = started(SymbolicPlanner(), START)
    assert planner.order == ("red", "blue", "green")
    assert decide(planner, routed_rope([RED, BLUE, GREEN])).done
    assert decide(planner, routed_rope([RED])).call == SkillCall("pull", "blue")


# ----------------------------------------------------------------------------- fixed order
def test_fixed_order_alternates_pull_and_insert_until_routed() -> None:
    planner = started(FixedOrderPlanner(("red", "blue", "green")), START)
    assert decide(planner, START).call == SkillCall("pull", "red")
    pulled = [step(0, "pull", "red", True)]
    assert decide(planner, START, pulled).call == SkillCall("insert", "red")
    failed = [*pulled, step(1, "insert", "red", False)]
    assert decide(planner, START, failed, failures=5).call == SkillCall("pull", "red")  # never flatten
    routed = [*pulled, step(1, "insert", "red", True)]
    assert decide(planner, routed_rope([RED]), routed).call == SkillCall("pull", "blue")
    assert decide(planner, routed_rope([RED, BLUE, GREEN])).done


def test_fixed_order_rejects_an_order_that_does_not_fit_the_scene() -> None:
    with pytest.raises(ValueError, match="permutation"):
        started(FixedOrderPlanner(("red", "blue")), START)


def test_failures_since_recovery_skips_pulls() -> None:
    history = [step(0, "insert", "red", False), step(1, "pull", "red", True), step(2, "insert", "red", False)]
    assert failures_since_recovery(context(CLIPS, START, history=history, consecutive_failures=2)) == 2
    assert failures_since_recovery(context(CLIPS, START, history=history, consecutive_failures=0)) == 0


# ----------------------------------------------------------------------------- factory
def test_make_planner(monkeypatch: pytest.MonkeyPatch) -> None:
    order = ("red", "blue", "green")
    assert isinstance(make_planner("rule_based", scene_order=order), RuleBasedPlanner)
    assert isinstance(make_planner("symbolic", scene_order=order), SymbolicPlanner)
    fixed = make_planner("fixed_order", scene_order=order)
    assert isinstance(fixed, FixedOrderPlanner) and fixed.order == order
    local_server = VLMConfig(base_url="http://127.0.0.1:9/v1", api_key_env="DLOROUTE_UNSET_KEY")
    monkeypatch.delenv("DLOROUTE_UNSET_KEY", raising=False)
    vlm = make_planner(
        "vlm", scene_order=order, vlm_config=local_server.model_copy(update={"failure_reasoning": False})
    )
    assert isinstance(vlm, VLMPlanner) and vlm.name == "vlm" and vlm.config.failure_reasoning
    with pytest.raises(ValueError, match="DLOROUTE_UNSET_KEY"):
        make_planner("vlm", scene_order=order, vlm_config=VLMConfig(api_key_env="DLOROUTE_UNSET_KEY"))
    with pytest.raises(ValueError, match="unknown planner"):
        make_planner("oracle", scene_order=order)
